"""Schema of ``planner = "wgpm"`` task files (spec 35).

Values are in the file's units; :func:`armgen.planning.wgpm.config.configure` checks what
needs the robot or the plan's duration and converts to SI. A field whose default is a physical
quantity (``t_rmax``, the tracking bounds) defaults to None here and to its SI value there, so
that the default does not change with the file's units."""

from __future__ import annotations

from typing import Annotated, Literal, Optional

from pydantic import Field, model_validator

from ...schemas import StrictModel, rule_error
from ..common.collision import CollisionFields
from ..toolpath.schema import path_union
from ..common.schema import (Check, Damping, Description, EulerIntegrator, NonNegative, Positive, RelativePath, RobotReference,
                             Start, Timing, Units, resolved_rate_workload)

# A criterion's gain: its sign comes from the criterion (maximised or minimised), not the file.
Gain = Annotated[float, Field(ge=0, description="≥ 0: the criterion's sense gives the sign")]


class Criterion(StrictModel):
    """One normalised criterion ``u = (H − H_lo) / (H_hi − H_lo)``: gain k_hi when it is bad
    (u ≤ u_th), k_lo when good (u ≥ u_th + u_band)."""

    k_hi: Gain = 0.0
    k_lo: Gain = 0.0
    H_lo: float = 0.0
    H_hi: float = 1.0
    u_th: float = Field(0.3, ge=0, le=1)
    u_band: Positive = 0.4

    @model_validator(mode="after")
    def _gains_and_range(self) -> Criterion:
        if self.k_lo > self.k_hi:
            raise rule_error(f"k_lo = {self.k_lo} exceeds k_hi = {self.k_hi}; the gain must be largest when the "
                             "criterion is bad (k_hi ≥ k_lo)")
        if not self.H_hi > self.H_lo:
            raise rule_error(f"H_hi = {self.H_hi} must exceed H_lo = {self.H_lo} (the range that normalises the "
                             "criterion to [0, 1])")
        return self


class Criteria(StrictModel):
    manipulability: Optional[Criterion] = None
    joint_manipulability: Optional[Criterion] = None
    zghal: Optional[Criterion] = None
    condition: Optional[Criterion] = None


class Method(StrictModel):
    name: Literal["wgpm", "pinv", "clamp"] = "wgpm"
    band: float = Field(0.1, gt=0, lt=0.5, description="fraction of each joint's range in each damping band: two "
                                                       "bands and a free band share the range")
    t_rmax: Optional[NonNegative] = Field(None, description="angle unit/s: the repulsive speed at a limit; "
                                                            "default 10 deg/s")
    delta: Positive = 1e-4
    ramp_time: NonNegative = Field(2.0, description="s; at most half the plan's duration when ramp_out")
    ramp_out: bool = True
    criteria: Criteria = Field(default_factory=Criteria)


class Tracking(StrictModel):
    pos_tol: Optional[Positive] = Field(None, description="length unit; default 1 mm")
    ori_tol: Optional[Positive] = Field(None, description="angle unit; default 1 deg")


class WgpmTaskFile(CollisionFields):
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
