"""Schema of ``planner = "fault_tolerant"`` task files (spec 30).

Values are in the file's units; :func:`armgen.planning.fault_tolerant.config.configure`
resolves the joints against the robot, checks the fault time against the plan's duration and
converts to SI. A field whose default is a physical quantity (``v_band``, the completion
bounds) defaults to None here and to its SI value there, so that the default does not change
with the file's units."""

from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

from pydantic import Field

from ...schemas import StrictModel
from ..common.collision import CollisionFields
from ..toolpath.schema import path_union
from ..common import schema as common
from ..common.schema import (Damping, Description, EulerIntegrator, NonNegative, Positive, RelativePath, RobotReference,
                             Start, Timing, Units)

JointRef = Union[Annotated[int, Field(ge=1)], Annotated[str, Field(min_length=1, max_length=64)]]
JointList = Annotated[list[JointRef], Field(max_length=64)]
# Gains weigh the index that is maximised: a negative one would drive it down instead of up.
Gains = Annotated[list[NonNegative], Field(min_length=1, max_length=64)]


class Fault(StrictModel):
    joints: JointList = Field(default_factory=list, description="joint numbers (1-based) or names that lock")
    time: Optional[float] = Field(None, description="s, within the plan; default: half the duration")


class Method(StrictModel):
    name: Literal["gpm", "wln", "pinv"] = "gpm"
    index: Literal["omega", "relative", "sigma_min"] = "omega"
    K: NonNegative = Field(1.0, description="GPM gain on ∇H (≥ 0: the index is maximised)")
    b: NonNegative = Field(1.0, description="WLN weight gain (≥ 0: the index is maximised)")
    weight_rule: Literal["plain", "smooth"] = "smooth"
    v_band: Optional[Positive] = Field(None, description="angle unit/s: the smooth rule's activation band; "
                                                         "default 0.2 rad/s")
    omega_floor: Positive = 1e-3
    delta: Positive = 1e-4
    a: Optional[Gains] = Field(None, description="one weight per joint; default all 1")


class Completion(StrictModel):
    pos_tol: Optional[Positive] = Field(None, description="length unit; default 1 mm")
    ori_tol: Optional[Positive] = Field(None, description="angle unit; default 1 deg")
    max_joint_speed: Optional[Positive] = Field(None, description="angle unit/s; default 120 deg/s")


class Sweep(StrictModel):
    K: Gains = Field(default_factory=lambda: [0.0, 0.5, 1.0, 2.0, 4.0])
    b: Gains = Field(default_factory=lambda: [0.0, 0.5, 1.0, 2.0, 4.0])
    rules: Annotated[list[Literal["plain", "smooth"]], Field(min_length=1, max_length=2)] = Field(
        default_factory=lambda: ["plain", "smooth"])
    joints: Union[Literal["all"], JointList] = "all"
    fine_step: Positive = Field(0.005, description="s")


class Check(common.Check):
    reach: Literal["error", "report"] = "error"


class FaultTolerantTaskFile(CollisionFields):
    """A path task with a locked-joint fault (spec 30)."""

    planner: Literal["fault_tolerant"]
    description: Optional[Description] = None
    robot: RobotReference
    start: Start = "q0"
    units: Units = Field(default_factory=Units)
    path: path_union(RelativePath)
    timing: Optional[Timing] = Field(None, description="required for a circle or line; not used by a program")
    integrator: EulerIntegrator = Field(default_factory=EulerIntegrator)
    damping: Damping = Field(default_factory=Damping)
    method: Method = Field(default_factory=Method)
    fault: Fault = Field(default_factory=Fault)
    completion: Completion = Field(default_factory=Completion)
    sweep: Sweep = Field(default_factory=Sweep)
    check: Check = Field(default_factory=Check)


# (integration steps, CSV samples): the same timing and integrator fields as a Cartesian task
workload = common.resolved_rate_workload
