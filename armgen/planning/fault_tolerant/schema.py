"""Schema of ``planner = "fault_tolerant"`` task files (spec 30)."""

from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

from pydantic import Field

from ...schemas import StrictModel
from ..toolpath.schema import path_union
from ..common import schema as common
from ..common.schema import (Damping, Description, EulerIntegrator, Positive, RelativePath, RobotReference, Start, Timing,
                             Units)

JointRef = Union[Annotated[int, Field(ge=1)], Annotated[str, Field(min_length=1, max_length=64)]]
JointList = Annotated[list[JointRef], Field(max_length=64)]
Gains = Annotated[list[float], Field(min_length=1, max_length=64)]


class Fault(StrictModel):
    joints: JointList = Field(default_factory=list, description="joint numbers (1-based) or names that lock")
    time: Optional[float] = Field(None, description="s, default: half the duration")


class Method(StrictModel):
    name: Literal["gpm", "wln", "pinv"] = "gpm"
    index: Literal["omega", "relative", "sigma_min"] = "omega"
    K: float = 1.0
    b: float = 1.0
    weight_rule: Literal["plain", "smooth"] = "smooth"
    v_band: Positive = 0.2
    omega_floor: Positive = 1e-3
    delta: Positive = 1e-4
    a: Optional[Gains] = None


class Completion(StrictModel):
    pos_tol: Positive = 1.0
    ori_tol: Positive = 1.0
    max_joint_speed: Positive = 120.0


class Sweep(StrictModel):
    K: Gains = Field(default_factory=lambda: [0.0, 0.5, 1.0, 2.0, 4.0])
    b: Gains = Field(default_factory=lambda: [0.0, 0.5, 1.0, 2.0, 4.0])
    rules: Annotated[list[Literal["plain", "smooth"]], Field(min_length=1, max_length=2)] = Field(
        default_factory=lambda: ["plain", "smooth"])
    joints: Union[Literal["all"], JointList] = "all"
    fine_step: Positive = 0.005


class Check(common.Check):
    reach: Literal["error", "report"] = "error"


class FaultTolerantTaskFile(StrictModel):
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
