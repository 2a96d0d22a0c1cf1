"""A sampled plan (``planner = "snake"``) → ``CTRL_MODE_SAMPLED``: every joint's samples as a
const table in flash, one row per tick of the plan's output step."""

from __future__ import annotations

import numpy as np

from ...planning.result import PlanResult
from ...robot import Robot
from ..configuration import (MAX_SAMPLES, SAMPLE_TIME_TOL_S, FirmwareTask, common_fields, number, sample_column,
                             task_header, template)
from ..errors import FirmwareError
from ..literals import c_reals


def _planned_robot(config, plan: PlanResult, source: str) -> Robot:
    """The task's robot, which must be the one the plan was made for (robot file SHA-256 in
    plan.json: a plan read from disk whose robot file changed since is refused)."""
    robot = config.arm.robot
    recorded = plan.metadata.get("robot")
    planned = recorded.get("sha256") if isinstance(recorded, dict) else None
    name = recorded.get("name", "?") if isinstance(recorded, dict) else "?"
    if planned != robot.sha256:
        raise FirmwareError(f"{source}: the plan is for robot '{name}' (robot file sha256 {str(planned)[:12]}…), not "
                            f"'{robot.name}' ({robot.sha256[:12]}…); give the plan's robot file, or re-plan for this robot")
    return robot


def firmware_task(config, plan: PlanResult, source: str) -> FirmwareTask:
    """CTRL_MODE_SAMPLED from a snake plan (``config``: the planner's typed task, its robot and
    output step; ``plan``: the samples): every robot joint's column (by name,
    :func:`sample_column`) as a const table in flash, one row per output step; the controller
    commands row k at tick k."""
    robot = _planned_robot(config, plan, source)
    columns = [sample_column(j) for j in robot.joints]
    missing = [c for c in columns if c not in plan.columns]
    if missing:
        raise FirmwareError(f"{source}: the plan has no column {', '.join(missing)} for robot '{robot.name}''s joints "
                            "(a sampled plan gives every joint's samples by name)")
    t = plan.column("t_s")
    dt = config.output_step
    if len(t) < 2:
        raise FirmwareError(f"{source}: a sampled plan needs at least two samples; regenerate it with armgen plan")
    k = np.arange(len(t))
    if not np.all(np.abs(t - (t[0] + k * dt)) <= SAMPLE_TIME_TOL_S):
        raise FirmwareError(f"{source}: t_s is not t_0 + k·{dt:g} s: the controller ticks once per output step; "
                            "regenerate the plan with armgen plan")
    if len(t) > MAX_SAMPLES:
        raise FirmwareError(f"{source}: {len(t)} samples, more than the controller's table takes "
                            f"(CTRL_MAX_SAMPLES = {MAX_SAMPLES}); re-plan with a larger motion.output_step")
    q = np.column_stack([plan.column(c) for c in columns])
    if not np.all(np.isfinite(q)):
        raise FirmwareError(f"{source}: the plan has non-finite joint samples; regenerate it with armgen plan")
    n_rows = len(t)
    samples = "\n".join(template("sampled_row.h", values=c_reals(row, "joint sample")) for row in q)
    tables = template("sampled_table.h", rows=n_rows, samples=samples) + "\n\n"
    fields = template("sampled.h", common=common_fields(robot, "CTRL_MODE_SAMPLED", dt, q[0]))
    comment = template("sampled_comment.txt", planner="snake", rows=n_rows, ndof=robot.n,
                       step=number(dt), float_bytes=n_rows * robot.n * 4, double_bytes=n_rows * robot.n * 8)
    header = task_header(robot, source, fields, comment, tables=tables)
    return FirmwareTask(robot, "sampled", header, dt, n_rows - 1, source, 1, dict(enumerate(columns)))
