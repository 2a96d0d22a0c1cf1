"""The PTP task's typed configuration (:class:`PtpConfig`, SI units) and :func:`configure`,
which makes it from the validated task file (:class:`~.schema.PtpTaskFile`) and the task's
robot: it converts the angles to rad, checks the per-joint tables against the robot's joints,
the waypoints against its limits, and the bounds against the waypoints' own speeds."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Union

import numpy as np

from ...description.files import ANGLE_UNITS
from ...errors import TaskFileError, excerpt
from ...robot import Robot
from ..common.collision import TaskCollision, configure_collision
from .families import JointWaypoints, preset_accel
from .poses import SolvedPoses, solve_pose_waypoints
from .schema import PerJointBound, PtpTaskFile

# Waypoint speeds equal to ω_max are allowed (the paper's segment 1); this relative slack
# absorbs the unit conversion of equal numbers.
BOUND_RTOL = 1e-12


@dataclass(frozen=True)
class PtpConfig:
    """A ``planner = "ptp"`` task, SI units. Arrays ``omega_max``/``eps_max`` are (joints, segments)."""

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
    robot: str | None = None  # the task's robot reference, as plan.json records it
    solved_poses: SolvedPoses | None = None  # waypoints given as tool poses: the IK's solutions (poses.py)
    robot_model: Robot | None = None  # the named robot: its qdlim/qddlim are checked against the plan
    collision: TaskCollision | None = None  # the robot's capsules and the task's obstacles: every sample checked

    @property
    def n_waypoints(self) -> int:
        return len(self.joints[0].theta)

    @property
    def n_segments(self) -> int:
        return self.n_waypoints - 1

    @property
    def angle_scale(self) -> float:
        """rad per angle unit of the task file (for messages in the file's unit)."""
        return ANGLE_UNITS[self.angle_unit]


def waypoint_label(k: int) -> str:
    """``A``, ``B``, … as in the spec (``#k`` past ``Z``)."""
    return chr(ord("A") + k) if k < 26 else f"#{k}"


def segment_label(k: int) -> str:
    return f"segment {k + 1} ({waypoint_label(k)}→{waypoint_label(k + 1)})"


def _joint_table(value: Union[list, dict], field: str, names: tuple[str, ...], source: str) -> dict:
    """A robot task's per-joint table, checked to name exactly the robot's joints."""
    if not isinstance(value, dict):
        raise TaskFileError(f"{source}: field '{field}' must be a table with one array per joint of the robot "
                            f"({', '.join(names)}), e.g. {field} = {{ {names[0]} = [...], ... }}")
    unknown = set(value) - set(names)
    if unknown:
        raise TaskFileError(f"{source}: field '{field}' names unknown joint(s) {', '.join(sorted(unknown))}; "
                            f"the robot's joints are {', '.join(names)}")
    missing = [n for n in names if n not in value]
    if missing:
        raise TaskFileError(f"{source}: field '{field}' lacks joint(s) {', '.join(missing)}; give waypoints for every "
                            "joint of the robot")
    return value


def _per_joint(value: Union[list[float], dict[str, list[float]], None], field: str, names: tuple[str, ...],
               single: bool, scale: float, source: str) -> list[Optional[np.ndarray]]:
    """One array per joint (in the robot's order) from a single joint's array or a robot's table, in SI."""
    if value is None:
        return [None] * len(names)
    if single:
        return [np.array(value, dtype=float) * scale]
    table = _joint_table(value, field, names, source)
    return [np.array(table[name], dtype=float) * scale for name in names]


def _bounds(value: PerJointBound | None, field: str, names: tuple[str, ...], nseg: int, scale: float,
            source: str) -> np.ndarray | None:
    """A bound given as a number, a per-segment array, or (robot) a per-joint table of either: (joints, segments), SI."""
    if value is None:
        return None
    table = _joint_table(value, field, names, source) if isinstance(value, dict) else None
    out = np.empty((len(names), nseg))
    for j, name in enumerate(names):
        out[j] = table[name] if table is not None else value
    return out * scale


def _check_revolute(robot: Robot, reference: str, source: str) -> None:
    prismatic = [j.name for j in robot.joints if not j.revolute]
    if prismatic:
        raise TaskFileError(f"{source}: field 'robot' = {excerpt(repr(reference))} has prismatic joint(s) "
                            f"{', '.join(prismatic)}; the ptp planner plans revolute joints (angles) only")


def _check_limits(joints: tuple[JointWaypoints, ...], single: bool, angle_unit: str, scale: float,
                  source: str) -> None:
    for jw in joints:
        if jw.qlim is None:
            continue
        for k, q in enumerate(jw.theta):
            if not jw.qlim[0] <= q <= jw.qlim[1]:
                field = f"waypoints.theta{'' if single else '.' + jw.name}[{k}]"
                raise TaskFileError(f"{source}: field '{field}' = {q / scale:.6g} {angle_unit} is outside joint "
                                    f"'{jw.name}' limits [{jw.qlim[0] / scale:.6g}, {jw.qlim[1] / scale:.6g}] "
                                    f"{angle_unit}; move the waypoint inside the limits")


def configure(model: PtpTaskFile, robot: Robot | None, source: str) -> PtpConfig:
    """The task's :class:`PtpConfig` (see docs/ptp.md). Without a robot the task is one joint
    ``j1``; with one, every per-joint table names exactly its joints, all revolute, and tool-pose
    waypoints are solved by its inverse kinematics (from here on they are joint waypoints)."""
    scale = ANGLE_UNITS[model.units.angle]
    if model.robot is None:  # a single joint, even beside a robot given for the firmware (it drives joint 1)
        robot = None
    single = robot is None
    if robot is None:
        names: tuple[str, ...] = ("j1",)
        qlims: tuple[Optional[tuple[float, float]], ...] = (None,)
    else:
        _check_revolute(robot, str(model.robot), source)
        names = tuple(j.name for j in robot.joints)
        qlims = tuple(j.qlim for j in robot.joints)
    wp = model.waypoints
    solved = None
    collision = configure_collision(model, robot, source)
    if wp.xyz is not None:
        assert robot is not None  # the schema refuses tool-pose waypoints without a robot
        rpy = None if wp.rpy is None else np.array(wp.rpy, dtype=float) * scale
        solved = solve_pose_waypoints(robot, np.array(wp.xyz, dtype=float), rpy, wp.seed, source, scale, collision)
        thetas: list[Optional[np.ndarray]] = list(solved.q.T)
        omegas = (_per_joint(wp.omega, "waypoints.omega", names, single, scale, source) if wp.omega is not None
                  else [np.zeros(len(solved.q)) for _ in names])
    else:
        thetas = _per_joint(wp.theta, "waypoints.theta", names, single, scale, source)
        omegas = _per_joint(wp.omega, "waypoints.omega", names, single, scale, source)
    epss = _per_joint(wp.eps, "waypoints.eps", names, single, scale, source)
    joints = tuple(JointWaypoints(name, theta, omega, eps, qlim)
                   for name, theta, omega, eps, qlim in zip(names, thetas, omegas, epss, qlims))
    _check_limits(joints, single, model.units.angle, scale, source)
    nseg = len(joints[0].theta) - 1
    config = PtpConfig(
        source, model.method, tuple(model.compare), model.step, model.units.angle, joints,
        None if wp.t is None else np.array(wp.t, dtype=float),
        _bounds(model.timing.omega_max, "timing.omega_max", names, nseg, scale, source),
        _bounds(model.timing.eps_max, "timing.eps_max", names, nseg, scale, source),
        model.timing.grid, model.robot, solved, robot, collision)
    if config.omega_max is not None:
        _check_bounds_against_waypoints(config)
    return config


def _check_bounds_against_waypoints(config: PtpConfig) -> None:
    """ω_max (ε_max) must not be below a waypoint's own speed (preset acceleration)."""
    scale, unit = config.angle_scale, config.angle_unit
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
