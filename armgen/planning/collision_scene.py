"""The arm's capsules, the task's obstacles and the plan's closest approach, drawn in a 3-D axes:
the one drawing of the collision model (docs/collision.md) that every planner's figure and
``armgen animate`` use.

- **Capsules** (``robot.collision``, DH or URDF alike): each a cylinder with hemispherical caps,
  light and semi-transparent, at the plotted configuration: its segment's ends through the arm's
  own frames (``robot.frames``), with the axis drawn as a thin line inside.
- **Obstacles** (the task's ``[[obstacles]]`` as ``plan.json`` records them, in the task's units):
  spheres, capsules, boxes, and a half-space as a square patch of its boundary plane as large as
  the scene.
- **The closest approach**: at the time of ``summary.collision`` (the least distance over the
  plan's samples and checked pairs), the pair's two witness points (on the two surfaces; for an
  overlap, the deepest points) joined by a line, labelled with the pair and the distance.

A planner that draws its arm in 2-D views (the snake's top and side views) gets the same shapes
as the outlines of their projections (:func:`draw_capsule_outlines`, :func:`draw_obstacles_2d`,
:func:`draw_approach_2d`), with obstacles named by their index among the task's ``[[obstacles]]``
where its own vocabulary shares that list (``indices``).

The witness points come from the same geometry as the collision functions
(:mod:`armgen.symbolic.collision_geometry`), evaluated at the plan's sample, so the marker's
length is the distance ``plan.json`` reports. Everything is drawn in mm, as the other 3-D panels.
A robot without capsules and a task without obstacles get no scene (:func:`plan_scene` is None):
their figures are unchanged.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np
from matplotlib.patches import Polygon
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from pydantic import ValidationError
from scipy.spatial import ConvexHull

from ..description.collision import (BoxObstacle, CapsuleObstacle, Obstacle, PlaneObstacle, SphereObstacle,
                                     obstacle_kind)
from ..description.frames import rpy_matrix
from ..errors import PlanFileError
from ..robot import Robot
from ..symbolic import collision_geometry as geometry
from .common.collision import CollisionFields, obstacles_si
from .common.schema import Units

MM = 1e3  # the scene is drawn in mm
CAPSULE_COLOUR = "tab:cyan"
CAPSULE_ALPHA = 0.25  # light: the links and the other capsules stay visible through a capsule
OBSTACLE_COLOUR = "0.45"
OBSTACLE_ALPHA = 0.3
APPROACH_COLOUR = "tab:red"
# Facets of a capsule's surface: around its axis, and rings per hemispherical cap. 16 × 6 reads
# as round at the figures' sizes and keeps an animation frame of 20 capsules under ~4 000 facets.
FACETS_AROUND = 16
RINGS_PER_CAP = 6
# The second view of the closest approach looks across the gap from this little above the
# horizontal: low enough that the gap is seen near its true length, high enough to see the table.
ACROSS_ELEVATION_DEG = 12.0
# A half-space whose unit normal leans out of a 2-D view's plane by more than this is not seen
# edge-on: its projection covers the whole view, and the view does not draw it. Rounding of a
# normal given in the view's plane stays far below.
EDGE_ON_TOL = 1e-9
# A summary pair: "capsule 2 – capsule 4" or "capsule 1 – obstacles[0] (sphere)".
PAIR = re.compile(r"^capsule (\d+) – (?:capsule (\d+)|obstacles\[(\d+)\] \((\w+)\))$")


@dataclass(frozen=True)
class ClosestApproach:
    """The plan's least distance: at ``sample`` (time ``t``, s) between the two surfaces of
    ``pair``, ``distance`` (m, negative for an overlap) between ``points`` (2 × 3, m, base frame:
    the first shape's witness point, then the second's)."""

    sample: int
    t: float
    pair: str
    distance: float
    points: np.ndarray


@dataclass(frozen=True)
class Scene:
    """What a plan's figures draw of its collision model: the robot's capsules (when it has a
    usable collision model), the task's obstacles (SI, base frame) and the closest approach
    (None when ``plan.json`` has no ``summary.collision``)."""

    robot: Robot
    obstacles: tuple[Obstacle, ...]
    approach: ClosestApproach | None
    # each obstacle's index among the task's [[obstacles]] (None: 0, 1, …), for a planner whose
    # [[obstacles]] also hold its own vocabulary (the snake's tube obstacles)
    indices: tuple[int, ...] | None = None

    @property
    def has_capsules(self) -> bool:
        return self.robot.has_collision

    @property
    def names(self) -> list[str]:
        return obstacle_names(self.obstacles, self.indices)


def plan_scene(result, robot: Robot, q: np.ndarray, obstacles: tuple[Obstacle, ...] | None = None,
               indices: tuple[int, ...] | None = None) -> Scene | None:
    """The :class:`Scene` of a plan (``result``, a PlanResult, with its ``plan.json``; ``q`` its
    joint values per sample), None when there is nothing to draw: no capsules and no obstacles.
    ``obstacles`` (SI, base frame) with their ``indices`` among the task's ``[[obstacles]]`` for a
    planner whose ``[[obstacles]]`` also hold its own vocabulary, drawn by its own figures (the
    snake's tube obstacles); default: the task's, all of the collision vocabulary."""
    meta = result.metadata
    obstacles = task_obstacles(meta) if obstacles is None else obstacles
    if not robot.has_collision and not obstacles:
        return None
    report = (meta.get("summary") or {}).get("collision")
    approach = None
    if isinstance(report, dict) and robot.has_collision and "pair" in report and "t_s" in report:
        sample = int(np.argmin(np.abs(result.column("t_s") - float(report["t_s"]))))
        approach = closest_approach(robot, q[sample], obstacles, str(report["pair"]), sample, float(report["t_s"]),
                                    indices)
    return Scene(robot, obstacles, approach, indices)


def task_obstacles(meta: dict) -> tuple[Obstacle, ...]:
    """The obstacles of the task ``plan.json`` records (``task.obstacles`` in ``task.units``), SI."""
    task = meta.get("task")
    if not isinstance(task, dict) or not task.get("obstacles"):
        return ()
    units = task.get("units") if isinstance(task.get("units"), dict) else {}
    try:
        fields = CollisionFields.model_validate({"obstacles": task["obstacles"]})
        # a PTP task's [units] gives the angle only: its lengths are in m
        units = Units(length=units.get("length", "m"), angle=units.get("angle", "rad"))
    except ValidationError as exc:
        raise PlanFileError(f"plan.json: task.obstacles: {exc.errors()[0]['msg']}; it is not what `armgen plan` "
                            "wrote: re-run `armgen plan`") from None
    return obstacles_si(fields.obstacles, units)


def obstacle_names(obstacles: tuple[Obstacle, ...], indices: tuple[int, ...] | None = None) -> list[str]:
    """Each obstacle as the task and ``summary.collision`` name it: ``obstacles[2] (box)``, by its
    index among the task's [[obstacles]] (``indices``; default 0, 1, …)."""
    indices = range(len(obstacles)) if indices is None else indices
    return [f"obstacles[{k}] ({obstacle_kind(o)})" for k, o in zip(indices, obstacles)]


# -- the closest approach ------------------------------------------------------------------


@lru_cache(maxsize=None)
def _witness_functions() -> dict[str, ca.Function]:
    """The collision functions' witness geometry as numeric functions of one pair: a capsule's
    axis ``[a, b]`` against a segment (a capsule's axis, a sphere's centre twice), a half-space
    (unit normal, offset) or a box (centre, axes, half-extents); each returns the axis distance,
    the axis' witness point and the unit direction in which the distance grows as it moves."""
    a, b = ca.SX.sym("a", 3), ca.SX.sym("b", 3)

    def function(name: str, others: list[ca.SX], witness: geometry.Witness) -> ca.Function:
        point = a + witness.parameter * (b - a)
        return ca.Function(name, [a, b, *others], [witness.distance, point, witness.normal])

    c, e = ca.SX.sym("c", 3), ca.SX.sym("e", 3)
    normal, offset = ca.SX.sym("n", 3), ca.SX.sym("offset")
    centre, axes, half = ca.SX.sym("centre", 3), ca.SX.sym("R", 3, 3), ca.SX.sym("half", 3)
    return {"segment": function("segment", [c, e], geometry.segment_segment_witness(a, b, c, e)),
            "plane": function("plane", [normal, offset], geometry.segment_halfspace_witness(a, b, normal, offset)),
            "box": function("box", [centre, axes, half], geometry.segment_box_witness(a, b, centre, axes, half))}


def capsule_ends(robot: Robot, frames: np.ndarray) -> np.ndarray:
    """Each capsule's segment ends (capsules × 2 × 3, m, base frame) at one configuration's
    ``robot.frames``."""
    ends = []
    for capsule in robot.collision.capsules:
        pose = frames[capsule.frame]
        ends.append([pose[:3, :3] @ np.asarray(end, dtype=float) + pose[:3, 3] for end in (capsule.a, capsule.b)])
    return np.array(ends).reshape(-1, 2, 3)


def closest_approach(robot: Robot, q: np.ndarray, obstacles: tuple[Obstacle, ...], pair: str, sample: int = 0,
                     t: float = 0.0, indices: tuple[int, ...] | None = None) -> ClosestApproach:
    """The witness points of ``pair`` (``summary.collision``'s name of it) at joint values ``q``;
    ``indices`` as in :func:`obstacle_names`."""
    match = PAIR.match(pair)
    if match is None:
        raise PlanFileError(f"plan.json: summary.collision.pair = {pair!r} names no pair of capsules or obstacles; "
                            "re-run `armgen plan`")
    first, second, index, kind = match.groups()
    capsules = robot.collision.capsules
    ends = capsule_ends(robot, robot.frames(np.asarray(q, dtype=float)))
    i = int(first)
    j = int(second) if second is not None else None
    indices = list(range(len(obstacles)) if indices is None else indices)
    if index is not None:  # the obstacle's place in ``obstacles`` (past the end: not there)
        index = indices.index(int(index)) if int(index) in indices else len(obstacles)
    if i >= len(capsules) or (j is not None and j >= len(capsules)) or (
            index is not None and (index >= len(obstacles) or obstacle_kind(obstacles[index]) != kind)):
        raise PlanFileError(f"plan.json: summary.collision.pair = {pair!r} names a capsule or obstacle the robot "
                            f"'{robot.name}' and the task do not have; re-run `armgen plan`")
    functions = _witness_functions()
    a, b = ends[i]
    if j is not None:
        axis, point, normal = functions["segment"](a, b, *ends[j])
        radii = capsules[j].radius
    else:
        obstacle = obstacles[index]
        if isinstance(obstacle, SphereObstacle):
            axis, point, normal = functions["segment"](a, b, obstacle.centre, obstacle.centre)
            radii = obstacle.radius
        elif isinstance(obstacle, CapsuleObstacle):
            axis, point, normal = functions["segment"](a, b, obstacle.a, obstacle.b)
            radii = obstacle.radius
        elif isinstance(obstacle, BoxObstacle):
            axis, point, normal = functions["box"](a, b, obstacle.centre, rpy_matrix(*obstacle.rpy),
                                                   0.5 * np.asarray(obstacle.size, dtype=float))
            radii = 0.0
        else:
            unit = np.asarray(obstacle.normal, dtype=float) / np.linalg.norm(obstacle.normal)
            axis, point, normal = functions["plane"](a, b, unit, float(unit @ np.asarray(obstacle.point, dtype=float)))
            radii = 0.0
    point, normal = np.asarray(point, dtype=float).ravel(), np.asarray(normal, dtype=float).ravel()
    distance = float(axis) - capsules[i].radius - radii
    # the first surface lies the capsule's radius back from its axis against the direction in
    # which the distance grows; the second a further `distance` along the same line
    near = point - capsules[i].radius * normal
    return ClosestApproach(sample, t, pair, distance, np.array([near, near - distance * normal]))


# -- drawing ---------------------------------------------------------------------------------


def _basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two unit vectors across ``axis`` and its unit direction (z for a zero-length axis)."""
    length = float(np.linalg.norm(axis))
    w = axis / length if length > 0 else np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(w, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(w, u), w


def capsule_surface(a: np.ndarray, b: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The surface of the capsule ``[a, b]``, ``radius`` as (X, Y, Z) grids for ``plot_surface``:
    the cap around ``a`` from its pole to its rim, then the cap around ``b`` from its rim to its
    pole; the band between the two rims is the cylinder. Every point lies ``radius`` from the
    segment."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    u, v, w = _basis(b - a)
    around = np.linspace(0.0, 2.0 * np.pi, FACETS_AROUND + 1)
    ring = np.cos(around)[:, None] * u + np.sin(around)[:, None] * v  # (around, 3)
    rows = []
    for centre, latitudes in ((a, np.linspace(-np.pi / 2, 0.0, RINGS_PER_CAP + 1)),
                              (b, np.linspace(0.0, np.pi / 2, RINGS_PER_CAP + 1))):
        for phi in latitudes:
            rows.append(centre + radius * (np.cos(phi) * ring + np.sin(phi) * w))
    grid = np.array(rows)  # (rings, around, 3)
    return grid[..., 0], grid[..., 1], grid[..., 2]


def draw_capsule(ax, a: np.ndarray, b: np.ndarray, radius: float, name: str, colour: str, alpha: float,
                 axis: bool = True) -> list:
    """One capsule (m) drawn in mm: its surface (gid ``name``) and, with ``axis``, its segment as
    a thin line (gid ``name axis``)."""
    x, y, z = (values * MM for values in capsule_surface(a, b, radius))
    surface = ax.plot_surface(x, y, z, color=colour, alpha=alpha, linewidth=0, shade=True)
    surface.set_gid(name)
    if not axis:
        return [surface]
    axis_line, = ax.plot(*(np.array([a, b]) * MM).T, color=colour, lw=0.8, alpha=0.9)
    axis_line.set_gid(f"{name} axis")
    return [surface, axis_line]


def draw_capsules(ax, robot: Robot, frames: np.ndarray) -> list:
    """The arm's capsules at one configuration (its ``robot.frames``); returns the artists drawn
    (to remove them for the next animation frame)."""
    artists = []
    for k, ((a, b), capsule) in enumerate(zip(capsule_ends(robot, frames), robot.collision.capsules)):
        artists += draw_capsule(ax, a, b, capsule.radius, f"capsule {k}", CAPSULE_COLOUR, CAPSULE_ALPHA)
    return artists


def box_faces(obstacle: BoxObstacle) -> np.ndarray:
    """The six faces of a box obstacle (6 × 4 × 3, m, base frame), each a loop of corners."""
    rotation = rpy_matrix(*obstacle.rpy)
    half = 0.5 * np.asarray(obstacle.size, dtype=float)
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
    corners = (signs * half) @ rotation.T + np.asarray(obstacle.centre, dtype=float)
    loops = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    return corners[np.array(loops)]


def plane_patch(obstacle: PlaneObstacle, centre: np.ndarray, half: float) -> np.ndarray:
    """A square of the half-space's boundary plane (4 × 3, m): centred where ``centre`` (the
    scene's centre) projects onto it, ``2 half`` on a side (the scene's size)."""
    u, v, n = _basis(np.asarray(obstacle.normal, dtype=float))
    point = np.asarray(obstacle.point, dtype=float)
    foot = centre - ((centre - point) @ n) * n
    return np.array([foot + half * (su * u + sv * v) for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def obstacle_extent(obstacles: tuple[Obstacle, ...]) -> np.ndarray:
    """Points (m) that bound the bounded obstacles (spheres, capsules, boxes): for the scene's limits."""
    points = []
    for obstacle in obstacles:
        if isinstance(obstacle, SphereObstacle):
            points += [np.asarray(obstacle.centre) + s * obstacle.radius for s in (-1.0, 1.0)]
        elif isinstance(obstacle, CapsuleObstacle):
            points += [np.asarray(end) + s * obstacle.radius for end in (obstacle.a, obstacle.b) for s in (-1.0, 1.0)]
        elif isinstance(obstacle, BoxObstacle):
            points += list(box_faces(obstacle).reshape(-1, 3))
    return np.array(points, dtype=float).reshape(-1, 3)


def draw_obstacles(ax, obstacles: tuple[Obstacle, ...], centre: np.ndarray, half: float,
                   names: list[str] | None = None) -> list:
    """The task's obstacles (m) drawn in mm, each with the gid of its task name
    (``obstacles[0] (sphere)``, or ``names``); a half-space as its boundary plane's square around
    the scene's ``centre`` (m), ``2 half`` (m) on a side."""
    artists = []
    for obstacle, name in zip(obstacles, names if names is not None else obstacle_names(obstacles)):
        if isinstance(obstacle, SphereObstacle):
            artists += draw_capsule(ax, obstacle.centre, obstacle.centre, obstacle.radius, name, OBSTACLE_COLOUR,
                                    OBSTACLE_ALPHA, axis=False)
            continue
        if isinstance(obstacle, CapsuleObstacle):
            artists += draw_capsule(ax, obstacle.a, obstacle.b, obstacle.radius, name, OBSTACLE_COLOUR, OBSTACLE_ALPHA)
            continue
        faces = box_faces(obstacle) if isinstance(obstacle, BoxObstacle) else plane_patch(obstacle, centre, half)[None]
        patch = Poly3DCollection(faces * MM, facecolor=OBSTACLE_COLOUR, edgecolor="0.3", linewidth=0.4,
                                 alpha=OBSTACLE_ALPHA)
        patch.set_gid(name)
        ax.add_collection3d(patch)
        artists.append(patch)
    return artists


def draw_approach(ax, approach: ClosestApproach) -> list:
    """The closest approach: its witness points joined by a line (gid ``closest approach``),
    labelled with the pair, the distance and the time."""
    points = approach.points * MM
    label = f"closest approach {approach.distance * MM:.1f} mm: {approach.pair} (t = {approach.t:.2f} s)"
    line, = ax.plot(*points.T, "-o", color=APPROACH_COLOUR, lw=1.6, ms=4, label=label)
    line.set_gid("closest approach")
    text = ax.text(*points.mean(axis=0), f" {approach.distance * MM:.1f} mm", color=APPROACH_COLOUR, fontsize=7)
    return [line, text]


def capsule_outline(a: np.ndarray, b: np.ndarray, radius: float) -> np.ndarray:
    """The outline (k × 2) of a capsule's projection onto a coordinate plane, given its projected
    ends ``a``, ``b`` (2-D): exactly the stadium of that radius around the projected segment (a
    disc for a zero-length one)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    axis = b - a
    start = np.arctan2(axis[1], axis[0]) + np.pi / 2 if np.hypot(*axis) > 0 else 0.0
    half = np.linspace(0.0, -np.pi, FACETS_AROUND // 2 + 1)  # from the left side round the end
    around = lambda centre, angles: centre + radius * np.column_stack([np.cos(angles), np.sin(angles)])  # noqa: E731
    return np.vstack([around(b, start + half), around(a, start - np.pi + half)])


def draw_capsule_outlines(ax, robot: Robot, frames: np.ndarray, view: tuple[int, int], offset: np.ndarray) -> list:
    """The arm's capsules at one configuration in a 2-D view (coordinates ``view`` of the base
    frame shifted by ``offset``, m; drawn in mm): each the outline of its projection, light and
    semi-transparent, with the gid ``capsule k``; returns the patches."""
    i, j = view
    patches = []
    for k, ((a, b), capsule) in enumerate(zip(capsule_ends(robot, frames) + offset, robot.collision.capsules)):
        outline = capsule_outline(a[[i, j]], b[[i, j]], capsule.radius) * MM
        patch = Polygon(outline, closed=True, facecolor=CAPSULE_COLOUR, edgecolor=CAPSULE_COLOUR, alpha=CAPSULE_ALPHA,
                        lw=0.6)
        patch.set_gid(f"capsule {k}")
        ax.add_patch(patch)
        patches.append(patch)
    return patches


def draw_approach_2d(ax, approach: ClosestApproach, view: tuple[int, int], offset: np.ndarray) -> list:
    """The closest approach's marker in a 2-D view (as :func:`draw_capsule_outlines`)."""
    i, j = view
    points = (approach.points + offset)[:, [i, j]] * MM
    label = f"closest approach {approach.distance * MM:.1f} mm: {approach.pair} (t = {approach.t:.2f} s)"
    line, = ax.plot(*points.T, "-o", color=APPROACH_COLOUR, lw=1.6, ms=3, label=label)
    line.set_gid("closest approach")
    return [line]


def obstacle_outline(obstacle: Obstacle, view: tuple[int, int], limits: np.ndarray) -> np.ndarray | None:
    """The outline (k × 2, m) of an obstacle's projection onto the coordinate plane ``view``: a
    sphere's disc and a capsule's stadium (:func:`capsule_outline`), a box's the convex hull of its
    corners' projections; a half-space seen edge-on (its normal in the view's plane) the part of
    ``limits`` (the view's ``[[x0, x1], [y0, y1]]``, m) on its solid side. None where nothing
    shows: a half-space seen otherwise, whose projection covers the whole view, or one whose solid
    side misses ``limits``."""
    i, j = view
    if isinstance(obstacle, SphereObstacle):
        centre = np.asarray(obstacle.centre, dtype=float)[[i, j]]
        return capsule_outline(centre, centre, obstacle.radius)
    if isinstance(obstacle, CapsuleObstacle):
        return capsule_outline(np.asarray(obstacle.a, dtype=float)[[i, j]], np.asarray(obstacle.b, dtype=float)[[i, j]],
                               obstacle.radius)
    if isinstance(obstacle, BoxObstacle):
        corners = box_faces(obstacle).reshape(-1, 3)[:, [i, j]]
        return corners[ConvexHull(corners).vertices]
    normal = np.asarray(obstacle.normal, dtype=float) / np.linalg.norm(obstacle.normal)
    if abs(normal[3 - i - j]) > EDGE_ON_TOL:
        return None
    across = normal[[i, j]] / np.linalg.norm(normal[[i, j]])
    height = lambda p: float((p - np.asarray(obstacle.point, dtype=float)[[i, j]]) @ across)  # noqa: E731
    (x0, x1), (y0, y1) = limits
    rectangle = [np.array(corner) for corner in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))]
    kept = []  # the rectangle clipped to the solid side (height ≤ 0), corner by corner
    for p, q in zip(rectangle, rectangle[1:] + rectangle[:1]):
        if height(p) <= 0:
            kept.append(p)
        if height(p) * height(q) < 0:  # the boundary crosses this edge
            kept.append(p + height(p) / (height(p) - height(q)) * (q - p))
    return np.array(kept) if len(kept) >= 3 else None


def draw_obstacles_2d(ax, obstacles: tuple[Obstacle, ...], view: tuple[int, int], offset: np.ndarray,
                      names: list[str] | None = None) -> list:
    """The task's obstacles in a 2-D view (as :func:`draw_capsule_outlines`: coordinates ``view`` of
    the base frame shifted by ``offset``, m; drawn in mm), each the outline of its projection
    (:func:`obstacle_outline`; a half-space within the axes' current limits, so set them first)
    with the gid of its task name (or ``names``, as :func:`draw_obstacles`); returns the patches."""
    i, j = view
    limits = np.array([ax.get_xlim(), ax.get_ylim()]) / MM - np.asarray(offset, dtype=float)[[i, j]][:, None]
    patches = []
    for obstacle, name in zip(obstacles, names if names is not None else obstacle_names(obstacles)):
        outline = obstacle_outline(obstacle, view, limits)
        if outline is None:
            continue
        patch = Polygon((outline + np.asarray(offset, dtype=float)[[i, j]]) * MM, closed=True,
                        facecolor=OBSTACLE_COLOUR, edgecolor="0.3", alpha=OBSTACLE_ALPHA, lw=0.6)
        patch.set_gid(name)
        ax.add_patch(patch)
        patches.append(patch)
    return patches


def scene_points(scene: Scene, frames: np.ndarray) -> np.ndarray:
    """Points (m) the scene's limits must hold besides the arm's frame origins: the capsules'
    surfaces' extremes in ``frames`` (one configuration or several) and the bounded obstacles."""
    points = [obstacle_extent(scene.obstacles)]
    if scene.has_capsules:
        radii = np.array([c.radius for c in scene.robot.collision.capsules])
        for pose in np.asarray(frames).reshape(-1, *np.shape(frames)[-3:]):
            ends = capsule_ends(scene.robot, pose)
            points += [(ends + sign * radii[:, None, None]).reshape(-1, 3) for sign in (-1.0, 1.0)]
    if scene.approach is not None:
        points.append(scene.approach.points)
    return np.vstack(points)


def scene_panel(ax, scene: Scene, frames: np.ndarray, tool_path: np.ndarray | None, clearance: float | None,
                across: bool = False) -> None:
    """The arm at the closest approach (``frames``: its ``robot.frames`` there) in a 3-D axes:
    the links between the joint frames, the capsules, the obstacles, the marker, and the
    executed tool path (m) for orientation; a cube around all of them, in mm. With ``across``
    the camera looks across the marker (horizontally at right angles to it, from a little above),
    where the gap shows at its true length."""
    origins = frames[:, :3, 3]
    points = np.vstack([origins, scene_points(scene, frames)] + ([tool_path] if tool_path is not None else []))
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre, half = 0.5 * (lo + hi), max(0.5 * float(np.max(hi - lo)), 1e-3)
    low, high = MM * (centre - half), MM * (centre + half)
    ax.set(xlim=(low[0], high[0]), ylim=(low[1], high[1]), zlim=(low[2], high[2]), xlabel="x [mm]", ylabel="y [mm]",
           zlabel="z [mm]")
    ax.set_box_aspect((1, 1, 1), zoom=0.85)
    ax.tick_params(labelsize=6)
    if tool_path is not None:
        ax.plot(*(tool_path * MM).T, color="tab:red", lw=0.8, alpha=0.6, label="executed tool path")
    ax.plot(*(origins * MM).T, "-o", color="tab:blue", lw=2.5, ms=3, label="links (joint frames)")
    if scene.has_capsules:
        draw_capsules(ax, scene.robot, frames)
    draw_obstacles(ax, scene.obstacles, centre, half, scene.names)
    title = "the arm's capsules and the task's obstacles"
    if scene.approach is not None:
        draw_approach(ax, scene.approach)
        title = f"closest approach at t = {scene.approach.t:.2f} s: {scene.approach.distance * MM:.1f} mm"
        if clearance is not None:
            title += f" (clearance {clearance * MM:.3g} mm)"
        if across:
            gap = scene.approach.points[1] - scene.approach.points[0]
            # a vertical gap (a table below) shows from any side: keep the default azimuth then
            azimuth = np.degrees(np.arctan2(gap[1], gap[0])) + 90.0 if np.hypot(gap[0], gap[1]) > 1e-9 else -60.0
            ax.view_init(elev=ACROSS_ELEVATION_DEG, azim=azimuth)
            title = "the same, viewed across the gap"
    ax.set_title(title, fontsize=9)
    if not across:
        ax.legend(fontsize=7, loc="upper left")
