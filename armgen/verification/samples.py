"""Seeded input samples for comparing generated C with the symbolic reference.

Joint configurations come in three kinds: uniform inside the limits; near a limit (a
joint at ``10^-k`` of its range from a bound, k in [2, 7]), where the Zghal terms blow
up; and near-singular (every joint at a multiple of 90° plus 1e-7 noise, which aligns
axes of DH chains built from 0/±90° twists). The other inputs are drawn per function:
task velocities and null-space vectors ~N(0, 1), damping in {0, 1e-4, 1e-2, 0.1},
``δ`` and the band fraction in sensible ranges, WLN weights in [1, 11]; lock masks with up to
two zeros, variable-damping thresholds, criterion ranges and gains of the spec 30/35 functions
in their documented ranges (see ``batch_inputs``).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from ..robot import Robot
from ..symbolic import ik
from ..symbolic.model import FROM_JACOBIAN

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


def batch_inputs(func: ca.Function, robot: Robot, q: np.ndarray, rng: np.random.Generator,
                 precision: str = "double") -> list[np.ndarray]:
    """Inputs of ``func`` for every configuration in ``q`` (samples×n), drawn together:
    entry k has shape ``(samples,)`` for a scalar input, ``(samples, rows)`` for a vector and
    ``(samples, rows, cols)`` for a matrix (the J input of the *_from_jacobian twins)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    count = len(q)
    args: list[np.ndarray] = []
    damping = DAMPING_CHOICES if precision == "double" else FLOAT_DAMPING_CHOICES
    criterion_scales = np.array(CRITERION_SCALES) * np.where(np.arange(4) == 2, robot.n, 1)
    names = func.name_in()
    for k, name in enumerate(names):
        rows = func.sparsity_in(k).shape[0]
        vector = (count, rows)
        if name == "q":
            args.append(q)
        elif name == "J":  # the robot's Jacobian at q
            args.append(robot.jacobian(q).reshape(count, 6, robot.n))
        elif name == "T_target":  # ik: the pose at q, solved from a seed near q (IK_SEED_SPREAD)
            args.append(robot.fk(q).reshape(count, 4, 4))
        elif name == "q_seed":
            args.append(np.clip(q + rng.normal(scale=IK_SEED_SPREAD, size=(count, robot.n)), robot.qmin, robot.qmax))
        elif name == "q_rest":
            args.append(rng.uniform(robot.qmin, robot.qmax, size=(count, robot.n)))
        elif name == "use_rest":
            args.append(rng.integers(0, 2, size=count).astype(float))
        elif name == "tol_position":
            args.append(np.full(count, ik.TOL_POSITION if precision == "double" else ik.FLOAT_TOL))
        elif name == "tol_orientation":
            args.append(np.full(count, ik.TOL_ORIENTATION if precision == "double" else ik.FLOAT_TOL))
        elif name == "max_iterations":  # double also checks the early stop (float is judged by its pose)
            capped = (rng.random(count) < 0.5) if precision == "double" else np.zeros(count, dtype=bool)
            args.append(np.where(capped, rng.integers(1, ik.MAX_ITERATIONS + 1, size=count),
                                 ik.MAX_ITERATIONS).astype(float))
        elif name == "q_init":
            args.append(rng.uniform(robot.qmin, robot.qmax, size=(count, robot.n)))
        elif name == "damping":
            args.append(rng.choice(damping, size=count))
        elif name == "delta":
            lo = FLOAT_WGPM_MIN_LOG_DELTA if (precision == "float" and func.name().removesuffix(FROM_JACOBIAN) == "step_wgpm") else -4
            args.append(10 ** rng.uniform(lo, -1, size=count))
        elif name == "band":
            args.append(rng.uniform(0.02, 0.3, size=count))
        elif name == "a":
            args.append(rng.uniform(0.5, 2.0, size=vector))
        elif name == "W":
            args.append(1 + rng.uniform(0, 10, size=vector))
        elif name == "mask":  # 0 = locked; up to two locked joints, at least m healthy when possible
            locked = rng.integers(0, min(3, rows), size=count)
            rank = np.argsort(rng.random(vector), axis=1).argsort(axis=1)  # a random order of the joints
            args.append(np.where(rank < locked[:, None], 0.0, 1.0))
        elif name == "epsilon":
            args.append(rng.uniform(*EPSILON_RANGE[precision], size=count))
        elif name in ("lambda_max", "rho_max"):
            args.append(rng.uniform(*LAMBDA_MAX_RANGE[precision], size=count))
        elif name == "t_rmax":
            args.append(rng.uniform(0, 0.5, size=count))
        elif name == "ramp":  # off, full, or in between: a third each
            args.append(np.choose(rng.integers(0, 3, size=count), [np.zeros(count), np.ones(count),
                                                                    rng.uniform(0, 1, size=count)]))
        elif name == "H_lo":
            args.append(rng.uniform(0, 1, size=vector) * criterion_scales)
        elif name == "H_hi":
            args.append(args[names.index("H_lo")] + rng.uniform(0.5, 2, size=vector) * criterion_scales)
        elif name == "k_hi":
            args.append(rng.uniform(0, 1, size=vector))
        elif name == "k_lo":
            args.append(args[names.index("k_hi")] * rng.uniform(0, 1, size=vector))
        elif name == "u_th":
            args.append(rng.uniform(0, 0.6, size=vector))
        elif name == "u_band":
            args.append(rng.uniform(0.1, 0.5, size=vector))
        elif name == "omega":
            args.append(rng.uniform(0, 0.3, size=vector))
        elif name == "b":
            args.append(rng.uniform(0, 5, size=count))
        elif name == "omega_floor":
            args.append(10 ** rng.uniform(-4, -2, size=count))
        elif name == "v_band":  # half of them 0, which selects the plain on/off rule
            args.append(np.where(rng.random(count) < 0.5, 0.0, rng.uniform(0.05, 0.5, size=count)))
        else:
            args.append(rng.normal(size=vector))
    return args


def function_inputs(func: ca.Function, robot: Robot, q: np.ndarray, rng: np.random.Generator,
                    precision: str = "double") -> list[np.ndarray | float]:
    """Inputs for one call of ``func`` at configuration ``q`` (one sample of :func:`batch_inputs`)."""
    return [float(a[0]) if a.ndim == 1 else a[0] for a in batch_inputs(func, robot, np.asarray(q)[None], rng, precision)]
