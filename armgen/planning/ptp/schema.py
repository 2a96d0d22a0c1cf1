"""Schema of ``planner = "ptp"`` task files (spec 40). Per-joint values are either an array
(single joint, no robot) or a table with one array per joint of the robot; the parser checks
the joint names and counts against the robot."""

from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

from pydantic import Field

from ...schemas import StrictModel
from ..common.schema import Description, Positive, RobotReference, SpeedCheck

MAX_WAYPOINTS = 10_000
Values = Annotated[list[float], Field(max_length=MAX_WAYPOINTS)]
PerJoint = Union[Values, Annotated[dict[str, Values], Field(max_length=64)]]
Bound = Union[float, Values]
PerJointBound = Union[Bound, Annotated[dict[str, Bound], Field(max_length=64)]]
Method = Literal["cubic", "3-4", "3-5-3", "quintic"]


class Units(StrictModel):
    angle: Literal["rad", "deg"] = "rad"


Triples = Annotated[list[Annotated[list[float], Field(min_length=3, max_length=3)]], Field(max_length=MAX_WAYPOINTS)]


class Waypoints(StrictModel):
    t: Optional[Values] = Field(None, description="knot times, s, strictly increasing")
    theta: Optional[PerJoint] = Field(None, description="joint angles per waypoint (or give xyz/rpy)")
    omega: Optional[PerJoint] = Field(None, description="joint speeds per waypoint (default 0 with xyz)")
    eps: Optional[PerJoint] = None
    xyz: Optional[Triples] = Field(None, description="tool positions, m (solved by the inverse kinematics)")
    rpy: Optional[Triples] = Field(None, description="tool orientations R = Rz(yaw) Ry(pitch) Rx(roll), units.angle")
    seed: Optional[Union[str, Values]] = Field(None, description="configuration the first pose is solved from")


class Timing(StrictModel):
    omega_max: Optional[PerJointBound] = None
    eps_max: Optional[PerJointBound] = None
    grid: Optional[Positive] = Field(None, description="s: computed durations are rounded up to this grid")


class PtpTaskFile(StrictModel):
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


def workload(task: PtpTaskFile) -> tuple[float, float]:
    """PTP integrates nothing; its samples are known once the knot times are (computed later
    from the bounds when waypoints.t is absent, and capped there by the planner)."""
    t = task.waypoints.t
    samples = (t[-1] - t[0]) / task.step + 1 if t and len(t) > 1 else 0.0
    return 0.0, samples
