"""The task-file vocabulary of the cell's obstacles and the collision criterion (issue 38), in
the style of :mod:`armgen.planning.common.schema`: ``[[obstacles]]`` (spheres, capsules, boxes,
half-spaces) and ``[collision]`` (clearance, activation, gain), in the task file's units, and
their conversion to SI (:func:`obstacles_si`, :func:`collision_si`).

A planner's task model takes them by deriving from :class:`CollisionFields`; its config holds
the :class:`TaskCollision` of :func:`configure_collision`. The resolved-rate planners add
``−gain ∇H_C`` to their null-space term (:func:`criterion_term`); :func:`clearance_report`
measures every plan's samples and :func:`enforce_clearance` refuses one below ``clearance``
(docs/collision.md, "Obstacles in task files")::

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
    gain = 0.01            # α = −gain ∇H_C in the resolved-rate planners' null-space term
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Callable, Literal, Optional, Union

import casadi as ca
import numpy as np
from pydantic import Discriminator, Field, Tag, ValidationError, model_validator

from ...description.collision import (MAX_OBSTACLE_SLOTS, BoxObstacle, CapsuleObstacle, Obstacle, PlaneObstacle,
                                      SphereObstacle, obstacle_kind, obstacle_parameters)
from ...description.files import ANGLE_UNITS, LENGTH_UNITS
from ...description.model import MAX_ABS_ANGLE_RAD, MAX_ABS_LENGTH_M
from ...errors import PlanningError, TaskFileError
from ...robot import Robot
from ...schemas import (MAX_INPUT_FILE_BYTES, StrictModel, format_validation_error, parse_toml_bounded,
                        read_input_file, rule_error)
from ..backends import make_backend
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
    # α = −gain ∇H_C (rad/s): ∇H_C reaches ~40 per rad at d = c + 3(ρ − c)/4 on a 0.4 m lever and
    # grows like 1/(d − c)³ toward the clearance, so 0.01 asks a fraction of a joint's speed limit
    # for the self-motion until the arm is close (tests/test_collision_planning.py's scene)
    gain: NonNegative = Field(0.01, description="rad²/s: the criterion's weight in the planner's null-space "
                                                "term α = −gain ∇H_C")

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


class CollisionFields(StrictModel):
    """The task-file fields of every planner that moves a robot's joints: ``[[obstacles]]`` and
    ``[collision]`` (a planner's task model derives from this class)."""

    obstacles: Obstacles = Field(default_factory=list, description="the cell's obstacles (base frame, file units)")
    collision: Optional[CollisionSettings] = Field(
        None, description="clearance, activation and gain of the collision criterion (required with obstacles)")


@dataclass(frozen=True)
class TaskCollision:
    """A task's collision model on a robot with capsules, in SI: the obstacles, the criterion's
    settings (None: the plan is only measured, against the arm itself), and the obstacle inputs
    of the collision functions (:func:`~armgen.description.collision.obstacle_parameters`)."""

    obstacles: tuple[Obstacle, ...]
    settings: Collision | None
    parameters: dict[str, np.ndarray]


def configure_collision(model: Any, robot: Robot | None, source: str) -> TaskCollision | None:
    """The task's :class:`TaskCollision` (None for a robot without capsules and a task without
    obstacles). A task that gives obstacles or ``[collision]`` to a robot without capsules is
    refused, and so is one with obstacles but no ``[collision]`` or more obstacles than slots."""
    entries, settings = model.obstacles, model.collision
    # a ptp task gives angles only: its lengths (tool positions) are in m
    units = Units(length=getattr(model.units, "length", "m"), angle=model.units.angle)
    if robot is None:
        if entries or settings is not None:
            raise TaskFileError(f"{source}: field '{'obstacles' if entries else 'collision'}': the task names no robot, "
                                "so there is no arm to keep clear; give 'robot' (one with [[collision]] capsules), or "
                                "remove [[obstacles]] and [collision]")
        return None
    if not robot.has_collision:
        if entries or settings is not None:
            field = "obstacles" if entries else "collision"
            why = f" ({robot.collision.unusable})" if robot.collision.unusable else ""
            raise TaskFileError(f"{source}: field '{field}': robot '{robot.name}' has no collision capsules{why}, so "
                                "nothing can keep the arm clear of the obstacles; give the robot file [[collision]] "
                                "capsules (docs/collision.md), or remove [[obstacles]] and [collision] from the task")
        return None
    if entries and settings is None:
        raise TaskFileError(f"{source}: field 'collision': the task has [[obstacles]] but no [collision] table; add "
                            "[collision] with activation = (the distance where the criterion starts, length unit) "
                            "and, optionally, clearance and gain")
    obstacles = obstacles_si(entries, units)
    try:
        parameters = obstacle_parameters(obstacles, robot.collision.slots)
    except ValueError as exc:
        raise TaskFileError(f"{source}: field 'obstacles': {exc}") from None
    return TaskCollision(obstacles, None if settings is None else collision_si(settings, units), parameters)


def ik_arguments(collision: TaskCollision | None) -> dict[str, Any]:
    """The keyword arguments of :meth:`armgen.robot.Robot.ik` that keep its solutions clear of a
    task's obstacles at its clearance (none for a task without [collision]: the robot's own
    capsules, if any, are checked at clearance 0)."""
    if collision is None:
        return {}
    settings = collision.settings
    return {"obstacles": collision.obstacles,
            **({} if settings is None else {"clearance": settings.clearance, "activation": settings.activation})}


def nearest_pair(robot: Robot, q: np.ndarray, collision: TaskCollision | None) -> tuple[float, str]:
    """The least distance (m) at ``q`` over the pairs a task checks and that pair, named as a plan
    report names it (``"capsule 2 – obstacles[0] (sphere)"``)."""
    obstacles = () if collision is None else collision.obstacles
    distances = robot.collision_distances(q, obstacles)
    entry = int(np.argmin(distances))
    first, second = robot.collision_pairs()[entry]
    if entry >= len(robot.collision.self_pairs()):
        second = _pair_name(second, obstacles)
    return float(distances[entry]), f"{first} – {second}"


class ObstacleFile(CollisionFields):
    """An obstacle file (``armgen ik --obstacles``): a task's ``[units]``, ``[[obstacles]]`` and
    ``[collision]`` tables alone (``gain`` is the planners' and is not used by the IK)."""

    units: Units = Field(default_factory=Units, description="length and angle units of the file")


def load_obstacle_file(path: str | Path, robot: Robot) -> TaskCollision | None:
    """The obstacles and clearance of an obstacle file for ``robot``, in SI; errors
    (:class:`~armgen.errors.TaskFileError`, exit 2) name the file, the field and the fix."""
    source = str(path)
    document = parse_toml_bounded(read_input_file(path, MAX_INPUT_FILE_BYTES, "obstacle file", TaskFileError),
                                  source, TaskFileError)
    try:
        model = ObstacleFile.model_validate(document)
    except ValidationError as exc:
        raise TaskFileError(format_validation_error(
            exc, source, document, "an obstacle file holds [units], [[obstacles]] and [collision] as a task file does "
            "(docs/collision.md)")) from None
    _check_reach(model, source)
    return configure_collision(model, robot, source)


def _check_reach(model: ObstacleFile, source: str) -> None:
    """Refuse a length beyond ±MAX_ABS_LENGTH_M (after [units]), an angle beyond
    ±MAX_ABS_ANGLE_RAD, a normal's entry beyond ±MAX_ABS_LENGTH_M: far out of any arm's reach
    (what Robot.ik refuses), so a typo in a value or in [units] is an error naming the field."""
    length, angle = LENGTH_UNITS[model.units.length], ANGLE_UNITS[model.units.angle]
    # (field, its largest magnitude in SI, the bound, its unit)
    checks = []
    for k, entry in enumerate(model.obstacles):
        for name, value in entry.model_dump().items():
            if name == "rpy":
                checks.append((f"obstacles[{k}].rpy", value, max(map(abs, value)) * angle, MAX_ABS_ANGLE_RAD, "rad"))
            elif name == "normal":  # a direction: its length does not matter, but must stay representable
                checks.append((f"obstacles[{k}].normal", value, max(map(abs, value)), MAX_ABS_LENGTH_M, "m"))
            elif name != "type":
                size = max(map(abs, value)) if isinstance(value, list) else abs(value)
                checks.append((f"obstacles[{k}].{name}", value, size * length, MAX_ABS_LENGTH_M, "m"))
    if model.collision is not None:
        checks += [(f"collision.{name}", getattr(model.collision, name), getattr(model.collision, name) * length,
                    MAX_ABS_LENGTH_M, "m") for name in ("clearance", "activation")]
    for field, value, size, bound, unit in checks:
        if size > bound:
            raise TaskFileError(f"{source}: field '{field}' = {value} is beyond ±{bound:g} {unit} (after [units]), far "
                                "out of any arm's reach: check the value and [units]")


# The collision criterion's inputs besides q, by the name CasADi gives them; in a kernel each
# carries the prefix, so no planner's own input shares its name.
KERNEL_PREFIX = "collision_"


def criterion_term(model: Any, inputs: Any) -> Callable[[ca.SX], ca.SX]:
    """``q ↦ −gain ∇H_C(q)`` for a planner's kernel (``model``: its SymbolicModel; ``inputs``: its
    input Packing): the obstacle slots, the clearance, the activation and the gain become kernel
    inputs once (set them with :func:`set_kernel_inputs`), the term is taken at each stage's q.
    A planner adds it to its null-space term α, whose step projects it as the other criteria."""
    criterion = model.function("collision_criterion")
    arguments = []
    for k in range(1, criterion.n_in()):
        rows, cols = criterion.size_in(k)
        arguments.append(ca.reshape(inputs.add(KERNEL_PREFIX + criterion.name_in(k), rows * cols), rows, cols))
    gain = inputs.add(KERNEL_PREFIX + "gain", 1)

    def term(q: ca.SX) -> ca.SX:
        return -gain * criterion(q, *arguments)[1]

    return term


def set_kernel_inputs(kernel: Any, collision: TaskCollision) -> None:
    """Write the task's obstacles and settings into a kernel built with :func:`criterion_term`."""
    settings = collision.settings
    values = {**collision.parameters, "clearance": settings.clearance, "activation": settings.activation,
              "gain": settings.gain}
    for name, value in values.items():
        kernel.set(KERNEL_PREFIX + name, np.asarray(value, dtype=float).reshape(-1, order="F"))


def task_collision(config: Any) -> TaskCollision | None:
    """The :class:`TaskCollision` of a planner's typed config (``config.collision``, or its path
    task's for the planners of :mod:`armgen.planning.taskpath`), None when it has none."""
    found = getattr(config, "collision", None)
    if found is None:
        found = getattr(getattr(config, "path", None), "collision", None)
    return found if isinstance(found, TaskCollision) else None


def uses_criterion(collision: TaskCollision | None) -> bool:
    """Whether a planner's null-space term takes ``H_C`` (a task with ``[collision]``)."""
    return collision is not None and collision.settings is not None


def _pair_name(label: str, obstacles: tuple[Obstacle, ...]) -> str:
    """An obstacle slot's label (``box 1``) as the task names the obstacle: ``obstacles[4] (box)``,
    its index among the task's [[obstacles]]."""
    kind, slot = label.rsplit(" ", 1)
    same = [k for k, o in enumerate(obstacles) if obstacle_kind(o) == kind]
    return f"obstacles[{same[int(slot)]}] ({kind})"


def plan_distances(robot: Robot, q: np.ndarray, obstacles: tuple[Obstacle, ...]) -> np.ndarray:
    """``robot.collision_distances`` at every row of ``q`` (samples × pairs), through a planning
    kernel: composed once per machine and kept in the kernel store (:mod:`..backends`), where
    the Robot method derives the function again in every process (~0.4 s for a 7-DOF arm)."""

    def build(model: Any, inputs: Any, outputs: Any) -> None:
        distances = model.function("collision_distances")
        arguments = [inputs.add("q", model.n)]
        for k in range(1, distances.n_in()):
            rows, cols = distances.size_in(k)
            arguments.append(ca.reshape(inputs.add(distances.name_in(k), rows * cols), rows, cols))
        outputs.add("d", distances(*arguments))

    kernel = make_backend(robot, "symbolic").kernel(("collision_distances",), build)
    for name, value in obstacle_parameters(obstacles, robot.collision.slots).items():
        kernel.set(name, value.reshape(-1, order="F"))
    q = np.atleast_2d(q)
    out = np.empty((len(q), kernel.outputs["d"].stop - kernel.outputs["d"].start))
    q_slot, d_slot = kernel.inputs["q"], kernel.outputs["d"]
    for k, row in enumerate(q):
        kernel.x[q_slot] = row
        kernel()
        out[k] = kernel.y[d_slot]
    return out


def clearance_report(robot: Robot, t: np.ndarray, q: np.ndarray, collision: TaskCollision) -> dict[str, Any] | None:
    """``summary.collision`` of a plan (joint values ``q`` at the times ``t``, SI): the least
    distance over every sample and checked pair (the arm's self pairs and each moving capsule
    against each obstacle), its pair (``"capsule 2 – obstacles[0] (sphere)"``) and time, the least of the self pairs alone, and whether
    the plan keeps ``clearance``; None when there is no pair to measure."""
    distances = plan_distances(robot, q, collision.obstacles)
    labels = robot.collision_pairs()
    self_pairs = len(robot.collision.self_pairs())
    active = [k for k, (first, second) in enumerate(labels) if k < self_pairs or _is_given(second, collision)]
    if not active:  # no self pair and no obstacle: nothing to measure
        return None
    sample, column = np.unravel_index(int(np.argmin(distances[:, active])), (len(t), len(active)))
    pair = labels[active[column]]
    first = pair[0]
    second = pair[1] if active[column] < self_pairs else _pair_name(pair[1], collision.obstacles)
    clearance = collision.settings.clearance if collision.settings is not None else 0.0
    least = float(distances[sample, active[column]])
    report = {
        "min_clearance_m": least,
        "pair": f"{first} – {second}",
        "t_s": float(t[sample]),
        "clearance_m": clearance,
        "within_clearance": bool(least >= clearance),
        "samples_checked": int(len(t)),
        "obstacles": len(collision.obstacles),
    }
    if self_pairs:
        self_sample, self_pair = np.unravel_index(int(np.argmin(distances[:, :self_pairs])), (len(t), self_pairs))
        report["min_self_clearance_m"] = float(distances[self_sample, self_pair])
        report["self_pair"] = " – ".join(labels[self_pair])
        report["self_t_s"] = float(t[self_sample])
    return report


def _is_given(slot_label: str, collision: TaskCollision) -> bool:
    """Whether an obstacle slot (``sphere 1``) holds one of the task's obstacles."""
    kind, slot = slot_label.rsplit(" ", 1)
    return int(slot) < sum(obstacle_kind(o) == kind for o in collision.obstacles)


def enforce_clearance(report: dict[str, Any] | None, policy: str, source: str) -> None:
    """Raise the infeasible-plan error (exit 3) for a plan closer than ``clearance`` unless
    ``policy`` ([check] limits) is ``"report"``."""
    if not report or report["within_clearance"] or policy == "report":
        return
    first, second = report["pair"].split(" – ")
    least = report["min_clearance_m"]
    raise PlanningError(
        f"{source}: the plan brings {first} to {least * 1e3:.1f} mm {'into' if least < 0 else 'from'} {second} at "
        f"t = {report['t_s']:.3f} s, below [collision] clearance = {report['clearance_m'] * 1e3:.1f} mm; nothing was "
        "written. Raise [collision] gain or activation (a resolved-rate plan), move the path or the start away from "
        "it, or, to write the plan and inspect it, set [check] limits = \"report\" (or --set check.limits=report)")
