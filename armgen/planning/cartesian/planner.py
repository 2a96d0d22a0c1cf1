"""Cartesian redundancy resolution along a path (spec 20).

``q̇ = J⁺ ẋ + (I − J⁺ J) α`` through the generated ``step_gpm`` with variable damping, where
``α`` is one of: 0 (minimum norm), the repetitive operator ``α_R``, the Zghal descent
``α_L`` (plain, or with latched per-joint windows), or the additive combination
``γ_R α_R + γ_L α_L``. Integrated by explicit Euler (the paper's), RK4, optionally closed
loop (CLIK). All inputs in SI after loading; the task file may use mm/deg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import casadi as ca
import numpy as np

from ...errors import PlanningError, TaskFileError, excerpt
from ...progress import progress
from ...description import rpy_matrix
from ...description.model import MAX_ABS_LENGTH_M
from ...robot import Robot, load_robot
from ...symbolic.steps import min_eigenvalue
from ..backends import make_backend
from ..limits import check_start_off_limits, limit_report
from ..toolpath.paths import CirclePath, LinePath, TimeLaw
from ..result import PlanResult
from ..toolpath.accuracy import path_accuracy
from ..toolpath.limits import SelfMotionLimiter, plan_with_speed_limits
from ..toolpath.task import ProgramSpec, parse_program, program_motion, reach_radius
from ..toolpath.timelaw import ProgramMotion
from .windows import JointWindows

METHODS = ("pinv", "repetitive", "zghal", "zghal_improved", "combined")
# The methods that descend Zghal's joint-limit criterion H_L (with gain rho_L).
JOINT_LIMIT_METHODS = ("zghal", "zghal_improved", "combined")
INTEGRATORS = ("euler", "rk4")
PATH_TYPES = ("circle", "line")
LENGTH_SCALE = {"m": 1.0, "mm": 1e-3}
ANGLE_SCALE = {"rad": 1.0, "deg": math.pi / 180}
# A plan whose tool leaves the path by more than this is reported as not feasible
# (unreachable target or a singularity the damping could not cross): open-loop Euler drift
# at h = 0.02 s stays below 0.8 mm on the bundled examples. The path tolerance
# (toolpath.accuracy, default 0.1 mm) is the accuracy a plan must meet where it applies.
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
    program: ProgramSpec | None = None  # path.type = "program": the moves, and
    motion: ProgramMotion | None = None  # their geometry and time law from the start pose
    start_label: str = ""

    def with_motion(self, motion: ProgramMotion) -> CartesianTask:
        """This task driven by ``motion``: the duration is the motion's, rounded up to whole steps."""
        return replace(self, motion=motion, duration=math.ceil(motion.duration / self.step - 1e-9) * self.step)


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
        raise TaskFileError(f"{source}: field '{where}.{key}' = {excerpt(repr(value))} must be a finite number")
    if positive and value <= 0:
        raise TaskFileError(f"{source}: field '{where}.{key}' = {value} must be > 0")
    if nonneg and value < 0:
        raise TaskFileError(f"{source}: field '{where}.{key}' = {value} must be ≥ 0")
    return float(value)


def _vector(table: dict, key: str, where: str, source: str, length: int, scale: float) -> np.ndarray:
    value = table.get(key)
    if not isinstance(value, list) or len(value) != length or \
            not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value):
        raise TaskFileError(f"{source}: field '{where}.{key}' must be a list of {length} finite numbers, got {excerpt(repr(value))}")
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
        raise TaskFileError(f"{source}: [units] length must be m|mm and angle rad|deg, got {excerpt(repr(lunit))}, {excerpt(repr(aunit))}")
    ls, as_ = LENGTH_SCALE[lunit], ANGLE_SCALE[aunit]

    start = task.get("start", "q0")
    if isinstance(start, dict):
        q_start, label = start_from_pose(robot, start, source, ls, as_)
    elif isinstance(start, str):
        if start not in robot.configurations:
            known = ", ".join(sorted(robot.configurations)) or "none"
            default = " (the default)" if "start" not in task else ""
            raise TaskFileError(
                f"{source}: field 'start' = {excerpt(repr(start))}{default} is not a configuration of robot "
                f"'{robot.name}' (known: {known}); name one of them, give {robot.n} joint values, or give a tool pose "
                "solved by the IK: start = { pose = { xyz = [...], rpy = [...] } }" + _urdf_hint(robot))
        q_start, label = robot.configuration(start), start
    else:
        q_units = np.array([as_ if j.revolute else ls for j in robot.joints])
        q_start, label = _vector(task, "start", "task", source, robot.n, 1.0) * q_units, "explicit"
    robot.check_within_limits(q_start, f"{source}: field 'start'")
    return robot, q_start, label, ls, as_


def _urdf_hint(robot: Robot) -> str:
    """Where a named configuration of a robot read from a URDF alone goes (a URDF holds none)."""
    if robot.source != robot.urdf.get("file"):
        return ""
    return ("; a URDF holds no named configurations: add one in a robot file that references it "
            "(urdf = \"...\" and a [configurations] table, docs/urdf.md)")


def start_from_pose(robot: Robot, start: dict, source: str, ls: float, as_: float) -> tuple[np.ndarray, str]:
    """``start = { pose = { xyz, rpy }, seed = … }``: the joint values that reach the pose (the
    robot's IK, inside the limits, its self-motion away from them), and a label saying which.
    Without ``seed`` the IK starts from the robot's ``q0``, or, for a robot without one (a URDF
    holds no configurations), where ``armgen ik`` starts: the middle of the joint limits turned
    about the first joint's axis toward the pose; the label says so."""
    pose = _table(start, "pose", source)
    target = np.eye(4)
    target[:3, 3] = _vector(pose, "xyz", "start.pose", source, 3, ls)
    if np.abs(target[:3, 3]).max() > MAX_ABS_LENGTH_M:  # Robot.ik refuses it (a ValueError)
        raise TaskFileError(f"{source}: field 'start.pose.xyz' is beyond ±{MAX_ABS_LENGTH_M:g} m (after [units]), out "
                            "of any arm's reach: check the value and [units]")
    target[:3, :3] = rpy_matrix(*_vector(pose, "rpy", "start.pose", source, 3, as_))
    seed = start.get("seed", "q0" if "q0" in robot.configurations else None)
    if isinstance(seed, list):
        q_units = np.array([as_ if j.revolute else ls for j in robot.joints])
        seed = _vector(start, "seed", "start", source, robot.n, 1.0) * q_units
        robot.check_within_limits(seed, f"{source}: field 'start.seed'")
    elif isinstance(seed, str) and seed not in robot.configurations:
        known = ", ".join(sorted(robot.configurations)) or "none"
        raise TaskFileError(
            f"{source}: field 'start.seed' = {excerpt(repr(seed))} is not a configuration of robot '{robot.name}' "
            f"(known: {known}); name one of them, give {robot.n} joint values, or leave start.seed out to start the "
            "IK from the robot's q0 (else from the middle of the joint limits, as armgen ik does)")
    result = robot.ik(target, seed=seed)
    seed_label = (f"seed {seed!r}" if isinstance(seed, str) else "seed 'given joint values'" if seed is not None
                  else "the middle of the joint limits")
    if not result.success:  # a pose outside the workspace: bad input (exit 2)
        raise TaskFileError(
            f"{source}: field 'start.pose' is not reachable: the inverse kinematics from {seed_label} stopped "
            f"{float(result.position_error) * 1e3:.3g} mm / {math.degrees(float(result.orientation_error)):.3g} deg "
            "from it; the pose may be outside the workspace or beyond the joint limits: move it, or give a seed "
            "(start.seed = a configuration name or joint values) closer to the configuration you want")
    label = (f"pose (IK from {seed_label}: position error {float(result.position_error):.1e} m, "
             f"orientation error {float(result.orientation_error):.1e} rad, {int(result.iterations)} iterations)")
    if seed is None:
        label += (f"; note: robot '{robot.name}' has no configuration q0 and the task gives no start.seed, so the IK "
                  "started where armgen ik does (the middle of the joint limits, turned toward the pose); set "
                  "start.seed to choose the configuration")
    return np.asarray(result.q, dtype=float), label


def parse_path_and_timing(task: dict, source: str, ls: float, as_: float):
    """(path type, via, end, end rotation or None, duration, time law) from [path] and [timing]."""
    path = _table(task, "path", source)
    path_type = path.get("type", "circle")
    if path_type not in PATH_TYPES:
        raise TaskFileError(f"{source}: field 'path.type' = {excerpt(repr(path_type))} is not one of {', '.join(PATH_TYPES)}")
    via = _vector(path, "via", "path", source, 3, ls) if path_type == "circle" else None
    end = _vector(path, "end", "path", source, 3, ls)
    orientation = path.get("orientation", "hold")
    if orientation not in ("hold", "interpolate"):
        raise TaskFileError(f"{source}: field 'path.orientation' = {excerpt(repr(orientation))} must be 'hold' or 'interpolate'")
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
    robot, q_start, start_label, ls, as_ = parse_robot_and_start(task, source)
    program = motion = None
    if _table(task, "path", source).get("type") == "program":
        if "timing" in task:
            raise TaskFileError(f"{source}: [timing] is not used with path.type = 'program' (time comes from "
                                "path.speed and path.acceleration); remove [timing]")
        program = parse_program(task["path"], source, ls, as_)
        motion = program_motion(program, robot.fk(q_start), robot, source)
        path_type, via, end, end_rotation, duration, law = ("program", None, np.zeros(3), None, motion.duration,
                                                            TimeLaw("constant"))
    else:
        path_type, via, end, end_rotation, duration, law = parse_path_and_timing(task, source, ls, as_)

    m = _table(task, "method", source)
    name = m.get("name", "pinv")
    if name not in METHODS:
        raise TaskFileError(f"{source}: field 'method.name' = {excerpt(repr(name))} is not one of {', '.join(METHODS)}")
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
    if name in JOINT_LIMIT_METHODS and params.rho_L > 0:
        check_start_off_limits(robot, q_start, f"method '{name}'", source)
    if params.T_sum_L < params.T_smo_L:
        raise TaskFileError(f"{source}: method.T_sum_L = {params.T_sum_L} must be ≥ method.T_smo_L = {params.T_smo_L}")

    integ = _table(task, "integrator", source)
    integrator = integ.get("method", "euler")
    if integrator not in INTEGRATORS:
        raise TaskFileError(f"{source}: field 'integrator.method' = {excerpt(repr(integrator))} is not one of {', '.join(INTEGRATORS)}")
    step = _number(integ, "step", "integrator", source, 0.02, positive=True)
    if step > duration and motion is None:
        raise TaskFileError(f"{source}: integrator.step = {step} is longer than timing.duration = {duration}")
    damping = _table(task, "damping", source)
    parsed = CartesianTask(
        robot=robot, q_start=q_start, path_type=path_type, via=via, end=end, end_rotation=end_rotation,
        duration=duration, law=law, method=params, integrator=integrator, step=step,
        clik_gain=_number(integ, "clik_gain", "integrator", source, 0.0, nonneg=True),
        damping_epsilon=_number(damping, "epsilon", "damping", source, 0.01, positive=True),
        damping_max=_number(damping, "lambda_max", "damping", source, 0.05, nonneg=True),
        output_every=int(_number(integ, "output_every", "integrator", source, 1, positive=True)),
        raw=task, program=program, start_label=start_label,
    )
    return parsed if motion is None else parsed.with_motion(motion)


def sym_orientation_error(r_actual: ca.SX, r_desired: ca.SX) -> ca.SX:
    """½ Σ r_i × r_d,i over the columns (the usual small-angle orientation error, base frame),
    computed as ½ vee(R_d Rᵀ − R R_dᵀ)."""
    s = ca.mtimes(r_desired, r_actual.T)
    return 0.5 * ca.vertcat(s[2, 1] - s[1, 2], s[0, 2] - s[2, 0], s[1, 0] - s[0, 1])


def sym_rpy(rot: ca.SX) -> ca.SX:
    """:func:`armgen.description.frames.matrix_rpy` in CasADi: [roll, pitch, yaw] of Rz(yaw) Ry(pitch) Rx(roll)."""
    return ca.vertcat(ca.atan2(rot[2, 1], rot[2, 2]), ca.atan2(-rot[2, 0], ca.hypot(rot[0, 0], rot[1, 0])),
                      ca.atan2(rot[1, 0], rot[0, 0]))


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
        caller (plan_task judges it after refining the step)."""
        self.task = task
        self.check_path = check_path
        self.robot = task.robot
        self.backend = backend or make_backend(self.robot, backend_kind)
        self.rows = list(self.robot.task_rows)
        T0, _ = self.backend.call("fk_jacobian", task.q_start)
        self.p0, self.r0 = T0[:3, 3].copy(), T0[:3, :3].copy()
        # a program's plan stays within the joint speed limits (self-motion scaled first)
        self.limiter = SelfMotionLimiter(self.robot, self.backend, self.rows) if task.motion is not None else None
        if task.motion is not None:  # built, and its reach checked, when parsed
            self.path = task.motion.program
        elif task.path_type == "circle":
            self.path = CirclePath(self.p0, task.via, task.end, self.r0)
        else:
            r_end = task.end_rotation if task.end_rotation is not None else self.r0
            self.path = LinePath(self.p0, task.end, self.r0, r_end)
        if task.motion is None:
            self._check_reach()
        mp = task.method
        shape = "linear" if mp.name == "combined" else "quadratic"
        self.windows = JointWindows(self.robot.n, mp.T_smo_L, mp.T_sum_L, shape)
        self.damped_steps = 0
        self._band_lo = self.robot.qmin + mp.theta_s
        self._band_hi = self.robot.qmax - mp.theta_s

    def _check_reach(self) -> None:
        """Reject a path that leaves the sphere the arm can reach (sum of link lengths)."""
        reach = reach_radius(self.robot)
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

        def build(model, x, y):
            n = model.n
            fk_jacobian, zghal, step_gpm = (model.function(f) for f in self.FUNCTIONS)
            q, q_init, windows = x.add("q", n), x.add("q_init", n), x.add("windows", n)
            h, rho_l, gain, eps, lam_max = (x.add(k, 1) for k in ("h", "rho_L", "clik_gain", "epsilon", "lambda_max"))
            at = [[x.add(f"{k}{s}", size) for k, size in self.STAGE_INPUTS] for s in range(stages)]
            flags = []

            def law(qs, p_d, r_d, xdot, gamma_r, a_r, b_r):
                pose, jac = fk_jacobian(qs)
                pos_err = p_d - pose[:3, 3]
                ori_err = sym_orientation_error(pose[:3, :3], ca.reshape(r_d, 3, 3))
                cmd = xdot + gain * ca.vertcat(pos_err, ori_err)
                h_l, grad_l = zghal(qs)
                alpha = gamma_r * (a_r * (q_init - qs) / b_r) + windows * (-rho_l * grad_l)
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

        key = ("cartesian", self.task.integrator, "damped" if damped else "undamped", self.robot.task_rows)
        return self.backend.kernel(key, build)

    def run(self) -> PlanResult:
        task = self.task
        n, h = self.robot.n, task.step
        steps = int(round(task.duration / h))
        if abs(steps * h - task.duration) > 1e-9 * task.duration:
            raise TaskFileError(f"timing.duration = {task.duration} s is not a multiple of integrator.step = {h} s")
        kernel, damped_kernel = self._kernel(False), None  # the damped one is built when first needed
        for key, value in (("q_init", task.q_start), ("h", h), ("rho_L", task.method.rho_L),
                           ("clik_gain", task.clik_gain), ("epsilon", task.damping_epsilon),
                           ("lambda_max", task.damping_max)):
            kernel.set(key, value)
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


def plan_task(task: dict, source: str, backend: str = "symbolic") -> PlanResult:
    """The task's plan within its path tolerance: the integrator step is halved as needed
    (toolpath.accuracy) and the step used written into ``task`` (so the task records its plan)."""
    parsed = parse_cartesian_task(task, source)
    shared = make_backend(parsed.robot, backend)

    def run(motion, step):
        planned = replace(parsed, step=step)
        planned = planned if motion is None else planned.with_motion(motion)
        return CartesianPlanner(planned, backend=shared, check_path=False).run()

    return plan_with_speed_limits(run, parsed.motion, parsed.program and parsed.program.angular_speed, parsed.robot,
                                  source, path_accuracy(task, parsed.step, parsed.motion is not None),
                                  parsed.duration, check_on_circle_or_line)
