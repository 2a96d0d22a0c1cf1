"""Fault-tolerant planning (spec 30): joint-manipulability index, GPM vs WLN, locked joints.

``planner = "fault_tolerant"``. The tool follows a Cartesian path (the Cartesian planner's
circle or line, optionally relative to the start pose and run for several turns); from
``fault.time`` the joints in ``fault.joints`` are locked (``q̇_k = 0``): their Jacobian
columns are removed and the index is recomputed on the healthy columns. Per step:

- index ``H`` and ``∇H`` (``method.index``): ``omega`` — ``H_M = Σ a_i ω_i`` by the generated
  ``ft_index`` (smooth ``ω_i = sqrt(det(J₋ᵢJ₋ᵢᵀ) + δ²)`` on the healthy columns, AD gradient);
  ``relative`` — ``H_M / w`` (quotient rule on ``ft_index``'s outputs); ``sigma_min`` —
  ``Σ a_i σ_min(J₋ᵢ)`` by NumPy SVD with a central-difference gradient (numeric only);
- ``gpm``: ``q̇ = J⁺ẋ + K (I − J⁺J) ∇H`` (maximise); ``wln``: ``q̇ = W⁻¹Jᵀ(JW⁻¹Jᵀ)⁻¹ẋ``
  with the weights of the generated ``wln_weights`` (plain on/off rule or the smooth ramp);
  ``pinv``: minimum norm (baseline);
- the solve is the generated ``step_fault`` (lock mask, weights, null-space vector, variable
  damping from σ_min of the weighted healthy Jacobian, estimated in the C by Jacobi sweeps);
- explicit Euler, closed loop ``ẋ + K_p e`` by default (recorded in the metadata).

For a 7-DOF arm with a spherical shoulder and wrist (detected from the joint axes) the
shoulder–wrist distance is fixed by the elbow alone, so the wrist-centre path — known
without inverse kinematics because the path fixes the tool pose — shows before planning
whether the path needs a longer (or shorter) arm than the elbow allows; that is reported
as infeasible (``check.reach = "error"``, default) or recorded and planned anyway
(``"report"``).

Sweeps over K, b, the weight rule and the locked joint are ``armgen sweep`` runs (one row per
plan with the summary below; see docs/fault_tolerance.md).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, Sequence

import casadi as ca
import numpy as np

from ...errors import PlanningError
from ...progress import progress
from ..backends import Backend, make_backend
from ..common.collision import criterion_term, set_kernel_inputs, uses_criterion
from ..limits import limit_report
from ..result import PlanResult
from ..taskpath import (TIMED_WIDTH, TaskPath, base_columns, path_metadata, plan_path_task,
                       smoothness, sym_base_row, sym_tracking)
from ..toolpath.limits import SelfMotionLimiter
from .reach import srs_reach_check
from .config import FaultMethod, FaultSpec, FaultTolerantTask

# Central-difference step of the σ_min variant's gradient (rad): truncation ~h² and rounding
# ~eps/h balance near 1e-6 for O(1) singular values.
SIGMA_FD_STEP = 1e-6
# A WLN weight "switch" must move the weight by more than this (W ≥ 1, so 1 %).
SWITCH_MIN_DW = 0.01


# -- the planner ---------------------------------------------------------------------------

@dataclass
class Segment:
    """The rows planned so far (each a full output row, time first)."""

    rows: list[np.ndarray] = field(default_factory=list)


class FaultTolerantPlanner:
    """Integrates one task; ``run`` plans it, ``run_locks`` shares the pre-fault segment among
    several locked joints (the sweep)."""


    def __init__(self, task: FaultTolerantTask, backend_kind: str = "symbolic", backend: Backend | None = None):
        self.task = task
        self.robot = task.robot
        self.rows = list(self.robot.task_rows)
        self.backend = backend or make_backend(self.robot, backend_kind)
        pose0, _ = self.backend.call("fk_jacobian", task.path.q_start)
        self.path = TaskPath(task.path, pose0)
        # a program's plan stays within the joint speed limits (self-motion scaled first)
        self.limiter = SelfMotionLimiter(self.robot, self.backend, self.rows) if task.path.motion is not None else None
        self.reach = srs_reach_check(self.robot, self.backend, task.path.q_start, self.path)
        if self.reach is not None and not self.reach.feasible and task.check_mode == "error":
            raise PlanningError(self.infeasible_message())

    def infeasible_message(self) -> str:
        r, p = self.reach, self.task.path
        assert r is not None and r.first_bad_t_s is not None and r.needed_at_bad_m is not None
        lo, hi = r.distance_range_m
        what = (f"at most {hi * 1e3:.1f} mm (elbow {r.elbow} straight)" if r.needed_at_bad_m > hi
                else f"at least {lo * 1e3:.1f} mm (elbow {r.elbow} fully bent)")
        return (f"start '{p.start_label}' is infeasible for this path: at t = {r.first_bad_t_s:.2f} s the wrist centre "
                f"must be {r.needed_at_bad_m * 1e3:.1f} mm from the shoulder, but the arm reaches {what}; the elbow "
                "would hit full stretch and the arm turn singular. Start with the elbow bent further (robot iiwa14: "
                "start = \"q0_feasible\", elbow −60°) or shrink the path; check.reach = \"report\" plans it anyway")

    # -- one step -------------------------------------------------------------------------
    def index(self, q: np.ndarray, mask: np.ndarray, method: FaultMethod) -> tuple[float, np.ndarray, np.ndarray, float]:
        """(H, ∇H, per-joint index values, w) on the healthy columns."""
        a = np.asarray(method.a)
        omega, h_m, grad, w, grad_w = self.backend.call("ft_index", q, mask, a, method.delta)
        omega, grad, grad_w = omega.ravel(), grad.ravel(), grad_w.ravel()
        h_m, w = float(h_m.ravel()[0]), float(w.ravel()[0])
        if method.index == "omega":
            return h_m, grad, omega, w
        if method.index == "relative":
            return h_m / w, grad / w - h_m * grad_w / (w * w), omega / w, w
        per = self._sigma_terms(q, mask)
        h = float(np.dot(mask * a, per))
        grad = np.zeros(self.robot.n)
        for k in np.flatnonzero(mask):
            e = np.zeros(self.robot.n)
            e[k] = SIGMA_FD_STEP
            grad[k] = (np.dot(mask * a, self._sigma_terms(q + e, mask))
                       - np.dot(mask * a, self._sigma_terms(q - e, mask))) / (2 * SIGMA_FD_STEP)
        return h, grad, per, w

    def _sigma_terms(self, q: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """σ_min(J₋ᵢ) of the healthy Jacobian per healthy joint i (0 with fewer columns than rows)."""
        (jac,) = self.backend.call("jacobian", q)
        jh = jac[self.rows] * mask
        out = np.zeros(self.robot.n)
        for i in np.flatnonzero(mask):
            out[i] = np.linalg.svd(np.delete(jh, i, axis=1), compute_uv=False)[len(self.rows) - 1] \
                if jh.shape[1] - 1 >= len(self.rows) else 0.0
        return out

    def _kernel(self, method: FaultMethod):
        """One fused call per step: index, weights or null-space term, masked step, q(t + h)."""
        rows = self.rows
        numeric_index = method.index == "sigma_min"  # NumPy SVD and differences: an input
        with_collision = uses_criterion(self.task.path.collision)

        def build(model, x, y):
            n = model.n
            # the twins of ft_index and step_fault take the J of this step's fk_jacobian
            fk_jacobian, ft_index, wln_weights, step_fault = (model.function(f) for f in (
                "fk_jacobian", "ft_index_from_jacobian", "wln_weights", "step_fault_from_jacobian"))
            q, qd_prev, mask, a = (x.add(k, n) for k in ("q", "qd_prev", "mask", "a"))
            K, b, omega_floor, v_band, delta, gain, eps, lam_max, h = (
                x.add(k, 1) for k in ("K", "b", "omega_floor", "v_band", "delta", "clik_gain", "epsilon", "lambda_max",
                                      "h"))
            if numeric_index:
                h_in, grad_in, per_in = x.add("H", 1), x.add("grad_H", n), x.add("per_joint", n)
            timed = x.add("timed", TIMED_WIDTH)
            avoid = criterion_term(model, x) if with_collision else None
            pose, jac = fk_jacobian(q)
            pos_err, ori_err, cmd = sym_tracking(pose, timed, gain)
            omega, h_m, grad, w, grad_w = ft_index(jac, mask, a, delta)
            if method.index == "omega":
                index, grad_index, per = h_m, grad, omega
            elif method.index == "relative":
                index, grad_index, per = h_m / w, grad / w - h_m * grad_w / (w * w), omega / w
            else:
                index, grad_index, per = h_in, grad_in, per_in
            ones, zeros = ca.DM.ones(n), ca.DM.zeros(n)
            weights, active, alpha = ones, zeros, zeros
            if method.name == "gpm":
                alpha = K * grad_index
            elif method.name == "wln":
                if method.weight_rule == "smooth":
                    # the direction test on the unweighted (minimum-norm) motion of this step:
                    # continuous in t and independent of W, so the weights cannot feed back on it
                    probe = step_fault(jac, cmd[rows], mask, ones, zeros, eps, lam_max)[0]
                    weights, active = wln_weights(grad_index, per, probe, mask, b, omega_floor, v_band)
                else:
                    weights, active = wln_weights(grad_index, per, qd_prev, mask, b, omega_floor, 0.0)
            if avoid is not None:  # the collision criterion descends beside the method's own term
                alpha = alpha + avoid(q)
            qd, lam, sigma = step_fault(jac, cmd[rows], mask, weights, alpha, eps, lam_max)
            y.add("row", ca.vertcat(sym_base_row(q, qd, pose, jac, pos_err, ori_err, cmd, rows, lam, sigma), index, w,
                                    per, 1 - mask, weights, active))
            y.add("q_next", q + h * qd)

        key = ("fault", method.name, method.index, method.weight_rule if method.name == "wln" else "",
               self.robot.task_rows, "collision" if with_collision else "")
        return self.backend.kernel(key, build)

    def segment(self, kernel, timed: np.ndarray, q: np.ndarray, qd_prev: np.ndarray, k0: int, k1: int,
                mask: np.ndarray, method: FaultMethod, seg: Segment, bar, last: bool) -> tuple[np.ndarray, np.ndarray]:
        """Steps k0 … k1−1 (and the final sample k1 when ``last``); returns (q, q̇) after k1−1."""
        p, n = self.task.path, self.robot.n
        h = p.step
        x, slot = kernel.x, kernel.inputs
        x[slot["mask"]] = mask
        x[slot["q"]] = q
        x[slot["qd_prev"]] = qd_prev
        row_out, q_next, qd_out = kernel.outputs["row"], kernel.outputs["q_next"], slice(n, 2 * n)
        stop = k1 + 1 if last else k1
        for k in range(k0, stop):
            x[slot["timed"]] = timed[k]
            if method.index == "sigma_min":
                index, grad, per, _ = self.index(x[slot["q"]], mask, method)
                x[slot["H"]], x[slot["grad_H"]], x[slot["per_joint"]] = index, grad, per
            kernel()
            row = np.empty(1 + kernel.y[row_out].size)
            row[0] = k * h
            row[1:] = kernel.y[row_out]
            if self.limiter is not None:
                row[1 + n:1 + 2 * n] = self.limiter(row[1:1 + n], row[1 + n:1 + 2 * n], mask)
            seg.rows.append(row)
            if k == k1:
                break
            x[slot["q"]] = kernel.y[q_next] if self.limiter is None else row[1:1 + n] + h * row[1 + n:1 + 2 * n]
            x[slot["qd_prev"]] = row[1:][qd_out]
            if not np.all(np.isfinite(x[slot["q"]])):
                raise PlanningError(f"joint angles became non-finite at t = {(k + 1) * h:.3f} s; lower integrator.step "
                                    "or the method gains (method.K / method.b)")
            bar.update(1)
        return x[slot["q"]].copy(), x[slot["qd_prev"]].copy()

    def run_locks(self, method: FaultMethod | None = None,
                  lock_sets: Sequence[tuple[int, ...]] | None = None) -> list[PlanResult]:
        method = method or self.task.method
        p = self.task.path
        lock_sets = [self.task.fault.joints] if lock_sets is None else list(lock_sets)
        k_f = self.task.lock_step if any(lock_sets) else p.steps + 1
        healthy = np.ones(self.robot.n)
        kernel = self._kernel(method)
        for key, value in (("a", method.a), ("K", method.K), ("b", method.b),
                           ("omega_floor", method.omega_floor), ("v_band", method.v_band), ("delta", method.delta),
                           ("clik_gain", p.clik_gain if p.clik else 0.0), ("epsilon", p.damping_epsilon),
                           ("lambda_max", p.damping_max), ("h", p.step)):
            kernel.set(key, value)
        if uses_criterion(p.collision):
            set_kernel_inputs(kernel, p.collision)
        timed = self.path.timed_inputs(np.arange(p.steps + 1) * p.step)
        results = []
        started = time.perf_counter()
        total = min(k_f, p.steps) + len(lock_sets) * max(p.steps - k_f, 0)
        with progress(total, f"planning {method.label}") as bar:
            pre = Segment()
            q, qd_prev = self.segment(kernel, timed, p.q_start.copy(), np.zeros(self.robot.n), 0, min(k_f, p.steps),
                                      healthy, method, pre, bar, last=k_f > p.steps)
            for joints in lock_sets:
                seg = Segment(list(pre.rows))
                if k_f <= p.steps:
                    fault = FaultSpec(joints, self.task.fault.time)
                    self.segment(kernel, timed, q.copy(), qd_prev.copy(), k_f, p.steps,
                                 fault.mask(self.robot.n, True), method, seg, bar, last=True)
                results.append(self._result(seg, method, joints, k_f, time.perf_counter() - started))
        return results

    def run(self) -> PlanResult:
        return self.run_locks()[0]

    # -- output ---------------------------------------------------------------------------
    def columns(self) -> list[str]:
        n = self.robot.n
        return (base_columns(n) + ["H_M_1", "w_1"] + [f"omega{i + 1}_1" for i in range(n)]
                + [f"lock{i + 1}_1" for i in range(n)] + [f"W{i + 1}_1" for i in range(n)]
                + [f"active{i + 1}_1" for i in range(n)])

    def _result(self, seg: Segment, method: FaultMethod, joints: tuple[int, ...], k_f: int,
                elapsed: float) -> PlanResult:
        p = self.task.path
        data = np.array(seg.rows)
        keep = [k for k in range(len(seg.rows)) if k % p.output_every == 0 or k == len(seg.rows) - 1]
        result = PlanResult(self.columns(), data[keep], {})
        result.metadata = self._metadata(data, seg, method, joints, k_f, elapsed)
        result.config = replace(self.task, method=method, fault=replace(self.task.fault, joints=joints))
        return result

    def verdict(self, data: np.ndarray, seg: Segment, method: FaultMethod, joints: tuple[int, ...],
                k_f: int) -> dict[str, Any]:
        """Spec 30's per-lock report: completion, H_M over time, smoothness, weight switches."""
        n, h, cols = self.robot.n, self.task.path.step, self.columns()
        col = {c: data[:, k] for k, c in enumerate(cols)}
        t = col["t_s"]
        q = data[:, 1:1 + n]
        qd = data[:, 1 + n:1 + 2 * n]
        after = t >= (k_f * h - 1e-12) if k_f < len(t) else np.zeros(len(t), dtype=bool)
        window = after if after.any() else np.ones(len(t), dtype=bool)
        violations, margin = limit_report(self.robot, t, q)
        c = self.task.completion
        pos = float(np.max(col["pos_err_m"][window]))
        ori = float(np.max(col["ori_err_rad"][window]))
        speed = float(np.max(np.abs(qd[window])))
        completed = pos <= c.pos_tol and ori <= c.ori_tol and speed <= c.max_joint_speed and not violations
        skip = (k_f - 1,) if 0 < k_f < len(t) else ()
        smooth = smoothness(qd, h, skip)
        active = data[:, cols.index("active1_1"):cols.index("active1_1") + n]
        masks = 1.0 - data[:, cols.index("lock1_1"):cols.index("lock1_1") + n]
        both = (masks[1:] > 0) & (masks[:-1] > 0)
        weights = data[:, cols.index("W1_1"):cols.index("W1_1") + n]
        jumps = np.abs(np.diff(weights, axis=0)) * both
        # a switch: the activation crosses ½ and the weight moves by more than SWITCH_MIN_DW
        # (joints whose ∂H/∂q_i is rounding noise, e.g. the base joint, toggle without effect)
        switches = int(np.sum(((active[1:] > 0.5) != (active[:-1] > 0.5)) & both & (jumps > SWITCH_MIN_DW)))
        h_m = col["H_M_1"]
        before = ~after
        reasons = []
        if pos > c.pos_tol:
            reasons.append(f"position error {pos * 1e3:.2f} mm")
        if ori > c.ori_tol:
            reasons.append(f"orientation error {math.degrees(ori):.2f} deg")
        if speed > c.max_joint_speed:
            reasons.append(f"joint speed {math.degrees(speed):.0f} deg/s")
        if violations:
            reasons.append("joint limits left: " + ", ".join(v["joint"] for v in violations))
        return {
            "method": method.label,
            "locked": [self.robot.joints[j].name for j in joints],
            "completed": bool(completed),
            "why_not": "; ".join(reasons),
            "max_pos_err_after_lock_mm": pos * 1e3,
            "max_ori_err_after_lock_deg": math.degrees(ori),
            "peak_joint_speed_after_lock_deg_s": math.degrees(speed),
            "H_M_start": float(h_m[0]),
            "H_M_before_lock": float(h_m[before][-1]) if before.any() else float(h_m[0]),
            "H_M_min_after_lock": float(np.min(h_m[after])) if after.any() else None,
            "H_M_end": float(h_m[-1]),
            "w_min_after_lock": float(np.min(col["w_1"][after])) if after.any() else float(np.min(col["w_1"])),
            "peak_ddq_deg_s2": math.degrees(smooth["peak_ddq_rad_s2"]),
            "lock_jump_deg_s": float(np.degrees(np.max(np.abs(qd[k_f] - qd[k_f - 1])))) if skip else 0.0,
            "total_variation_dq_deg_s": math.degrees(smooth["total_variation_dq_rad_s"]),
            "weight_switches": switches,
            "weight_total_variation": float(np.sum(jumps)),
            "max_weight_step": float(np.max(jumps)) if jumps.size else 0.0,
            "limit_violations": violations,
            "min_limit_margin_deg": math.degrees(margin),
            "damped_steps": int(np.count_nonzero(col["damping_1"] > 0)),
        }

    def _metadata(self, data: np.ndarray, seg: Segment, method: FaultMethod, joints: tuple[int, ...], k_f: int,
                  elapsed: float) -> dict[str, Any]:
        task = self.task
        meta = path_metadata(task.path)
        verdict = self.verdict(data, seg, method, joints, k_f)
        meta.update({
            "method": method.name,
            "parameters": {"index": method.index, "K": method.K, "b": method.b, "weight_rule": method.weight_rule,
                           "v_band_rad_s": method.v_band, "omega_floor": method.omega_floor, "delta": method.delta,
                           "a": list(method.a)},
            "fault": {"joints": [self.robot.joints[j].name for j in joints], "time_s": task.fault.time,
                      "first_locked_step": k_f if joints else None},
            "completion": {"pos_tol_mm": task.completion.pos_tol * 1e3,
                           "ori_tol_deg": math.degrees(task.completion.ori_tol),
                           "max_joint_speed_deg_s": math.degrees(task.completion.max_joint_speed)},
            "reach_check": self.reach.to_dict() if self.reach is not None else None,
            "sweep": {"K": list(task.sweep.K), "b": list(task.sweep.b), "rules": list(task.sweep.rules),
                      "joints": [self.robot.joints[j].name for j in task.sweep.joints],
                      "fine_step_s": task.sweep.fine_step},
            "verdict": verdict,
            "summary": {
                "task_completed": verdict["completed"],
                "max_pos_error_mm": float(np.max(data[:, self.columns().index("pos_err_m")]) * 1e3),
                "max_ori_error_deg": float(np.degrees(np.max(data[:, self.columns().index("ori_err_rad")]))),
                "max_pos_error_after_lock_mm": verdict["max_pos_err_after_lock_mm"],
                "peak_joint_speed_after_lock_deg_s": verdict["peak_joint_speed_after_lock_deg_s"],
                "H_M_before_lock": verdict["H_M_before_lock"],
                "peak_ddq_deg_s2": verdict["peak_ddq_deg_s2"],
                "weight_switches": verdict["weight_switches"],
                "max_weight_step": verdict["max_weight_step"],
                "w_min_after_lock_mm3": verdict["w_min_after_lock"] * 1e9,
                "limit_violations": verdict["limit_violations"],
                "max_abs_q_deg": np.degrees(np.max(np.abs(data[:, 1:1 + self.robot.n]), axis=0)).tolist(),
                "damped_steps": verdict["damped_steps"],
                # steps whose self-motion was scaled to keep the joints within their speed limits
                **({"self_motion_limited_steps": self.limiter.limited_steps} if self.limiter else {}),
                "plan_seconds": elapsed,
            },
        })
        if self.reach is not None and not self.reach.feasible:
            meta["summary"]["infeasible_start"] = self.infeasible_message()
        return meta


def plan(config: FaultTolerantTask, backend: str = "symbolic") -> PlanResult:
    """The task's plan (:func:`~armgen.planning.taskpath.plan_path_task`)."""
    return plan_path_task(config, backend, FaultTolerantPlanner)
