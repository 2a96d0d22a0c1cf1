"""The fault-tolerant planner's task file (``planner = "fault_tolerant"``): fault, method,
completion, sweep and check tables, parsed into a :class:`FaultTolerantTask` (SI units)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ...errors import TaskFileError, excerpt
from ...robot import Robot
from ..cartesian.planner import _number, _table
from ..taskpath import PathTask, parse_path_task

METHODS = ("gpm", "wln", "pinv")
INDEX_VARIANTS = ("omega", "relative", "sigma_min")
WEIGHT_RULES = ("plain", "smooth")
CHECK_MODES = ("error", "report")
TOP_FIELDS = {"planner", "robot", "start", "units", "path", "timing", "integrator", "damping", "method", "fault",
              "completion", "sweep", "check", "description"}
# Sweep defaults (spec 30: "choose K and b by a sweep that the example can rerun").
DEFAULT_SWEEP_K = (0.0, 0.5, 1.0, 2.0, 4.0)
DEFAULT_SWEEP_B = (0.0, 0.5, 1.0, 2.0, 4.0)


@dataclass(frozen=True)
class FaultSpec:
    joints: tuple[int, ...] = ()  # 0-based
    time: float = 0.0

    def mask(self, n: int, locked: bool) -> np.ndarray:
        mask = np.ones(n)
        if locked:
            mask[list(self.joints)] = 0.0
        return mask


@dataclass(frozen=True)
class FaultMethod:
    name: str = "gpm"
    index: str = "omega"
    K: float = 1.0
    b: float = 1.0
    weight_rule: str = "smooth"
    v_band: float = 0.2  # rad/s: the smooth rule's activation band
    omega_floor: float = 1e-3
    delta: float = 1e-4
    a: tuple[float, ...] = ()

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

    pos_tol: float = 1e-3  # m
    ori_tol: float = math.radians(1.0)  # rad
    max_joint_speed: float = math.radians(120.0)  # rad/s (the iiwa 14's slowest axes: 85-135 deg/s)


@dataclass(frozen=True)
class SweepSpec:
    K: tuple[float, ...] = DEFAULT_SWEEP_K
    b: tuple[float, ...] = DEFAULT_SWEEP_B
    rules: tuple[str, ...] = WEIGHT_RULES
    joints: tuple[int, ...] = ()  # 0-based; empty = every joint
    fine_step: float = 0.005


@dataclass(frozen=True)
class FaultTolerantTask:
    path: PathTask
    fault: FaultSpec
    method: FaultMethod
    completion: Completion = Completion()
    sweep: SweepSpec = SweepSpec()
    check_mode: str = "error"
    raw: dict[str, Any] = field(default_factory=dict)

    @property
    def robot(self) -> Robot:
        return self.path.robot


# -- parsing -------------------------------------------------------------------------------

def _choice(table: dict, key: str, where: str, source: str, choices: Sequence[str], default: str) -> str:
    value = table.get(key, default)
    if value not in choices:
        raise TaskFileError(f"{source}: field '{where}.{key}' = {excerpt(repr(value))} is not one of {', '.join(choices)}")
    return value


def _number_list(table: dict, key: str, where: str, source: str, default: Sequence[float], nonneg: bool = True,
                 scale: float = 1.0) -> tuple[float, ...]:
    value = table.get(key, list(default))
    if not isinstance(value, list) or not value or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value):
        raise TaskFileError(f"{source}: field '{where}.{key}' must be a non-empty list of finite numbers, got {excerpt(repr(value))}")
    if nonneg and any(v < 0 for v in value):
        raise TaskFileError(f"{source}: field '{where}.{key}' = {value} has a negative entry; gains must be ≥ 0 "
                            "(the index is maximised; a negative gain would minimise it)")
    return tuple(float(v) * scale for v in value)


def parse_joints(value: Any, robot: Robot, where: str, source: str) -> tuple[int, ...]:
    """Joint numbers (1-based) or names → sorted 0-based indices; errors name the bad entry."""
    if not isinstance(value, list):
        raise TaskFileError(f"{source}: field '{where}' must be a list of joint numbers (1..{robot.n}) or names, "
                            f"got {excerpt(repr(value))}")
    names = [j.name for j in robot.joints]
    out: list[int] = []
    for k, item in enumerate(value):
        if isinstance(item, str) and item in names:
            idx = names.index(item)
        elif isinstance(item, int) and not isinstance(item, bool) and 1 <= item <= robot.n:
            idx = item - 1
        else:
            raise TaskFileError(
                f"{source}: field '{where}'[{k}] = {excerpt(repr(item))} is not a joint of robot '{robot.name}': give a number "
                f"1..{robot.n} or a name ({', '.join(names)})")
        if idx in out:
            raise TaskFileError(f"{source}: field '{where}' names joint {names[idx]} twice")
        out.append(idx)
    return tuple(sorted(out))


def parse_fault_tolerant_task(task: dict, source: str) -> FaultTolerantTask:
    path = parse_path_task(task, source, TOP_FIELDS)
    robot, as_ = path.robot, path.angle_scale

    f = _table(task, "fault", source)
    unknown = set(f) - {"joints", "time"}
    if unknown:
        raise TaskFileError(f"{source}: unknown field(s) fault.{', fault.'.join(sorted(unknown))}; allowed: joints, time")
    joints = parse_joints(f.get("joints", []), robot, "fault.joints", source)
    if len(joints) == robot.n:
        raise TaskFileError(f"{source}: fault.joints locks all {robot.n} joints of '{robot.name}': nothing could move; "
                            f"lock at most {robot.n - 1} (a single joint reproduces spec 30)")
    t_f = _number(f, "time", "fault", source, path.duration / 2)
    if not 0.0 <= t_f <= path.duration:
        raise TaskFileError(f"{source}: fault.time = {t_f} s is outside the plan [0, {path.duration:g}] s; "
                            "choose a time within timing.duration")

    m = _table(task, "method", source)
    unknown = set(m) - {"name", "index", "K", "b", "weight_rule", "v_band", "omega_floor", "delta", "a"}
    if unknown:
        raise TaskFileError(f"{source}: unknown field(s) method.{', method.'.join(sorted(unknown))}")
    name = _choice(m, "name", "method", source, METHODS, "gpm")
    for key in ("K", "b"):
        if key in m and isinstance(m[key], (int, float)) and not isinstance(m[key], bool) and m[key] < 0:
            raise TaskFileError(f"{source}: field 'method.{key}' = {m[key]} must be ≥ 0 (a negative gain would "
                                "drive the joint-manipulability index down instead of up)")
    a = _number_list(m, "a", "method", source, [1.0] * robot.n) if "a" in m else (1.0,) * robot.n
    if len(a) != robot.n:
        raise TaskFileError(f"{source}: field 'method.a' needs {robot.n} entries (one per joint), got {len(a)}")
    method = FaultMethod(
        name=name,
        index=_choice(m, "index", "method", source, INDEX_VARIANTS, "omega"),
        K=_number(m, "K", "method", source, 1.0, nonneg=True),
        b=_number(m, "b", "method", source, 1.0, nonneg=True),
        weight_rule=_choice(m, "weight_rule", "method", source, WEIGHT_RULES, "smooth"),
        v_band=_number(m, "v_band", "method", source, 0.2 / as_, positive=True) * as_,
        omega_floor=_number(m, "omega_floor", "method", source, 1e-3, positive=True),
        delta=_number(m, "delta", "method", source, 1e-4, positive=True),
        a=a,
    )

    c = _table(task, "completion", source)
    ls = path.length_scale
    completion = Completion(
        pos_tol=_number(c, "pos_tol", "completion", source, 1e-3 / ls, positive=True) * ls,
        ori_tol=_number(c, "ori_tol", "completion", source, math.radians(1.0) / as_, positive=True) * as_,
        max_joint_speed=_number(c, "max_joint_speed", "completion", source, math.radians(120.0) / as_,
                                positive=True) * as_,
    )

    s = _table(task, "sweep", source)
    rules = s.get("rules", list(WEIGHT_RULES))
    if not isinstance(rules, list) or not rules or any(r not in WEIGHT_RULES for r in rules):
        raise TaskFileError(f"{source}: field 'sweep.rules' = {excerpt(repr(rules))} must list some of {', '.join(WEIGHT_RULES)}")
    sweep_joints = s.get("joints", "all")
    sweep = SweepSpec(
        K=_number_list(s, "K", "sweep", source, DEFAULT_SWEEP_K),
        b=_number_list(s, "b", "sweep", source, DEFAULT_SWEEP_B),
        rules=tuple(rules),
        joints=tuple(range(robot.n)) if sweep_joints == "all" else parse_joints(sweep_joints, robot, "sweep.joints",
                                                                                 source),
        fine_step=_number(s, "fine_step", "sweep", source, 0.005, positive=True),
    )
    check = _table(task, "check", source)
    return FaultTolerantTask(path=path, fault=FaultSpec(joints, t_f), method=method, completion=completion,
                             sweep=sweep, check_mode=_choice(check, "reach", "check", source, CHECK_MODES, "error"),
                             raw=task)
