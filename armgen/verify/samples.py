"""Seeded input samples for comparing generated C with the symbolic reference.

Joint configurations come in three kinds: uniform inside the limits; near a limit (a
joint at ``10^-k`` of its range from a bound, k in [2, 7]), where the Zghal terms blow
up; and near-singular (every joint at a multiple of 90° plus 1e-7 noise, which aligns
axes of DH chains built from 0/±90° twists). The other inputs are drawn per function:
task velocities and null-space vectors ~N(0, 1), damping in {0, 1e-4, 1e-2, 0.1},
``δ`` and the band fraction in sensible ranges, WLN weights in [1, 11].
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from ..robot import Robot

NEAR_LIMIT_FRACTION = 0.15
NEAR_SINGULAR_FRACTION = 0.15
SINGULAR_NOISE = 1e-7
DAMPING_CHOICES = (0.0, 1e-4, 1e-2, 0.1)
# Float precision cannot resolve a task velocity through a nearly singular Jacobian without
# damping, so float comparisons draw damping from the damped choices only.
FLOAT_DAMPING_CHOICES = (1e-2, 0.1)


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


def function_inputs(func: ca.Function, robot: Robot, q: np.ndarray, rng: np.random.Generator,
                    precision: str = "double") -> list[np.ndarray | float]:
    """Inputs for one call of ``func`` at configuration ``q``."""
    args: list[np.ndarray | float] = []
    damping = DAMPING_CHOICES if precision == "double" else FLOAT_DAMPING_CHOICES
    for k in range(func.n_in()):
        name = func.name_in(k)
        shape = func.sparsity_in(k).shape
        if name == "q":
            args.append(q)
        elif name == "q_init":
            args.append(rng.uniform(robot.qmin, robot.qmax))
        elif name == "damping":
            args.append(float(rng.choice(damping)))
        elif name == "delta":
            args.append(float(10 ** rng.uniform(-4, -1)))
        elif name == "band":
            args.append(float(rng.uniform(0.02, 0.3)))
        elif name == "a":
            args.append(rng.uniform(0.5, 2.0, size=shape[0]))
        elif name == "W":
            args.append(1 + rng.uniform(0, 10, size=shape[0]))
        else:
            args.append(rng.normal(size=shape[0]))
    return args
