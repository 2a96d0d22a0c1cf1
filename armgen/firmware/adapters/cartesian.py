"""``planner = "cartesian"`` → ``CTRL_MODE_RESOLVED_RATE``: the controller integrates the same
circle, line or program with the same method, Euler step and CLIK gain as the plan."""

from __future__ import annotations

import numpy as np

from ...errors import excerpt
from ..configuration import (FirmwareTask, common_fields, geometric_path, number, program_path,
                             program_tables, task_header, template)
from ..errors import FirmwareError
from ..literals import c_ints, c_real

METHOD_IDS = {"pinv": "CTRL_METHOD_PINV", "repetitive": "CTRL_METHOD_REPETITIVE", "zghal": "CTRL_METHOD_ZGHAL",
              "zghal_improved": "CTRL_METHOD_ZGHAL_IMPROVED", "combined": "CTRL_METHOD_COMBINED"}


def _rotation(config) -> tuple[np.ndarray, float]:
    """The end orientation's axis (tool frame) and angle: the planner's own, from its FK of the start."""
    if config.end_rotation is None:
        return np.array([0.0, 0.0, 1.0]), 0.0
    from ...planning.cartesian.planner import CartesianPlanner

    path = CartesianPlanner(config, "symbolic").path
    return path.axis_local, float(path.angle)


def firmware_task(config, source: str) -> FirmwareTask:
    """The controller's task of a cartesian plan: ``config`` the planner's typed task the plan
    was made with (its step after any refinement); a program runs the plan's final motion."""
    if config.integrator != "euler":
        raise FirmwareError(f"{source}: integrator.method = {excerpt(repr(config.integrator))}: the controller integrates with "
                            "explicit Euler, one step per tick; re-plan with integrator.method = \"euler\"")
    robot, mp = config.robot, config.method
    steps = int(round(config.duration / config.step))
    if config.motion is not None:
        path = program_path(config.duration)
    else:
        axis, angle = _rotation(config)
        path = geometric_path(config.path_type, config.via, config.end, axis, angle, config.duration, config.law,
                              source)
    # .damping = 0 in the template: the planner damps only below σ_min = ε, which no bundled
    # plan reaches; plans that used damping are refused (refusal: summary.damped_steps > 0).
    fields = template("resolved_rate.h", common=common_fields(robot, "CTRL_MODE_RESOLVED_RATE", config.step,
                                                              config.q_start),
                      path=path, method=METHOD_IDS[mp.name], rho_R=c_real(mp.rho_R), T_smo_R=c_real(mp.T_smo_R),
                      rho_L=c_real(mp.rho_L), theta_s=c_real(mp.theta_s), T_smo_L=c_real(mp.T_smo_L),
                      T_sum_L=c_real(mp.T_sum_L), gamma_R_ramp=c_real(mp.gamma_R_ramp),
                      clik_gain=c_real(config.clik_gain), task_rows=c_ints(robot.task_rows))
    comment = template("resolved_rate_comment.txt", path=config.path_type,
                       law="the plan's trapezoidal" if config.motion is not None else config.law.kind,
                       duration=number(config.duration), method=mp.name, step=number(config.step), steps=steps,
                       clik_gain=number(config.clik_gain))
    header = task_header(robot, source, fields, comment, tables=program_tables(config.motion))
    return FirmwareTask(robot, "resolved_rate", header, config.step, steps, source, config.output_every)
