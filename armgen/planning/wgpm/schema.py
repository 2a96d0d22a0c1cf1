"""Schema of ``planner = "wgpm"`` task files (spec 35)."""

from __future__ import annotations

from typing import Literal, Optional

from pydantic import Field

from ...schemas import StrictModel
from ..toolpath.schema import path_union
from ..common.schema import (Check, Damping, Description, EulerIntegrator, NonNegative, Positive, RelativePath, RobotReference,
                             Start, Timing, Units, resolved_rate_workload)


class Criterion(StrictModel):
    k_hi: float = 0.0
    k_lo: float = 0.0
    H_lo: float = 0.0
    H_hi: float = 1.0
    u_th: float = Field(0.3, description="in [0, 1]")
    u_band: Positive = 0.4


class Criteria(StrictModel):
    manipulability: Optional[Criterion] = None
    joint_manipulability: Optional[Criterion] = None
    zghal: Optional[Criterion] = None
    condition: Optional[Criterion] = None


class Method(StrictModel):
    name: Literal["wgpm", "pinv", "clamp"] = "wgpm"
    band: Positive = Field(0.1, description="fraction of each joint range, < 0.5")
    t_rmax: float = Field(10.0, description="angle unit per s, ≥ 0")
    delta: Positive = 1e-4
    ramp_time: NonNegative = 2.0
    ramp_out: bool = True
    criteria: Criteria = Field(default_factory=Criteria)


class Tracking(StrictModel):
    pos_tol: Positive = 1e-3
    ori_tol: Positive = 1.0


class WgpmTaskFile(StrictModel):
    """A path task with weighted gradient projection (spec 35)."""

    planner: Literal["wgpm"]
    description: Optional[Description] = None
    robot: RobotReference
    start: Start = "q0"
    units: Units = Field(default_factory=Units)
    path: path_union(RelativePath)
    timing: Optional[Timing] = Field(None, description="required for a circle or line; not used by a program")
    integrator: EulerIntegrator = Field(default_factory=EulerIntegrator)
    damping: Damping = Field(default_factory=Damping)
    method: Method = Field(default_factory=Method)
    tracking: Tracking = Field(default_factory=Tracking)
    check: Check = Field(default_factory=Check)


# (integration steps, CSV samples): the same timing and integrator fields as a Cartesian task
workload = resolved_rate_workload
