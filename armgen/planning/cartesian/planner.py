"""Cartesian redundancy resolution along a path (spec 20).

``q̇ = J⁺ ẋ + (I − J⁺ J) α`` through the generated ``step_gpm`` with variable damping, where
``α`` is one of: 0 (minimum norm), the repetitive operator ``α_R``, the Zghal descent
``α_L`` (plain, or with latched per-joint windows), or the additive combination
``γ_R α_R + γ_L α_L``. Integrated by explicit Euler (the paper's), RK4, optionally closed
loop (CLIK). All inputs in SI after loading; the task file may use mm/deg.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import casadi as ca
import numpy as np

from ...errors import PlanningError
from ...progress import progress
from ...symbolic.steps import min_eigenvalue
from ..backends import make_backend
from ..common.collision import criterion_term, set_kernel_inputs, uses_criterion
from ..common.path import PathGeometry
from ..common.symbolic import sym_orientation_error, sym_rpy
from ..limits import limit_report
from ..result import PlanResult
from ..toolpath.limits import SelfMotionLimiter, plan_with_speed_limits
from .config import CartesianTask
from .windows import JointWindows

# A plan whose tool leaves the path by more than this is reported as not feasible
# (unreachable target or a singularity the damping could not cross): open-loop Euler drift
# at h = 0.02 s stays below 0.8 mm on the bundled examples. The path tolerance
# (toolpath.accuracy, default 0.1 mm) is the accuracy a plan must meet where it applies.
MAX_PATH_ERROR = 5e-3  # m


def positive_definite(a: ca.SX) -> ca.SX:
    """1 when the symmetric matrix ``a`` is positive definite (every LDLᵀ pivot > 0), else 0."""
    m = a.shape[0]
    lower = [[None] * m for _ in range(m)]
    pivots = []
    for j in range(m):
        pivots.append(a[j, j] - sum((lower[j][k] ** 2 * pivots[k] for k in range(j)), ca.SX(0)))
        for i in range(j + 1, m):
            lower[i][j] = (a[i, j] - sum((lower[i][k] * lower[j][k] * pivots[k] for k in range(j)), ca.SX(0))) / pivots[j]
    return ca.logic_all(ca.vertcat(*[p > 0 for p in pivots]))


class CartesianPlanner:
    """Integrates the resolved-rate law; the same code for every backend."""

    FUNCTIONS = ("fk_jacobian", "zghal", "step_gpm_from_jacobian")

    def __init__(self, task: CartesianTask, backend_kind: str = "symbolic", backend=None, check_path: bool = True):
        """``check_path`` False leaves the check that the tool stayed on a circle or line to the
        caller (plan judges it after refining the step)."""
        self.task = task
        self.check_path = check_path
        self.robot = task.robot
        self.backend = backend or make_backend(self.robot, backend_kind)
        self.rows = list(self.robot.task_rows)
        T0, _ = self.backend.call("fk_jacobian", task.q_start)
        self.p0, self.r0 = T0[:3, 3].copy(), T0[:3, :3].copy()
        # a program's plan stays within the joint speed limits (self-motion scaled first)
        self.limiter = SelfMotionLimiter(self.robot, self.backend, self.rows) if task.motion is not None else None
        if task.motion is not None:  # built, and its reach checked, when configured
            self.path = task.motion.program
        else:
            geometry = PathGeometry(task.path_type, task.via, task.end, task.end_rotation)
            self.path = geometry.build_within_reach(T0, self.robot)
        mp = task.method
        shape = "linear" if mp.name == "combined" else "quadratic"
        self.windows = JointWindows(self.robot.n, mp.T_smo_L, mp.T_sum_L, shape)
        self.damped_steps = 0
        self._band_lo = self.robot.qmin + mp.theta_s
        self._band_hi = self.robot.qmax - mp.theta_s

    # -- the pieces of the law -------------------------------------------------------
    def desired(self, t):
        """(position, rotation, task velocity [v; ω]) at time t (a number or an array of times)."""
        if self.task.motion is not None:
            return self.task.motion(t)
        T = self.task.duration
        t = np.asarray(t, dtype=float)
        s, ds = self.task.law(t / T)
        p, dp, rot, dw = self.path(s)
        sdot = np.where((0.0 <= t) & (t <= T), ds / T, 0.0)[..., None]
        return p, rot, np.concatenate([dp * sdot, dw * sdot], axis=-1)

    def alpha_coefficients(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(γ_R, a, b) of the repetitive term γ_R · a (q_init − q) / b at the times t (a = 0 while it is off)."""
        mp, T = self.task.method, self.task.duration
        zero, one = np.zeros_like(t), np.ones_like(t)
        if mp.name in ("pinv", "zghal", "zghal_improved"):
            return zero, zero, one
        t_sta = T / 2
        on = (t > t_sta) & (t < T)  # off before T/2; its limit 0 at T (removable singularity for ρ_R > 1)
        a = np.where(on, np.minimum(((t - t_sta) / mp.T_smo_R) ** 2, 1.0) * mp.rho_R, 0.0)
        b = np.where(on, T - t, 1.0)
        gamma_r = np.clip((t - T / 2) / mp.gamma_R_ramp, 0.0, 1.0) if mp.name == "combined" else one
        return gamma_r, a, b

    def in_band(self, q: np.ndarray) -> np.ndarray:
        return (q > self._band_hi) | (q < self._band_lo)

    # -- integration -----------------------------------------------------------------
    STAGE_INPUTS = (("p_d", 3), ("r_d", 9), ("xdot", 6), ("gamma_R", 1), ("a_R", 1), ("b_R", 1))

    def _kernel(self, damped: bool):
        """One fused call per step: the law at t (and, for RK4, at t + h/2 and t + h) and q(t + h).

        The damping needs σ_min(J) only below ε. The undamped kernel (``damped`` False) tests
        λ_min(J Jᵀ) > ε² by the pivots of J Jᵀ − ε² I (positive definite: all LDLᵀ pivots > 0),
        uses λ = 0 and flags the step otherwise; the damped kernel computes σ_min by tridiagonal bisection
        sweeps and applies λ = λ_max √(1 − (σ_min/ε)²) below ε."""
        stages = 3 if self.task.integrator == "rk4" else 1
        rows = self.rows
        with_collision = uses_criterion(self.task.collision)

        def build(model, x, y):
            n = model.n
            fk_jacobian, zghal, step_gpm = (model.function(f) for f in self.FUNCTIONS)
            q, q_init, windows = x.add("q", n), x.add("q_init", n), x.add("windows", n)
            h, rho_l, gain, eps, lam_max = (x.add(k, 1) for k in ("h", "rho_L", "clik_gain", "epsilon", "lambda_max"))
            at = [[x.add(f"{k}{s}", size) for k, size in self.STAGE_INPUTS] for s in range(stages)]
            avoid = criterion_term(model, x) if with_collision else None
            flags = []

            def law(qs, p_d, r_d, xdot, gamma_r, a_r, b_r):
                pose, jac = fk_jacobian(qs)
                pos_err = p_d - pose[:3, 3]
                ori_err = sym_orientation_error(pose[:3, :3], ca.reshape(r_d, 3, 3))
                cmd = xdot + gain * ca.vertcat(pos_err, ori_err)
                h_l, grad_l = zghal(qs)
                alpha = gamma_r * (a_r * (q_init - qs) / b_r) + windows * (-rho_l * grad_l)
                if avoid is not None:  # the collision criterion descends beside the method's own terms
                    alpha = alpha + avoid(qs)
                gram = ca.mtimes(jac[rows, :], jac[rows, :].T)
                if damped:
                    sigma = ca.sqrt(ca.fmax(min_eigenvalue(gram), 0))
                    lam = ca.if_else(sigma >= eps, 0, ca.sqrt(1 - (sigma / eps) ** 2) * lam_max)
                else:
                    flags.append(1 - positive_definite(gram - eps * eps * ca.SX.eye(len(rows))))
                    lam = ca.SX(0)
                qd = step_gpm(jac, cmd[rows], alpha, lam)  # the twin: J of this stage's fk_jacobian
                return qd, pose, jac, pos_err, ori_err, cmd, lam, h_l

            qd, pose, jac, pos_err, ori_err, cmd, lam, h_l = law(q, *at[0])
            if stages == 1:
                q_next = q + h * qd
            else:
                k2 = law(q + h / 2 * qd, *at[1])[0]
                k3 = law(q + h / 2 * k2, *at[1])[0]
                k4 = law(q + h * k3, *at[2])[0]
                q_next = q + h / 6 * (qd + 2 * k2 + 2 * k3 + k4)
            # the row from q on; J q̇ − ẋ_cmd measures how exactly the step met the command
            y.add("row", ca.vertcat(q, qd, pose[:3, 3], sym_rpy(pose[:3, :3]), ca.norm_2(pos_err), ca.norm_2(ori_err),
                                    ca.norm_2((ca.mtimes(jac, qd) - cmd)[rows]), lam, h_l,
                                    0.5 * ca.sumsqr(q - q_init)))
            y.add("q_next", q_next)
            y.add("needs_damping", sum(flags, ca.SX(0)) if flags else ca.SX(0))

        key = ("cartesian", self.task.integrator, "damped" if damped else "undamped", self.robot.task_rows,
               "collision" if with_collision else "")
        return self.backend.kernel(key, build)

    def run(self) -> PlanResult:
        task = self.task
        n, h = self.robot.n, task.step
        steps = int(round(task.duration / h))  # a whole number (common.path.check_step)
        kernel, damped_kernel = self._kernel(False), None  # the damped one is built when first needed
        for key, value in (("q_init", task.q_start), ("h", h), ("rho_L", task.method.rho_L),
                           ("clik_gain", task.clik_gain), ("epsilon", task.damping_epsilon),
                           ("lambda_max", task.damping_max)):
            kernel.set(key, value)
        if uses_criterion(task.collision):
            set_kernel_inputs(kernel, task.collision)
        # everything that depends on t alone, for every step and stage, in the kernel's input order
        t = np.arange(steps + 1) * h
        blocks = []
        for dt in ((0.0, h / 2, h) if task.integrator == "rk4" else (0.0,)):
            p_d, r_d, xdot = self.desired(t + dt)
            blocks += [p_d, np.swapaxes(r_d, -1, -2).reshape(-1, 9), xdot,
                       *(c[:, None] for c in self.alpha_coefficients(t + dt))]
        timed = np.hstack(blocks)
        timed_slot = slice(kernel.inputs["p_d0"].start, kernel.inputs["p_d0"].start + timed.shape[1])
        x, q_slot, w_slot = kernel.x, kernel.inputs["q"], kernel.inputs["windows"]
        columns = self._columns()
        data = np.empty((steps + 1, len(columns)))
        row_end = columns.index("window1_1")
        mp = task.method
        uses_windows = mp.name in ("zghal_improved", "combined")
        # the Zghal term's weight: off, always on, or the latched windows
        weight = {"pinv": np.zeros(n), "repetitive": np.zeros(n), "zghal": np.ones(n)}.get(mp.name)
        windows = self.windows.update(0.0, self.in_band(task.q_start))
        x[q_slot] = task.q_start
        x[w_slot] = windows if weight is None else weight
        q = x[q_slot]  # a view: the current joint angles
        with progress(steps, f"planning {mp.name}") as bar:
            for k in range(steps + 1):
                if uses_windows:
                    windows = self.windows.update(k * h, self.in_band(q))
                    x[w_slot] = windows
                    data[k, row_end:] = windows
                x[timed_slot] = timed[k]
                kernel()
                out = kernel
                if kernel.y[-1]:
                    damped_kernel = damped_kernel or self._kernel(True)
                    damped_kernel.x[:] = x
                    damped_kernel()
                    out = damped_kernel
                data[k, 1:row_end] = out.y[out.outputs["row"]]
                qd = data[k, 1 + n:1 + 2 * n]
                limited = qd if self.limiter is None else self.limiter(data[k, 1:1 + n], qd)
                if limited is not qd:  # the self-motion was scaled: an Euler step with the limited q̇
                    data[k, 1 + n:1 + 2 * n] = limited
                if k < steps:
                    x[q_slot] = out.y[out.outputs["q_next"]] if limited is qd else data[k, 1:1 + n] + h * limited
                    bar.update(1)
        data[:, 0] = t
        if not uses_windows:
            data[:, row_end:] = windows
        q_all = data[:, 1:1 + n]
        if not np.all(np.isfinite(q_all)):
            k = int(np.argmin(np.all(np.isfinite(q_all), axis=1)))
            raise PlanningError(f"joint angles became non-finite at t = {t[k]:.3f} s; lower integrator.step "
                                "or the method gains")
        self.damped_steps = int(np.count_nonzero(data[:, columns.index("damping_1")] > 0))
        keep = [k for k in range(steps + 1) if k % task.output_every == 0 or k == steps]
        result = PlanResult(columns, data[keep], {})
        result.metadata = self._metadata(result)
        if task.motion is None and self.check_path:  # a program's is checked naming its move
            check_on_circle_or_line(result)
        return result

    def _columns(self) -> list[str]:
        n = self.robot.n
        cols = ["t_s"] + [f"q{i + 1}_rad" for i in range(n)] + [f"dq{i + 1}_rad_s" for i in range(n)]
        cols += ["x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad", "pos_err_m", "ori_err_rad",
                 "task_residual_1", "damping_1", "H_L_1", "H_R_rad2"]
        cols += [f"window{i + 1}_1" for i in range(n)]
        return cols

    def _metadata(self, result: PlanResult) -> dict[str, Any]:
        n, task = self.robot.n, self.task
        t = result.column("t_s")
        q = result.data[:, 1:1 + n]
        qd = result.data[:, 1 + n:1 + 2 * n]
        violations, _ = limit_report(self.robot, t, q)
        travel = np.sum(np.abs(np.diff(q, axis=0)), axis=0)
        return {
            "method": task.method.name,
            "robot": {"name": self.robot.name, "file": self.robot.source, "sha256": self.robot.sha256,
                      "qlim_rad": [list(j.qlim) for j in self.robot.joints]},
            "start": {"label": task.start_label, "q_rad": task.q_start.tolist()},
            "parameters": {k: getattr(task.method, k) for k in task.method.__dataclass_fields__},
            "integrator": {"method": task.integrator, "step_s": task.step, "clik_gain": task.clik_gain,
                           "open_loop": task.clik_gain == 0},
            "damping": {"epsilon": task.damping_epsilon, "lambda_max": task.damping_max},
            "path": {"type": task.path_type, "duration_s": task.duration,
                     "law": task.law.kind if task.motion is None else "trapezoidal"},
            "summary": {
                "final_deviation_deg": np.degrees(q[-1] - task.q_start).tolist(),
                "max_final_deviation_deg": float(np.degrees(np.max(np.abs(q[-1] - task.q_start)))),
                "max_abs_q_deg": np.degrees(np.max(np.abs(q), axis=0)).tolist(),
                "limit_violations": violations,
                "max_pos_error_mm": float(np.max(result.column("pos_err_m")) * 1e3),
                "max_ori_error_deg": float(np.degrees(np.max(result.column("ori_err_rad")))),
                "max_task_residual": float(np.max(result.column("task_residual_1"))),
                "start_joint_speed_deg_s": float(np.degrees(np.linalg.norm(qd[0]))),
                "end_joint_speed_deg_s": float(np.degrees(np.linalg.norm(qd[-1]))),
                "joint_travel_deg": np.degrees(travel).tolist(),
                "total_joint_travel_deg": float(np.degrees(travel.sum())),
                "damped_steps": int(self.damped_steps),
                # steps whose self-motion was scaled to keep the joints within their speed limits
                **({"self_motion_limited_steps": self.limiter.limited_steps} if self.limiter else {}),
                "window_openings": self.windows.openings.tolist(),
            },
        }


def check_on_circle_or_line(result: PlanResult) -> None:
    """Refuse a plan whose tool left its circle or line by more than MAX_PATH_ERROR."""
    error = result.column("pos_err_m")
    if error.max() > MAX_PATH_ERROR:
        k = int(np.argmax(error > MAX_PATH_ERROR))
        raise PlanningError(
            f"the tool left the path by {error.max() * 1e3:.1f} mm (> {MAX_PATH_ERROR * 1e3:.0f} mm), first at "
            f"t = {result.data[k, 0]:.2f} s: the path is not reachable from this start (check path.via/path.end, the "
            "start configuration, or a singularity on the way)")


def plan(config: CartesianTask, backend: str = "symbolic") -> PlanResult:
    """The task's plan within its path tolerance: the integrator step is halved as needed
    (toolpath.accuracy); ``result.config`` is the task with the step the plan used."""
    shared = make_backend(config.robot, backend)

    def run(motion, step):
        planned = replace(config, step=step)
        planned = planned if motion is None else planned.with_motion(motion)
        return CartesianPlanner(planned, backend=shared, check_path=False).run()

    result, step = plan_with_speed_limits(run, config.motion, config.program and config.program.angular_speed,
                                          config.robot, config.source, config.accuracy, config.duration,
                                          check_on_circle_or_line)
    used = replace(config, step=step)
    result.config = used if result.motion is None else used.with_motion(result.motion)
    return result
