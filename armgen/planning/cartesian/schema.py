"""Schema of ``planner = "cartesian"`` task files (spec 20): the shared vocabulary
(:mod:`armgen.planning.common.schema`) plus the integrator and the method. Values are in the
file's units; :mod:`.config` converts them to SI."""

from __future__ import annotations

from typing import Annotated, Literal, Optional

from pydantic import Field

from ...schemas import StrictModel
from ..common.collision import CollisionFields
from ..common.schema import (Check, Damping, Description, NonNegative, Path, Positive, RobotReference, Start, Timing,
                             Units, resolved_rate_workload)
from ..toolpath.schema import path_union


class Integrator(StrictModel):
    method: Literal["euler", "rk4"] = "euler"
    step: Positive = Field(0.02, description="s")
    clik_gain: NonNegative = Field(0.0, description="closed-loop gain K_p, 1/s (0 = open loop)")
    output_every: Annotated[int, Field(ge=1)] = Field(1, description="write every k-th step to the CSV")


class Method(StrictModel):
    """The defaults shown are the plain methods'; ``combined`` and ``zghal_improved`` have their own
    (docs/cartesian.md), which :func:`.config.method_params` gives the fields a file leaves out."""

    name: Literal["pinv", "repetitive", "zghal", "zghal_improved", "combined"] = "pinv"
    rho_R: NonNegative = 2.8
    T_smo_R: Positive = 10.0
    rho_L: NonNegative = 0.025
    theta_s: Positive = Field(20.0, description="angle unit of the file; left out: 20 degrees in any unit")
    T_smo_L: Positive = 40.0
    T_sum_L: Positive = 80.0
    gamma_R_ramp: Positive = 20.0


class CartesianTaskFile(CollisionFields):
    """A Cartesian path task (spec 20)."""

    planner: Literal["cartesian"]
    description: Optional[Description] = None
    robot: RobotReference
    start: Start = "q0"
    units: Units = Field(default_factory=Units)
    path: path_union(Path)
    timing: Optional[Timing] = Field(None, description="required for a circle or line; not used by a program")
    integrator: Integrator = Field(default_factory=Integrator)
    damping: Damping = Field(default_factory=Damping)
    method: Method = Field(default_factory=Method)
    check: Check = Field(default_factory=Check)


# (integration steps, CSV samples), estimated before planning
workload = resolved_rate_workload
