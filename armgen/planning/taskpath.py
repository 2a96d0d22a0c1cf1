"""Shared parts of the resolved-rate planners of specs 30 and 35 (``fault_tolerant``, ``wgpm``):
the task-file fields they share with the Cartesian planner (robot, start, path, timing,
integrator, damping), the desired pose and twist along the path, the base CSV columns and
the smoothness/tracking metrics.

Paths are :mod:`armgen.planning.toolpath.paths`' circle and line. Two additions for these planners:
``path.relative = true`` gives ``via``/``end`` as offsets from the start tool position (so
a task file can state "a circle of radius R beside the start" for any start), and
``path.turns`` (circle only) runs the circle that many times over the duration (spec 30's
twist ``ẋ = [0, πR sin πt, −πR cos πt, 0, 0, 0]`` over T = 4 s is two turns at constant
speed: ``via = [0, R, −R]``, ``end = [0, 2R, 0]`` relative, ``law = "constant"``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Callable

import casadi as ca
import numpy as np

from ..errors import TaskFileError, excerpt
from ..robot import Robot
from .backends import make_backend
from .common.collision import TaskCollision, configure_collision
from .common.path import WHOLE_STEP_SLACK, PathGeometry, check_step, path_geometry, program_task, timing_law
from .common.start import start_configuration, unit_scales
from .common.symbolic import sym_orientation_error, sym_rpy
from .result import PlanResult
from .toolpath.accuracy import PathAccuracy, path_tolerance
from .toolpath.limits import plan_with_speed_limits
from .toolpath.paths import TimeLaw
from .toolpath.schema import ProgramPath
from .toolpath.task import ProgramSpec
from .toolpath.timelaw import ProgramMotion


@dataclass(frozen=True)
class PathTask:
    """The fields every resolved-rate task of specs 30 and 35 shares (SI units). ``tolerance``:
    the path tolerance (m) a plan must meet (None: the deviation is only reported; a circle or
    line of these planners gets one only by stating ``[check] path_tolerance``, as they leave
    the path on purpose after a joint locks); ``length_unit``: the file's, for messages."""

    robot: Robot
    q_start: np.ndarray
    start_label: str
    path_type: str
    via: np.ndarray | None
    end: np.ndarray
    relative: bool
    turns: float
    end_rotation: np.ndarray | None
    duration: float
    law: TimeLaw
    step: float
    clik: bool
    clik_gain: float
    damping_epsilon: float
    damping_max: float
    output_every: int
    tolerance: float | None
    length_unit: str
    program: ProgramSpec | None = None  # path.type = "program": the moves, and
    motion: ProgramMotion | None = None  # their geometry and time law from the start pose
    collision: TaskCollision | None = None  # the obstacles and [collision] (robot with capsules)

    @property
    def steps(self) -> int:
        return int(round(self.duration / self.step))

    @property
    def geometry(self) -> PathGeometry:
        """The circle or line (not for a program)."""
        return PathGeometry(self.path_type, self.via, self.end, self.end_rotation, self.relative, self.turns)

    @property
    def accuracy(self) -> PathAccuracy:
        """The tolerance a plan of this task must meet, from its step."""
        return PathAccuracy(self.tolerance, self.step, self.length_unit)

    def with_motion(self, motion: ProgramMotion) -> PathTask:
        """This task driven by ``motion`` (a program's new time law): the plan's duration is the
        motion's, rounded up to whole steps (the tool rests at its end for the remainder)."""
        return replace(self, motion=motion, duration=math.ceil(motion.duration / self.step - WHOLE_STEP_SLACK) * self.step)


def configure_path_task(model: Any, robot: Robot, source: str) -> PathTask:
    """The shared part of a validated fault_tolerant or wgpm task (its ``start``, ``units``,
    ``path``, ``timing``, ``integrator``, ``damping`` and ``check.path_tolerance``) in SI on the
    task's loaded ``robot``; errors name ``source``'s field and the fix."""
    collision = configure_collision(model, robot, source)
    q_start, label = start_configuration(model.start, model.units, robot, source, "start" in model.model_fields_set,
                                         collision)
    ls, as_ = unit_scales(model.units)
    integ = model.integrator
    if integ.method != "euler":
        raise TaskFileError(f"{source}: integrator.method = {excerpt(repr(integ.method))}: this planner integrates with "
                            "explicit Euler only (its weights use the previous step's velocity); remove the field or "
                            "set 'euler'")
    step = integ.step
    is_program = isinstance(model.path, ProgramPath)
    shared = dict(robot=robot, q_start=q_start, start_label=label, step=step, clik=integ.clik,
                  clik_gain=integ.clik_gain, damping_epsilon=model.damping.epsilon,
                  damping_max=model.damping.lambda_max, output_every=integ.output_every,
                  tolerance=path_tolerance(model.check.path_tolerance, model.units.length, is_program),
                  length_unit=model.units.length, collision=collision)
    if is_program:  # its time comes from the program (no [timing])
        program = program_task(model.path, model.timing, robot, q_start, ls, as_, source)
        blank = PathTask(path_type="program", via=None, end=np.zeros(3), relative=False, turns=1.0, end_rotation=None,
                         duration=0.0, law=TimeLaw("constant"), program=program.spec, **shared)
        return blank.with_motion(program.motion)
    geometry = path_geometry(model.path, ls, as_)
    duration, law = timing_law(model.timing, source)
    check_step(step, duration, source)
    return PathTask(path_type=geometry.type, via=geometry.via, end=geometry.end, relative=geometry.relative,
                    turns=geometry.turns, end_rotation=geometry.end_rotation, duration=duration, law=law, **shared)


class TaskPath:
    """The desired pose and twist of a :class:`PathTask` from the start pose."""

    def __init__(self, task: PathTask, start_pose: np.ndarray):
        self.task = task
        self.p0, self.r0 = start_pose[:3, 3].copy(), start_pose[:3, :3].copy()
        if task.motion is not None:  # a program: built, and its reach checked, when configured
            self.path = task.motion.program
            return
        self.path = task.geometry.build_within_reach(start_pose, task.robot)

    def __call__(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, rotation, twist [v; ω]) at time t (a number or an array of times)."""
        if self.task.motion is not None:
            return self.task.motion(t)
        T = self.task.duration
        t = np.asarray(t, dtype=float)
        s, ds = self.task.law(t / T)
        turns = self.task.turns
        p, dp, rot, dw = self.path(turns * s)
        sdot = np.where((0.0 <= t) & (t <= T), turns * ds / T, 0.0)[..., None]
        return p, rot, np.concatenate([dp * sdot, dw * sdot], axis=-1)

    def timed_inputs(self, t: np.ndarray) -> np.ndarray:
        """Per time: desired position, rotation (column-major) and twist, one row each (a
        fused step's t-dependent inputs)."""
        p_d, r_d, xdot = self(t)
        return np.hstack([p_d, np.swapaxes(r_d, -1, -2).reshape(-1, 9), xdot])


TIMED_WIDTH = 18  # columns of TaskPath.timed_inputs: position 3, rotation 9, twist 6


def sym_tracking(pose: ca.SX, timed: ca.SX, clik_gain: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """Position and orientation errors and the commanded twist ẋ + K_p e in CasADi, from one row of
    :meth:`TaskPath.timed_inputs`."""
    pos_err = timed[:3] - pose[:3, 3]
    ori_err = sym_orientation_error(pose[:3, :3], ca.reshape(timed[3:12], 3, 3))
    return pos_err, ori_err, timed[12:18] + clik_gain * ca.vertcat(pos_err, ori_err)


def sym_base_row(q, qd, pose, jac, pos_err, ori_err, cmd, rows, damping, sigma_min) -> ca.SX:
    """The row of :func:`base_columns` without the time, in CasADi (‖J q̇ − ẋ_cmd‖ on the task
    rows is the residual)."""
    return ca.vertcat(q, qd, pose[:3, 3], sym_rpy(pose[:3, :3]), ca.norm_2(pos_err), ca.norm_2(ori_err),
                      ca.norm_2((ca.mtimes(jac, qd) - cmd)[rows]), damping, sigma_min)


def base_columns(n: int) -> list[str]:
    return (["t_s"] + [f"q{i + 1}_rad" for i in range(n)] + [f"dq{i + 1}_rad_s" for i in range(n)]
            + ["x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad", "pos_err_m", "ori_err_rad",
               "task_residual_1", "damping_1", "sigma_min_1"])


def smoothness(qd: np.ndarray, h: float, skip: tuple[int, ...] = ()) -> dict[str, float]:
    """Peak |q̈| (finite differences of q̇ between steps; transitions listed in ``skip``
    excluded, e.g. the instant a joint locks) and the total variation Σ|Δq̇| (rad/s)."""
    diff = np.abs(np.diff(qd, axis=0))
    keep = np.ones(diff.shape[0], dtype=bool)
    for k in skip:
        if 0 <= k < keep.size:
            keep[k] = False
    peak = float(np.max(diff[keep]) / h) if keep.any() else 0.0
    return {"peak_ddq_rad_s2": peak, "total_variation_dq_rad_s": float(np.sum(diff))}


def path_metadata(task: PathTask) -> dict[str, Any]:
    return {
        "robot": {"name": task.robot.name, "file": task.robot.source, "sha256": task.robot.sha256,
                  "qlim_rad": [list(j.qlim) for j in task.robot.joints]},
        "start": {"label": task.start_label, "q_rad": task.q_start.tolist()},
        "path": {"type": task.path_type, "relative": task.relative, "turns": task.turns,
                 "duration_s": task.duration, "law": task.law.kind},
        "integrator": {"method": "euler", "step_s": task.step, "clik": task.clik,
                       "clik_gain": task.clik_gain if task.clik else 0.0, "open_loop": not task.clik},
        "damping": {"epsilon": task.damping_epsilon, "lambda_max": task.damping_max},
    }


def plan_path_task(config: Any, backend: str, planner: Callable[..., Any]) -> PlanResult:
    """The plan of a task whose ``path`` is a :class:`PathTask` (fault_tolerant, wgpm) by
    ``planner(task, backend=...)``'s ``run()``: a program is slowed where a joint would exceed its
    speed limits and the integrator step halved to meet a stated path tolerance
    (toolpath.accuracy); ``result.config`` is the task as planned (the step and, for a program,
    the motion used)."""
    shared = make_backend(config.robot, backend)
    path = config.path

    def run(motion, step):
        stepped = replace(path, step=step)
        planned = replace(config, path=stepped if motion is None else stepped.with_motion(motion))
        return planner(planned, backend=shared).run()

    result, _ = plan_with_speed_limits(run, path.motion, path.program and path.program.angular_speed, config.robot,
                                       config.source, path.accuracy, path.duration)
    return result
