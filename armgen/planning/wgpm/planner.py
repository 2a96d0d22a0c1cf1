"""Multi-constraint weighted GPM with damped least squares (spec 35).

``planner = "wgpm"``. The tool follows a Cartesian path (the Cartesian planner's circle or
line, optionally relative to the start and over several turns) and each step is one call of
the generated ``step_wgpm`` — continuous joint-limit weights ``W_b = I − W_c``, repulsive
field ``t_r``, variable damping from σ_min of ``J W_b`` (tridiagonal bisection in the C), the oblique
projector ``N_wb = I − W_b J_wb^# J``, normalised criteria with online gains:

    q̇ = W_b J_wb^# ẋ + N_wb · ramp(t) · (t_r + W_b Σ_j k_j ∇H_nj)

``ramp(t)`` brings the secondary terms in from rest over ``method.ramp_time`` (and, by
default, out again before the end, so the plan is rest-to-rest). For comparison the same
planner runs ``method.name = "pinv"`` (the damped pseudo-inverse, nothing else) and
``"clamp"`` (a binary clamp: a joint that would cross its limit in this step is frozen — its
column removed through the generated ``step_fault`` mask — and released as soon as the
unclamped solution moves it back inside).

The spec's comparison (pinv vs clamp vs wgpm on one task) and the survey over random tasks are
``armgen sweep`` runs over ``method.name`` (docs/wgpm.md).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import casadi as ca
import numpy as np

from ...errors import PlanningError
from ...progress import progress
from ...symbolic.steps import WGPM_CRITERIA, scaled_step, weighted_gram
from ..backends import Backend, make_backend
from ..common.collision import criterion_term, set_kernel_inputs, uses_criterion
from ..limits import limit_report
from ..result import PlanResult
from ..taskpath import (TIMED_WIDTH, TaskPath, base_columns, path_metadata, plan_path_task, smoothness, sym_base_row,
                        sym_tracking)
from ..toolpath.limits import SelfMotionLimiter
from .config import WgpmMethod, WgpmTask

SHORT = {"manipulability": "w", "joint_manipulability": "M", "zghal": "L", "condition": "kappa"}


def smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def wgpm_null_space_term(jac: ca.SX, w_c: ca.SX, rho: ca.SX, alpha: ca.SX) -> ca.SX:
    """What ``step_wgpm`` adds to q̇ for a further null-space vector ``alpha`` (the collision
    criterion's −gain ∇H_C): its q̇ = z + W_b² Jᵀ (J_wb J_wbᵀ + ρ² I)⁻¹ (ẋ − J z) is linear in z,
    so z + W_b α adds W_b α − W_b² Jᵀ (J_wb J_wbᵀ + ρ² I)⁻¹ J W_b α, with W_b = I − diag(w_c) and ρ
    of the same step: α enters as the criteria's gradients do (unramped: it acts from t = 0)."""
    w_b = 1 - w_c
    scale = w_b * w_b
    return scaled_step(jac, ca.DM.zeros(jac.shape[0]), scale, w_b * alpha, rho * rho, weighted_gram(jac, scale))


class WgpmPlanner:
    FUNCTIONS = ("fk_jacobian", "step_wgpm_from_jacobian", "step_fault_from_jacobian")

    def __init__(self, task: WgpmTask, backend_kind: str = "symbolic", backend: Backend | None = None):
        self.task = task
        self.robot = task.path.robot
        self.rows = list(self.robot.task_rows)
        self.backend = backend or make_backend(self.robot, backend_kind)
        pose0, _ = self.backend.call("fk_jacobian", task.path.q_start)
        self.path = TaskPath(task.path, pose0)
        # a program's plan stays within the joint speed limits (self-motion scaled first)
        self.limiter = SelfMotionLimiter(self.robot, self.backend, self.rows) if task.path.motion is not None else None

    def ramp(self, t: np.ndarray, method: WgpmMethod) -> np.ndarray:
        if method.ramp_time <= 0:
            return np.ones_like(t)
        up = smoothstep(t / method.ramp_time)
        down = smoothstep((self.task.path.duration - t) / method.ramp_time) if method.ramp_out else 1.0
        return up * down

    def _kernel(self, method: WgpmMethod):
        """One fused call per step. ``pinv`` and ``clamp`` still evaluate ``step_wgpm`` for the
        criteria (ramp 0); their step is ``step_fault``'s. The clamp's loop (freeze the joints
        this step would push out, solve again, at most n times) is unrolled: once nothing is
        frozen any more, the further rounds repeat the same solve."""
        rows, robot = self.rows, self.robot
        with_collision = uses_criterion(self.task.path.collision)

        def build(model, x, y):
            n = model.n
            fk_jacobian, step_wgpm, step_fault = (model.function(f) for f in self.FUNCTIONS)
            q = x.add("q", n)
            scalars = [x.add(k, 1) for k in ("band", "t_rmax", "epsilon", "lambda_max", "delta")]
            gain, h = x.add("clik_gain", 1), x.add("h", 1)
            vectors = [x.add(k, len(WGPM_CRITERIA)) for k in ("H_lo", "H_hi", "k_hi", "k_lo", "u_th", "u_band")]
            timed, ramp = x.add("timed", TIMED_WIDTH), x.add("ramp", 1)
            eps, lam_max = scalars[2], scalars[3]
            pose, jac = fk_jacobian(q)
            avoid = criterion_term(model, x)(q) if with_collision else ca.DM.zeros(n)
            pos_err, ori_err, cmd = sym_tracking(pose, timed, gain)
            qd, w_c, rho, sigma, gains, crit = step_wgpm(jac, q, cmd[rows], *scalars, ramp, *vectors)
            if with_collision and method.name == "wgpm":
                qd = qd + wgpm_null_space_term(jac[rows, :], w_c, rho, avoid)
            if method.name != "wgpm":
                ones = ca.DM.ones(n)
                mask = ca.SX(ones)
                for _ in range(n if method.name == "clamp" else 1):
                    qd, rho, sigma = step_fault(jac, cmd[rows], mask, ones, avoid, eps, lam_max)
                    if method.name == "clamp":
                        nxt = q + h * qd
                        out = ca.logic_and(mask > 0, ca.logic_or(nxt > robot.qmax, nxt < robot.qmin))
                        mask = ca.if_else(out, 0, mask)
                w_c, gains = 1 - mask, ca.DM.zeros(len(WGPM_CRITERIA))
            y.add("row", ca.vertcat(sym_base_row(q, qd, pose, jac, pos_err, ori_err, cmd, rows, rho, sigma), ramp, crit,
                                    gains, w_c))
            y.add("q_next", q + h * qd)

        return self.backend.kernel(("wgpm", method.name, self.robot.task_rows, "collision" if with_collision else ""),
                                   build)

    def columns(self) -> list[str]:
        n = self.robot.n
        return (base_columns(n) + ["ramp_1"] + [f"H_{SHORT[c]}_1" for c in WGPM_CRITERIA]
                + [f"k_{SHORT[c]}_1" for c in WGPM_CRITERIA] + [f"wc{i + 1}_1" for i in range(n)])

    def run(self, method: WgpmMethod | None = None) -> PlanResult:
        method = method or self.task.method
        p, n = self.task.path, self.robot.n
        h = p.step
        kernel = self._kernel(method)
        for key, value in (("band", method.band), ("t_rmax", method.t_rmax), ("epsilon", p.damping_epsilon),
                           ("lambda_max", p.damping_max), ("delta", method.delta),
                           ("clik_gain", p.clik_gain if p.clik else 0.0), ("h", h),
                           *zip(("H_lo", "H_hi", "k_hi", "k_lo", "u_th", "u_band"), method.vectors())):
            kernel.set(key, value)
        if uses_criterion(p.collision):
            set_kernel_inputs(kernel, p.collision)
        t = np.arange(p.steps + 1) * h
        ramp = self.ramp(t, method) if method.name == "wgpm" else np.zeros_like(t)
        timed = np.hstack([self.path.timed_inputs(t), ramp[:, None]])
        x, q_slot = kernel.x, kernel.inputs["q"]
        timed_slot = slice(kernel.inputs["timed"].start, kernel.inputs["ramp"].stop)
        row_out, q_next = kernel.outputs["row"], kernel.outputs["q_next"]
        data = np.empty((p.steps + 1, len(self.columns())))
        data[:, 0] = t
        x[q_slot] = p.q_start
        started = time.perf_counter()
        with progress(p.steps, f"planning {method.name}") as bar:
            for k in range(p.steps + 1):
                x[timed_slot] = timed[k]
                kernel()
                data[k, 1:] = kernel.y[row_out]
                if self.limiter is not None:
                    data[k, 1 + n:1 + 2 * n] = self.limiter(data[k, 1:1 + n], data[k, 1 + n:1 + 2 * n])
                if k == p.steps:
                    break
                x[q_slot] = kernel.y[q_next] if self.limiter is None else data[k, 1:1 + n] + h * data[k, 1 + n:1 + 2 * n]
                bar.update(1)
        q_all = data[:, 1:1 + n]
        if not np.all(np.isfinite(q_all)):
            k = int(np.argmin(np.all(np.isfinite(q_all), axis=1)))
            raise PlanningError(f"joint angles became non-finite at t = {t[k]:.3f} s; lower integrator.step "
                                "or the criterion gains")
        damped = int(np.count_nonzero(data[:, self.columns().index("damping_1")] > 0))
        keep = [k for k in range(p.steps + 1) if k % p.output_every == 0 or k == p.steps]
        result = PlanResult(self.columns(), data[keep], {})
        result.metadata = self._metadata(data, data[:, 1 + n:1 + 2 * n], method, damped, time.perf_counter() - started)
        result.config = replace(self.task, method=method)
        return result

    def _metadata(self, data: np.ndarray, qd: np.ndarray, method: WgpmMethod, damped: int,
                  elapsed: float) -> dict[str, Any]:
        n, task = self.robot.n, self.task
        cols = self.columns()
        t = data[:, 0]
        q = data[:, 1:1 + n]
        violations, margin = limit_report(self.robot, t, q)
        pos = float(np.max(data[:, cols.index("pos_err_m")]))
        ori = float(np.max(data[:, cols.index("ori_err_rad")]))
        smooth = smoothness(qd, task.path.step)
        tracks = pos <= task.pos_tol and ori <= task.ori_tol
        meta = path_metadata(task.path)
        meta.update({
            "method": method.name,
            "parameters": {"band": method.band, "t_rmax_rad_s": method.t_rmax, "delta": method.delta,
                           "ramp_time_s": method.ramp_time, "ramp_out": method.ramp_out,
                           "criteria": {c: vars(k) for c, k in zip(WGPM_CRITERIA, method.criteria)}},
            "tracking": {"pos_tol_mm": task.pos_tol * 1e3, "ori_tol_deg": math.degrees(task.ori_tol)},
            "summary": {
                "within_limits": not violations,
                "tracks": bool(tracks),
                "limit_violations": violations,
                "max_abs_q_deg": np.degrees(np.max(np.abs(q), axis=0)).tolist(),
                "max_abs_q_overall_deg": float(np.degrees(np.max(np.abs(q)))),
                "min_limit_margin_deg": math.degrees(margin),
                "max_pos_error_mm": pos * 1e3,
                "max_ori_error_deg": math.degrees(ori),
                "peak_ddq_deg_s2": math.degrees(smooth["peak_ddq_rad_s2"]),
                "total_variation_dq_deg_s": math.degrees(smooth["total_variation_dq_rad_s"]),
                "peak_dq_deg_s": float(np.degrees(np.max(np.abs(qd)))),
                "start_joint_speed_deg_s": float(np.degrees(np.linalg.norm(qd[0]))),
                "end_joint_speed_deg_s": float(np.degrees(np.linalg.norm(qd[-1]))),
                "damped_steps": int(damped),
                # steps whose self-motion was scaled to keep the joints within their speed limits
                **({"self_motion_limited_steps": self.limiter.limited_steps} if self.limiter else {}),
                "plan_seconds": elapsed,
            },
        })
        return meta


def plan(config: WgpmTask, backend: str = "symbolic") -> PlanResult:
    """The task's plan (:func:`~armgen.planning.taskpath.plan_path_task`)."""
    return plan_path_task(config, backend, WgpmPlanner)
