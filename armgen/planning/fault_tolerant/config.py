"""The fault-tolerant planner's configuration (spec 30): the validated task file
(:class:`~.schema.FaultTolerantTaskFile`) and its robot turned into a :class:`FaultTolerantTask`
in SI units, the joints of the fault and of the sweep resolved against the robot."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import TaskFileError
from ...robot import Robot
from ..common.start import unit_scales
from ..taskpath import PathTask, configure_path_task
from .schema import FaultTolerantTaskFile, JointRef

# SI defaults of the fields whose value is a physical quantity (the schema leaves them None).
DEFAULT_V_BAND = 0.2  # rad/s: the smooth rule's activation band
DEFAULT_POS_TOL = 1e-3  # m
DEFAULT_ORI_TOL = math.radians(1.0)  # rad
DEFAULT_MAX_JOINT_SPEED = math.radians(120.0)  # rad/s (the iiwa 14's slowest axes: 85-135 deg/s)
# A fault time within this many steps of a step boundary locks at that boundary (rounding of
# time / step, e.g. 2.0 / 0.02 = 99.99999999999999).
LOCK_STEP_SLACK = 1e-9


@dataclass(frozen=True)
class FaultSpec:
    joints: tuple[int, ...]  # 0-based, sorted
    time: float  # s

    def mask(self, n: int, locked: bool) -> np.ndarray:
        mask = np.ones(n)
        if locked:
            mask[list(self.joints)] = 0.0
        return mask


@dataclass(frozen=True)
class FaultMethod:
    name: str  # gpm, wln, pinv
    index: str  # omega, relative, sigma_min
    K: float
    b: float
    weight_rule: str  # plain, smooth
    v_band: float  # rad/s
    omega_floor: float
    delta: float
    a: tuple[float, ...]  # one weight per joint

    @property
    def label(self) -> str:
        if self.name == "gpm":
            return f"gpm K={self.K:g}"
        if self.name == "wln":
            return f"wln-{self.weight_rule} b={self.b:g}"
        return "pinv"


@dataclass(frozen=True)
class Completion:
    """A locked-joint run completes the task when, after the lock, the tool stays within these
    errors, no joint is faster than ``max_joint_speed`` and no joint leaves its limits."""

    pos_tol: float  # m
    ori_tol: float  # rad
    max_joint_speed: float  # rad/s


@dataclass(frozen=True)
class SweepSpec:
    """The ``[sweep]`` table, recorded in plan.json (the sweep itself is an ``armgen sweep`` run)."""

    K: tuple[float, ...]
    b: tuple[float, ...]
    rules: tuple[str, ...]
    joints: tuple[int, ...]  # 0-based
    fine_step: float  # s


@dataclass(frozen=True)
class FaultTolerantTask:
    path: PathTask
    fault: FaultSpec
    method: FaultMethod
    completion: Completion
    sweep: SweepSpec
    check_mode: str  # check.reach: an infeasible start is an "error" or a "report"
    source: str  # the task file, named in messages

    @property
    def robot(self) -> Robot:
        return self.path.robot

    @property
    def lock_step(self) -> int:
        """The first step at which the fault applies (steps + 1 without a fault)."""
        if not self.fault.joints:
            return self.path.steps + 1
        return int(math.ceil(self.fault.time / self.path.step - LOCK_STEP_SLACK))


def joint_indices(refs: list[JointRef], robot: Robot, where: str, source: str) -> tuple[int, ...]:
    """Joint numbers (1-based) or names → sorted 0-based indices; errors name the bad entry."""
    names = [j.name for j in robot.joints]
    out: list[int] = []
    for k, item in enumerate(refs):
        if isinstance(item, str) and item in names:
            idx = names.index(item)
        elif isinstance(item, int) and 1 <= item <= robot.n:
            idx = item - 1
        else:
            raise TaskFileError(
                f"{source}: field '{where}'[{k}] = {item!r} is not a joint of robot '{robot.name}': give a number "
                f"1..{robot.n} or a name ({', '.join(names)})")
        if idx in out:
            raise TaskFileError(f"{source}: field '{where}' names joint {names[idx]} twice; give each joint once")
        out.append(idx)
    return tuple(sorted(out))


def _fault(model: FaultTolerantTaskFile, robot: Robot, path: PathTask, source: str) -> FaultSpec:
    joints = joint_indices(model.fault.joints, robot, "fault.joints", source)
    if len(joints) == robot.n:
        raise TaskFileError(f"{source}: fault.joints locks all {robot.n} joints of '{robot.name}': nothing could move; "
                            f"lock at most {robot.n - 1} (a single joint reproduces spec 30)")
    time = path.duration / 2 if model.fault.time is None else model.fault.time
    if not 0.0 <= time <= path.duration:
        what = "the program's duration" if path.motion is not None else "timing.duration"
        raise TaskFileError(f"{source}: fault.time = {time} s is outside the plan [0, {path.duration:g}] s; "
                            f"choose a time within {what}")
    return FaultSpec(joints, time)


def _method(model: FaultTolerantTaskFile, robot: Robot, angle: float, source: str) -> FaultMethod:
    m = model.method
    if m.a is not None and len(m.a) != robot.n:
        raise TaskFileError(f"{source}: field 'method.a' needs {robot.n} entries (one per joint of '{robot.name}'), "
                            f"got {len(m.a)}")
    return FaultMethod(name=m.name, index=m.index, K=m.K, b=m.b, weight_rule=m.weight_rule,
                       v_band=DEFAULT_V_BAND if m.v_band is None else m.v_band * angle,
                       omega_floor=m.omega_floor, delta=m.delta,
                       a=(1.0,) * robot.n if m.a is None else tuple(m.a))


def configure(model: FaultTolerantTaskFile, robot: Robot, source: str) -> FaultTolerantTask:
    """The task in SI units, its joints resolved against ``robot``; a :class:`TaskFileError`
    names the field and the fix."""
    path = configure_path_task(model, robot, source)
    length, angle = unit_scales(model.units)
    fault, method = _fault(model, robot, path, source), _method(model, robot, angle, source)
    c, s = model.completion, model.sweep
    completion = Completion(
        pos_tol=DEFAULT_POS_TOL if c.pos_tol is None else c.pos_tol * length,
        ori_tol=DEFAULT_ORI_TOL if c.ori_tol is None else c.ori_tol * angle,
        max_joint_speed=DEFAULT_MAX_JOINT_SPEED if c.max_joint_speed is None else c.max_joint_speed * angle)
    sweep = SweepSpec(
        K=tuple(s.K), b=tuple(s.b), rules=tuple(s.rules),
        joints=tuple(range(robot.n)) if s.joints == "all" else joint_indices(s.joints, robot, "sweep.joints", source),
        fine_step=s.fine_step)
    return FaultTolerantTask(path=path, fault=fault, method=method, completion=completion, sweep=sweep,
                             check_mode=model.check.reach, source=source)
