"""Seeded input samples for comparing generated C with the symbolic reference.

Joint configurations come in three kinds: uniform inside the limits; near a limit (a
joint at ``10^-k`` of its range from a bound, k in [2, 7]), where the Zghal terms blow
up; and near-singular (every joint at a multiple of 90° plus 1e-7 noise, which aligns
axes of DH chains built from 0/±90° twists). The other inputs are drawn per function:
task velocities and null-space vectors ~N(0, 1), damping in {0, 1e-4, 1e-2, 0.1},
``δ`` and the band fraction in sensible ranges, WLN weights in [1, 11]; lock masks with up to
two zeros, variable-damping thresholds, criterion ranges and gains of the spec 30/35 functions
in their documented ranges, and the collision functions' obstacles, clearance and activation
(see ``_DRAWS``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..description.collision import OBSTACLE_INPUTS, OBSTACLE_KINDS
from ..description.frames import rpy_matrix
from ..robot import Robot
from ..symbolic import ik
from ..symbolic.model import FROM_JACOBIAN
from ..symbolic.numeric import NumericModel

NEAR_LIMIT_FRACTION = 0.15
NEAR_SINGULAR_FRACTION = 0.15
SINGULAR_NOISE = 1e-7
DAMPING_CHOICES = (0.0, 1e-4, 1e-2, 0.1)
# Float precision cannot resolve a task velocity through a nearly singular Jacobian without
# damping, so float comparisons draw damping from the damped choices only.
FLOAT_DAMPING_CHOICES = (1e-2, 0.1)
# Variable damping (step_fault, step_wgpm): threshold ε and maximum λ (ρ_max). Float draws ε ≥ 0.03
# and λ_max ≤ 0.05, so that the slope ∂ρ²/∂σ² = (λ_max/ε)² ≤ 2.8 does not amplify the float error
# of the bisection estimate of σ_min² (~1e-7 ‖J Jᵀ‖) into the step.
EPSILON_RANGE = {"double": (0.005, 0.1), "float": (0.03, 0.1)}
LAMBDA_MAX_RANGE = {"double": (0.01, 0.1), "float": (0.01, 0.05)}
# step_wgpm's condition index tr(JJᵀ)/(m (det JJᵀ + δ²)^{1/m}) has a gradient that scales like
# δ^{-2(m+1)/m} at an exact singularity, where ∂det/∂q is pure rounding: float needs δ ≥ 1e-2
# (documented in docs/wgpm.md), so float draws log10 δ from [-2, -1] for that function.
FLOAT_WGPM_MIN_LOG_DELTA = -2
# Typical magnitudes of step_wgpm's criteria (w, H_M, H_L per joint, condition index): H_lo is
# drawn in [0, 1]·scale and H_hi = H_lo + [0.5, 2]·scale.
CRITERION_SCALES = (0.1, 0.5, 8.0, 20.0)
# ik starts from the sample plus N(0, 0.2 rad) per joint: a few steps from the target pose, so
# the float solver (whose path may part from the double one's) converges too; double compares
# every output bit for bit whatever the path.
IK_SEED_SPREAD = 0.2


def joint_samples(robot: Robot, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(q samples (count×n), kind per sample: 0 uniform, 1 near limit, 2 near singular)."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.qmin, robot.qmax
    span = hi - lo
    kind = rng.choice(3, size=count, p=[1 - NEAR_LIMIT_FRACTION - NEAR_SINGULAR_FRACTION,
                                         NEAR_LIMIT_FRACTION, NEAR_SINGULAR_FRACTION])
    q = rng.uniform(lo, hi, size=(count, robot.n))
    for s in np.flatnonzero(kind == 1):
        j = rng.integers(robot.n)
        gap = span[j] * 10.0 ** (-rng.uniform(2, 7))
        q[s, j] = lo[j] + gap if rng.random() < 0.5 else hi[j] - gap
    quarter = math.pi / 2
    for s in np.flatnonzero(kind == 2):
        k_lo = np.ceil(lo / quarter)
        k_hi = np.floor(hi / quarter)
        multiples = np.array([rng.integers(a, b + 1) if a <= b else 0 for a, b in zip(k_lo, k_hi)]) * quarter
        q[s] = np.clip(multiples + rng.normal(scale=SINGULAR_NOISE, size=robot.n), lo + 1e-9, hi - 1e-9)
    return q, kind


@dataclass(frozen=True)
class _Batch:
    """What the draws of one function's inputs share: ``args`` holds the inputs drawn so far."""

    func: ca.Function
    robot: Robot
    q: np.ndarray
    rng: np.random.Generator
    precision: str
    args: list[np.ndarray]

    @property
    def count(self) -> int:
        return len(self.q)

    def reference(self, name: str) -> np.ndarray:
        """The symbolic model's function ``name`` at the configurations (its only output): what
        derives from q is drawn from the reference, never from the compiled code under test."""
        (value,) = NumericModel(self.robot.symbolic).evaluate(name, self.q).values()
        return value

    def earlier(self, name: str) -> np.ndarray:
        return self.args[self.func.name_in().index(name)]

    def criterion_scales(self) -> np.ndarray:
        return np.array(CRITERION_SCALES) * np.where(np.arange(4) == 2, self.robot.n, 1)


def batch_inputs(func: ca.Function, robot: Robot, q: np.ndarray, rng: np.random.Generator,
                 precision: str = "double") -> list[np.ndarray]:
    """Inputs of ``func`` for every configuration in ``q`` (samples×n), drawn together:
    entry k has shape ``(samples,)`` for a scalar input, ``(samples, rows)`` for a vector and
    ``(samples, rows, cols)`` for a matrix (the J input of the *_from_jacobian twins)."""
    batch = _Batch(func, robot, np.atleast_2d(np.asarray(q, dtype=float)), rng, precision, [])
    for k, name in enumerate(func.name_in()):
        draw = _DRAWS.get(name, _normal)
        batch.args.append(draw(batch, func.sparsity_in(k).shape[0]))
    return batch.args


def _normal(b: _Batch, rows: int) -> np.ndarray:
    return b.rng.normal(size=(b.count, rows))


def _iteration_caps(b: _Batch, rows: int) -> np.ndarray:
    """Double also checks the early stop (float is judged by its pose)."""
    capped = (b.rng.random(b.count) < 0.5) if b.precision == "double" else np.zeros(b.count, dtype=bool)
    return np.where(capped, b.rng.integers(1, ik.MAX_ITERATIONS + 1, size=b.count), ik.MAX_ITERATIONS).astype(float)


def _delta(b: _Batch, rows: int) -> np.ndarray:
    float_wgpm = b.precision == "float" and b.func.name().removesuffix(FROM_JACOBIAN) == "step_wgpm"
    lo = FLOAT_WGPM_MIN_LOG_DELTA if float_wgpm else -4
    return 10 ** b.rng.uniform(lo, -1, size=b.count)


def _lock_mask(b: _Batch, rows: int) -> np.ndarray:
    """0 = locked; up to two locked joints, at least m healthy when possible."""
    locked = b.rng.integers(0, min(3, rows), size=b.count)
    rank = np.argsort(b.rng.random((b.count, rows)), axis=1).argsort(axis=1)  # a random order of the joints
    return np.where(rank < locked[:, None], 0.0, 1.0)


def _ramp(b: _Batch, rows: int) -> np.ndarray:
    """Off, full, or in between: a third each."""
    return np.choose(b.rng.integers(0, 3, size=b.count), [np.zeros(b.count), np.ones(b.count),
                                                          b.rng.uniform(0, 1, size=b.count)])


def _ik_tolerance(double: float) -> Callable[[_Batch, int], np.ndarray]:
    """The ik success threshold: ``double`` for the double build, ``ik.FLOAT_TOL`` for float."""
    return lambda b, rows: np.full(b.count, double if b.precision == "double" else ik.FLOAT_TOL)


# The configuration, what derives from it, and the ik solver's inputs (a seed near q, IK_SEED_SPREAD).
_CONFIGURATION_DRAWS: dict[str, Callable[[_Batch, int], np.ndarray]] = {
    "q": lambda b, rows: b.q,
    "J": lambda b, rows: b.reference("jacobian").reshape(b.count, 6, b.robot.n),
    "T_target": lambda b, rows: b.reference("fk").reshape(b.count, 4, 4),
    "q_seed": lambda b, rows: np.clip(b.q + b.rng.normal(scale=IK_SEED_SPREAD, size=(b.count, b.robot.n)),
                                      b.robot.qmin, b.robot.qmax),
    "q_rest": lambda b, rows: b.rng.uniform(b.robot.qmin, b.robot.qmax, size=(b.count, b.robot.n)),
    "use_rest": lambda b, rows: b.rng.integers(0, 2, size=b.count).astype(float),
    "tol_position": _ik_tolerance(ik.TOL_POSITION),
    "tol_orientation": _ik_tolerance(ik.TOL_ORIENTATION),
    "max_iterations": _iteration_caps,
}
# The resolved-rate steps' parameters, variable damping (step_fault, step_wgpm) included.
_STEP_DRAWS: dict[str, Callable[[_Batch, int], np.ndarray]] = {
    "q_init": lambda b, rows: b.rng.uniform(b.robot.qmin, b.robot.qmax, size=(b.count, b.robot.n)),
    "damping": lambda b, rows: b.rng.choice(DAMPING_CHOICES if b.precision == "double" else FLOAT_DAMPING_CHOICES,
                                            size=b.count),
    "delta": _delta,
    "band": lambda b, rows: b.rng.uniform(0.02, 0.3, size=b.count),
    "a": lambda b, rows: b.rng.uniform(0.5, 2.0, size=(b.count, rows)),
    "W": lambda b, rows: 1 + b.rng.uniform(0, 10, size=(b.count, rows)),
    "mask": _lock_mask,
    "epsilon": lambda b, rows: b.rng.uniform(*EPSILON_RANGE[b.precision], size=b.count),
    "lambda_max": lambda b, rows: b.rng.uniform(*LAMBDA_MAX_RANGE[b.precision], size=b.count),
    "rho_max": lambda b, rows: b.rng.uniform(*LAMBDA_MAX_RANGE[b.precision], size=b.count),
    "t_rmax": lambda b, rows: b.rng.uniform(0, 0.5, size=b.count),
    "ramp": _ramp,
}
# step_wgpm's criterion bands and gains; H_hi and k_lo are drawn relative to H_lo and k_hi.
_CRITERION_BAND_DRAWS: dict[str, Callable[[_Batch, int], np.ndarray]] = {
    "H_lo": lambda b, rows: b.rng.uniform(0, 1, size=(b.count, rows)) * b.criterion_scales(),
    "H_hi": lambda b, rows: b.earlier("H_lo") + b.rng.uniform(0.5, 2, size=(b.count, rows)) * b.criterion_scales(),
    "k_hi": lambda b, rows: b.rng.uniform(0, 1, size=(b.count, rows)),
    "k_lo": lambda b, rows: b.earlier("k_hi") * b.rng.uniform(0, 1, size=(b.count, rows)),
    "u_th": lambda b, rows: b.rng.uniform(0, 0.6, size=(b.count, rows)),
    "u_band": lambda b, rows: b.rng.uniform(0.1, 0.5, size=(b.count, rows)),
    "omega": lambda b, rows: b.rng.uniform(0, 0.3, size=(b.count, rows)),
    "b": lambda b, rows: b.rng.uniform(0, 5, size=b.count),
    "omega_floor": lambda b, rows: 10 ** b.rng.uniform(-4, -2, size=b.count),
    # half of them 0, which selects the plain on/off rule
    "v_band": lambda b, rows: np.where(b.rng.random(b.count) < 0.5, 0.0, b.rng.uniform(0.05, 0.5, size=b.count)),
}
# Obstacles of the collision functions (docs/collision.md): each slot active with probability
# OBSTACLE_ACTIVE; centres and points uniform in the cube of half-width the arm's reach at the
# samples (so that some pass close to the arm), radii and half-extents in OBSTACLE_SIZE (m),
# boxes turned by uniform roll, pitch, yaw, planes with a uniform random unit normal.
OBSTACLE_ACTIVE = 0.9
OBSTACLE_SIZE = (0.02, 0.25)
# clearance in [0, 0.05] m, activation 0.05–0.3 m above it: bands the arm's distances cross.
CLEARANCE_RANGE = (0.0, 0.05)
ACTIVATION_BAND = (0.05, 0.3)


def _reach(b: _Batch) -> float:
    return float(np.max(np.linalg.norm(b.reference("fk")[..., :3, 3], axis=-1)))


def _points(b: _Batch, slots: int) -> np.ndarray:
    reach = _reach(b)
    return b.rng.uniform(-reach, reach, size=(b.count, 3, slots))


def _sizes(b: _Batch, rows: int, slots: int) -> np.ndarray:
    return b.rng.uniform(*OBSTACLE_SIZE, size=(b.count, rows, slots))


def _active(b: _Batch, slots: int) -> np.ndarray:
    return (b.rng.random((b.count, 1, slots)) < OBSTACLE_ACTIVE).astype(float)


def _obstacle_slots(kind: str) -> Callable[[_Batch, int], np.ndarray]:
    """The (samples, rows, slots) draws of one obstacle input (rows as OBSTACLE_ROWS)."""

    def draw(b: _Batch, rows: int) -> np.ndarray:
        slots = b.func.sparsity_in(b.func.name_in().index(OBSTACLE_INPUTS[kind])).shape[1]
        if kind == "sphere":
            parts = [_points(b, slots), _sizes(b, 1, slots)]
        elif kind == "capsule":
            parts = [_points(b, slots), _points(b, slots), _sizes(b, 1, slots)]
        elif kind == "box":
            angles = b.rng.uniform(-math.pi, math.pi, size=(b.count, slots, 3))
            rotations = np.array([[rpy_matrix(*angles[s, k]).T.reshape(-1) for k in range(slots)]
                                  for s in range(b.count)]).transpose(0, 2, 1)
            parts = [_points(b, slots), rotations, _sizes(b, 3, slots)]
        else:
            normals = b.rng.normal(size=(b.count, 3, slots))
            normals /= np.linalg.norm(normals, axis=1, keepdims=True)
            offsets = np.einsum("sik,sik->sk", normals, _points(b, slots))[:, None, :]
            parts = [normals, offsets]
        return np.concatenate([*parts, _active(b, slots)], axis=1)

    return draw


_COLLISION_DRAWS: dict[str, Callable[[_Batch, int], np.ndarray]] = {
    **{OBSTACLE_INPUTS[kind]: _obstacle_slots(kind) for kind in OBSTACLE_KINDS},
    "clearance": lambda b, rows: b.rng.uniform(*CLEARANCE_RANGE, size=b.count),
    "activation": lambda b, rows: b.earlier("clearance") + b.rng.uniform(*ACTIVATION_BAND, size=b.count),
}
# Any other input (task velocities, null-space vectors, gradients) is ~N(0, 1): _normal.
_DRAWS = {**_CONFIGURATION_DRAWS, **_STEP_DRAWS, **_CRITERION_BAND_DRAWS, **_COLLISION_DRAWS}


def function_inputs(func: ca.Function, robot: Robot, q: np.ndarray, rng: np.random.Generator,
                    precision: str = "double") -> list[np.ndarray | float]:
    """Inputs for one call of ``func`` at configuration ``q`` (one sample of :func:`batch_inputs`)."""
    return [float(a[0]) if a.ndim == 1 else a[0] for a in batch_inputs(func, robot, np.asarray(q)[None], rng, precision)]
