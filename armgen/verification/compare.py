"""Compare compiled C functions with the CasADi interpreter over seeded samples.

Error measure per call and output: ``max|C − ref| / max(max|ref|, floor)``. Double uses a
tiny floor (true normwise relative error) against CasADi's interpreter. Float is compared with
the double reference (the NumPy replay of the same SX instructions) evaluated at the float-rounded inputs (the float code never sees anything else), with a
unit floor so that outputs that pass through zero are judged on an absolute SI scale,
and skipping configurations closer to a limit than ``FLOAT_MIN_LIMIT_DISTANCE`` (there the
Zghal barrier's value depends on digits that float does not hold).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import casadi as ca
import numpy as np

from ..robot import Robot
from ..symbolic import ik
from ..symbolic.model import FROM_JACOBIAN, IK_FUNCTIONS
from ..symbolic.replay import BatchFunction
from .samples import batch_inputs, joint_samples

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
    # FK: its tolerance FLOAT_TOL plus the float FK's error (fk above); a miss the double
    # solver shares is not counted (float_ik_errors)]
    "ik": ik.FLOAT_TOL + 2e-6,
    # [the dynamics: the recursions over n links (rotations, cross products, the inertials
    # rounded to float); seen ≤ 2.4e-6 (rnea), 2.2e-6 (gravity), 1.4e-6 (coriolis) and 5.5e-7
    # (mass_matrix) over 5 000–10 000 samples on the 6–7-joint arms of example-robot-data]
    "gravity": 2e-5,
    "rnea": 2e-5,
    "mass_matrix": 5e-6,
    "coriolis": 2e-5,
    # [the collision distances: FK, the segment clamps and the box-frame transforms in float; seen
    # ≤ 5.7e-7 m absolute on distances up to 3 m (3000 samples, a 7-DOF arm with 5 capsules and 12
    # obstacle slots)]
    "collision_distances": 5e-6,
    # [the barrier's slope (up to 7600/(ρ − c) per m, symbolic.collision.BARRIER_FLOOR) times float's
    # error in ∂d/∂q, ~1e-5 where a distance is stationary (the verifier's near-singular samples:
    # a straight wrist); seen 1.5e-2 (a 7-DOF arm, 3000 samples), 6.7e-4 (a planar 3R). Two axes
    # within ~1e-6 rad of parallel (the bundled panda's column and forearm at the straight-arm
    # sample q2 = −q4 = π/2) have a whole overlap of closest points: double takes them as parallel
    # (segment_segment_witness), float's a·e − b² is rounding noise above that threshold and puts
    # the witness elsewhere on the overlap, whose lever moves the gradient: seen 0.27 (panda,
    # 10 000 samples); the bound is twice that, as the error is a choice of witness, not a sum]
    "collision_criterion": 0.5,
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


def _per_sample(values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """One input for all samples, each flattened column-major: (samples, rows·cols)."""
    n = len(values)
    return values.reshape(n, 1) if values.ndim == 1 else values.reshape(n, *shape).transpose(0, 2, 1).reshape(n, -1)


def _batched_reference(func: ca.Function, inputs: list[np.ndarray]) -> list[np.ndarray]:
    """Evaluate ``func`` on all samples at once with ``Function.map``; outputs (samples, rows, cols)."""
    n = len(inputs[0])
    stacked = []  # map() takes the samples' matrices side by side: (rows, samples·cols)
    for k, values in enumerate(inputs):
        rows, cols = func.sparsity_in(k).shape
        stacked.append(_per_sample(values, (rows, cols)).reshape(n, cols, rows).transpose(2, 0, 1)
                       .reshape(rows, n * cols))
    outs = func.map(n)(*stacked)
    outs = outs if isinstance(outs, tuple) else (outs,)
    result = []
    for k, out in enumerate(outs):
        rows, cols = func.sparsity_out(k).shape
        result.append(np.array(out).reshape(rows, n, cols).transpose(1, 0, 2))
    return result


def _replayed_reference(func: ca.Function, inputs: list[np.ndarray]) -> list[np.ndarray]:
    """``func`` on all samples by the NumPy replay of its SX instructions (shaped as
    _batched_reference's): the float comparison's double reference. Its bounds are ≥ 2e-6, and
    the replay is the interpreter's operations in the same order (equal to it to ~1e-13), at an
    eighth of the interpreter's cost on 10 000 samples; the double comparison, bit for bit, keeps
    CasADi's interpreter."""
    n = len(inputs[0])
    columns = [np.ascontiguousarray(_per_sample(values, func.sparsity_in(k).shape).T) for k, values in enumerate(inputs)]
    return [out.reshape(func.size2_out(k), func.size1_out(k), n).transpose(2, 1, 0)
            for k, out in enumerate(BatchFunction(func)(columns, n))]


def _ik_reference(robot: Robot, func: ca.Function, inputs: list[np.ndarray]) -> list[np.ndarray]:
    """ik's outputs at the samples, by the NumPy replay of its SX (which leaves the loop for the
    converged samples, where CasADi's map runs every iteration), shaped as _batched_reference's."""
    n = len(inputs[0])
    columns = [_per_sample(values, func.sparsity_in(k).shape).T for k, values in enumerate(inputs)]
    return [out.T[:, :, None] for out in robot.symbolic.ik_definition.batch(columns, n)]


def float_ik_errors(robot: Robot, inputs: list[np.ndarray], got: list[np.ndarray],
                    refs: list[np.ndarray]) -> np.ndarray:
    """Per sample, how far the float ik's answer is from its target: the double FK's position
    and orientation errors (the larger) of its q, where the float C claims success or the double
    solver (``refs``, at the same float-rounded inputs) converged; 0 where both report a miss
    (unless the float q is not finite).

    A miss that the double twin shares is the method's (a reachable pose that no attempt
    reached, e.g. one beside a joint limit), not a float error; a float miss where double
    converges, and a claimed success that the double FK does not confirm, are errors."""
    success = ik.OUTPUT_NAMES.index("success")
    reached = _batched_reference(robot.symbolic.ik_definition.errors, [got[0][:, :, 0], inputs[0]])
    err = np.nan_to_num(np.maximum(reached[0], reached[1]).reshape(-1), nan=np.inf)
    claimed = got[success].reshape(-1) != 0
    double_converged = refs[success].reshape(-1) != 0
    return np.where(claimed | double_converged | ~np.isfinite(err), err, 0.0)


@dataclass
class ReferenceSamples:
    """One function's seeded inputs (as :func:`~armgen.verification.samples.batch_inputs` gives
    them; float-rounded for float) and the interpreter's outputs there (samples, rows, cols)."""

    inputs: list[np.ndarray]
    outputs: list[np.ndarray]


def reference_samples(references: dict[str, ca.Function], robot: Robot, samples: int, seed: int, precision: str,
                      on_function: Callable[[], None] = lambda: None) -> dict[str, ReferenceSamples]:
    """The inputs and reference outputs :func:`compare_model` compares with, per function. It
    needs no compiled code, so the verifier computes it while the compilers run."""
    if precision == "float":
        # draw extra so that `samples` remain after dropping the too-near-limit ones
        q_all, _ = joint_samples(robot, 2 * samples, seed)
        dist = np.minimum(q_all - robot.qmin, robot.qmax - q_all).min(axis=1)
        q_all = q_all[dist >= FLOAT_MIN_LIMIT_DISTANCE][:samples]
    else:
        q_all, _ = joint_samples(robot, samples, seed)
    prepared = {}
    for index, (name, func) in enumerate(references.items()):
        inputs = batch_inputs(func, robot, q_all, np.random.default_rng([seed, index]), precision)
        if precision == "float":  # the float code never sees anything else
            inputs = [a.astype(np.float32).astype(float) for a in inputs]
        if name in IK_FUNCTIONS:
            reference = _ik_reference(robot, func, inputs)
        elif precision == "float":
            reference = _replayed_reference(func, inputs)
        else:
            reference = _batched_reference(func, inputs)
        prepared[name] = ReferenceSamples(inputs, reference)
        on_function()
    return prepared


class BatchEvaluator(Protocol):
    """Compiled functions evaluated on many samples in one call: the verifier's kernel library
    (:class:`~armgen.codegen.api_kernel.KernelLibrary`) or a ctypes
    :class:`~armgen.codegen.compiled.CompiledModel` built with batched entries."""

    precision: str

    def batch(self, name: str, inputs: list[np.ndarray]) -> list[np.ndarray]: ...


def compare_model(compiled: BatchEvaluator, references: dict[str, ca.Function], robot: Robot, samples: int,
                  seed: int, on_function: Callable[[], None] = lambda: None,
                  prepared: dict[str, ReferenceSamples] | None = None) -> list[FunctionComparison]:
    """Each compiled function against the interpreter at ``samples`` seeded inputs (``prepared``
    by :func:`reference_samples`, or drawn here), every sample through the library's batched
    entry: one C call per function. ``on_function`` is called after each function (a progress bar).
    The float ik is judged by the pose its answer reaches (its iterations may differ from
    double's; :func:`float_ik_errors`), the other functions output by output."""
    precision = compiled.precision
    if prepared is None:
        prepared = reference_samples(references, robot, samples, seed, precision)
    floor = FLOAT_FLOOR if precision == "float" else DOUBLE_FLOOR
    report = []
    for name, func in references.items():
        inputs, refs = prepared[name].inputs, prepared[name].outputs
        got = compiled.batch(name, [_per_sample(a, func.sparsity_in(k).shape) for k, a in enumerate(inputs)])
        err = np.zeros(len(inputs[0]))
        if name in IK_FUNCTIONS and precision == "float":
            err = float_ik_errors(robot, inputs, got, refs)
            got, refs = [], []
        for out, ref in zip(got, refs):
            # entries that agree exactly (also NaN with NaN, inf with inf) differ by 0; a NaN on
            # one side only is an infinite error
            same = (out == ref) | (np.isnan(out) & np.isnan(ref))
            diff = np.nan_to_num(np.where(same, 0.0, np.abs(out - ref)), nan=np.inf)
            scale = np.maximum(np.abs(np.where(np.isfinite(ref), ref, 0.0)).max(axis=(1, 2)), floor)
            err = np.maximum(err, diff.max(axis=(1, 2)) / scale)
        worst_at = int(np.argmax(err))
        bound = DOUBLE_REL_BOUND if precision == "double" else FLOAT_BOUNDS[name.removesuffix(FROM_JACOBIAN)]
        report.append(FunctionComparison(name, precision, len(err), float(err[worst_at]), worst_at, bound))
        on_function()
    return report
