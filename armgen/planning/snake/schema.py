"""Schema of ``planner = "snake"`` task files (spec 50)."""

from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

from pydantic import Field, StringConstraints

from ...schemas import StrictModel
from ..common.schema import Description, NonNegative, Positive, RobotReference, SpeedCheck, Vector3

MAX_WAYPOINTS = 10_000
MAX_OBSTACLES = 1_000
Direction = Union[Vector3, Literal["natural"]]


class Units(StrictModel):
    length: Literal["m", "mm"] = "m"
    angle: Literal["rad", "deg"] = "rad"


class Path(StrictModel):
    waypoints: Annotated[list[Vector3], Field(min_length=2, max_length=MAX_WAYPOINTS)]
    start_tangent: Optional[Direction] = Field(None, description="default: the rail direction")
    end_tangent: Direction = "natural"


class Rail(StrictModel):
    start: Optional[Vector3] = None


class Motion(StrictModel):
    driven: Literal["base", "tip"] = "base"
    v: Positive = Field(description="cruise speed, length unit per s")
    duration: Positive = 10.0
    ramp: Positive = 1.0
    output_step: Positive = 0.01


class Solver(StrictModel):
    method: Literal["exact", "denoised"] = "exact"
    h: NonNegative = 0.1
    integrator: Optional[Literal["RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA"]] = None
    rtol: Positive = 1e-3
    atol: Positive = 1e-6
    state: Literal["link", "absolute"] = "link"
    max_wall_time: Positive = 60.0


class Links(StrictModel):
    outer_diameter: Positive = 0.040
    wall: Positive = 0.002
    density: Positive = 2700.0
    EA: Positive = 1e9


class Obstacle(StrictModel):
    name: Optional[Annotated[str, StringConstraints(min_length=1, max_length=200)]] = None
    type: Literal["box", "cylinder", "plate", "tank"]
    min: Optional[Vector3] = None
    max: Optional[Vector3] = None
    centre: Optional[Vector3] = None
    axis: Optional[Vector3] = None
    diameter: Optional[Positive] = None
    point: Optional[Vector3] = None
    normal: Optional[Vector3] = None
    opening_diameter: Optional[NonNegative] = None
    faces: Optional[Annotated[list[Literal["x-", "x+", "y-", "y+", "z-", "z+"]], Field(max_length=6)]] = None


class SnakeTaskFile(StrictModel):
    """Snake-arm tip following along waypoints (spec 50)."""

    planner: Literal["snake"]
    description: Optional[Description] = None
    robot: RobotReference = "snake12"
    units: Units = Field(default_factory=Units)
    path: Path
    rail: Rail = Field(default_factory=Rail)
    motion: Motion
    solver: Solver = Field(default_factory=Solver)
    links: Links = Field(default_factory=Links)
    obstacles: Annotated[list[Obstacle], Field(max_length=MAX_OBSTACLES)] = Field(default_factory=list)
    check: SpeedCheck = Field(default_factory=SpeedCheck)


def workload(task: SnakeTaskFile) -> tuple[float, float]:
    samples = task.motion.duration / task.motion.output_step + 1
    return samples, samples
