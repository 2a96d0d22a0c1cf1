"""``armgen plot`` for snake plans (spec 50): the arm drawn along its path at several instants
in separate small panels (like the paper's figures: top view, plus a side view when the path
leaves the plane; each view zoomed to the arm and path), the universal-joint angles over time
with each joint's limits, and the accuracy traces (tip deviation,
worst chord error, smallest clearance).

The arm is redrawn from the CSV's feed and joint angles by the robot's forward kinematics (the
same numpy chain the planner checks against), so the figure shows what the angles do, not what
the solver intended; the path is the spline through the waypoints stored in ``plan.json``. A
snake robot with capsules adds the shared collision row (:mod:`armgen.planning.collision_scene`):
the links' capsules at their closest approach, to each other or to the task's obstacles of the
collision vocabulary (sphere, capsule, box by centre, plane: docs/collision.md), in the robot's
base frame. Those obstacles are drawn in the snapshots and the animation too, by the same module
(the outline of each one's projection), where the task file puts them.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Rectangle

from pydantic import ValidationError

from ...description.collision import Obstacle
from ...errors import PlanFileError
from ...robot import Robot
from ..animation import SCENE_MARGIN
from ..collision_scene import (draw_approach_2d, draw_capsule_outlines, draw_obstacles_2d, obstacle_names, plan_scene,
                               task_obstacles)
from ..plotting import (SCENE_HEIGHT_IN, collision_row, collision_view, joint_style, limit_lines, new_figure,
                        plan_robot)
from ..result import PlanResult
from .config import translated
from .schema import Obstacle as ObstacleEntry, is_capsule_checked
from .spline import HermiteSpline

INSTANTS = 6  # arm poses drawn, evenly spaced over the motion
PLANAR_TOL = 1e-9  # m: a path whose z spread is below this is drawn in one (top) view
FLOOR = 1e-14  # mm, floor of the log-scale accuracy traces (exact solver: ~1e-13 mm; below is rounding)
# mm: an accuracy trace that stays below this is rounding (the exact solver reaches ~1e-13 mm;
# 1 pm is far below any physical tolerance and far above double rounding of metre-sized
# chains): the panel says "exact to <its maximum>" instead of drawing the noise.
ROUNDING_MM = 1e-9
# The accuracy traces' colours: distinct from each other and from the arm (tab:blue).
ACCURACY_COLOURS = {"tip": "tab:purple", "chord": "tab:brown", "clearance": "tab:green"}
VIEW_MARGIN = 0.06  # of the largest extent: room around the arm and path in each snapshot


def arm_centres(result: PlanResult, meta: dict, robot: Robot | None = None) -> np.ndarray:
    """The joint centres (m) of every sample, by the forward kinematics of ``robot`` (default:
    the plan's, :func:`~armgen.planning.plotting.plan_robot`)."""
    from .arm import snake_arm

    arm = snake_arm(robot if robot is not None else plan_robot(result), "plan.json")
    return arm.joint_centres(snake_joint_values(result, arm))[0] + rail_place(meta, arm)


def rail_place(meta: dict, arm) -> np.ndarray:
    """Where the figures put the robot's base frame (m): the rail's start from ``plan.json``
    less the base joint's centre at feed 0 (``arm``: :func:`~.arm.snake_arm`)."""
    return np.asarray(meta["rail"]["start_m"], dtype=float) - arm.base0


def snake_joint_values(result: PlanResult, arm) -> np.ndarray:
    """The robot's joint vector per sample (the rail's feed, then α and β of each link), from
    the plan's columns (``arm``: the plan robot's :func:`~.arm.snake_arm`)."""
    n = arm.n_links
    alpha = np.column_stack([result.column(f"a{i + 1}_rad") for i in range(n)])
    beta = np.column_stack([result.column(f"b{i + 1}_rad") for i in range(n)])
    return arm.q_vector(result.column("feed_m"), alpha, beta)


def vocabulary_obstacles(meta: dict, place: np.ndarray) -> tuple[tuple[Obstacle, ...], tuple[int, ...]]:
    """The task's obstacles of the collision vocabulary as ``plan.json`` records the task (its
    ``[[obstacles]]`` in its units), SI, moved into the robot's base frame as the planner measures
    them (the base at ``place``, :func:`rail_place`), with their indices among the task's
    ``[[obstacles]]`` (where the tube's count too)."""
    task = meta.get("task")
    entries = task.get("obstacles") if isinstance(task, dict) else None
    if not entries:
        return (), ()
    try:
        checked = [k for k, entry in enumerate(entries) if is_capsule_checked(ObstacleEntry.model_validate(entry))]
    except ValidationError as exc:
        raise PlanFileError(f"plan.json: task.obstacles: {exc.errors()[0]['msg']}; it is not what `armgen plan` "
                            "wrote: re-run `armgen plan`") from None
    fields = [{key: value for key, value in entries[k].items() if key != "name"} for k in checked]
    obstacles = task_obstacles({"task": {"obstacles": fields, "units": task.get("units") or {}}})
    return tuple(translated(obstacle, -np.asarray(place, dtype=float)) for obstacle in obstacles), tuple(checked)


def draw_obstacles(ax, obstacles: list[dict], view: tuple[int, int]) -> None:
    i, j = view
    # plates are drawn across the tank that holds them (else 4 opening radii each side)
    extent = {k: (ob["min_mm"][k], ob["max_mm"][k]) for ob in obstacles if ob["type"] == "tank" for k in range(3)}
    for ob in obstacles:
        kind = ob["type"]
        style = dict(color="0.55", alpha=0.45, lw=0)
        if kind == "box":
            lo, hi = np.array(ob["min_mm"]), np.array(ob["max_mm"])
            ax.add_patch(Rectangle((lo[i], lo[j]), hi[i] - lo[i], hi[j] - lo[j], **style))
        elif kind == "cylinder" and view == (0, 1):
            c = ob["centre_mm"]
            ax.add_patch(Circle((c[0], c[1]), ob["diameter_mm"] / 2, **style))
        elif kind == "plate":
            p, n, r = np.array(ob["point_mm"]), np.array(ob["normal"]), ob["opening_diameter_mm"] / 2
            if abs(n[i]) > 0.99:  # plate seen edge-on: a line with its opening as a gap
                lo, hi = extent.get(j, (p[j] - 4 * r, p[j] + 4 * r))
                ax.plot([p[i], p[i]], [lo, p[j] - r], color="0.3", lw=2.5, solid_capstyle="butt")
                ax.plot([p[i], p[i]], [p[j] + r, hi], color="0.3", lw=2.5, solid_capstyle="butt")
        elif kind == "tank":
            lo, hi = np.array(ob["min_mm"]), np.array(ob["max_mm"])
            ax.add_patch(Rectangle((lo[i], lo[j]), hi[i] - lo[i], hi[j] - lo[j], fill=False, ec="0.3", lw=1.2))


def _view_limits(points: np.ndarray, i: int, j: int) -> tuple[tuple[float, float], tuple[float, float]]:
    """Axis limits around the arm and path in view (i, j), with a margin, so the motion fills the panel."""
    lo, hi = points[:, [i, j]].min(axis=0), points[:, [i, j]].max(axis=0)
    pad = VIEW_MARGIN * max(float(np.max(hi - lo)), 1.0)
    return (lo[0] - pad, hi[0] + pad), (lo[1] - pad, hi[1] + pad)


def accuracy_panel(ax, result: PlanResult, t: np.ndarray) -> None:
    """Tip deviation and worst chord error (log scale), or "exact to …" when they are rounding
    only, and the smallest clearance on a twin axis; one legend, one colour per trace."""
    exact: dict[str, float] = {}  # label -> its maximum [mm], for the traces that are rounding only
    for key, column, label in (("tip", "tip_dev_m", "tip deviation from the path"),
                               ("chord", "chord_err_max_m", "worst chord error")):
        values = np.nan_to_num(result.column(column) * 1e3, nan=np.inf)
        if np.max(values) < ROUNDING_MM:
            exact[label] = float(np.max(values))
        else:
            ax.semilogy(t, np.maximum(values, FLOOR), color=ACCURACY_COLOURS[key], lw=1.0, label=f"{label} [mm]")
    title = "accuracy (forward kinematics on the recovered angles)"
    if exact:
        bound = max(exact.values())
        ax.text(0.5, 0.55, "exact to rounding:\n" + "\n".join(f"{label} ≤ {value:.1e} mm" for label, value in exact.items()),
                transform=ax.transAxes, ha="center", va="center", fontsize=10, bbox={"fc": "white", "ec": "0.7"})
        title += f": exact to {bound:.0e} mm"
    handles, labels = ax.get_legend_handles_labels()
    clear = result.column("clearance_min_m")
    if np.all(np.isfinite(clear)):
        ax2 = ax.twinx()
        (line,) = ax2.plot(t, clear * 1e3, color=ACCURACY_COLOURS["clearance"], lw=1.0)
        ax2.set_ylabel("smallest clearance [mm]")
        handles, labels = handles + [line], labels + ["smallest clearance [mm] (right axis)"]
    if handles:
        ax.legend(handles, labels, fontsize=8, loc="upper left")
    if len(exact) == 2:  # nothing on the left axis: no ticks that would suggest a scale
        ax.set_yticks([])
    else:
        ax.grid(alpha=0.3)
    ax.set(xlabel="t [s]", title=title)


def plot_snake(result: PlanResult, robot: Robot | None = None) -> Figure:
    """The figure; the arm through ``robot``'s kinematics (default: the plan's, :func:`plan_robot`)."""
    from .arm import snake_arm

    meta = result.metadata
    if "rail" not in meta or "path" not in meta:
        raise PlanFileError("plan.json lacks the snake planner's rail/path metadata; re-run `armgen plan`")
    robot = robot if robot is not None else plan_robot(result)
    place = rail_place(meta, snake_arm(robot, "plan.json"))
    obstacles, indices = vocabulary_obstacles(meta, place)
    t = result.column("t_s")
    centres = arm_centres(result, meta, robot) * 1e3
    path = meta["path"]
    wp = np.asarray(path["waypoints_m"], dtype=float)
    spline = HermiteSpline(wp, path.get("start_tangent"), path.get("end_tangent"))
    dense = spline.position(np.linspace(0, spline.length, 4000)) * 1e3
    planar = np.ptp(wp[:, 2]) < PLANAR_TOL
    views = [((0, 1), "top (x–y)")] if planar else [((0, 1), "top (x–y)"), ((0, 2), "side (x–z)")]
    n = sum(1 for c in result.columns if c.startswith("a") and c.endswith("_rad"))
    instants = np.unique(np.linspace(0, t.size - 1, INSTANTS).round().astype(int))
    # two panel columns: (top, side) per instant, or the instants of a planar path row by row
    panels = [(k, view) for k in instants for view in views]
    rows = -(-len(panels) // 2)
    everything = np.vstack([centres.reshape(-1, 3), dense])
    limits = {view: _view_limits(everything, *view) for view, _ in views}
    (x0, x1), (y0, y1) = limits[views[0][0]]
    panel_h = min(max(7.5 * (y1 - y0) / (x1 - x0), 1.1), 4.0) + 0.6  # the data's aspect at 7.5 in wide
    collision = _collision_view(result, robot, obstacles, indices)
    heights = [rows * panel_h + 0.5, 4.7] + ([SCENE_HEIGHT_IN] if collision is not None else [])
    fig = new_figure(16, sum(heights))
    snapshots, traces, *below = fig.subfigures(len(heights), 1, height_ratios=heights)
    grid = snapshots.add_gridspec(rows, 2)
    for p, (k, (view, name)) in enumerate(panels):
        i, j = view
        ax = snapshots.add_subplot(grid[p // 2, p % 2])
        xlim, ylim = limits[view]
        ax.set(xlim=xlim, ylim=ylim, aspect="equal")  # first: a half-space seen edge-on fills them
        draw_obstacles(ax, meta.get("obstacles", []), view)
        draw_obstacles_2d(ax, obstacles, view, place, obstacle_names(obstacles, indices))
        if collision is not None:  # the links' capsules, where the snapshots place the arm
            draw_capsule_outlines(ax, collision.robot, collision.robot.frames(collision.q[k]), view, place)
        ax.plot(dense[:, i], dense[:, j], color="k", lw=0.8, ls="--", label="path (spline)")
        ax.plot(centres[k, :, i], centres[k, :, j], "-o", color="tab:blue", ms=2.5, lw=2.5, label="arm")
        ax.plot(centres[k, 0, i], centres[k, 0, j], "s", ms=6, color="tab:green", label="base joint")
        ax.plot(centres[k, -1, i], centres[k, -1, j], "*", ms=11, color="tab:red", label="tip")
        ax.set_title(f"t = {t[k]:.1f} s, {name}", fontsize=9)
        ax.tick_params(labelsize=7)
        ax.set_xlabel(f"{'xyz'[i]} [mm]", fontsize=8)
        ax.set_ylabel(f"{'xyz'[j]} [mm]", fontsize=8)
        ax.grid(alpha=0.3)
        if p == 0:
            ax.legend(fontsize=6, loc="upper left", ncol=4)
    snapshots.suptitle("the arm at evenly spaced instants (obstacles grey, plates edge-on with their openings)",
                       fontsize=10)
    ax_angles, ax_acc = traces.subplots(1, 2)
    names = [f"α{i + 1}" for i in range(n)] + [f"β{i + 1}" for i in range(n)]
    for i in range(n):  # robot joint 2i+1 is α_{i+1}, 2i+2 is β_{i+1}: one colour per joint
        ax_angles.plot(t, np.degrees(result.column(f"a{i + 1}_rad")), lw=1.0, ls="-",
                       color=joint_style(2 * i)["color"], label=names[i])
        ax_angles.plot(t, np.degrees(result.column(f"b{i + 1}_rad")), lw=1.0, ls=":",
                       color=joint_style(2 * i + 1)["color"], label=names[n + i])
    qlim = meta.get("robot", {}).get("qlim_rad", [])
    if len(qlim) == 2 * n + 1:
        order = [name for pair in zip(names[:n], names[n:]) for name in pair]
        limit_lines(ax_angles, [tuple(np.degrees(lim)) for lim in qlim[1:]], order, t[-1])
    ax_angles.set(xlabel="t [s]", ylabel="joint angle [deg]",
                  title="universal-joint angles (α solid, β dotted; limits dashed in each joint's colour)")
    ax_angles.legend(fontsize=6, ncol=6, loc="lower left")
    ax_angles.grid(alpha=0.3)
    accuracy_panel(ax_acc, result, t)
    if below:
        collision_row(below[0], result, collision)
    summary = meta.get("summary", {})
    fig.suptitle(f"{meta.get('robot', {}).get('name', '')} — {summary.get('solver', '')} solver, {summary.get('driven', '')} "
                 f"driven — max tip deviation {summary.get('max_tip_deviation_mm', float('nan')):.3g} mm — max |angle| "
                 f"{summary.get('max_abs_joint_angle_deg', float('nan')):.1f}°")
    return fig


def _collision_view(result: PlanResult, robot: Robot, obstacles: tuple[Obstacle, ...], indices: tuple[int, ...]):
    """The shared collision row's view of a snake plan on a robot with capsules (its links against
    each other and the task's ``obstacles`` of the collision vocabulary, base frame, with their
    ``indices`` in the file: :func:`vocabulary_obstacles`; the tube's obstacles are drawn in the
    snapshots), else None. Drawn in the robot's base frame (the snapshots place the rail's start)."""
    if "collision" not in result.metadata.get("summary", {}):
        return None
    from .arm import snake_arm

    return collision_view(result, robot, snake_joint_values(result, snake_arm(robot, "plan.json")), obstacles, indices)


def animation_scene(fig, result: PlanResult, frames: np.ndarray, robot: Robot):
    """The animation's scene of a snake plan (:func:`armgen.planning.animation.animate_plan`): the
    arm's centre line in top view (and side view when the path leaves the plane) with the path and
    the obstacles (the tube's, and those of the collision vocabulary); returns the function that
    draws frame ``f``."""
    from .arm import snake_arm

    meta = result.metadata
    centres = arm_centres(result, meta, robot)[frames] * 1e3
    wp = np.asarray(meta["path"]["waypoints_m"], dtype=float) * 1e3
    views = [(0, 1)] if np.ptp(wp[:, 2]) < PLANAR_TOL else [(0, 1), (0, 2)]
    # a robot with capsules: its links' outlines in each view, moving with the arm, the task's
    # obstacles of the collision vocabulary and the closest approach of its links to each other or
    # to them (collision_scene, in the snapshots' place)
    arm = snake_arm(robot, "plan.json")
    q = snake_joint_values(result, arm)
    place = rail_place(meta, arm)
    scene = plan_scene(result, robot, q, *vocabulary_obstacles(meta, place))
    poses = robot.frames(q[frames]) if scene is not None and scene.has_capsules else None
    outlines: list = []
    lines = []
    for v, (i, j) in enumerate(views):
        ax = fig.add_subplot(len(views), 1, v + 1)
        everything = np.vstack([centres.reshape(-1, 3), wp])
        lo, hi = everything.min(axis=0), everything.max(axis=0)
        pad = SCENE_MARGIN * float(np.max(hi - lo))
        ax.set(xlim=(lo[i] - pad, hi[i] + pad), ylim=(lo[j] - pad, hi[j] + pad), aspect="equal",
               xlabel=f"{'xyz'[i]} [mm]", ylabel=f"{'xyz'[j]} [mm]", title=("top view", "side view")[v])
        draw_obstacles(ax, meta.get("obstacles", []), (i, j))
        if scene is not None:  # after the limits: a half-space seen edge-on fills them
            draw_obstacles_2d(ax, scene.obstacles, (i, j), place, scene.names)
        ax.plot(wp[:, i], wp[:, j], "k--", lw=0.8, label="path")
        ax.tick_params(labelsize=6)
        links, = ax.plot([], [], "-o", color="tab:blue", lw=2.5, ms=2.5)
        tip, = ax.plot([], [], "*", color="tab:red", ms=10)
        if scene is not None and scene.approach is not None:
            draw_approach_2d(ax, scene.approach, (i, j), place)
            ax.legend(fontsize=6, loc="upper left")
        lines.append((ax, links, tip, i, j))

    def draw(f: int) -> None:
        for artist in outlines:
            artist.remove()
        outlines.clear()
        for ax, links, tip, i, j in lines:
            links.set_data(centres[f, :, i], centres[f, :, j])
            tip.set_data([centres[f, -1, i]], [centres[f, -1, j]])
            if poses is not None:
                outlines.extend(draw_capsule_outlines(ax, robot, poses[f], (i, j), place))
    return draw
