"""The PTP task file (``planner = "ptp"``), parsed and checked into a :class:`PtpConfig` (SI units)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import RobotFileError, TaskFileError, excerpt
from ...robot import Robot, load_robot
from .families import DEFAULT_METHOD, METHODS, JointWaypoints, preset_accel
from .poses import POSE_FIELDS, solve_pose_waypoints

DEFAULT_STEP_S = 1e-3
ANGLE_SCALE = {"rad": 1.0, "deg": math.pi / 180.0}
# Waypoint speeds equal to ω_max are allowed (the paper's segment 1); this relative slack
# absorbs the unit conversion of equal numbers.
BOUND_RTOL = 1e-12


@dataclass(frozen=True)
class PtpConfig:
    """A parsed ``planner = "ptp"`` task, SI units. Arrays ``omega_max``/``eps_max`` are (joints, segments)."""

    source: str
    method: str
    compare: tuple[str, ...]
    step: float
    angle_unit: str
    joints: tuple[JointWaypoints, ...]
    times: np.ndarray | None
    omega_max: np.ndarray | None
    eps_max: np.ndarray | None
    grid: float | None
    robot: str | None = None
    solved_poses: dict[str, Any] | None = None  # waypoints given as tool poses: the IK's solutions (poses.py)
    robot_model: Robot | None = None  # the named robot: its qdlim/qddlim are checked against the plan

    @property
    def n_waypoints(self) -> int:
        return len(self.joints[0].theta)

    @property
    def n_segments(self) -> int:
        return self.n_waypoints - 1


_TOP_FIELDS = {"planner", "description", "robot", "method", "compare", "step", "units", "waypoints", "timing", "check"}
_WAYPOINT_FIELDS = {"t", "theta", "omega", "eps", *POSE_FIELDS}
_TIMING_FIELDS = {"omega_max", "eps_max", "grid"}


def waypoint_label(k: int) -> str:
    """``A``, ``B``, … as in the spec (``#k`` past ``Z``)."""
    return chr(ord("A") + k) if k < 26 else f"#{k}"


def segment_label(k: int) -> str:
    return f"segment {k + 1} ({waypoint_label(k)}→{waypoint_label(k + 1)})"


class _Fields:
    """Typed access to task fields; errors name the file, the field and the fix."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, field: str, message: str) -> TaskFileError:
        return TaskFileError(f"{self.source}: field '{field}' {message}")

    def number(self, value: Any, field: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(field, f"must be a number, got {excerpt(repr(value))}")
        if not math.isfinite(value):
            raise self.fail(field, f"is {value}; give a finite number")
        return float(value)

    def positive(self, value: Any, field: str, fix: str) -> float:
        x = self.number(value, field)
        if x <= 0:
            raise self.fail(field, f"= {value} must be > 0; {fix}")
        return x

    def vector(self, value: Any, field: str, length: int | None = None) -> np.ndarray:
        if not isinstance(value, list):
            raise self.fail(field, f"must be an array of numbers, got {type(value).__name__} {excerpt(repr(value))}")
        if length is not None and len(value) != length:
            raise self.fail(field, f"has {len(value)} entries but there are {length} waypoints; give one per waypoint")
        return np.array([self.number(v, f"{field}[{k}]") for k, v in enumerate(value)])

    def table(self, doc: dict, key: str, required: bool, allowed: set[str]) -> dict:
        if key not in doc:
            if required:
                raise self.fail(key, f"is missing; add a [{key}] table")
            return {}
        value = doc[key]
        if not isinstance(value, dict):
            raise self.fail(key, f"must be a table ([{key}])")
        unknown = set(value) - allowed
        if unknown:
            raise self.fail(key, f"has unknown field(s) {', '.join(sorted(unknown))}; allowed: {', '.join(sorted(allowed))}")
        return value


def _per_joint(fields: _Fields, value: Any, field: str, names: tuple[str, ...], single: bool) -> dict[str, Any]:
    """A per-joint table (robot) or a bare value (single joint) as ``{joint: value}``."""
    if single:
        if isinstance(value, dict):
            raise fields.fail(field, "is a table but the task names no robot; give an array for the single joint")
        return {names[0]: value}
    if not isinstance(value, dict):
        raise fields.fail(field, f"must be a table with one array per joint of the robot ({', '.join(names)}), "
                                 f"e.g. {field} = {{ {names[0]} = [...], ... }}")
    unknown = set(value) - set(names)
    missing = [n for n in names if n not in value]
    if unknown:
        raise fields.fail(field, f"names unknown joint(s) {', '.join(sorted(unknown))}; "
                                 f"the robot's joints are {', '.join(names)}")
    if missing:
        raise fields.fail(field, f"lacks joint(s) {', '.join(missing)}; give waypoints for every joint of the robot")
    return value


def _bound_array(fields: _Fields, value: Any, field: str, names: tuple[str, ...], single: bool, nseg: int,
                 scale: float, fix: str) -> np.ndarray:
    """A bound given as a number, a per-segment array, or (robot) a per-joint table of either."""
    table = _per_joint(fields, value, field, names, single) if isinstance(value, dict) else None
    out = np.empty((len(names), nseg))
    for j, name in enumerate(names):
        item, where = (table[name], f"{field}.{name}") if table is not None else (value, field)
        if isinstance(item, list):
            if len(item) != nseg:
                raise fields.fail(where, f"has {len(item)} entries but there are {nseg} segments; "
                                         "give one per segment or a single number")
            out[j] = [fields.positive(v, f"{where}[{k}]", fix) for k, v in enumerate(item)]
        else:
            out[j] = fields.positive(item, where, fix)
    return out * scale


def parse_ptp_task(task: dict[str, Any], source: str) -> PtpConfig:
    """Validate a ``planner = "ptp"`` task dict and convert it to SI (see docs/ptp.md)."""
    fields = _Fields(source)
    unknown = set(task) - _TOP_FIELDS
    if unknown:
        raise TaskFileError(f"{source}: unknown field(s) {', '.join(sorted(unknown))}; allowed: {', '.join(sorted(_TOP_FIELDS))}")
    method = task.get("method", DEFAULT_METHOD)
    if method not in METHODS:
        raise fields.fail("method", f"= {excerpt(repr(method))} is not one of {', '.join(METHODS)}")
    compare_raw = task.get("compare", [])
    if (not isinstance(compare_raw, list) or any(m not in METHODS for m in compare_raw)
            or len(set(compare_raw)) != len(compare_raw)):
        raise fields.fail("compare", f"= {excerpt(repr(compare_raw))} must be a list of distinct method names from {', '.join(METHODS)}")
    step = fields.positive(task.get("step", DEFAULT_STEP_S), "step", "give the CSV sample step in seconds, e.g. 0.001")
    units = fields.table(task, "units", False, {"angle"})
    angle_unit = units.get("angle", "rad")
    if angle_unit not in ANGLE_SCALE:
        raise fields.fail("units.angle", f"= {excerpt(repr(angle_unit))} must be \"rad\" or \"deg\"")
    scale = ANGLE_SCALE[angle_unit]

    robot_name = task.get("robot")
    robot = None
    qlims: list[tuple[float, float] | None]
    if robot_name is None:
        names: tuple[str, ...] = ("j1",)
        qlims = [None]
    else:
        if not isinstance(robot_name, str) or not robot_name:
            raise fields.fail("robot", f"= {excerpt(repr(robot_name))} must be a bundled robot name or a robot file path")
        try:
            robot = load_robot(robot_name)
        except RobotFileError as exc:
            raise TaskFileError(f"{source}: field 'robot': {exc}") from None
        prismatic = [j.name for j in robot.joints if not j.revolute]
        if prismatic:
            raise fields.fail("robot", f"= {excerpt(repr(robot_name))} has prismatic joint(s) {', '.join(prismatic)}; "
                                       "the ptp planner plans revolute joints (angles) only")
        names = tuple(j.name for j in robot.joints)
        qlims = [j.qlim for j in robot.joints]
    single = robot_name is None

    wp = fields.table(task, "waypoints", True, _WAYPOINT_FIELDS)
    solved_poses = None
    if "xyz" in wp:  # tool poses: joint angles by the inverse kinematics, stopping at each unless omega is given
        if single:
            raise fields.fail("waypoints.xyz", "needs a robot (the task names none); add robot = \"<name>\"")
        q_solved, solved_poses = solve_pose_waypoints(robot, wp, source, scale)
        wp = {**wp, "theta": {name: (q_solved[:, j] / scale).tolist() for j, name in enumerate(names)}}
        wp.setdefault("omega", {name: [0.0] * len(q_solved) for name in names})
    elif any(key in wp for key in POSE_FIELDS):
        raise fields.fail("waypoints.rpy", "and waypoints.seed need waypoints.xyz (the tool positions); add it")
    for key in ("theta", "omega"):
        if key not in wp:
            raise fields.fail(f"waypoints.{key}", "is missing; give the waypoint angles (theta) and velocities (omega)")
    thetas = _per_joint(fields, wp["theta"], "waypoints.theta", names, single)
    omegas = _per_joint(fields, wp["omega"], "waypoints.omega", names, single)
    epss = _per_joint(fields, wp["eps"], "waypoints.eps", names, single) if "eps" in wp else None
    first = thetas[names[0]]
    if not isinstance(first, list) or len(first) < 2:
        where = "waypoints.theta" if single else f"waypoints.theta.{names[0]}"
        raise fields.fail(where, f"must list at least two waypoints (got {excerpt(repr(first))}); a plan goes from A to B at least")
    n = len(first)
    joints = []
    for name, qlim in zip(names, qlims):
        sfx = "" if single else f".{name}"
        theta = fields.vector(thetas[name], f"waypoints.theta{sfx}", n) * scale
        omega = fields.vector(omegas[name], f"waypoints.omega{sfx}", n) * scale
        eps = fields.vector(epss[name], f"waypoints.eps{sfx}", n) * scale if epss is not None else None
        if qlim is not None:
            for k, q in enumerate(theta):
                if not qlim[0] <= q <= qlim[1]:
                    raise fields.fail(f"waypoints.theta{sfx}[{k}]",
                                      f"= {q / scale:.6g} {angle_unit} is outside joint '{name}' limits "
                                      f"[{qlim[0] / scale:.6g}, {qlim[1] / scale:.6g}] {angle_unit}; "
                                      "move the waypoint inside the limits")
        joints.append(JointWaypoints(name, theta, omega, eps, qlim))

    timing = fields.table(task, "timing", False, _TIMING_FIELDS)
    times = None
    if "t" in wp:
        times = fields.vector(wp["t"], "waypoints.t", n)
        for k in range(n - 1):
            if not times[k] < times[k + 1]:
                raise fields.fail(f"waypoints.t[{k + 1}]",
                                  f"= {times[k + 1]:g} s is not after waypoints.t[{k}] = {times[k]:g} s; "
                                                          "knot times must be strictly increasing")
        if "grid" in timing:
            raise fields.fail("timing.grid", "rounds computed durations, but waypoints.t is given; remove timing.grid "
                                             "or remove waypoints.t to compute the times from timing.omega_max")
    elif "omega_max" not in timing:
        raise fields.fail("waypoints.t", "is missing and there is no timing.omega_max; give the knot times or the speed bound")
    omega_max = eps_max = grid = None
    if "omega_max" in timing:
        omega_max = _bound_array(fields, timing["omega_max"], "timing.omega_max", names, single, n - 1, scale,
                                 "give the joint speed bound in angle units per second")
    if "eps_max" in timing:
        eps_max = _bound_array(fields, timing["eps_max"], "timing.eps_max", names, single, n - 1, scale,
                               "give the joint acceleration bound in angle units per second squared, or remove it")
        if omega_max is None:
            raise fields.fail("timing.eps_max", "needs timing.omega_max as well; add timing.omega_max")
    if "grid" in timing:
        grid = fields.positive(timing["grid"], "timing.grid", "give the duration grid in seconds (e.g. 1.0) or remove it")
    config = PtpConfig(source, method, tuple(compare_raw), step, angle_unit, tuple(joints), times, omega_max, eps_max,
                       grid, robot_name, solved_poses, robot)
    if omega_max is not None:
        _check_bounds_against_waypoints(config)
    for m in dict.fromkeys([method, *compare_raw]):
        _check_method_applicable(config, m)
    return config


def _check_bounds_against_waypoints(config: PtpConfig) -> None:
    """ω_max (ε_max) must not be below a waypoint's own speed (preset acceleration)."""
    scale, unit = ANGLE_SCALE[config.angle_unit], config.angle_unit
    for j, jw in enumerate(config.joints):
        sfx = "" if len(config.joints) == 1 else f" of joint '{jw.name}'"
        for k in range(config.n_segments):
            for i in (k, k + 1):
                if abs(jw.omega[i]) > config.omega_max[j, k] * (1 + BOUND_RTOL):
                    raise TaskFileError(
                        f"{config.source}: field 'timing.omega_max' for {segment_label(k)}{sfx} is "
                        f"{config.omega_max[j, k] / scale:.6g} {unit}/s, below |waypoints.omega[{i}]| = "
                        f"{abs(jw.omega[i]) / scale:.6g} {unit}/s at waypoint {waypoint_label(i)}; "
                        "raise omega_max or lower the waypoint speed")
            if config.eps_max is not None:
                for i in (k, k + 1):
                    preset = preset_accel(config.method, jw, i, config.n_segments)
                    if preset is not None and abs(preset) > config.eps_max[j, k] * (1 + BOUND_RTOL):
                        raise TaskFileError(
                            f"{config.source}: field 'timing.eps_max' for {segment_label(k)}{sfx} is "
                            f"{config.eps_max[j, k] / scale:.6g} {unit}/s², below the preset |waypoints.eps[{i}]| = "
                            f"{abs(preset) / scale:.6g} {unit}/s²; raise eps_max or lower the preset acceleration")


def _check_method_applicable(config: PtpConfig, method: str) -> None:
    if method == "3-5-3" and config.n_waypoints < 4:
        raise TaskFileError(f"{config.source}: method '3-5-3' needs at least 4 waypoints (cubic, quintic…, cubic), "
                            f"got {config.n_waypoints}; use '3-4' or 'cubic' (field 'method' or 'compare')")
    if (method == config.method and config.times is None and method == "3-5-3" and config.n_waypoints == 5
            and config.joints[0].eps is None):
        raise TaskFileError(f"{config.source}: field 'waypoints.t' is missing, but the 5-waypoint 3-5-3 plan chooses the "
                            "acceleration at C from both quintic durations together, so its segment times cannot be "
                            "computed one by one; give waypoints.t, or waypoints.eps, or use method '3-4' to compute the times")
