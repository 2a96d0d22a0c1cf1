"""Schema of ``planner = "ptp"`` task files (spec 40): the parser of the task file.

Per-joint values are an array (a single-joint task, no robot) or a table with one array per
joint of the robot. The schema checks what the file alone decides: types, signs, the array
lengths against the waypoint and segment counts, strictly increasing knot times, which fields
need which others, and the methods' waypoint counts. What needs the robot (the joint names
and count, revolute joints only, the joint limits, the inverse kinematics of tool-pose
waypoints) is :func:`armgen.planning.ptp.config.configure`'s. Rule violations read
``<file>: field '<field>' <what>; <fix>`` like the type errors."""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Union, get_args

import numpy as np
from pydantic import Discriminator, Field, Tag, model_validator

from ...description.files import ANGLE_UNITS
from ...description.model import MAX_ABS_ANGLE_RAD, MAX_ABS_LENGTH_M
from ...errors import excerpt
from ...schemas import StrictModel, rule_error
from ..common.collision import CollisionFields
from ..common.schema import Description, Positive, RobotReference, SpeedCheck

MAX_WAYPOINTS = 10_000
Method = Literal["cubic", "3-4", "3-5-3", "quintic"]
METHODS: tuple[str, ...] = get_args(Method)
# 3-5-3 is cubic, quintic…, cubic: at least three segments.
MIN_WAYPOINTS_3_5_3 = 4

Values = Annotated[list[float], Field(max_length=MAX_WAYPOINTS)]
PositiveValues = Annotated[list[Positive], Field(max_length=MAX_WAYPOINTS)]
JointTable = Annotated[dict[str, Values], Field(max_length=64)]


def _shape(value: Any) -> str:
    """The union member a per-joint value is read as (an error then names only that member's problem)."""
    if isinstance(value, dict):
        return "table"
    return "array" if isinstance(value, list) else "number"


PerJoint = Annotated[Union[Annotated[Values, Tag("array")], Annotated[JointTable, Tag("table")]],
                     Discriminator(lambda value: "table" if isinstance(value, dict) else "array")]
Bound = Annotated[Union[Annotated[Positive, Tag("number")], Annotated[PositiveValues, Tag("array")]],
                  Discriminator(_shape)]
PerJointBound = Annotated[Union[Annotated[Positive, Tag("number")], Annotated[PositiveValues, Tag("array")],
                                Annotated[dict[str, Bound], Field(max_length=64), Tag("table")]],
                          Discriminator(_shape)]
Triples = Annotated[list[Annotated[list[float], Field(min_length=3, max_length=3)]], Field(max_length=MAX_WAYPOINTS)]


class Units(StrictModel):
    angle: Literal["rad", "deg"] = "rad"


class Waypoints(StrictModel):
    t: Optional[Values] = Field(None, description="knot times, s, strictly increasing")
    theta: Optional[PerJoint] = Field(None, description="joint angles per waypoint (or give xyz/rpy)")
    omega: Optional[PerJoint] = Field(None, description="joint speeds per waypoint (default 0 with xyz)")
    eps: Optional[PerJoint] = Field(None, description="preset accelerations per waypoint (quintic, 3-5-3)")
    xyz: Optional[Triples] = Field(None, description="tool positions, m (solved by the inverse kinematics)")
    rpy: Optional[Triples] = Field(None, description="tool orientations R = Rz(yaw) Ry(pitch) Rx(roll), units.angle")
    seed: Optional[Union[str, Values]] = Field(None, description="configuration the first pose is solved from")


class Timing(StrictModel):
    omega_max: Optional[PerJointBound] = Field(None, description="joint speed bound, angle unit/s")
    eps_max: Optional[PerJointBound] = Field(None, description="joint acceleration bound, angle unit/s²")
    grid: Optional[Positive] = Field(None, description="s: computed durations are rounded up to this grid")


def _fail(field: str, message: str) -> Exception:
    return rule_error(f"field '{field}' {message}")


def _per_joint_arrays(value: Values | dict[str, Values] | None, field: str) -> list[tuple[str, list[float]]]:
    """(field name, array) of an array or of each entry of a per-joint table."""
    if value is None:
        return []
    if isinstance(value, dict):
        return [(f"{field}.{name}", array) for name, array in value.items()]
    return [(field, value)]


class PtpTaskFile(CollisionFields):
    """Point-to-point joint splines through velocity-constrained waypoints (spec 40)."""

    planner: Literal["ptp"]
    description: Optional[Description] = None
    robot: Optional[RobotReference] = None
    method: Method = "3-4"
    compare: Annotated[list[Method], Field(max_length=4)] = Field(default_factory=list)
    step: Positive = Field(1e-3, description="CSV sample step, s")
    units: Units = Field(default_factory=Units)
    waypoints: Waypoints
    timing: Timing = Field(default_factory=Timing)
    check: SpeedCheck = Field(default_factory=SpeedCheck, description="with a robot: the plan against its qdlim/qddlim")

    def first_waypoints(self) -> tuple[str, list[Any]]:
        """(field, values) that count the waypoints: the tool poses, else the first joint's angles."""
        wp = self.waypoints
        if wp.xyz is not None:
            return "waypoints.xyz", wp.xyz
        arrays = _per_joint_arrays(wp.theta, "waypoints.theta")
        return arrays[0] if arrays else ("waypoints.theta", [])

    @model_validator(mode="after")
    def _rules(self) -> PtpTaskFile:
        if len(set(self.compare)) != len(self.compare):
            raise _fail("compare", f"= {excerpt(repr(self.compare))} must be a list of distinct method names from "
                                   f"{', '.join(METHODS)}")
        self._check_waypoint_fields()
        self._check_single_joint_shapes()
        n = len(self.first_waypoints()[1])
        self._check_waypoint_counts(n)
        self._check_timing(n)
        self._check_methods(n)
        return self

    def _check_waypoint_fields(self) -> None:
        wp = self.waypoints
        if wp.xyz is not None:
            if self.robot is None:
                raise _fail("waypoints.xyz", "needs a robot (the task names none); add robot = \"<name>\"")
            if wp.theta is not None:
                raise _fail("waypoints", "gives both theta and xyz; give either theta (joint angles) or xyz/rpy "
                                         "(tool poses), not both")
            if wp.rpy is not None and len(wp.rpy) != len(wp.xyz):
                raise _fail("waypoints.rpy", f"has {len(wp.rpy)} entries but there are {len(wp.xyz)} waypoints "
                                             "(waypoints.xyz); give one [roll, pitch, yaw] per waypoint")
            scale = ANGLE_UNITS[self.units.angle]
            for name, values, bound, unit in (("xyz", wp.xyz, MAX_ABS_LENGTH_M, "m"),
                                              ("rpy", wp.rpy or [], MAX_ABS_ANGLE_RAD / scale, self.units.angle)):
                beyond = np.abs(np.asarray(values, dtype=float).reshape(-1, 3)) > bound
                if beyond.any():
                    k = int(np.argwhere(beyond)[0][0])
                    raise _fail(f"waypoints.{name}[{k}]", f"is beyond ±{bound:g} {unit}; no pose of an arm needs that: "
                                                          "check the value and [units]")
            return
        for key in ("rpy", "seed"):
            if getattr(wp, key) is not None:
                raise _fail(f"waypoints.{key}", "needs waypoints.xyz (the tool positions); add it, or remove "
                                                f"waypoints.{key} to give joint angles (theta)")
        for key in ("theta", "omega"):
            if getattr(wp, key) is None:
                raise _fail(f"waypoints.{key}", "is missing; give the waypoint angles (theta) and velocities (omega)")

    def _check_single_joint_shapes(self) -> None:
        """Without a robot the task is one joint: a per-joint table has no joints to name."""
        if self.robot is not None:
            return
        for field, value in (("waypoints.theta", self.waypoints.theta), ("waypoints.omega", self.waypoints.omega),
                             ("waypoints.eps", self.waypoints.eps), ("timing.omega_max", self.timing.omega_max),
                             ("timing.eps_max", self.timing.eps_max)):
            if isinstance(value, dict):
                raise _fail(field, "is a table but the task names no robot; give an array for the single joint")

    def _check_waypoint_counts(self, n: int) -> None:
        wp = self.waypoints
        if n < 2:
            field, values = self.first_waypoints()
            raise _fail(field, f"must list at least two waypoints (got {excerpt(repr(values))}); a plan goes from A to "
                               "B at least")
        for key in ("theta", "omega", "eps"):
            for field, values in _per_joint_arrays(getattr(wp, key), f"waypoints.{key}"):
                if len(values) != n:
                    raise _fail(field, f"has {len(values)} entries but there are {n} waypoints; give one per waypoint")
        if wp.t is not None:
            if len(wp.t) != n:
                raise _fail("waypoints.t", f"has {len(wp.t)} entries but there are {n} waypoints; give one per waypoint")
            for k in range(n - 1):
                if not wp.t[k] < wp.t[k + 1]:
                    raise _fail(f"waypoints.t[{k + 1}]", f"= {wp.t[k + 1]:g} s is not after waypoints.t[{k}] = "
                                                         f"{wp.t[k]:g} s; knot times must be strictly increasing")

    def _check_timing(self, n: int) -> None:
        timing = self.timing
        if self.waypoints.t is not None:
            if timing.grid is not None:
                raise _fail("timing.grid", "rounds computed durations, but waypoints.t is given; remove timing.grid "
                                           "or remove waypoints.t to compute the times from timing.omega_max")
        elif timing.omega_max is None:
            raise _fail("waypoints.t", "is missing and there is no timing.omega_max; give the knot times or the speed "
                                       "bound")
        for key in ("omega_max", "eps_max"):
            value = getattr(timing, key)
            entries = value.items() if isinstance(value, dict) else [("", value)]
            for name, bound in entries:
                if isinstance(bound, list) and len(bound) != n - 1:
                    where = f"timing.{key}" + (f".{name}" if name else "")
                    raise _fail(where, f"has {len(bound)} entries but there are {n - 1} segments; give one per "
                                       "segment or a single number")
        if timing.eps_max is not None and timing.omega_max is None:
            raise _fail("timing.eps_max", "needs timing.omega_max as well; add timing.omega_max")

    def _check_methods(self, n: int) -> None:
        wp = self.waypoints
        for method in dict.fromkeys([self.method, *self.compare]):
            if method == "3-5-3" and n < MIN_WAYPOINTS_3_5_3:
                raise rule_error(f"method '3-5-3' needs at least {MIN_WAYPOINTS_3_5_3} waypoints (cubic, quintic…, "
                                 f"cubic), got {n}; use '3-4' or 'cubic' (field 'method' or 'compare')")
        if self.method == "3-5-3" and wp.t is None and n == 5 and wp.eps is None:
            raise rule_error("field 'waypoints.t' is missing, but the 5-waypoint 3-5-3 plan chooses the acceleration at "
                             "C from both quintic durations together, so its segment times cannot be computed one by "
                             "one; give waypoints.t, or waypoints.eps, or use method '3-4' to compute the times")


def workload(task: PtpTaskFile) -> tuple[float, float]:
    """PTP integrates nothing; its samples are known once the knot times are (computed later
    from the bounds when waypoints.t is absent, and capped there by the planner)."""
    t = task.waypoints.t
    samples = (t[-1] - t[0]) / task.step + 1 if t and len(t) > 1 else 0.0
    return 0.0, samples
