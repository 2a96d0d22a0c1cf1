"""Cartesian redundancy resolution along a path (spec 20).

``q̇ = J⁺ ẋ + (I − J⁺ J) α`` through the generated ``step_gpm`` with variable damping, where
``α`` is one of: 0 (minimum norm), the repetitive operator ``α_R``, the Zghal descent
``α_L`` (plain, or with latched per-joint windows), or the additive combination
``γ_R α_R + γ_L α_L``. Integrated by explicit Euler (the paper's), RK4, optionally closed
loop (CLIK). All inputs in SI after loading; the task file may use mm/deg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...errors import PlanningError, TaskFileError
from ...progress import progress
from ...robot import Robot, load_robot, matrix_rpy, rpy_matrix
from ..backends import make_backend
from ..paths import CirclePath, LinePath, TimeLaw
from ..result import PlanResult
from .windows import JointWindows

METHODS = ("pinv", "repetitive", "zghal", "zghal_improved", "combined")
INTEGRATORS = ("euler", "rk4")
PATH_TYPES = ("circle", "line")
LENGTH_SCALE = {"m": 1.0, "mm": 1e-3}
ANGLE_SCALE = {"rad": 1.0, "deg": math.pi / 180}
# A plan whose tool leaves the path by more than this is reported as not feasible
# (unreachable target or a singularity the damping could not cross): open-loop Euler drift
# at h = 0.02 s stays below 0.1 mm on the bundled examples.
MAX_PATH_ERROR = 5e-3  # m


@dataclass(frozen=True)
class MethodParams:
    name: str = "pinv"
    rho_R: float = 2.8
    T_smo_R: float = 10.0
    rho_L: float = 0.025
    theta_s: float = math.radians(20)
    T_smo_L: float = 40.0
    T_sum_L: float = 80.0
    gamma_R_ramp: float = 20.0


@dataclass(frozen=True)
class CartesianTask:
    robot: Robot
    q_start: np.ndarray
    path_type: str
    via: np.ndarray | None
    end: np.ndarray
    end_rotation: np.ndarray | None
    duration: float
    law: TimeLaw
    method: MethodParams
    integrator: str = "euler"
    step: float = 0.02
    clik_gain: float = 0.0
    damping_epsilon: float = 0.01
    damping_max: float = 0.05
    output_every: int = 1
    raw: dict[str, Any] = field(default_factory=dict)


def _table(task: dict, key: str, source: str) -> dict:
    value = task.get(key, {})
    if not isinstance(value, dict):
        raise TaskFileError(f"{source}: '{key}' must be a table ([{key}])")
    return value


def _number(table: dict, key: str, where: str, source: str, default: float | None = None, positive: bool = False,
            nonneg: bool = False) -> float:
    if key not in table:
        if default is None:
            raise TaskFileError(f"{source}: missing field '{where}.{key}'")
        return default
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise TaskFileError(f"{source}: field '{where}.{key}' = {value!r} must be a finite number")
    if positive and value <= 0:
        raise TaskFileError(f"{source}: field '{where}.{key}' = {value} must be > 0")
    if nonneg and value < 0:
        raise TaskFileError(f"{source}: field '{where}.{key}' = {value} must be ≥ 0")
    return float(value)


def _vector(table: dict, key: str, where: str, source: str, length: int, scale: float) -> np.ndarray:
    value = table.get(key)
    if not isinstance(value, list) or len(value) != length or \
            not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value):
        raise TaskFileError(f"{source}: field '{where}.{key}' must be a list of {length} finite numbers, got {value!r}")
    return np.array(value, dtype=float) * scale


def parse_robot_and_start(task: dict, source: str) -> tuple[Robot, np.ndarray, str, float, float]:
    """The task's robot, start configuration (SI, checked against the limits), the start's
    label, and the file's length and angle scales."""
    robot_name = task.get("robot")
    if not isinstance(robot_name, str):
        raise TaskFileError(f"{source}: missing field 'robot' (a bundled name or a robot file path)")
    robot = load_robot(robot_name)
    units = _table(task, "units", source)
    lunit, aunit = units.get("length", "m"), units.get("angle", "rad")
    if lunit not in LENGTH_SCALE or aunit not in ANGLE_SCALE:
        raise TaskFileError(f"{source}: [units] length must be m|mm and angle rad|deg, got {lunit!r}, {aunit!r}")
    ls, as_ = LENGTH_SCALE[lunit], ANGLE_SCALE[aunit]

    start = task.get("start", "q0")
    if isinstance(start, str):
        q_start, label = robot.configuration(start), start
    else:
        q_units = np.array([as_ if j.revolute else ls for j in robot.joints])
        q_start, label = _vector(task, "start", "task", source, robot.n, 1.0) * q_units, "explicit"
    robot.check_within_limits(q_start, f"{source}: field 'start'")
    return robot, q_start, label, ls, as_


def parse_path_and_timing(task: dict, source: str, ls: float, as_: float):
    """(path type, via, end, end rotation or None, duration, time law) from [path] and [timing]."""
    path = _table(task, "path", source)
    path_type = path.get("type", "circle")
    if path_type not in PATH_TYPES:
        raise TaskFileError(f"{source}: field 'path.type' = {path_type!r} is not one of {', '.join(PATH_TYPES)}")
    via = _vector(path, "via", "path", source, 3, ls) if path_type == "circle" else None
    end = _vector(path, "end", "path", source, 3, ls)
    orientation = path.get("orientation", "hold")
    if orientation not in ("hold", "interpolate"):
        raise TaskFileError(f"{source}: field 'path.orientation' = {orientation!r} must be 'hold' or 'interpolate'")
    end_rotation = None
    if orientation == "interpolate":
        if path_type != "line":
            raise TaskFileError(f"{source}: path.orientation = 'interpolate' needs path.type = 'line'")
        end_rotation = rpy_matrix(*_vector(path, "end_rpy", "path", source, 3, as_))

    timing = _table(task, "timing", source)
    duration = _number(timing, "duration", "timing", source, positive=True)
    law = TimeLaw(timing.get("law", "cubic"), _number(timing, "blend", "timing", source, 0.2))
    return path_type, via, end, end_rotation, duration, law


def parse_cartesian_task(task: dict, source: str) -> CartesianTask:
    robot, q_start, _, ls, as_ = parse_robot_and_start(task, source)
    path_type, via, end, end_rotation, duration, law = parse_path_and_timing(task, source, ls, as_)

    m = _table(task, "method", source)
    name = m.get("name", "pinv")
    if name not in METHODS:
        raise TaskFileError(f"{source}: field 'method.name' = {name!r} is not one of {', '.join(METHODS)}")
    defaults = MethodParams(name)
    if name == "combined":
        defaults = MethodParams(name, rho_L=1e-4, T_smo_L=20.0, T_sum_L=40.0)
    elif name == "zghal_improved":
        defaults = MethodParams(name, rho_L=0.04, T_smo_L=40.0, T_sum_L=80.0)
    params = MethodParams(
        name=name,
        rho_R=_number(m, "rho_R", "method", source, defaults.rho_R, nonneg=True),
        T_smo_R=_number(m, "T_smo_R", "method", source, defaults.T_smo_R, positive=True),
        rho_L=_number(m, "rho_L", "method", source, defaults.rho_L, nonneg=True),
        theta_s=_number(m, "theta_s", "method", source, defaults.theta_s / as_, positive=True) * as_,
        T_smo_L=_number(m, "T_smo_L", "method", source, defaults.T_smo_L, positive=True),
        T_sum_L=_number(m, "T_sum_L", "method", source, defaults.T_sum_L, positive=True),
        gamma_R_ramp=_number(m, "gamma_R_ramp", "method", source, defaults.gamma_R_ramp, positive=True),
    )
    if params.T_sum_L < params.T_smo_L:
        raise TaskFileError(f"{source}: method.T_sum_L = {params.T_sum_L} must be ≥ method.T_smo_L = {params.T_smo_L}")

    integ = _table(task, "integrator", source)
    integrator = integ.get("method", "euler")
    if integrator not in INTEGRATORS:
        raise TaskFileError(f"{source}: field 'integrator.method' = {integrator!r} is not one of {', '.join(INTEGRATORS)}")
    step = _number(integ, "step", "integrator", source, 0.02, positive=True)
    if step > duration:
        raise TaskFileError(f"{source}: integrator.step = {step} is longer than timing.duration = {duration}")
    damping = _table(task, "damping", source)
    return CartesianTask(
        robot=robot, q_start=q_start, path_type=path_type, via=via, end=end, end_rotation=end_rotation,
        duration=duration, law=law, method=params, integrator=integrator, step=step,
        clik_gain=_number(integ, "clik_gain", "integrator", source, 0.0, nonneg=True),
        damping_epsilon=_number(damping, "epsilon", "damping", source, 0.01, positive=True),
        damping_max=_number(damping, "lambda_max", "damping", source, 0.05, nonneg=True),
        output_every=int(_number(integ, "output_every", "integrator", source, 1, positive=True)),
        raw=task,
    )


def orientation_error(r_actual: np.ndarray, r_desired: np.ndarray) -> np.ndarray:
    """½ Σ r_i × r_d,i over the columns (the usual small-angle orientation error, base frame),
    computed as ½ vee(R_d Rᵀ − R R_dᵀ)."""
    s = r_desired @ r_actual.T
    return 0.5 * np.array([s[2, 1] - s[1, 2], s[0, 2] - s[2, 0], s[1, 0] - s[0, 1]])


class CartesianPlanner:
    """Integrates the resolved-rate law; the same code for every backend."""

    FUNCTIONS = ("fk_jacobian", "zghal", "step_gpm")

    def __init__(self, task: CartesianTask, backend_kind: str = "symbolic"):
        self.task = task
        self.robot = task.robot
        self.backend = make_backend(self.robot, backend_kind, self.FUNCTIONS)
        self.rows = list(self.robot.task_rows)
        T0, _ = self.backend.call("fk_jacobian", task.q_start)
        self.p0, self.r0 = T0[:3, 3].copy(), T0[:3, :3].copy()
        if task.path_type == "circle":
            self.path = CirclePath(self.p0, task.via, task.end, self.r0)
        else:
            r_end = task.end_rotation if task.end_rotation is not None else self.r0
            self.path = LinePath(self.p0, task.end, self.r0, r_end)
        self._check_reach()
        mp = task.method
        shape = "linear" if mp.name == "combined" else "quadratic"
        self.windows = JointWindows(self.robot.n, mp.T_smo_L, mp.T_sum_L, shape)
        self.damped_steps = 0

    def _check_reach(self) -> None:
        """Reject a path that leaves the sphere the arm can reach (sum of link lengths)."""
        reach = sum(j.link_length + (j.qlim[1] if not j.revolute else 0.0) for j in self.robot.joints)
        reach += float(np.linalg.norm(self.robot.tool[:3, 3]))
        base = self.robot.base[:3, 3]
        points = self.path.sample_points()
        dist = np.linalg.norm(points - base, axis=1)
        if dist.max() > reach:
            k = int(np.argmax(dist))
            where = "path.via / path.end" if self.task.path_type == "circle" else "path.end"
            raise PlanningError(
                f"the path is unreachable: point {np.round(points[k] * 1e3, 1).tolist()} mm is "
                f"{dist[k] * 1e3:.0f} mm from the base, beyond the arm's reach of {reach * 1e3:.0f} mm; "
                f"move {where} closer")

    # -- the pieces of the law -------------------------------------------------------
    def desired(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, rotation, task velocity [v; ω]) at time t."""
        T = self.task.duration
        s, ds = self.task.law(t / T)
        p, dp, rot, dw = self.path(s)
        sdot = ds / T if 0.0 <= t <= T else 0.0
        return p, rot, np.concatenate([dp * sdot, dw * sdot])

    def damping(self, jac: np.ndarray) -> float:
        """Variable damping: λ² = (1 − (σ_min/ε)²) λ_max² below ε, 0 above (exact inverse)."""
        sigma = np.linalg.svd(jac[self.rows], compute_uv=False)[-1]
        eps = self.task.damping_epsilon
        if sigma >= eps:
            return 0.0
        return math.sqrt(1 - (sigma / eps) ** 2) * self.task.damping_max

    def alpha(self, t: float, q: np.ndarray, windows: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
        mp, T = self.task.method, self.task.duration
        zero = np.zeros(self.robot.n)
        h_l, grad_l = self.backend.call("zghal", q)  # logged for every method
        info = {"H_L": float(h_l.ravel()[0]), "H_R": 0.5 * float(np.sum((q - self.task.q_start) ** 2))}
        if mp.name == "pinv":
            return zero, info

        def alpha_r() -> np.ndarray:
            t_sta = T / 2
            if t <= t_sta or t >= T:
                return zero  # off before T/2; its limit 0 at T (removable singularity for ρ_R > 1)
            lam = min(((t - t_sta) / mp.T_smo_R) ** 2, 1.0)
            return lam * mp.rho_R * (self.task.q_start - q) / (T - t)

        def alpha_l() -> np.ndarray:
            return -mp.rho_L * grad_l.ravel()

        if mp.name == "repetitive":
            return alpha_r(), info
        if mp.name == "zghal":
            return alpha_l(), info
        if mp.name == "zghal_improved":
            return windows * alpha_l(), info
        gamma_r = min(max((t - T / 2) / mp.gamma_R_ramp, 0.0), 1.0)
        info["gamma_R"] = gamma_r
        return gamma_r * alpha_r() + windows * alpha_l(), info

    def qdot(self, t: float, q: np.ndarray, windows: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
        T_pose, jac = self.backend.call("fk_jacobian", q)
        p_d, r_d, xdot = self.desired(t)
        pos_err = p_d - T_pose[:3, 3]
        ori_err = orientation_error(T_pose[:3, :3], r_d)
        cmd = xdot.copy()
        if self.task.clik_gain > 0:
            cmd += self.task.clik_gain * np.concatenate([pos_err, ori_err])
        alpha, info = self.alpha(t, q, windows)
        lam = self.damping(jac)
        (qd,) = self.backend.call("step_gpm", q, cmd[self.rows], alpha, lam)
        info.update(pose=T_pose, jac=jac, pos_err=pos_err, ori_err=ori_err, xdot=xdot, damping=lam)
        return qd.ravel(), info

    def in_band(self, q: np.ndarray) -> np.ndarray:
        th = self.task.method.theta_s
        return (q > self.robot.qmax - th) | (q < self.robot.qmin + th)

    # -- integration -----------------------------------------------------------------
    def run(self) -> PlanResult:
        task = self.task
        h = task.step
        steps = int(round(task.duration / h))
        if abs(steps * h - task.duration) > 1e-9 * task.duration:
            raise TaskFileError(f"timing.duration = {task.duration} s is not a multiple of integrator.step = {h} s")
        q = task.q_start.copy()
        rows: list[np.ndarray] = []
        windows = self.windows.update(0.0, self.in_band(q))
        uses_windows = task.method.name in ("zghal_improved", "combined")
        with progress(steps, f"planning {task.method.name}") as bar:
            for k in range(steps + 1):
                t = k * h
                if uses_windows:
                    windows = self.windows.update(t, self.in_band(q))
                qd, info = self.qdot(t, q, windows)
                self.damped_steps += info["damping"] > 0
                if k % task.output_every == 0 or k == steps:
                    rows.append(self._row(t, q, qd, info, windows))
                if k == steps:
                    break
                if task.integrator == "euler":
                    q = q + h * qd
                else:
                    k1 = qd
                    k2, _ = self.qdot(t + h / 2, q + h / 2 * k1, windows)
                    k3, _ = self.qdot(t + h / 2, q + h / 2 * k2, windows)
                    k4, _ = self.qdot(t + h, q + h * k3, windows)
                    q = q + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
                if not np.all(np.isfinite(q)):
                    raise PlanningError(f"joint angles became non-finite at t = {t + h:.3f} s; lower integrator.step "
                                        "or the method gains")
                bar.update(1)
        data = np.array(rows)
        result = PlanResult(self._columns(), data, {})
        result.metadata = self._metadata(result)
        max_err = float(np.max(result.column("pos_err_m")))
        if max_err > MAX_PATH_ERROR:
            k = int(np.argmax(result.column("pos_err_m") > MAX_PATH_ERROR))
            raise PlanningError(
                f"the tool left the path by {max_err * 1e3:.1f} mm (> {MAX_PATH_ERROR * 1e3:.0f} mm), first at "
                f"t = {data[k, 0]:.2f} s: the path is not reachable from this start (check path.via/path.end, the "
                "start configuration, or a singularity on the way)")
        return result

    def _columns(self) -> list[str]:
        n = self.robot.n
        cols = ["t_s"] + [f"q{i + 1}_rad" for i in range(n)] + [f"dq{i + 1}_rad_s" for i in range(n)]
        cols += ["x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad", "pos_err_m", "ori_err_rad",
                 "task_residual_1", "damping_1", "H_L_1", "H_R_rad2"]
        cols += [f"window{i + 1}_1" for i in range(n)]
        return cols

    def _row(self, t, q, qd, info, windows) -> np.ndarray:
        pose = info["pose"]
        jac = info["jac"]
        # J q̇ − ẋ_cmd: how exactly the step met the commanded twist (0 when undamped)
        cmd = info["xdot"] + (self.task.clik_gain * np.concatenate([info["pos_err"], info["ori_err"]])
                              if self.task.clik_gain > 0 else 0.0)
        residual = float(np.linalg.norm((jac @ qd - cmd)[self.rows]))
        return np.concatenate([[t], q, qd, pose[:3, 3], matrix_rpy(pose[:3, :3]),
                               [np.linalg.norm(info["pos_err"]), np.linalg.norm(info["ori_err"]), residual,
                                info["damping"], info["H_L"], info["H_R"]], windows])

    def _metadata(self, result: PlanResult) -> dict[str, Any]:
        n, task = self.robot.n, self.task
        t = result.column("t_s")
        q = result.data[:, 1:1 + n]
        qd = result.data[:, 1 + n:1 + 2 * n]
        violations = []
        for i, j in enumerate(self.robot.joints):
            bad = (q[:, i] > j.qlim[1]) | (q[:, i] < j.qlim[0])
            if bad.any():
                violations.append({"joint": j.name, "first_t_s": float(t[np.argmax(bad)]),
                                   "last_t_s": float(t[len(bad) - 1 - np.argmax(bad[::-1])]),
                                   "max_abs_deg": float(np.degrees(np.max(np.abs(q[:, i]))))})
        travel = np.sum(np.abs(np.diff(q, axis=0)), axis=0)
        return {
            "method": task.method.name,
            "robot": {"name": self.robot.name, "file": self.robot.source, "sha256": self.robot.sha256,
                      "qlim_rad": [list(j.qlim) for j in self.robot.joints]},
            "parameters": {k: getattr(task.method, k) for k in task.method.__dataclass_fields__},
            "integrator": {"method": task.integrator, "step_s": task.step, "clik_gain": task.clik_gain,
                           "open_loop": task.clik_gain == 0},
            "damping": {"epsilon": task.damping_epsilon, "lambda_max": task.damping_max},
            "path": {"type": task.path_type, "duration_s": task.duration, "law": task.law.kind},
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
                "window_openings": self.windows.openings.tolist(),
            },
        }


def plan_task(task: dict, source: str, backend: str = "symbolic") -> PlanResult:
    parsed = parse_cartesian_task(task, source)
    return CartesianPlanner(parsed, backend).run()
