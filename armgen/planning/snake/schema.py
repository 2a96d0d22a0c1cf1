"""Schema of ``planner = "snake"`` task files (spec 50): the parser of the task file.

Values are in the file's units. The schema checks what the file alone decides: types, signs,
the fields each obstacle type takes, and the rules across fields (waypoints apart, the path
starting at the rail start, non-zero directions, ramps that fit the duration, an output step
that divides it, a tube wall thinner than half its diameter, boxes with min < max). What needs
the robot (the snake structure, the rail direction as the default start tangent, the link
length in the link mass) is :func:`armgen.planning.snake.config.configure`'s. A length whose
default is physical (the tube's diameter and wall) defaults to None here and to its SI value
there, so that the default does not change with the file's units."""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Union

import numpy as np
from pydantic import Discriminator, Field, StringConstraints, Tag, model_validator

from ...description.files import LENGTH_UNITS
from ...errors import excerpt
from ...schemas import StrictModel, rule_error
from ..common.collision import CollisionSettings
from ..common.schema import Description, NonNegative, Positive, RobotReference, SpeedCheck, Vector3

MAX_WAYPOINTS = 10_000
MAX_OBSTACLES = 1_000
MAX_SAMPLES = 1_000_000
# Waypoints closer than this (1 % of a link) are duplicates: a near-zero chord knot interval
# makes the Hermite form divide by it and the spline loop between much longer neighbours.
MIN_WAYPOINT_SPACING = 1e-3  # m
# The path must run along the rail over the base's travel within this (1 µm): the base joint rides
# the straight rail line, the path is where the other joints ride. The C² spline rings from the
# first bend into its straight rail part, by 4e-8 m (tank) and 3e-9 m (planar) over the bundled
# examples' feed; a path that really leaves the rail is off by millimetres.
RAIL_TOL = 1e-6  # m
# The output step must divide the duration up to the rounding of the quotient of two decimals.
DIVIDE_RTOL = 1e-9
# The paper's link: 40 mm OD aluminium tube, 2 mm wall (spec 50: ≈ 0.067 kg per 104 mm link).
DEFAULT_OUTER_DIAMETER_M = 0.040
DEFAULT_WALL_M = 0.002

Direction = Annotated[Union[Annotated[Vector3, Tag("vector")], Annotated[Literal["natural"], Tag("natural")]],
                      Discriminator(lambda value: "natural" if isinstance(value, str) else "vector")]
Face = Literal["x-", "x+", "y-", "y+", "z-", "z+"]
ObstacleType = Literal["box", "cylinder", "plate", "tank", "sphere", "capsule", "plane"]
# The fields each obstacle type needs, and the optional ones it may have (beside name and type).
# The tube's obstacles (box by min/max, cylinder, plate, tank) are checked against the tube of
# radius outer_diameter / 2 around the joint centres; the collision vocabulary of the other
# planners (sphere, capsule, box by centre/size/rpy, plane: docs/collision.md) against the links'
# capsules, which the robot file must give.
OBSTACLE_FIELDS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "box": (("min", "max"), ()),
    "tank": (("min", "max"), ("faces",)),
    "cylinder": (("centre", "diameter"), ("axis",)),
    "plate": (("point", "normal"), ("opening_diameter",)),
    "sphere": (("centre", "radius"), ()),
    "capsule": (("a", "b", "radius"), ()),
    "plane": (("point", "normal"), ()),
}
# A box given by its centre is the collision vocabulary's (a turned box), one given by min/max the tube's.
CAPSULE_BOX_FIELDS = (("centre", "size"), ("rpy",))


def is_capsule_checked(obstacle: Obstacle) -> bool:
    """Whether the obstacle is of the collision vocabulary (checked against the links' capsules)."""
    return obstacle.type in ("sphere", "capsule", "plane") or (obstacle.type == "box" and obstacle.centre is not None)


def obstacle_fields(obstacle: Obstacle) -> tuple[tuple[str, ...], tuple[str, ...]]:
    return CAPSULE_BOX_FIELDS if obstacle.type == "box" and obstacle.centre is not None else OBSTACLE_FIELDS[obstacle.type]


def mm(p: np.ndarray) -> list[float]:
    """A point (m) in mm, rounded for messages."""
    return [round(float(x) * 1e3, 3) for x in p]


class Units(StrictModel):
    length: Literal["m", "mm"] = "m"
    angle: Literal["rad", "deg"] = "rad"


class Path(StrictModel):
    waypoints: Annotated[list[Vector3], Field(min_length=2, max_length=MAX_WAYPOINTS)]
    start_tangent: Optional[Direction] = Field(None, description="default: the rail direction")
    end_tangent: Direction = "natural"


class Rail(StrictModel):
    start: Optional[Vector3] = Field(None, description="default: the first waypoint")


class Motion(StrictModel):
    driven: Literal["base", "tip"] = "base"
    v: Positive = Field(description="cruise speed, length unit per s")
    duration: Positive = Field(10.0, description="s")
    ramp: Positive = Field(1.0, description="s")
    output_step: Positive = Field(0.01, description="s")


class Solver(StrictModel):
    method: Literal["exact", "denoised"] = "exact"
    h: NonNegative = Field(0.1, description="s, denoising window")
    integrator: Optional[Literal["RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA"]] = Field(
        None, description="default RK45 (h > 0), Radau (h = 0)")
    rtol: Positive = 1e-3
    atol: Positive = Field(1e-6, description="m (SI, like the state)")
    state: Literal["link", "absolute"] = "link"
    max_wall_time: Positive = Field(60.0, description="s")


class Links(StrictModel):
    outer_diameter: Optional[Positive] = Field(None, description="length unit; default 40 mm")
    wall: Optional[Positive] = Field(None, description="length unit; default 2 mm")
    density: Positive = Field(2700.0, description="kg/m³")
    EA: Positive = Field(1e9, description="axial stiffness, N")


class Obstacle(StrictModel):
    """One obstacle; the fields it takes depend on ``type`` (:data:`OBSTACLE_FIELDS`)."""

    name: Optional[Annotated[str, StringConstraints(min_length=1, max_length=200)]] = None
    type: ObstacleType
    min: Optional[Vector3] = None
    max: Optional[Vector3] = None
    centre: Optional[Vector3] = None
    axis: Optional[Vector3] = Field(None, description="cylinder: default [0, 0, 1]")
    diameter: Optional[Positive] = None
    point: Optional[Vector3] = None
    normal: Optional[Vector3] = None
    opening_diameter: Optional[NonNegative] = Field(None, description="plate: default 0 (no opening)")
    faces: Optional[Annotated[list[Face], Field(max_length=6)]] = Field(None, description="tank: default all six")
    radius: Optional[NonNegative] = Field(None, description="sphere, capsule")
    a: Optional[Vector3] = Field(None, description="capsule: one end of its axis")
    b: Optional[Vector3] = Field(None, description="capsule: the other end")
    size: Optional[Annotated[list[Positive], Field(min_length=3, max_length=3)]] = Field(
        None, description="box by centre: full edge lengths along its axes")
    rpy: Optional[Vector3] = Field(None, description="box by centre: its axes, R = Rz(yaw) Ry(pitch) Rx(roll) "
                                                     "(angle unit); default 0")


def _fail(field: str, message: str) -> Exception:
    return rule_error(f"field '{field}' {message}")


def _close_pair(points: np.ndarray, spacing: float) -> tuple[int, int] | None:
    """The first pair (i < j, by j then i) of points closer than ``spacing``: a sweep along x."""
    order = np.argsort(points[:, 0], kind="stable")
    xs = points[order, 0]
    found: list[tuple[int, int]] = []
    for a in range(len(order)):
        b = a + 1
        while b < len(order) and xs[b] - xs[a] < spacing:
            if np.linalg.norm(points[order[a]] - points[order[b]]) < spacing:
                i, j = sorted((int(order[a]), int(order[b])))
                found.append((i, j))
            b += 1
    return min(found, key=lambda p: (p[1], p[0])) if found else None


def _check_direction(value: Any, field: str, natural: bool = False) -> None:
    """A direction must not be the zero vector (``natural``: the field may also say \"natural\")."""
    if isinstance(value, list) and not np.any(value):
        raise _fail(field, "is the zero vector; give a direction such as [1, 0, 0]" + (" or \"natural\"" if natural else ""))


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
    collision: Optional[CollisionSettings] = Field(
        None, description="clearance (and activation) of the links' capsules: required with sphere, capsule, plane "
                          "or centred box obstacles; gain is not used (the path fixes every link)")
    check: SpeedCheck = Field(default_factory=SpeedCheck)

    @property
    def length_scale(self) -> float:
        """m per length unit of the file."""
        return LENGTH_UNITS[self.units.length]

    @model_validator(mode="after")
    def _rules(self) -> SnakeTaskFile:
        self._check_path()
        self._check_motion()
        self._check_links()
        for k, obstacle in enumerate(self.obstacles):
            self._check_obstacle(obstacle, k)
        return self

    def _check_path(self) -> None:
        """Waypoints at least MIN_WAYPOINT_SPACING apart (any two, not only neighbours), the first
        at the rail start, tangents that are directions."""
        waypoints = np.array(self.path.waypoints, dtype=float) * self.length_scale
        pair = _close_pair(waypoints, MIN_WAYPOINT_SPACING)
        if pair is not None:
            i, j = pair
            dist = float(np.linalg.norm(waypoints[i] - waypoints[j]))
            what = "duplicates" if dist == 0 else f"is only {dist * 1e3:.3g} mm from"
            raise _fail(f"path.waypoints[{j}]", f"= {mm(waypoints[j])} mm {what} path.waypoints[{i}]; waypoints must "
                                                f"be at least {MIN_WAYPOINT_SPACING * 1e3:g} mm apart (remove or merge it)")
        if self.rail.start is not None:
            rail_start = np.array(self.rail.start, dtype=float) * self.length_scale
            if np.linalg.norm(waypoints[0] - rail_start) > RAIL_TOL:
                raise _fail("path.waypoints[0]", f"= {mm(waypoints[0])} mm is not the rail start {mm(rail_start)} mm; "
                                                 "the path begins where the base joint starts (set rail.start or the "
                                                 "first waypoint)")
        _check_direction(self.path.start_tangent, "path.start_tangent", natural=True)
        _check_direction(self.path.end_tangent, "path.end_tangent", natural=True)

    def _check_motion(self) -> None:
        motion = self.motion
        if 2 * motion.ramp > motion.duration:
            raise _fail("motion.ramp", f"= {motion.ramp:g} s: two ramps do not fit in motion.duration = "
                                       f"{motion.duration:g} s; choose ramp ≤ duration / 2")
        samples = motion.duration / motion.output_step
        if samples > MAX_SAMPLES or abs(samples - round(samples)) > DIVIDE_RTOL * samples:
            raise _fail("motion.output_step", f"= {motion.output_step:g} s must divide motion.duration = "
                                              f"{motion.duration:g} s into at most {MAX_SAMPLES} steps")

    def _check_links(self) -> None:
        links, ls = self.links, self.length_scale
        outer = links.outer_diameter * ls if links.outer_diameter is not None else DEFAULT_OUTER_DIAMETER_M
        wall = links.wall * ls if links.wall is not None else DEFAULT_WALL_M
        if 2 * wall > outer:
            raise _fail("links.wall", "is more than half the outer diameter; give the tube's wall thickness")

    @staticmethod
    def _check_obstacle(obstacle: Obstacle, k: int) -> None:
        where = f"obstacles[{k}]"
        needed, optional = obstacle_fields(obstacle)
        given = [key for key in Obstacle.model_fields
                 if key not in ("name", "type") and getattr(obstacle, key) is not None]
        for key in needed:
            if getattr(obstacle, key) is None:
                raise _fail(f"{where}.{key}", f"is missing; a {obstacle.type} takes {' and '.join(needed)}"
                                              + (f" (optional: {', '.join(optional)})" if optional else ""))
        foreign = [key for key in given if key not in needed + optional]
        if foreign:
            raise _fail(f"{where}.{foreign[0]}", f"is not a field of a {obstacle.type} (it takes "
                                                 f"{', '.join(needed + optional)}); remove it")
        for key in ("axis", "normal"):
            _check_direction(getattr(obstacle, key), f"{where}.{key}")
        if obstacle.min is not None and obstacle.max is not None and np.any(np.array(obstacle.min) >= obstacle.max):
            raise _fail(where, f"needs min < max in every coordinate (min = {excerpt(repr(obstacle.min))}, max = "
                               f"{excerpt(repr(obstacle.max))})")


def workload(task: SnakeTaskFile) -> tuple[float, float]:
    samples = task.motion.duration / task.motion.output_step + 1
    return samples, samples
