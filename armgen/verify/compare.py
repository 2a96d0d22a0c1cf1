"""Compare compiled C functions with the CasADi interpreter over seeded samples.

Error measure per call and output: ``max|C − ref| / max(max|ref|, floor)``. Double uses a
tiny floor (true normwise relative error). Float is compared with the double reference
evaluated at the float-rounded inputs (the float code never sees anything else), with a
unit floor so that outputs that pass through zero are judged on an absolute SI scale,
and skipping configurations closer to a limit than ``FLOAT_MIN_LIMIT_DISTANCE`` (there the
Zghal barrier's value depends on digits that float does not hold).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..robot import Robot
from ..symbolic import ik
from ..symbolic.model import FROM_JACOBIAN, IK_FUNCTIONS
from ..codegen.compiled import CompiledModel
from .samples import function_inputs, joint_samples

# double: the generated code is the SX algorithm op for op; only libm may differ (≤ 1 ulp
# per call), which the chain of products amplifies by far less than 1e4.
DOUBLE_REL_BOUND = 1e-12
DOUBLE_FLOOR = 1e-300
FLOAT_FLOOR = 1.0
FLOAT_MIN_LIMIT_DISTANCE = 1e-3  # rad (or m): 4000 float ulps of a 2.4 rad angle
# Float bounds per function (normwise, unit floor), each about 10x the worst seen over
# 10 000 samples on the bundled robots; the reason for each size in brackets.
FLOAT_BOUNDS = {
    "fk": 2e-6,  # [chain of 8 rotations, ~16 ulp]
    "jacobian": 2e-6,
    "fk_jacobian": 2e-6,
    "repetitive": 2e-6,
    "zghal": 2e-2,  # [ulp(q)/distance-to-limit ≥ 2.4e-7/1e-3 per term, squared in the gradient]
    # [determinants by Householder QR of Jᵀ: relative error ~ ε κ(J), not ε κ(J)² as through
    # J Jᵀ; the gradient outputs dominate; seen ≤ 5.5e-5 (modular8) / 9.9e-5 (planar3 w)]
    "joint_manipulability": 1e-3,
    "manipulability": 1e-3,
    "continuous_weights": 1e-4,  # [band edges from float-rounded limits]
    "step_gpm": 2e-2,  # [condition number (σ_max/λ)² ≤ 1e4 with λ ≥ 1e-2, times float eps]
    "step_wln": 2e-2,
    "ft_index": 1e-3,  # [as joint_manipulability, masked columns; seen ≤ 5.2e-5 (planar3)]
    "wln_weights": 2e-6,  # [a few arithmetic ops per joint; seen 2.3e-7]
    # [σ_min² by bisection carries ~1e-7 ‖JJᵀ‖ absolute error, amplified by (λ_max/ε)² ≤ 2.8 into
    # ρ² and by the conditioning (σ_max/ε)² of the damped solve; seen 9e-4]
    "step_fault": 1e-2,
    # [step_fault's error plus the criteria gradients (condition index ~δ^{-2(m+1)/m} at a
    # singularity, float draws δ ≥ 1e-2) and the clipped gains; seen 5.7e-3 on planar3]
    "step_wgpm": 5e-2,
    # [ik: not the double solver's outputs (a float path may take other steps to another
    # solution of a redundant arm) but how far the float C's q is from the target, by the double
    # FK: its tolerance FLOAT_TOL plus the float FK's error (fk above)]
    "ik": ik.FLOAT_TOL + 2e-6,
}


@dataclass
class FunctionComparison:
    name: str
    precision: str
    samples: int
    max_error: float
    worst_sample: int
    bound: float

    @property
    def passed(self) -> bool:
        return bool(self.max_error <= self.bound)


def _round_to_float(args: list) -> list:
    return [float(np.float32(a)) if np.ndim(a) == 0 else np.asarray(a, dtype=np.float32).astype(float) for a in args]


def _batched_reference(func: ca.Function, calls: list[list]) -> list[np.ndarray]:
    """Evaluate ``func`` on all calls at once with ``Function.map``; outputs per call stacked."""
    n = len(calls)
    mapped = func.map(n)
    stacked = []
    for k in range(func.n_in()):
        shape = func.sparsity_in(k).shape  # map() takes the calls' matrices side by side
        stacked.append(np.hstack([np.reshape(np.asarray(c[k], dtype=float), shape, order="F") for c in calls]))
    outs = mapped(*stacked)
    outs = outs if isinstance(outs, tuple) else (outs,)
    result = []
    for k, out in enumerate(outs):
        rows, cols = func.sparsity_out(k).shape
        arr = np.array(out).reshape(rows, n, cols)  # map() concatenates the calls horizontally
        result.append(arr)
    return result


def _ik_reference(robot: Robot, calls: list[list]) -> list[np.ndarray]:
    """ik's outputs for the calls, by the NumPy replay of its SX (which leaves the loop for the
    converged samples, where CasADi's map runs every iteration), shaped as _batched_reference's."""
    n = len(calls)
    inputs = [np.stack([np.reshape(np.asarray(c[k], dtype=float), -1, order="F") for c in calls], axis=1)
              for k in range(len(calls[0]))]
    return [out.reshape(out.shape[0], n, 1) for out in ik.definition(robot).batch(inputs, n)]


def compare_model(compiled: CompiledModel, references: dict[str, ca.Function], robot: Robot, samples: int,
                  seed: int) -> list[FunctionComparison]:
    precision = compiled.precision
    if precision == "float":
        # draw extra so that `samples` remain after dropping the too-near-limit ones
        q_all, _ = joint_samples(robot, 2 * samples, seed)
        dist = np.minimum(q_all - robot.qmin, robot.qmax - q_all).min(axis=1)
        q_all = q_all[dist >= FLOAT_MIN_LIMIT_DISTANCE][:samples]
    else:
        q_all, _ = joint_samples(robot, samples, seed)
    report = []
    for index, (name, func) in enumerate(references.items()):
        rng = np.random.default_rng([seed, index])
        calls = [function_inputs(func, robot, q, rng, precision) for q in q_all]
        if precision == "float":
            calls = [_round_to_float(c) for c in calls]
        refs = _ik_reference(robot, calls) if name in IK_FUNCTIONS else _batched_reference(func, calls)
        floor = FLOAT_FLOOR if precision == "float" else DOUBLE_FLOOR
        worst, worst_at = 0.0, -1
        c_fn = compiled.raw[name]
        for s, call in enumerate(calls):
            got = c_fn(*call)
            err = 0.0
            if name in IK_FUNCTIONS and precision == "float":
                # judged by the pose it reaches, not by the double solver's outputs
                err = max(float(e) for e in ik.definition(robot).errors(got[0].reshape(-1), call[0]))
                got = []
            for k, out in enumerate(got):
                ref = refs[k][:, s, :]
                scale = max(float(np.max(np.abs(ref))), floor)
                err = max(err, float(np.max(np.abs(out - ref))) / scale)
            if not err <= worst:  # NaN counts as the worst
                worst, worst_at = err, s
        bound = DOUBLE_REL_BOUND if precision == "double" else FLOAT_BOUNDS[name.removesuffix(FROM_JACOBIAN)]
        report.append(FunctionComparison(name, precision, len(calls), worst, worst_at, bound))
    return report
