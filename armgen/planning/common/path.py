"""Path + timing: a task's circle or line (``[path]``) and ``[timing]``, validated by
:mod:`.schema`, → SI geometry and a time law; a program path (``type = "program"``) → its moves
and the motion from the start pose (:mod:`armgen.planning.toolpath.task`). What involves two
tables (a program takes no ``[timing]``, a circle or line needs it; the step fits the
duration) is checked here, naming the fields."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Union

import numpy as np

from ...description import rpy_matrix
from ...errors import PlanningError, TaskFileError
from ...robot import Robot
from ..toolpath.paths import CirclePath, LinePath, TimeLaw
from ..toolpath.schema import ProgramPath
from ..toolpath.task import ProgramSpec, program_motion, program_spec, reach_radius
from ..toolpath.timelaw import ProgramMotion
from .schema import Path, RelativePath, Timing


@dataclass(frozen=True)
class PathGeometry:
    """A circle (start → via → end → start) or a line (start → end) in SI. ``end_rotation``:
    the line's final orientation (None: the start's is held). ``relative``: via/end are offsets
    from the start tool position; ``turns``: circle turns over the duration."""

    type: str
    via: Optional[np.ndarray]
    end: np.ndarray
    end_rotation: Optional[np.ndarray] = None
    relative: bool = False
    turns: float = 1.0

    def build(self, start_pose: np.ndarray) -> Union[CirclePath, LinePath]:
        """The path from the start pose (4×4)."""
        p0, r0 = start_pose[:3, 3].copy(), start_pose[:3, :3].copy()
        via, end = self.via, self.end
        if self.relative:
            via, end = (None if via is None else via + p0), end + p0
        if self.type == "circle":
            return CirclePath(p0, via, end, r0)
        return LinePath(p0, end, r0, self.end_rotation if self.end_rotation is not None else r0)

    def build_within_reach(self, start_pose: np.ndarray, robot: Robot) -> Union[CirclePath, LinePath]:
        """The path from the start pose; one that leaves the sphere the arm can reach (about its
        base, :func:`~armgen.planning.toolpath.task.reach_radius`) makes the plan infeasible."""
        path = self.build(start_pose)
        points = path.sample_points()
        dist = np.linalg.norm(points - robot.base[:3, 3], axis=1)
        reach = reach_radius(robot)
        if dist.max() > reach:
            k = int(np.argmax(dist))
            where = "path.via / path.end" if self.type == "circle" else "path.end"
            raise PlanningError(
                f"the path is unreachable: point {np.round(points[k] * 1e3, 1).tolist()} mm is "
                f"{dist[k] * 1e3:.0f} mm from the base, beyond the arm's reach of {reach * 1e3:.0f} mm; "
                f"move {where} closer")
        return path


def path_geometry(path: Path, length_scale: float, angle_scale: float) -> PathGeometry:
    """The circle or line of a validated ``[path]`` table (its schema saw to a circle's via and an
    interpolating line's end_rpy; a :class:`RelativePath` may be relative and turn several
    times) in SI."""
    via = None if path.type != "circle" else np.array(path.via, dtype=float) * length_scale
    end = np.array(path.end, dtype=float) * length_scale
    end_rotation = None
    if path.orientation == "interpolate":
        end_rotation = rpy_matrix(*(np.array(path.end_rpy, dtype=float) * angle_scale))
    relative, turns = (path.relative, path.turns) if isinstance(path, RelativePath) else (False, 1.0)
    return PathGeometry(path.type, via, end, end_rotation, relative, turns)


def timing_law(timing: Optional[Timing], source: str) -> tuple[float, TimeLaw]:
    """(duration in s, time law) of a circle's or line's ``[timing]``."""
    if timing is None:
        raise TaskFileError(f"{source}: missing field 'timing.duration'; a circle or line needs [timing] duration = "
                            "<seconds>")
    return float(timing.duration), TimeLaw(timing.law, float(timing.blend))


# Slack of "the duration is a whole number of steps", relative to the duration: time and step
# are decimal numbers in the file (250 s / 0.02 s is 12 499.999999999998 in binary).
STEP_ROUNDING = 1e-9
# Slack (in steps) of rounding a program's duration up to whole steps: a duration within it of
# a whole number of steps is not given one more step for its rounding error.
WHOLE_STEP_SLACK = 1e-9


def check_step(step: float, duration: float, source: str) -> None:
    """The integrator step must fit the circle's or line's duration a whole number of times."""
    if step > duration:
        raise TaskFileError(f"{source}: integrator.step = {step} is longer than timing.duration = {duration}")
    if not math.isfinite(duration / step):
        raise TaskFileError(f"{source}: integrator.step = {step:g} s is too small for timing.duration = {duration:g} s; "
                            "give a step of at least a microsecond")
    steps = int(round(duration / step))
    if abs(steps * step - duration) > STEP_ROUNDING * duration:
        raise TaskFileError(f"{source}: timing.duration = {duration} s is not a multiple of integrator.step = {step} s")


@dataclass(frozen=True)
class ProgramTask:
    """A program path: its moves (SI) and its motion (geometry and nominal time law) from the
    start pose, its reach checked."""

    spec: ProgramSpec
    motion: ProgramMotion


def program_task(path: ProgramPath, timing: Optional[Timing], robot: Robot, q_start: np.ndarray, length_scale: float,
                 angle_scale: float, source: str) -> ProgramTask:
    """A validated program ``[path]`` → its moves and motion from the start configuration's tool
    pose; a program's time comes from its speeds, so a ``[timing]`` table is an error."""
    if timing is not None:
        raise TaskFileError(f"{source}: [timing] is not used with path.type = 'program' (time comes from path.speed "
                            "and path.acceleration); remove [timing]")
    spec = program_spec(path, source, length_scale, angle_scale)
    return ProgramTask(spec, program_motion(spec, robot.fk(q_start), robot, source))

