"""The snake task's typed configuration (:class:`SnakeTask`, SI units), the velocity law of the
driven end, and :func:`configure`, which makes the task from the validated task file
(:class:`~.schema.SnakeTaskFile`) and its robot: it reads the snake structure from the robot
(:func:`~.arm.snake_arm`), converts lengths to m and resolves the defaults that depend on the
robot (the start tangent along the rail, the link mass from the link length)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from types import SimpleNamespace
from typing import Optional

import numpy as np

from ...description.collision import BoxObstacle, CapsuleObstacle, SphereObstacle, obstacle_parameters
from ...robot import Robot
from ..common.collision import BoxEntry, CapsuleEntry, PlaneEntry, SphereEntry, TaskCollision, configure_collision
from .arm import SnakeArm, snake_arm
from .obstacles import FACES, Obstacle
from .schema import (DEFAULT_OUTER_DIAMETER_M, DEFAULT_WALL_M, Obstacle as ObstacleEntry, SnakeTaskFile,
                     is_capsule_checked)

DEFAULT_CYLINDER_AXIS = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class VelocityLaw:
    """The paper's law: ``ṡ = ½ v (1 − cos(π t / t_r))`` up to ``t_r``, ``v``, then
    ``½ v (1 + cos(π (t − T + t_r) / t_r))`` to rest at ``T`` (``t_r = 1 s``, ``T = 10 s``:
    ``½ v (1 + sin((t + 3/2)π))`` and ``½ v (1 + sin((t − 17/2)π))`` as the spec writes it).
    Travel ``v (T − t_r)``."""

    v: float
    duration: float
    ramp: float

    @property
    def travel(self) -> float:
        return self.v * (self.duration - self.ramp)

    def __call__(self, t):
        """(s, ṡ, s̈) relative to the start, vectorised over ``t``."""
        t = np.asarray(t, dtype=float)
        v, T, r = self.v, self.duration, self.ramp
        w = math.pi / r
        up = t <= r
        down = t > T - r
        u = np.where(down, np.minimum(t, T) - (T - r), 0.0)
        s = np.where(up, 0.5 * v * (t - np.sin(w * t) / w),
                     np.where(down, 0.5 * v * r + v * (T - 2 * r) + 0.5 * v * (u + np.sin(w * u) / w),
                              0.5 * v * r + v * (t - r)))
        sd = np.where(up, 0.5 * v * (1 - np.cos(w * t)), np.where(down, 0.5 * v * (1 + np.cos(w * u)), v))
        sdd = np.where(up, 0.5 * v * w * np.sin(w * t), np.where(down, -0.5 * v * w * np.sin(w * u), 0.0))
        after = t > T
        s = np.where(after, self.travel, s)
        sd = np.where(after, 0.0, sd)
        sdd = np.where(after, 0.0, sdd)
        return s, sd, sdd

    def scalar(self, t: float) -> tuple[float, float, float]:
        """Fast scalar form for the ODE right-hand side."""
        v, T, r = self.v, self.duration, self.ramp
        w = math.pi / r
        if t <= r:
            return 0.5 * v * (t - math.sin(w * t) / w), 0.5 * v * (1 - math.cos(w * t)), 0.5 * v * w * math.sin(w * t)
        if t <= T - r:
            return 0.5 * v * r + v * (t - r), v, 0.0
        if t <= T:
            u = t - (T - r)
            return (0.5 * v * r + v * (T - 2 * r) + 0.5 * v * (u + math.sin(w * u) / w),
                    0.5 * v * (1 + math.cos(w * u)), -0.5 * v * w * math.sin(w * u))
        return self.travel, 0.0, 0.0


@dataclass(frozen=True)
class SnakeTask:
    """A ``planner = "snake"`` task, SI units."""

    arm: SnakeArm
    waypoints: np.ndarray  # (m+1, 3) m, world
    start_tangent: np.ndarray | None  # unit; None: natural
    end_tangent: np.ndarray | None
    rail_start: np.ndarray
    driven: str
    law: VelocityLaw
    output_step: float
    solver: str
    h: float
    integrator: str
    rtol: float
    atol: float
    state: str
    max_wall_time: float
    outer_diameter: float  # m, the link tube
    wall: float  # m
    density: float  # kg/m³
    EA: float  # N
    link_mass: float  # kg
    obstacles: tuple[Obstacle, ...] = ()  # the tube's (box by min/max, cylinder, plate, tank)
    # the links' capsules against the collision vocabulary's obstacles (in the robot's base frame)
    # and [collision]'s clearance: None for a robot without capsules
    collision: TaskCollision | None = None
    # per obstacle of ``collision``, its index among the task's [[obstacles]]
    collision_indices: tuple[int, ...] = ()
    source: str = ""

    @property
    def tube_radius(self) -> float:
        return self.outer_diameter / 2

    @property
    def link_props(self) -> dict[str, float]:
        """The links' record in plan.json."""
        return {"outer_diameter_m": self.outer_diameter, "wall_m": self.wall, "density_kg_m3": self.density,
                "EA_N": self.EA, "mass_kg": self.link_mass, "length_m": self.arm.link}


def _unit(value: list[float] | tuple[float, ...]) -> np.ndarray:
    d = np.array(value, dtype=float)
    return d / np.linalg.norm(d)


def _direction(value: list[float] | str | None, default: Optional[np.ndarray]) -> np.ndarray | None:
    """A unit direction, None for \"natural\", ``default`` when the file leaves it out."""
    if value is None:
        return default
    return None if value == "natural" else _unit(value)


def _obstacle(entry: ObstacleEntry, k: int, ls: float) -> Obstacle:
    """One ``[[obstacles]]`` entry in SI (its fields checked by the schema for its type)."""
    name = entry.name or f"{entry.type} {k + 1}"
    if entry.type in ("box", "tank"):
        faces = tuple(entry.faces if entry.faces is not None else FACES) if entry.type == "tank" else ()
        return Obstacle(name, entry.type, np.array(entry.min, dtype=float) * ls, np.array(entry.max, dtype=float) * ls,
                        faces=faces)
    if entry.type == "cylinder":
        axis = _unit(entry.axis if entry.axis is not None else DEFAULT_CYLINDER_AXIS)
        return Obstacle(name, entry.type, np.array(entry.centre, dtype=float) * ls, axis, 0.5 * entry.diameter * ls)
    opening = entry.opening_diameter if entry.opening_diameter is not None else 0.0
    return Obstacle(name, entry.type, np.array(entry.point, dtype=float) * ls, _unit(entry.normal), 0.5 * opening * ls)


_COMMON_ENTRIES = {"sphere": (SphereEntry, ("centre", "radius")), "capsule": (CapsuleEntry, ("a", "b", "radius")),
                   "box": (BoxEntry, ("centre", "size", "rpy")), "plane": (PlaneEntry, ("point", "normal"))}


def _collision(model: SnakeTaskFile, robot: Robot, place: np.ndarray, source: str) -> tuple[TaskCollision | None,
                                                                                             tuple[int, ...]]:
    """The task's collision-vocabulary obstacles and ``[collision]`` as the other planners read them
    (:func:`~armgen.planning.common.collision.configure_collision`: a robot without capsules
    refused, and so are such obstacles without ``[collision]`` or beyond the robot's slots), moved
    from the task's frame into the robot's base frame (the base sits at ``place``), and their
    indices among the task's [[obstacles]]."""
    indices = tuple(k for k, entry in enumerate(model.obstacles) if is_capsule_checked(entry))
    entries = []
    for k in indices:
        entry = model.obstacles[k]
        kind, fields = _COMMON_ENTRIES[entry.type]
        entries.append(kind(type=entry.type, **{f: getattr(entry, f) for f in fields if getattr(entry, f) is not None}))
    found = configure_collision(SimpleNamespace(obstacles=entries, collision=model.collision, units=model.units),
                                robot, source)
    if found is None:
        return None, ()
    moved = tuple(translated(obstacle, -place) for obstacle in found.obstacles)
    return replace(found, obstacles=moved, parameters=obstacle_parameters(moved, robot.collision.slots)), indices


def translated(obstacle, shift: np.ndarray):
    """An obstacle of armgen.description.collision translated by ``shift`` (m)."""
    def by(point) -> tuple[float, float, float]:
        return tuple(float(v) for v in np.asarray(point, dtype=float) + shift)

    if isinstance(obstacle, SphereObstacle):
        return replace(obstacle, centre=by(obstacle.centre))
    if isinstance(obstacle, CapsuleObstacle):
        return replace(obstacle, a=by(obstacle.a), b=by(obstacle.b))
    if isinstance(obstacle, BoxObstacle):
        return replace(obstacle, centre=by(obstacle.centre))
    return replace(obstacle, point=by(obstacle.point))  # a PlaneObstacle


def configure(model: SnakeTaskFile, robot: Robot, source: str) -> SnakeTask:
    """The task's :class:`SnakeTask` on ``robot`` (which must be a snake arm of spec 50)."""
    ls = model.length_scale
    arm = snake_arm(robot, source)
    waypoints = np.array(model.path.waypoints, dtype=float) * ls
    rail_start = np.array(model.rail.start, dtype=float) * ls if model.rail.start is not None else waypoints[0].copy()
    motion, solver, links = model.motion, model.solver, model.links
    od = links.outer_diameter * ls if links.outer_diameter is not None else DEFAULT_OUTER_DIAMETER_M
    wall = links.wall * ls if links.wall is not None else DEFAULT_WALL_M
    mass = links.density * math.pi / 4 * (od ** 2 - (od - 2 * wall) ** 2) * arm.link
    collision, indices = _collision(model, robot, rail_start - arm.base0, source)
    return SnakeTask(
        arm=arm, waypoints=waypoints, start_tangent=_direction(model.path.start_tangent, _unit(arm.rail_dir.tolist())),
        end_tangent=_direction(model.path.end_tangent, None), rail_start=rail_start, driven=motion.driven,
        law=VelocityLaw(motion.v * ls, motion.duration, motion.ramp), output_step=motion.output_step,
        solver=solver.method, h=solver.h, integrator=solver.integrator or ("RK45" if solver.h > 0 else "Radau"),
        rtol=solver.rtol, atol=solver.atol, state=solver.state, max_wall_time=solver.max_wall_time,
        outer_diameter=od, wall=wall, density=links.density, EA=links.EA, link_mass=mass,
        obstacles=tuple(_obstacle(entry, k, ls) for k, entry in enumerate(model.obstacles)
                        if not is_capsule_checked(entry)),
        collision=collision, collision_indices=indices, source=source)
