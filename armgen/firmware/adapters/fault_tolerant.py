"""``planner = "fault_tolerant"`` → ``CTRL_MODE_FAULT_TOLERANT``: the plan's method and index on
board; the plan's fault (fault.joints from fault.time) becomes the runners' lock schedule."""

from __future__ import annotations

import math

from ...errors import excerpt
from ..configuration import FirmwareTask, common_fields, number, program_tables, task_header, template
from ..errors import FirmwareError
from ..literals import c_real, c_reals
from .path_task import path_task_fields

FT_METHOD_IDS = {"pinv": "CTRL_FT_PINV", "gpm": "CTRL_FT_GPM", "wln": "CTRL_FT_WLN"}
FT_INDEX_IDS = {"omega": "CTRL_FT_INDEX_OMEGA", "relative": "CTRL_FT_INDEX_RELATIVE"}
WLN_RULE_IDS = {"smooth": "CTRL_WLN_SMOOTH", "plain": "CTRL_WLN_PLAIN"}
# A fault time within this many steps of a step boundary locks at that boundary (rounding of
# time / step, e.g. 2.0 / 0.02 = 99.99999999999999), as in the planner.
LOCK_STEP_SLACK = 1e-9


def firmware_task(config, source: str) -> FirmwareTask:
    """The controller's task of a fault-tolerant plan (``config``: the planner's typed task); a
    program runs the plan's final motion."""
    path, m, robot = config.path, config.method, config.robot
    if m.index not in FT_INDEX_IDS:
        raise FirmwareError(f"{source}: method.index = {excerpt(repr(m.index))}: the controller computes the omega and relative "
                            "indices on board (generated ft_index); sigma_min is a NumPy SVD with a numeric gradient "
                            "in the planner only. Re-plan with method.index = \"omega\" or \"relative\"")
    steps = path.steps
    lock_tick, lock_mask = -1, 0
    if config.fault.joints:  # the planner's lock step: the first step at or after fault.time
        k_f = int(math.ceil(config.fault.time / path.step - LOCK_STEP_SLACK))
        if k_f <= steps:
            lock_tick, lock_mask = k_f, sum(1 << j for j in config.fault.joints)
    fields = template("fault_tolerant.h", common=common_fields(robot, "CTRL_MODE_FAULT_TOLERANT", path.step,
                                                               path.q_start),
                      **path_task_fields(path, source), method=FT_METHOD_IDS[m.name], index=FT_INDEX_IDS[m.index],
                      K=c_real(m.K), b=c_real(m.b), rule=WLN_RULE_IDS[m.weight_rule],
                      v_band=c_real(m.v_band), omega_floor=c_real(m.omega_floor), delta=c_real(m.delta),
                      a=c_reals(m.a or (1.0,) * robot.n), epsilon=c_real(path.damping_epsilon),
                      lambda_max=c_real(path.damping_max))
    comment = template("fault_tolerant_comment.txt", path=path.path_type, turns=number(path.turns), method=m.label,
                       index=m.index, step=number(path.step), steps=steps,
                       locked=", ".join(robot.joints[j].name for j in config.fault.joints) or "none",
                       lock_tick=lock_tick)
    header = task_header(robot, source, fields, comment, lock_tick, lock_mask, program_tables(path.motion))
    return FirmwareTask(robot, "fault_tolerant", header, path.step, steps, source, path.output_every,
                        lock_tick=lock_tick, lock_mask=lock_mask)
