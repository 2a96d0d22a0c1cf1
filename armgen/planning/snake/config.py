"""The snake planner's task file (``planner = "snake"``), parsed into a :class:`SnakeTask` (SI
units), and the velocity law of the driven end."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...errors import RobotFileError, TaskFileError, excerpt
from ...robot import load_robot
from .arm import SnakeArm, snake_arm
from .dynamics import METHODS as INTEGRATORS
from .obstacles import FACES, Obstacle

SOLVERS = ("exact", "denoised")
DRIVEN = ("base", "tip")
STATES = ("link", "absolute")
LENGTH_SCALE = {"m": 1.0, "mm": 1e-3}
ANGLE_SCALE = {"rad": 1.0, "deg": math.pi / 180.0}

# Waypoints closer than this (1 % of a link) are duplicates: a near-zero chord knot interval
# makes the Hermite form divide by it and the spline loop between much longer neighbours.
MIN_WAYPOINT_SPACING = 1e-3  # m
# The path must run along the rail over the base's travel within this (1 µm): the base joint rides
# the straight rail line, the path is where the other joints ride. The C² spline rings from the
# first bend into its straight rail part, by 4e-8 m (tank) and 3e-9 m (planar) over the bundled
# examples' feed; a path that really leaves the rail is off by millimetres.
RAIL_TOL = 1e-6  # m
MAX_SAMPLES = 1_000_000

# The paper's link: 40 mm OD aluminium tube, 2 mm wall (spec 50: ≈ 0.067 kg per 104 mm link).
DEFAULT_LINK = {"outer_diameter": 0.040, "wall": 0.002, "density": 2700.0, "EA": 1e9}


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


_TOP_FIELDS = {"planner", "description", "robot", "units", "path", "rail", "motion", "solver", "links", "obstacles",
               "check"}
_PATH_FIELDS = {"waypoints", "start_tangent", "end_tangent"}
_RAIL_FIELDS = {"start"}
_MOTION_FIELDS = {"driven", "v", "duration", "ramp", "output_step"}
_SOLVER_FIELDS = {"method", "h", "integrator", "rtol", "atol", "state", "max_wall_time"}
_LINK_FIELDS = {"outer_diameter", "wall", "density", "EA"}
_OBSTACLE_FIELDS = {"name", "type", "min", "max", "centre", "axis", "diameter", "point", "normal",
                    "opening_diameter", "faces"}


@dataclass
class SnakeTask:
    arm: SnakeArm
    waypoints: np.ndarray  # (m+1, 3) m, world
    start_tangent: np.ndarray | None
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
    tube_radius: float
    link_mass: float
    EA: float
    link_props: dict[str, float]
    obstacles: list[Obstacle] = field(default_factory=list)
    source: str = ""


class _Fields:
    def __init__(self, source: str, ls: float):
        self.source, self.ls = source, ls

    def fail(self, name: str, message: str) -> TaskFileError:
        return TaskFileError(f"{self.source}: field '{name}' {message}")

    def table(self, doc: dict, key: str, allowed: set[str], required: bool = False) -> dict:
        if key not in doc:
            if required:
                raise self.fail(key, f"is missing; add a [{key}] table (see docs/snake.md)")
            return {}
        value = doc[key]
        if not isinstance(value, dict):
            raise self.fail(key, f"must be a table ([{key}])")
        unknown = set(value) - allowed
        if unknown:
            raise self.fail(key, f"has unknown field(s) {', '.join(sorted(unknown))}; allowed: {', '.join(sorted(allowed))}")
        return value

    def number(self, table: dict, key: str, where: str, default: float | None = None, positive: bool = False,
               nonneg: bool = False, fix: str = "") -> float:
        name = f"{where}.{key}"
        if key not in table:
            if default is None:
                raise self.fail(name, f"is missing{'; ' + fix if fix else ''}")
            return default
        value = table[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.fail(name, f"= {excerpt(repr(value))} must be a finite number")
        if positive and value <= 0:
            raise self.fail(name, f"= {value} must be > 0{'; ' + fix if fix else ''}")
        if nonneg and value < 0:
            raise self.fail(name, f"= {value} must be ≥ 0{'; ' + fix if fix else ''}")
        return float(value)

    def choice(self, table: dict, key: str, where: str, choices: tuple[str, ...], default: str) -> str:
        value = table.get(key, default)
        if value not in choices:
            raise self.fail(f"{where}.{key}", f"= {excerpt(repr(value))} is not one of {', '.join(choices)}")
        return value

    def point(self, value: Any, name: str, scale: float) -> np.ndarray:
        if (not isinstance(value, list) or len(value) != 3
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
            raise self.fail(name, f"must be [x, y, z] (three finite numbers), got {excerpt(repr(value))}")
        return np.array(value, dtype=float) * scale

    def direction(self, value: Any, name: str) -> np.ndarray | None:
        if value == "natural":
            return None
        d = self.point(value, name, 1.0)
        if np.linalg.norm(d) == 0:
            raise self.fail(name, "is the zero vector; give a direction such as [1, 0, 0] or \"natural\"")
        return d / np.linalg.norm(d)


def _parse_obstacle(f: _Fields, raw: Any, k: int) -> Obstacle:
    where = f"obstacles[{k}]"
    if not isinstance(raw, dict):
        raise f.fail(where, "must be a table ([[obstacles]])")
    unknown = set(raw) - _OBSTACLE_FIELDS
    if unknown:
        raise f.fail(where, f"has unknown field(s) {', '.join(sorted(unknown))}; allowed: {', '.join(sorted(_OBSTACLE_FIELDS))}")
    kind = f.choice(raw, "type", where, ("box", "cylinder", "plate", "tank"), "")
    name = raw.get("name", f"{kind} {k + 1}")
    if not isinstance(name, str) or not name:
        raise f.fail(f"{where}.name", "must be a non-empty string")
    ls = f.ls
    if kind in ("box", "tank"):
        lo, hi = f.point(raw.get("min"), f"{where}.min", ls), f.point(raw.get("max"), f"{where}.max", ls)
        if np.any(lo >= hi):
            raise f.fail(where, "needs min < max in every coordinate")
        faces: tuple[str, ...] = ()
        if kind == "tank":
            faces_raw = raw.get("faces", list(FACES))
            if not isinstance(faces_raw, list) or any(x not in FACES for x in faces_raw):
                raise f.fail(f"{where}.faces", f"= {excerpt(repr(faces_raw))} must list faces from {', '.join(FACES)}")
            faces = tuple(faces_raw)
        return Obstacle(name, kind, lo, hi, faces=faces)
    if kind == "cylinder":
        axis = f.direction(raw.get("axis", [0, 0, 1]), f"{where}.axis")
        d = f.number(raw, "diameter", where, positive=True)
        return Obstacle(name, kind, f.point(raw.get("centre"), f"{where}.centre", ls), axis, 0.5 * d * ls)
    normal = f.direction(raw.get("normal"), f"{where}.normal")
    d = f.number(raw, "opening_diameter", where, 0.0, nonneg=True)
    return Obstacle(name, kind, f.point(raw.get("point"), f"{where}.point", ls), normal, 0.5 * d * ls)


def parse_snake_task(task: dict[str, Any], source: str) -> SnakeTask:
    unknown = set(task) - _TOP_FIELDS
    if unknown:
        raise TaskFileError(f"{source}: unknown field(s) {', '.join(sorted(unknown))}; allowed: {', '.join(sorted(_TOP_FIELDS))}")
    robot_name = task.get("robot", "snake12")
    if not isinstance(robot_name, str):
        raise TaskFileError(f"{source}: field 'robot' must be a bundled robot name or a robot file path")
    try:
        robot = load_robot(robot_name)
    except RobotFileError as exc:
        raise TaskFileError(f"{source}: field 'robot': {exc}") from None
    f0 = _Fields(source, 1.0)
    units = f0.table(task, "units", {"length", "angle"})
    lunit = f0.choice(units, "length", "units", tuple(LENGTH_SCALE), "m")
    f0.choice(units, "angle", "units", tuple(ANGLE_SCALE), "rad")
    ls = LENGTH_SCALE[lunit]
    f = _Fields(source, ls)
    arm = snake_arm(robot, source)

    path = f.table(task, "path", _PATH_FIELDS, required=True)
    raw_wp = path.get("waypoints")
    if not isinstance(raw_wp, list) or len(raw_wp) < 2:
        raise f.fail("path.waypoints", "must be a list of at least two [x, y, z] points")
    waypoints = np.array([f.point(p, f"path.waypoints[{k}]", ls) for k, p in enumerate(raw_wp)])
    _check_spacing(f, waypoints)
    rail = f.table(task, "rail", _RAIL_FIELDS)
    rail_start = f.point(rail["start"], "rail.start", ls) if "start" in rail else waypoints[0].copy()
    if np.linalg.norm(waypoints[0] - rail_start) > RAIL_TOL:
        raise f.fail("path.waypoints[0]", f"= {mm(waypoints[0])} mm is not the rail start {mm(rail_start)} mm; "
                     "the path begins where the base joint starts (set rail.start or the first waypoint)")
    start_tangent = f.direction(path.get("start_tangent", arm.rail_dir.tolist()), "path.start_tangent")
    end_tangent = f.direction(path.get("end_tangent", "natural"), "path.end_tangent")

    motion = f.table(task, "motion", _MOTION_FIELDS, required=True)
    driven = f.choice(motion, "driven", "motion", DRIVEN, "base")
    v = f.number(motion, "v", "motion", positive=True, fix="give the cruise speed (the paper: 120 mm/s)") * ls
    duration = f.number(motion, "duration", "motion", 10.0, positive=True)
    ramp = f.number(motion, "ramp", "motion", 1.0, positive=True)
    if 2 * ramp > duration:
        raise f.fail("motion.ramp", f"= {ramp} s: two ramps do not fit in motion.duration = {duration} s; "
                     "choose ramp ≤ duration / 2")
    output_step = f.number(motion, "output_step", "motion", 0.01, positive=True)
    samples = duration / output_step
    if samples > MAX_SAMPLES or abs(samples - round(samples)) > 1e-9 * samples:
        raise f.fail("motion.output_step", f"= {output_step} s must divide motion.duration = {duration} s into at most "
                     f"{MAX_SAMPLES} steps")

    solver = f.table(task, "solver", _SOLVER_FIELDS)
    method = f.choice(solver, "method", "solver", SOLVERS, "exact")
    h = f.number(solver, "h", "solver", 0.1, nonneg=True)
    integrator = f.choice(solver, "integrator", "solver", tuple(INTEGRATORS), "RK45" if h > 0 else "Radau")
    links = f.table(task, "links", _LINK_FIELDS)
    od = f.number(links, "outer_diameter", "links", DEFAULT_LINK["outer_diameter"] / ls, positive=True) * ls
    wall = f.number(links, "wall", "links", DEFAULT_LINK["wall"] / ls, positive=True) * ls
    if 2 * wall > od:
        raise f.fail("links.wall", "is more than half the outer diameter; give the tube's wall thickness")
    density = f.number(links, "density", "links", DEFAULT_LINK["density"], positive=True)
    EA = f.number(links, "EA", "links", DEFAULT_LINK["EA"], positive=True)
    mass = density * math.pi / 4 * (od ** 2 - (od - 2 * wall) ** 2) * arm.link

    raw_obs = task.get("obstacles", [])
    if not isinstance(raw_obs, list):
        raise f.fail("obstacles", "must be an array of tables ([[obstacles]])")
    obstacles = [_parse_obstacle(f, raw, k) for k, raw in enumerate(raw_obs)]
    return SnakeTask(
        arm=arm, waypoints=waypoints, start_tangent=start_tangent, end_tangent=end_tangent, rail_start=rail_start,
        driven=driven, law=VelocityLaw(v, duration, ramp), output_step=output_step, solver=method, h=h,
        integrator=integrator, rtol=f.number(solver, "rtol", "solver", 1e-3, positive=True),
        atol=f.number(solver, "atol", "solver", 1e-6, positive=True),
        state=f.choice(solver, "state", "solver", STATES, "link"),
        max_wall_time=f.number(solver, "max_wall_time", "solver", 60.0, positive=True),
        tube_radius=od / 2, link_mass=mass, EA=EA,
        link_props={"outer_diameter_m": od, "wall_m": wall, "density_kg_m3": density, "EA_N": EA, "mass_kg": mass,
                    "length_m": arm.link},
        obstacles=obstacles, source=source)


def mm(p: np.ndarray) -> list[float]:
    return [round(float(x) * 1e3, 3) for x in p]


def _close_pair(points: np.ndarray, spacing: float) -> tuple[int, int] | None:
    """The first pair (i < j, by j then i) of points closer than ``spacing``: a sweep along x."""
    order = np.argsort(points[:, 0], kind="stable")
    xs = points[order, 0]
    found: list[tuple[int, int]] = []
    for a in range(len(order)):
        b = a + 1
        while b < len(order) and xs[b] - xs[a] < spacing:
            if np.linalg.norm(points[order[a]] - points[order[b]]) < spacing:
                found.append(tuple(sorted((int(order[a]), int(order[b])))))
            b += 1
    return min(found, key=lambda p: (p[1], p[0])) if found else None


def _check_spacing(f: _Fields, waypoints: np.ndarray) -> None:
    """Any two waypoints (not only neighbours) closer than MIN_WAYPOINT_SPACING are an error."""
    pair = _close_pair(waypoints, MIN_WAYPOINT_SPACING)
    if pair is not None:
        i, j = pair
        dist = float(np.linalg.norm(waypoints[i] - waypoints[j]))
        what = "duplicates" if dist == 0 else f"is only {dist * 1e3:.3g} mm from"
        raise f.fail(f"path.waypoints[{j}]", f"= {mm(waypoints[j])} mm {what} path.waypoints[{i}]; waypoints must be "
                     f"at least {MIN_WAYPOINT_SPACING * 1e3:g} mm apart (remove or merge it)")
