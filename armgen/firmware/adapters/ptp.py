"""``planner = "ptp"`` → ``CTRL_MODE_PLAYBACK``: the plan's piecewise polynomials (knots and
coefficients per joint, the planner's result) evaluated on board at the task's output step; a
single-joint plan drives the robot's first joint."""

from __future__ import annotations

import numpy as np

from ...errors import excerpt
from ...planning.result import PlanResult
from ...robot import Robot
from ..configuration import MAX_SEGMENTS, FirmwareTask, common_fields, number, task_header, template
from ..errors import FirmwareError
from ..literals import c_ints, c_reals


def _joints(config, robot: Robot, source: str) -> dict[int, str]:
    """Robot joint → the plan's joint: by name for a task of the robot, else a single joint on joint 1."""
    names = [j.name for j in config.joints]
    robot_names = [j.name for j in robot.joints]
    if config.robot is not None and all(n in robot_names for n in names):
        return {robot_names.index(n): n for n in names}
    if len(names) == 1:  # a single-joint plan drives the robot's first joint
        return {0: names[0]}
    raise FirmwareError(f"{source}: the PTP plan's joints {names} are not joints of robot '{robot.name}' "
                        f"({', '.join(robot_names)})")


def firmware_task(config, plan: PlanResult, source: str, robot: Robot | None = None) -> FirmwareTask:
    """Playback of a ptp plan (``config``: the planner's typed task, its output step and joints;
    ``plan``: its knots and segment coefficients) on ``robot`` (default: the task's robot)."""
    robot = robot if robot is not None else config.robot_model
    if robot is None:
        raise FirmwareError(f"{source}: the PTP plan names no robot; give the robot to play it on")
    joints = _joints(config, robot, source)
    meta = plan.metadata
    if "segments" not in meta or "knot_times_s" not in meta:
        raise FirmwareError(f"{source}: no segment coefficients in the plan metadata (plan.json of a ptp plan)")
    knots = np.asarray(meta["knot_times_s"], dtype=float)
    nseg = len(knots) - 1
    if knots.ndim != 1 or nseg < 1 or not np.all(np.isfinite(knots)) or not np.all(np.diff(knots) > 0):
        raise FirmwareError(f"{source}: knot_times_s = {excerpt(knots.tolist())} must be at least two finite, strictly "
                            "increasing times; regenerate plan.json with armgen plan")
    coeffs = meta["segments"]["coefficients"]
    n_ticks = len(plan.column("t_s")) - 1
    q_start = np.zeros(robot.n)
    for i in range(robot.n):  # held joints: 0, or mid-range when 0 is outside the limits
        lo, hi = robot.joints[i].qlim
        q_start[i] = 0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi)
    active = [0] * robot.n
    rows = []
    for i, name in sorted(joints.items()):
        c = np.asarray(coeffs[name], dtype=float)
        if c.shape != (nseg, 6):
            raise FirmwareError(f"{source}: joint {name}: expected {nseg} x 6 coefficients, got {c.shape}")
        active[i] = 1
        q_start[i] = c[0, 0]
        rows.append(template("playback_joint.h", joint=i, coefficients=c_reals(c)))
    fields = template("playback.h", common=common_fields(robot, "CTRL_MODE_PLAYBACK", config.step, q_start), nseg=nseg,
                      n_ticks=n_ticks, knots=c_reals(knots), active=c_ints(active), coeffs="\n".join(rows))
    comment = template("playback_comment.txt", nseg=nseg, method=config.method, step=number(config.step),
                       joints=", ".join(f"{n} -> {robot.joints[i].name}" for i, n in joints.items()))
    # more segments than the controller's default: the build must raise CTRL_MAX_SEGMENTS (a -D)
    check = template("playback_segments_check.h", nseg=nseg) + "\n" if nseg > MAX_SEGMENTS else ""
    header = task_header(robot, source, fields, comment, tables=check)
    return FirmwareTask(robot, "playback", header, config.step, n_ticks, source, 1, joints, nseg)
