"""Snake-arm tip following along a spline (spec 50): planner ``"snake"``.

Pipeline: task file → robot structure (rail feed + universal joints) → path spline and rail
(:mod:`.snake_spline`) → joint-centre coordinates over time by the exact geometric solver
(:mod:`.snake_exact`) or the paper's denoised multi-link dynamics (:mod:`.snake_dynamics`) →
universal-joint angles (signed form) → forward kinematics on those angles → tip deviation,
chord errors, obstacle clearance (:mod:`.snake_obstacles`), speeds → CSV + metadata.

The task file may use mm/deg (``[units]``); everything is SI inside. See ``docs/snake.md``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...errors import PlanningError, RobotFileError, TaskFileError, excerpt
from ...robot import Robot, load_robot
from ..result import PlanResult
from .dynamics import EXPLICIT_METHODS, METHODS as INTEGRATORS, BarModel, DenoisedDynamics, DynamicsRun
from .exact import joint_rates, solve_exact
from .obstacles import FACES, Obstacle, clearances
from .spline import HermiteSpline, Track

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
# Joint-angle limits are enforced up to this (rounding of atan2 of exact chords).
ANGLE_LIMIT_TOL = 1e-9  # rad
# The exact solver must meet every chord to this (1e-9 mm, the spec's bar); it reaches ~1e-16 m.
EXACT_CHORD_TOL = 1e-12  # m
# Structure check of the robot file: forward kinematics of the DH table and of the universal-joint
# chain A_i = A_{i-1} Rz(α_i) Ry(β_i) must agree to rounding (metres, dimensionless).
STRUCTURE_TOL = 1e-9
MAX_SAMPLES = 1_000_000

# The paper's link: 40 mm OD aluminium tube, 2 mm wall (spec 50: ≈ 0.067 kg per 104 mm link).
DEFAULT_LINK = {"outer_diameter": 0.040, "wall": 0.002, "density": 2700.0, "EA": 1e9}


# -- the velocity law -------------------------------------------------------------------------
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


# -- the robot ----------------------------------------------------------------------------------
def _rz(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(a.shape + (3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1], out[..., 2, 2] = c, -s, s, c, 1.0
    return out


def uj_rotation(alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """R = Rz(α) Ry(β), vectorised."""
    ca, sa, cb, sb = np.cos(alpha), np.sin(alpha), np.cos(beta), np.sin(beta)
    R = np.empty(np.shape(alpha) + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 0, 2] = ca * cb, -sa, ca * sb
    R[..., 1, 0], R[..., 1, 1], R[..., 1, 2] = sa * cb, ca, sa * sb
    R[..., 2, 0], R[..., 2, 1], R[..., 2, 2] = -sb, 0.0, cb
    return R


def dh_frames(robot: Robot, q: np.ndarray) -> np.ndarray:
    """All DH frames after each joint, shape (samples, n, 4, 4), for ``q`` of shape (samples, n)
    (numpy, vectorised over samples; the same chain as the symbolic core)."""
    q = np.atleast_2d(q)
    N = q.shape[0]
    T = np.broadcast_to(robot.base, (N, 4, 4)).copy()
    out = np.empty((N, robot.n, 4, 4))
    for i, j in enumerate(robot.joints):
        ca_, sa_ = math.cos(j.alpha), math.sin(j.alpha)
        rx = np.array([[1, 0, 0, j.a], [0, ca_, -sa_, 0], [0, sa_, ca_, 0], [0, 0, 0, 1.0]])
        if robot.convention == "modified":
            T = T @ rx
        theta = q[:, i] + j.offset if j.revolute else np.full(N, j.theta)
        d = np.full(N, j.d) if j.revolute else j.d + j.offset + q[:, i]
        M = np.zeros((N, 4, 4))
        M[:, :3, :3] = _rz(theta)
        M[:, 2, 3] = d
        M[:, 3, 3] = 1.0
        T = T @ M
        if robot.convention == "standard":
            T = T @ rx
        out[:, i] = T
    return out


@dataclass(frozen=True)
class SnakeArm:
    """A snake arm read from a robot file: joint 1 prismatic (the rail feed), then pairs of
    revolute joints (α_i, β_i) forming universal joints with A_i = A_{i−1} Rz(α_i) Ry(β_i)."""

    robot: Robot
    n_links: int
    link: float  # m
    max_feed: float
    min_feed: float
    rail_dir: np.ndarray  # unit, robot base frame
    base0: np.ndarray  # base joint centre at feed 0, robot base frame
    A0: np.ndarray  # link-0 frame (the rail frame)
    qmin: np.ndarray  # (n_links, 2) α, β
    qmax: np.ndarray

    def q_vector(self, feed: np.ndarray, alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
        q = np.empty((feed.size, 1 + 2 * self.n_links))
        q[:, 0], q[:, 1::2], q[:, 2::2] = feed, alpha, beta
        return q

    def joint_centres(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint centres (samples, n_links + 1, 3) and link frames by forward kinematics of the
        robot's DH table (robot base frame)."""
        frames = dh_frames(self.robot, q)
        idx = [0] + [2 * i + 2 for i in range(self.n_links)]
        picked = frames[:, idx]
        return picked[:, :, :3, 3], picked[:, :, :3, :3]


def snake_arm(robot: Robot, source: str) -> SnakeArm:
    """Check that ``robot`` has the snake structure and extract its data (errors name the fix)."""
    def fail(msg: str) -> TaskFileError:
        return TaskFileError(f"{source}: field 'robot' = {excerpt(repr(robot.name))} is not a snake arm of spec 50 ({msg}); "
                             "use robot = \"snake12\" or a file of the same form (prismatic feed, then α/β pairs)")

    n = robot.n
    if n < 3 or n % 2 == 0:
        raise fail(f"{n} joints; expected 1 + 2·links")
    if robot.joints[0].revolute or not all(j.revolute for j in robot.joints[1:]):
        raise fail("joint 1 must be prismatic and the others revolute")
    n_links = (n - 1) // 2
    lengths = [robot.joints[2 * i + 2].a for i in range(n_links)]
    link = lengths[0]
    if link <= 0 or any(abs(x - link) > STRUCTURE_TOL for x in lengths):
        raise fail(f"link lengths (a of the β joints) {lengths} must be equal and positive")
    N = 3
    zero = np.zeros((1, n))
    frames0 = dh_frames(robot, zero)
    base0 = frames0[0, 0, :3, 3]
    one = zero.copy()
    one[0, 0] = 1.0
    rail_dir = dh_frames(robot, one)[0, 0, :3, 3] - base0
    A0 = frames0[0, 2, :3, :3]
    arm = SnakeArm(robot, n_links, link, robot.joints[0].qlim[1], robot.joints[0].qlim[0], rail_dir, base0, A0,
                   np.array([[robot.joints[1 + 2 * i].qlim[0], robot.joints[2 + 2 * i].qlim[0]] for i in range(n_links)]),
                   np.array([[robot.joints[1 + 2 * i].qlim[1], robot.joints[2 + 2 * i].qlim[1]] for i in range(n_links)]))
    if abs(np.linalg.norm(rail_dir) - 1.0) > STRUCTURE_TOL or np.linalg.norm(A0[:, 0] - rail_dir) > STRUCTURE_TOL:
        raise fail("at q = 0 the arm must lie straight along the feed direction")
    # the DH chain must be the universal-joint chain: compare at deterministic poses
    k = np.arange(1, N + 1)[:, None] * np.arange(1, n + 1)[None, :]
    q = 0.4 * np.sin(0.7 * k)
    centres, frames = arm.joint_centres(q)
    A = np.broadcast_to(A0, (N, 3, 3))
    x = centres[:, 0]
    if np.max(np.abs(x - (base0 + q[:, :1] * rail_dir))) > STRUCTURE_TOL:
        raise fail("joint 1 must carry the base joint centre along the feed")
    for i in range(n_links):
        A = A @ uj_rotation(q[:, 1 + 2 * i], q[:, 2 + 2 * i])
        x = x + link * A[:, :, 0]
        if np.max(np.abs(A - frames[:, i + 1])) > STRUCTURE_TOL or np.max(np.abs(x - centres[:, i + 1])) > STRUCTURE_TOL:
            raise fail(f"joints {2 + 2 * i}/{3 + 2 * i} do not form A_i = A_(i-1) Rz(α) Ry(β) with the link along x")
    if not np.allclose(robot.tool, np.eye(4)):
        raise fail("the tool frame must be the identity (the tip is the last joint centre)")
    return arm


# -- angle recovery -----------------------------------------------------------------------------
def recover_angles(arm: SnakeArm, centres: np.ndarray, rail_start: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Feed and universal-joint angles (signed form) from joint centres (samples, n+1, 3), world
    frame = robot base frame translated so the base joint at feed 0 sits at ``rail_start``:
    with ``(x, y, z)`` link i's unit axis in frame A_{i−1}, ``β = atan2(−z, hypot(x, y))``,
    ``α = atan2(y, x)``, ``A_i = A_{i−1} Rz(α) Ry(β)``."""
    N = centres.shape[0]
    feed = (centres[:, 0] - rail_start) @ arm.rail_dir
    axes = np.diff(centres, axis=1)
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    alpha = np.empty((N, arm.n_links))
    beta = np.empty((N, arm.n_links))
    A = np.broadcast_to(arm.A0, (N, 3, 3))
    for i in range(arm.n_links):
        c = np.einsum("nji,nj->ni", A, axes[:, i])
        beta[:, i] = np.arctan2(-c[:, 2], np.hypot(c[:, 0], c[:, 1]))
        alpha[:, i] = np.arctan2(c[:, 1], c[:, 0])
        A = A @ uj_rotation(alpha[:, i], beta[:, i])
    return feed, alpha, beta


def recover_angles_paper(arm: SnakeArm, centres: np.ndarray, rail_start: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper's form, for contrast: ``β = arccos(e1_i·e3_{i−1}) − π/2``,
    ``α = arccos(cos γ / cos β)`` with ``cos γ = e1_i·e1_{i−1}`` — α loses its sign."""
    N = centres.shape[0]
    feed = (centres[:, 0] - rail_start) @ arm.rail_dir
    axes = np.diff(centres, axis=1)
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    alpha = np.empty((N, arm.n_links))
    beta = np.empty((N, arm.n_links))
    A = np.broadcast_to(arm.A0, (N, 3, 3))
    for i in range(arm.n_links):
        e1 = axes[:, i]
        b = np.arccos(np.clip(np.einsum("nj,nj->n", e1, A[:, :, 2]), -1, 1)) - math.pi / 2
        cos_gamma = np.einsum("nj,nj->n", e1, A[:, :, 0])
        a = np.arccos(np.clip(cos_gamma / np.cos(b), -1, 1))
        alpha[:, i], beta[:, i] = a, b
        A = A @ uj_rotation(a, b)
    return feed, alpha, beta


# -- the task -----------------------------------------------------------------------------------
_TOP_FIELDS = {"planner", "description", "robot", "units", "path", "rail", "motion", "solver", "links", "obstacles"}
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
        raise f.fail("path.waypoints[0]", f"= {_mm(waypoints[0])} mm is not the rail start {_mm(rail_start)} mm; "
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


def _mm(p: np.ndarray) -> list[float]:
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
        raise f.fail(f"path.waypoints[{j}]", f"= {_mm(waypoints[j])} mm {what} path.waypoints[{i}]; waypoints must be "
                     f"at least {MIN_WAYPOINT_SPACING * 1e3:g} mm apart (remove or merge it)")


# -- planning ----------------------------------------------------------------------------------
@dataclass
class SnakeSolution:
    t: np.ndarray
    s: np.ndarray  # (samples, joints)
    sdot: np.ndarray
    solve_s: float  # wall time of the solver (coordinates over time)
    info: dict[str, Any]


def build_track(task: SnakeTask) -> Track:
    arm = task.arm
    spline = HermiteSpline(task.waypoints, task.start_tangent, task.end_tangent)
    arm_length = arm.n_links * arm.link
    if spline.length < arm_length:
        raise TaskFileError(
            f"{task.source}: field 'path.waypoints' gives a path of {spline.length * 1e3:.1f} mm, shorter than the arm "
            f"({arm.n_links} links × {arm.link * 1e3:g} mm = {arm_length * 1e3:g} mm); extend the path (it must hold the "
            "straight arm on the rail plus the travel)")
    return Track(spline, task.rail_start, arm.rail_dir, arm.max_feed)


def initial_coordinates(task: SnakeTask, track: Track) -> np.ndarray:
    """The arm straight on the rail, base joint at the rail's start (feed 0)."""
    return solve_exact(track, np.array([0.0]), "base", task.arm.n_links, task.arm.link)[0]


def _check_feed(task: SnakeTask, track: Track, feed: np.ndarray, t: np.ndarray) -> None:
    arm = task.arm
    over = feed > arm.max_feed
    if np.any(over):
        k = int(np.argmax(over))
        raise PlanningError(
            f"{task.source}: the base would feed {feed.max() * 1e3:.1f} mm (first beyond the rail at t = {t[k]:.2f} s), "
            f"beyond the rail's {arm.max_feed * 1e3:g} mm (robot joint '{arm.robot.joints[0].name}' limit); lower "
            "motion.v or motion.duration (travel = v·(duration − ramp))")
    if np.any(feed < arm.min_feed - RAIL_TOL):
        raise PlanningError(f"{task.source}: the base would leave the rail's start (feed {feed.min() * 1e3:.3f} mm < "
                            f"{arm.min_feed * 1e3:g} mm)")
    offset = track.rail_offset(float(feed.max()))
    if offset > RAIL_TOL:
        raise TaskFileError(
            f"{task.source}: field 'path.waypoints': the path leaves the rail line by {offset * 1e3:.4g} mm within the "
            f"base's travel ({feed.max() * 1e3:.1f} mm of feed); the path must run straight along the rail there (add "
            "collinear waypoints along the rail, or shorten the travel)")


def run_dynamics(task: SnakeTask, track: Track, s0: np.ndarray, t: np.ndarray) -> tuple[DynamicsRun, BarModel]:
    """The paper's multi-link model from rest at ``s0`` over ``t`` (capped at solver.max_wall_time)."""
    arm = task.arm
    driven_index = 0 if task.driven == "base" else arm.n_links
    model = BarModel(arm.link, task.link_mass, task.EA, task.h)
    off = float(s0[driven_index])
    law = task.law

    def driven_law(tt: float) -> tuple[float, float, float]:
        s, sd, sdd = law.scalar(tt)
        return off + s, sd, sdd

    dyn = DenoisedDynamics(track, model, arm.n_links, driven_index, driven_law)
    return dyn.run(s0, t, task.integrator, task.rtol, task.atol, task.max_wall_time, task.state), model


def solve(task: SnakeTask, track: Track, t: np.ndarray) -> SnakeSolution:
    """Joint coordinates over ``t`` with the task's solver (the exact one also as the reference)."""
    arm = task.arm
    s0 = initial_coordinates(task, track)
    driven_index = 0 if task.driven == "base" else arm.n_links
    rel, rel_d, _ = task.law(t)
    s_drv = s0[driven_index] + rel
    if task.driven == "base":
        _check_feed(task, track, s_drv, t)
    elif s_drv[-1] > track.spline.length:
        raise PlanningError(
            f"{task.source}: the tip would travel to path s = {s_drv[-1] * 1e3:.1f} mm, past the path's end at "
            f"{track.spline.length * 1e3:.1f} mm; extend path.waypoints or lower motion.v or motion.duration "
            "(travel = v·(duration − ramp))")
    started = time.perf_counter()
    try:
        s_exact = solve_exact(track, s_drv, task.driven, arm.n_links, arm.link)
    except PlanningError as exc:
        raise PlanningError(f"{task.source}: {exc}") from None
    exact_s = time.perf_counter() - started
    if task.driven == "tip":
        _check_feed(task, track, s_exact[:, 0], t)
    info: dict[str, Any] = {"initial_coordinates_m": s0.tolist()}
    if task.solver == "exact":
        sdot = joint_rates(track, s_exact, rel_d, task.driven)
        return SnakeSolution(t, s_exact, sdot, time.perf_counter() - started, info)
    run, model = run_dynamics(task, track, s0, t)
    info.update(integrator={"method": task.integrator, "rtol": task.rtol, "atol": task.atol, "state": task.state,
                            "h_s": task.h, "a_h": model.a_h, "b_h": model.b_h, "nfev": run.nfev, "njev": run.njev,
                            "wall_s": run.wall_s, "completed": bool(run.completed), "t_reached_s": run.t_reached,
                            "message": run.message, "explicit": task.integrator in EXPLICIT_METHODS},
                exact_reference_s=exact_s)
    if not run.completed:
        raise PlanningError(
            f"{task.source}: the {'stiff ' if task.h == 0 else ''}integration ({task.integrator}, h = {task.h} s) reached "
            f"t = {run.t_reached:.4g} s of {t[-1]:g} s ({run.message}); raise solver.max_wall_time, or use "
            "solver.h > 0 (the denoised model) with an explicit integrator")
    ds = run.s - s_exact
    info["vs_exact"] = {"max_coordinate_diff_mm": float(np.max(np.abs(ds)) * 1e3)}
    return SnakeSolution(t, run.s, run.sdot, run.wall_s, info)


def _locate(track: Track, task: SnakeTask, s: float) -> str:
    k = int(np.argmin(np.abs(track.spline.knots - s)))
    return f"path s = {s * 1e3:.1f} mm, near path.waypoints[{k}] = {_mm(task.waypoints[k])} mm"


def _check_angles(task: SnakeTask, track: Track, sol: SnakeSolution, alpha: np.ndarray, beta: np.ndarray) -> None:
    arm = task.arm
    for which, ang, col in (("α", alpha, 0), ("β", beta, 1)):
        lo, hi = arm.qmin[:, col], arm.qmax[:, col]
        bad = (ang < lo - ANGLE_LIMIT_TOL) | (ang > hi + ANGLE_LIMIT_TOL)
        if np.any(bad):
            excess = np.maximum(ang - hi, lo - ang)
            k, i = np.unravel_index(np.argmax(np.where(bad, excess, -np.inf)), ang.shape)
            joint = arm.robot.joints[1 + 2 * i + col]
            raise PlanningError(
                f"{task.source}: the path bends more than universal joint {i + 1} can: {which}{i + 1} (robot joint "
                f"'{joint.name}') would be {math.degrees(ang[k, i]):.2f}° at t = {sol.t[k]:.2f} s, outside "
                f"[{math.degrees(lo[i]):g}°, {math.degrees(hi[i]):g}°], at {_locate(track, task, float(sol.s[k, i]))}; "
                "widen that bend (larger radius: move or add waypoints) or use a robot with wider joint limits")


def plan_snake(task: SnakeTask, backend: str = "symbolic") -> PlanResult:
    arm = task.arm
    started = time.perf_counter()
    track = build_track(task)
    n_out = int(round(task.law.duration / task.output_step))
    t = np.arange(n_out + 1) * task.output_step
    sol = solve(task, track, t)
    # joint centres, angles (the solver's output) ...
    rec_started = time.perf_counter()
    centres = track.joints(sol.s, 0)[0]
    feed, alpha, beta = recover_angles(arm, centres, task.rail_start)
    recover_s = time.perf_counter() - rec_started
    _check_angles(task, track, sol, alpha, beta)
    # ... and the checks: forward kinematics on the recovered angles
    q = arm.q_vector(feed, alpha, beta)
    place = task.rail_start - arm.base0
    fk_centres = arm.joint_centres(q)[0] + place
    tip = fk_centres[:, -1]
    fk_check = _fk_cross_check(arm, q, tip - place, backend)
    s_tip_guess = sol.s[:, -1]
    _, tip_dev = track.spline.project(tip, s_tip_guess)
    tip_to_planned = np.linalg.norm(tip - centres[:, -1], axis=1)
    chord_err = np.linalg.norm(np.diff(centres, axis=1), axis=2) - arm.link
    if task.solver == "exact" and np.max(np.abs(chord_err)) > EXACT_CHORD_TOL:
        k, i = np.unravel_index(np.argmax(np.abs(chord_err)), chord_err.shape)
        raise PlanningError(f"{task.source}: the exact solver missed link {i + 1}'s chord by {chord_err[k, i]:.3g} m "
                            f"at t = {sol.t[k]:.2f} s ({_locate(track, task, float(sol.s[k, i]))}); the path is not "
                            "smooth enough there (add waypoints)")
    _, ps = track.joints(sol.s, 1)
    speeds = np.linalg.norm(ps, axis=2) * np.abs(sol.sdot)
    clear = clearances(task.obstacles, centres, task.tube_radius) if task.obstacles else {}
    _check_collisions(task, track, sol, clear)
    result = _result(task, sol, feed, alpha, beta, tip, tip_dev, chord_err, speeds, clear)
    result.metadata = _metadata(task, track, sol, alpha, beta, feed, tip_dev, tip_to_planned, chord_err, speeds, clear,
                                fk_centres, centres, fk_check, recover_s, time.perf_counter() - started)
    return result


def _fk_cross_check(arm: SnakeArm, q: np.ndarray, tip_base: np.ndarray, backend: str) -> dict[str, Any]:
    """The robot's generated ``fk`` (CasADi interpreter or compiled C) against the numpy chain."""
    if backend == "symbolic":  # the CasADi interpreter, without importing the code generator
        from ...symbolic.model import ModelOptions, SymbolicModel

        fk = SymbolicModel(arm.robot, ModelOptions(("fk",))).function("fk")
    else:
        from ..backends import make_backend

        fk = make_backend(arm.robot, backend, ("fk",)).functions["fk"]
    try:
        T = np.array(fk.map(q.shape[0])(q.T)).reshape(4, q.shape[0], 4)[:3, :, 3].T
    except Exception:  # a Callback without map support: evaluate sample by sample
        T = np.array([np.array(fk(qk))[:3, 3] for qk in q])
    return {"backend": backend, "max_tip_diff_m": float(np.max(np.abs(T - tip_base)))}


def _check_collisions(task: SnakeTask, track: Track, sol: SnakeSolution, clear: dict[str, np.ndarray]) -> None:
    for name, c in clear.items():
        if np.min(c) < 0:
            k, i = np.unravel_index(np.argmin(c), c.shape)
            raise PlanningError(
                f"{task.source}: link {i + 1} touches obstacle '{name}' at t = {sol.t[k]:.2f} s (clearance "
                f"{c[k, i] * 1e3:.2f} mm, tube radius {task.tube_radius * 1e3:g} mm), at "
                f"{_locate(track, task, float(sol.s[k, i]))}; move the waypoints away from it")


def _columns(n_links: int, n_joints: int) -> list[str]:
    cols = ["t_s", "feed_m"]
    for i in range(n_links):
        cols += [f"a{i + 1}_rad", f"b{i + 1}_rad"]
    cols += [f"sJ{j + 1}_m" for j in range(n_joints)]
    cols += ["base_speed_m_s", "tip_speed_m_s", "tip_x_m", "tip_y_m", "tip_z_m", "tip_dev_m", "chord_err_max_m",
             "clearance_min_m"]
    return cols


def _result(task, sol, feed, alpha, beta, tip, tip_dev, chord_err, speeds, clear) -> PlanResult:
    n = task.arm.n_links
    angles = np.empty((feed.size, 2 * n))
    angles[:, 0::2], angles[:, 1::2] = alpha, beta
    cmin = np.min(np.stack([c.min(axis=1) for c in clear.values()]), axis=0) if clear else np.full(feed.size, np.inf)
    data = np.column_stack([sol.t, feed, angles, sol.s, speeds[:, 0], speeds[:, -1], tip, tip_dev,
                            np.max(np.abs(chord_err), axis=1), cmin])
    return PlanResult(_columns(n, n + 1), data, {})


def _metadata(task, track, sol, alpha, beta, feed, tip_dev, tip_to_planned, chord_err, speeds, clear, fk_centres,
              centres, fk_check, recover_s, total_s) -> dict[str, Any]:
    arm = task.arm
    deg = np.degrees
    summary: dict[str, Any] = {
        "solver": task.solver,
        "driven": task.driven,
        "max_tip_deviation_mm": float(np.max(tip_dev) * 1e3),
        "max_tip_to_planned_point_mm": float(np.max(tip_to_planned) * 1e3),
        "max_chord_error_mm": float(np.max(np.abs(chord_err)) * 1e3),
        "max_chord_error_per_link_mm": (np.max(np.abs(chord_err), axis=0) * 1e3).tolist(),
        "max_joint_centre_fk_error_mm": float(np.max(np.linalg.norm(fk_centres - centres, axis=2)) * 1e3),
        "fk_cross_check": fk_check,
        "max_abs_alpha_deg": deg(np.max(np.abs(alpha), axis=0)).tolist(),
        "max_abs_beta_deg": deg(np.max(np.abs(beta), axis=0)).tolist(),
        "max_abs_joint_angle_deg": float(deg(max(np.max(np.abs(alpha)), np.max(np.abs(beta))))),
        "joint_limit_deg": [float(deg(arm.qmin.min())), float(deg(arm.qmax.max()))],
        "feed_range_mm": [float(feed.min() * 1e3), float(feed.max() * 1e3)],
        "max_base_speed_mm_s": float(np.max(speeds[:, 0]) * 1e3),
        "max_tip_speed_mm_s": float(np.max(speeds[:, -1]) * 1e3),
        "final_tip_mm": _mm(fk_centres[-1, -1]),
        "solve_time_s": sol.solve_s,
        "angle_recovery_time_s": recover_s,
        "solver_and_recovery_time_s": sol.solve_s + recover_s,
        "plan_time_s": total_s,
    }
    if clear:
        summary["min_clearance_mm"] = {name: float(np.min(c) * 1e3) for name, c in clear.items()}
        summary["min_clearance_per_link_mm"] = {name: (np.min(c, axis=0) * 1e3).tolist() for name, c in clear.items()}
    summary.update({k: v for k, v in sol.info.items() if k in ("integrator", "vs_exact", "exact_reference_s")})
    spline = track.spline
    return {
        "method": task.solver,
        "robot": {"name": arm.robot.name, "file": arm.robot.source, "sha256": arm.robot.sha256,
                  "qlim_rad": [list(j.qlim) for j in arm.robot.joints], "links": arm.n_links, "link_m": arm.link},
        "path": {"waypoints": len(task.waypoints), "waypoints_m": task.waypoints.tolist(), "length_m": spline.length,
                 "start_tangent": None if task.start_tangent is None else task.start_tangent.tolist(),
                 "end_tangent": None if task.end_tangent is None else task.end_tangent.tolist(),
                 "max_param_speed": spline.max_speed(),
                 "rail_offset_mm": track.rail_offset(float(feed.max())) * 1e3,
                 "knots_m": spline.knots.tolist()},
        "rail": {"start_m": task.rail_start.tolist(), "direction": arm.rail_dir.tolist(), "max_feed_m": arm.max_feed},
        "motion": {"driven": task.driven, "v_m_s": task.law.v, "duration_s": task.law.duration,
                   "ramp_s": task.law.ramp, "travel_m": task.law.travel, "output_step_s": task.output_step},
        "parameters": {"solver": task.solver, "h_s": task.h, "integrator": task.integrator, "rtol": task.rtol,
                       "atol": task.atol, "state": task.state, "max_wall_time_s": task.max_wall_time},
        "links": task.link_props,
        "obstacles": [o.describe() for o in task.obstacles],
        "summary": summary,
    }


def plan_task(task: dict, source: str, backend: str = "symbolic") -> PlanResult:
    return plan_snake(parse_snake_task(task, source), backend)
