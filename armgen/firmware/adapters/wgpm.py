"""``planner = "wgpm"`` (method.name = "wgpm") → ``CTRL_MODE_WEIGHTED_GPM``: the plan's weighted
gradient projection with its bands and ramps on board."""

from __future__ import annotations


from ...errors import excerpt
from ..configuration import FirmwareTask, common_fields, number, program_tables, task_header, template
from ..errors import FirmwareError
from ..literals import c_real, c_reals
from .path_task import path_task_fields


def firmware_task(config, source: str) -> FirmwareTask:
    """The controller's task of a wgpm plan (``config``: the planner's typed task); a program
    runs the plan's final motion."""
    path, m, robot = config.path, config.method, config.path.robot
    if m.name != "wgpm":
        raise FirmwareError(f"{source}: method.name = {excerpt(repr(m.name))} is the planner's comparison baseline; the controller "
                            "runs method.name = \"wgpm\" (step_wgpm)")
    h_lo, h_hi, k_hi, k_lo, u_th, u_band = m.vectors()
    fields = template("weighted_gpm.h", common=common_fields(robot, "CTRL_MODE_WEIGHTED_GPM", path.step, path.q_start),
                      **path_task_fields(path, source), band=c_real(m.band), t_rmax=c_real(m.t_rmax),
                      delta=c_real(m.delta), epsilon=c_real(path.damping_epsilon), rho_max=c_real(path.damping_max),
                      ramp_time=c_real(m.ramp_time), ramp_out=1 if m.ramp_out else 0, H_lo=c_reals(h_lo),
                      H_hi=c_reals(h_hi), k_hi=c_reals(k_hi), k_lo=c_reals(k_lo), u_th=c_reals(u_th),
                      u_band=c_reals(u_band))
    comment = template("weighted_gpm_comment.txt", path=path.path_type, turns=number(path.turns), band=number(m.band),
                       ramp_time=number(m.ramp_time), step=number(path.step), steps=path.steps)
    header = task_header(robot, source, fields, comment, tables=program_tables(path.motion))
    return FirmwareTask(robot, "weighted_gpm", header, path.step, path.steps, source, path.output_every)
