"""The task-file vocabulary of the cell's obstacles and the collision criterion (issue 38), in
the style of :mod:`armgen.planning.common.schema`: ``[[obstacles]]`` (spheres, capsules, boxes,
half-spaces) and ``[collision]`` (clearance, activation, gain), in the task file's units, and
their conversion to SI (:func:`obstacles_si`, :func:`collision_si`).

Ready for the planners (a planner's task model adds ``obstacles: Obstacles = []`` and
``collision: Optional[CollisionSettings] = None``); no planner takes them yet (docs/collision.md,
"Not yet")::

    [[obstacles]]
    type = "capsule"        # "sphere" | "capsule" | "box" | "plane"
    a = [600, -200, 0]
    b = [600, -200, 1200]
    radius = 80

    [[obstacles]]
    type = "box"
    centre = [500, 300, 400]
    size = [200, 300, 800]  # full edge lengths along the box's own axes
    rpy = [0, 0, 30]        # the box's axes: R = Rz(yaw) Ry(pitch) Rx(roll)

    [[obstacles]]
    type = "plane"          # a half-space: the solid side is the one the normal points away from
    point = [0, 0, 0]
    normal = [0, 0, 1]

    [collision]
    clearance = 20          # the hard minimum distance (length unit)
    activation = 100        # the criterion acts below this distance
    gain = 1.0
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal, Union

from pydantic import Discriminator, Field, Tag, model_validator

from ...description.collision import (MAX_OBSTACLE_SLOTS, BoxObstacle, CapsuleObstacle, Obstacle, PlaneObstacle,
                                      SphereObstacle)
from ...description.files import ANGLE_UNITS, LENGTH_UNITS
from ...schemas import StrictModel, rule_error
from .schema import NonNegative, Positive, Units, Vector3

Radius = Annotated[float, Field(ge=0, description="length unit")]


class SphereEntry(StrictModel):
    type: Literal["sphere"]
    centre: Vector3 = Field(description="length unit, base frame")
    radius: Radius


class CapsuleEntry(StrictModel):
    type: Literal["capsule"]
    a: Vector3 = Field(description="one end of the axis (length unit, base frame)")
    b: Vector3 = Field(description="the other end")
    radius: Radius


class BoxEntry(StrictModel):
    type: Literal["box"]
    centre: Vector3 = Field(description="length unit, base frame")
    size: Annotated[list[Annotated[float, Field(gt=0)]], Field(min_length=3, max_length=3)] = Field(
        description="full edge lengths along the box's axes (length unit)")
    rpy: Vector3 = Field(default_factory=lambda: [0.0, 0.0, 0.0],
                         description="the box's axes (angle unit): R = Rz(yaw) Ry(pitch) Rx(roll)")


class PlaneEntry(StrictModel):
    type: Literal["plane"]
    point: Vector3 = Field(description="a point of the boundary plane (length unit, base frame)")
    normal: Vector3 = Field(description="out of the solid half-space (any length but 0)")

    @model_validator(mode="after")
    def _normal_has_a_direction(self) -> PlaneEntry:
        if not any(self.normal):
            raise rule_error("normal = [0, 0, 0] has no direction; give the direction out of the solid side "
                             "(e.g. [0, 0, 1] for a table top)")
        return self


ObstacleEntry = Annotated[Union[Annotated[SphereEntry, Tag("sphere")], Annotated[CapsuleEntry, Tag("capsule")],
                                Annotated[BoxEntry, Tag("box")], Annotated[PlaneEntry, Tag("plane")]],
                          Discriminator(lambda value: value.get("type") if isinstance(value, dict) else None)]
# Up to MAX_OBSTACLE_SLOTS of each of the four kinds (the robot's slots decide how many fit).
Obstacles = Annotated[list[ObstacleEntry], Field(max_length=4 * MAX_OBSTACLE_SLOTS)]


class CollisionSettings(StrictModel):
    """``[collision]``: the hard minimum distance, where the criterion starts, and its gain."""

    clearance: NonNegative = Field(0.0, description="length unit: a plan closer than this is infeasible")
    activation: Positive = Field(description="length unit: the criterion H_C acts below this distance")
    gain: NonNegative = Field(1.0, description="the criterion's weight in the planner's null-space term")

    @model_validator(mode="after")
    def _activation_beyond_clearance(self) -> CollisionSettings:
        if not self.activation > self.clearance:
            raise rule_error(f"activation = {self.activation} must be beyond clearance = {self.clearance}: the "
                             "criterion acts between them")
        return self


@dataclass(frozen=True)
class Collision:
    """``[collision]`` in SI (m; the gain as given)."""

    clearance: float
    activation: float
    gain: float


def obstacles_si(entries: list[SphereEntry | CapsuleEntry | BoxEntry | PlaneEntry], units: Units) -> tuple[Obstacle, ...]:
    """The task's obstacles in SI (m, rad), for :meth:`armgen.robot.Robot.collision_distances`."""
    length, angle = LENGTH_UNITS[units.length], ANGLE_UNITS[units.angle]

    def point(values: list[float]) -> tuple[float, float, float]:
        return tuple(v * length for v in values)

    out: list[Obstacle] = []
    for entry in entries:
        if isinstance(entry, SphereEntry):
            out.append(SphereObstacle(point(entry.centre), entry.radius * length))
        elif isinstance(entry, CapsuleEntry):
            out.append(CapsuleObstacle(point(entry.a), point(entry.b), entry.radius * length))
        elif isinstance(entry, BoxEntry):
            out.append(BoxObstacle(point(entry.centre), point(entry.size), tuple(v * angle for v in entry.rpy)))
        else:
            out.append(PlaneObstacle(point(entry.point), tuple(entry.normal)))
    return tuple(out)


def collision_si(settings: CollisionSettings, units: Units) -> Collision:
    length = LENGTH_UNITS[units.length]
    return Collision(settings.clearance * length, settings.activation * length, settings.gain)
