"""Robot + start: a task's ``start`` (a configuration name, joint values or a tool pose solved by
the robot's IK) and ``[units]``, validated by :mod:`.schema`, → the start configuration in SI on
the task's loaded robot, checked against its limits, and a label saying where it came from."""

from __future__ import annotations

import math

import numpy as np

from ...description import rpy_matrix
from ...description.files import ANGLE_UNITS, LENGTH_UNITS
from ...description.model import MAX_ABS_LENGTH_M
from ...errors import TaskFileError, excerpt
from ...robot import Robot
from .collision import TaskCollision, ik_arguments
from .schema import Start, StartPose, Units


def unit_scales(units: Units) -> tuple[float, float]:
    """(length, angle) factors from the file's ``[units]`` to SI (m, rad)."""
    return LENGTH_UNITS[units.length], ANGLE_UNITS[units.angle]


def joint_values(values: list[float], robot: Robot, field: str, source: str, length_scale: float,
                 angle_scale: float) -> np.ndarray:
    """Joint values in the file's units (angle for a revolute joint, length for a prismatic one)
    → SI; their count must be the robot's joint count."""
    if len(values) != robot.n:
        raise TaskFileError(f"{source}: field '{field}' has {len(values)} joint values but robot '{robot.name}' has "
                            f"{robot.n} joints; give {robot.n} values in the file's [units]")
    scales = np.array([angle_scale if j.revolute else length_scale for j in robot.joints])
    return np.array(values, dtype=float) * scales


def start_configuration(start: Start, units: Units, robot: Robot, source: str,
                        given: bool = True, collision: TaskCollision | None = None) -> tuple[np.ndarray, str]:
    """The start configuration (SI, within the robot's limits) and its label. ``given`` False:
    the task left ``start`` to its default (an error says so). A tool-pose start is solved clear
    of the task's obstacles (``collision``) and of the arm itself."""
    ls, as_ = unit_scales(units)
    if isinstance(start, StartPose):
        q_start, label = start_from_pose(robot, start, source, ls, as_, collision)
    elif isinstance(start, str):
        if start not in robot.configurations:
            known = ", ".join(sorted(robot.configurations)) or "none"
            default = "" if given else " (the default)"
            raise TaskFileError(
                f"{source}: field 'start' = {excerpt(repr(start))}{default} is not a configuration of robot "
                f"'{robot.name}' (known: {known}); name one of them, give {robot.n} joint values, or give a tool pose "
                "solved by the IK: start = { pose = { xyz = [...], rpy = [...] } }" + _urdf_hint(robot))
        q_start, label = robot.configuration(start), start
    else:
        q_start, label = joint_values(start, robot, "start", source, ls, as_), "explicit"
    robot.check_within_limits(q_start, f"{source}: field 'start'")
    return q_start, label


def _urdf_hint(robot: Robot) -> str:
    """Where a named configuration of a robot read from a URDF alone goes (a URDF holds none)."""
    if robot.source != robot.urdf.get("file"):
        return ""
    return ("; a URDF holds no named configurations: add one in a robot file that references it "
            "(urdf = \"...\" and a [configurations] table, docs/urdf.md)")


def start_from_pose(robot: Robot, start: StartPose, source: str, ls: float, as_: float,
                    collision: TaskCollision | None = None) -> tuple[np.ndarray, str]:
    """``start = { pose = { xyz, rpy }, seed = … }``: the joint values that reach the pose (the
    robot's IK, inside the limits, its self-motion away from them, clear of ``collision``'s
    obstacles and of the arm itself at its clearance), and a label saying which.
    Without ``seed`` the IK starts from the robot's ``q0``, or, for a robot without one (a URDF
    holds no configurations), where ``armgen ik`` starts: the middle of the joint limits turned
    about the first joint's axis toward the pose; the label says so."""
    target = np.eye(4)
    target[:3, 3] = np.array(start.pose.xyz, dtype=float) * ls
    if np.abs(target[:3, 3]).max() > MAX_ABS_LENGTH_M:  # Robot.ik refuses it (a ValueError)
        raise TaskFileError(f"{source}: field 'start.pose.xyz' is beyond ±{MAX_ABS_LENGTH_M:g} m (after [units]), out "
                            "of any arm's reach: check the value and [units]")
    target[:3, :3] = rpy_matrix(*(np.array(start.pose.rpy, dtype=float) * as_))
    seed = start.seed if "seed" in start.model_fields_set else ("q0" if "q0" in robot.configurations else None)
    if isinstance(seed, list):
        seed = joint_values(seed, robot, "start.seed", source, ls, as_)
        robot.check_within_limits(seed, f"{source}: field 'start.seed'")
    elif isinstance(seed, str) and seed not in robot.configurations:
        known = ", ".join(sorted(robot.configurations)) or "none"
        raise TaskFileError(
            f"{source}: field 'start.seed' = {excerpt(repr(seed))} is not a configuration of robot '{robot.name}' "
            f"(known: {known}); name one of them, give {robot.n} joint values, or leave start.seed out to start the "
            "IK from the robot's q0 (else from the middle of the joint limits, as armgen ik does)")
    result = robot.ik(target, seed=seed, **ik_arguments(collision))
    seed_label = (f"seed {seed!r}" if isinstance(seed, str) else "seed 'given joint values'" if seed is not None
                  else "the middle of the joint limits")
    if result.colliding:  # reached, but only by configurations that collide
        raise TaskFileError(
            f"{source}: field 'start.pose': every configuration the inverse kinematics found (from {seed_label}) "
            f"that reaches it comes closer than the clearance (the best: least distance "
            f"{float(result.clearance) * 1e3:.1f} mm); move the pose or the obstacles, lower [collision] clearance, "
            "or give a start.seed near a configuration clear of them")
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
