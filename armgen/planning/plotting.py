"""Figure building blocks shared by every planner's plots, and the one way figures are saved.

Every ``plot_*`` function of a planner's ``plots`` module takes a :class:`PlanResult` and
RETURNS a :class:`matplotlib.figure.Figure` built with the object-oriented API (no pyplot
state, safe in threads and notebooks); :func:`save_figure` writes it in the format its
extension names (``.png``, ``.svg``, ``.pdf``), atomically.

Shared panels (the layout of the spec 20 paper's figures): joint angles in degrees with each
joint's own limits dashed in the joint's colour and labelled, joint velocities in deg/s with
their bounds when the plan has any, the task error, and the tool path in 3-D, top and side
view — planned (the task's geometric path rebuilt from ``plan.json``) against executed (forward
kinematics of the plan's joint angles: ``robot.fk`` of the robot ``plan.json`` records, DH or
URDF alike, found by :func:`plan_robot`).
The 2-D views are chosen from the path itself (:func:`principal_views`): face-on to the plane
the path lies in, and edge-on to it, so a circle in the y–z plane is drawn as a circle.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.colors import to_hex
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from pydantic import ValidationError

from ..errors import ArmgenError, PlanFileError, excerpt
from ..fileio import atomic_open
from ..robot import Robot, bundled_robots, load_robot, load_robot_any
from .collision_scene import Scene, plan_scene, scene_panel
from .common.path import path_geometry
from .common.schema import RelativePath, Units
from .common.start import unit_scales
from .result import PlanResult
from .toolpath.schema import ProgramPath
from .toolpath.task import build_program, program_spec

FORMATS = {".png": "png", ".svg": "svg", ".pdf": "pdf"}
DPI = 110  # raster output: legible 8-pt legends at the figure sizes used here
LOG_FLOOR = 1e-12  # where a log-scale trace of only zeros is drawn (a zero would vanish from the axis)
# 25 distinct colours: tab10, then the dark and the mid shades of tab20b's five hue groups, then
# tab20c's dark shades; with a line style that changes every 10 joints, 25+ joints stay apart.
JOINT_COLOURS = ([to_hex(c) for c in colormaps["tab10"].colors]
                 + [to_hex(colormaps["tab20b"].colors[k]) for k in (0, 4, 8, 12, 16, 2, 6, 10, 14, 18)]
                 + [to_hex(colormaps["tab20c"].colors[k]) for k in (0, 4, 8, 12, 16)])
JOINT_LINESTYLES = ("-", "--", "-.")
# A path whose plane normal lies within this angle of a coordinate axis is drawn in that
# coordinate plane (axes x, y, z as labelled); otherwise in its own principal axes.
AXIS_ALIGNED_DEG = 10.0
# Below this ratio of the second to the first principal spread a path is a straight line (or a
# point): every plane through it shows it, and the coordinate plane it is longest in is used.
STRAIGHT_RATIO = 1e-6
# Joint-limit labels: the height of one 7-pt label line as a fraction of the angle panel's
# y span (an angle panel is ~3 in = 216 pt high: 9 pt per line is ~4 %, 5 % leaves a gap).
# Limits closer than that share one label of several lines.
LIMIT_LABEL_LINE_FRACTION = 0.05
# Ticks per axis of the 3-D inset: more crowd the small panel.
INSET_TICKS = 4
# The collision row (the arm at its closest approach) is as tall as the tool-path row and a bit
# more: two 3-D panels, each a cube holding the arm, its capsules and the obstacles.
SCENE_HEIGHT_IN = 6.0
# A path in an error is quoted up to this length: a real deep path fits, a hand-edited
# plan.json's megabyte of name does not.
PATH_EXCERPT_CHARS = 400


class FigureOutputError(ArmgenError):
    """The figure's output path names no supported format (or no file)."""

    exit_code = 2


class FigureWriteError(ArmgenError):
    """The figure could not be written (directory not writable, disk full)."""

    exit_code = 4


def new_figure(width: float, height: float) -> Figure:
    """A figure with constrained layout, detached from pyplot."""
    return Figure(figsize=(width, height), layout="constrained")


def figure_format(out_path: str | Path) -> str:
    """The matplotlib format for ``out_path``'s extension, or a clear error."""
    path = Path(out_path)
    if str(out_path) in ("", "-") or str(out_path).endswith(("/", "\\")):
        raise FigureOutputError(f"output {excerpt(repr(str(out_path)))} is not a file name; give e.g. -o plan.png "
                                f"(formats: {', '.join(FORMATS)})")
    if path.is_dir():  # as for every other output: an existing directory in the way is exit 4
        raise FigureWriteError(f"cannot write {path}: is a directory; choose a file name such as plan.png")
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise FigureOutputError(f"output {excerpt(repr(str(out_path)))}: unknown figure format {excerpt(repr(path.suffix or '(no extension)'))}; "
                                f"use one of {', '.join(FORMATS)}")
    return fmt


def save_figure(fig: Figure, out_path: str | Path) -> Path:
    """Write ``fig`` to ``out_path`` in the format of its extension; the file appears complete or not at all."""
    fmt = figure_format(out_path)
    out = Path(out_path)
    try:
        with atomic_open(out, "wb") as handle:
            fig.savefig(handle, format=fmt, dpi=DPI, metadata={"Date": None} if fmt == "svg" else None)
    except OSError as exc:
        raise FigureWriteError(f"cannot write {out}: {exc.strerror or exc}; choose a writable path") from None
    return out


def joint_style(i: int) -> dict:
    """Colour and line style of joint ``i`` (0-based), distinct for at least 30 joints."""
    return {"color": JOINT_COLOURS[i % len(JOINT_COLOURS)], "ls": JOINT_LINESTYLES[(i // 10) % len(JOINT_LINESTYLES)]}


def joint_count(result: PlanResult) -> int:
    return sum(1 for c in result.columns if c.startswith("q") and c.endswith("_rad") and c[1:-4].isdigit())


def plan_robot(result: PlanResult, plan_file: str | Path | None = None, robot: str | Path | Robot | None = None) -> Robot:
    """The robot a plan was made for, drawn through its own forward kinematics.

    ``robot`` (``--robot``: a robot file, URDF or bundled name) is used as given when its joint
    count fits the plan. Otherwise the robot recorded in ``plan.json`` (``robot.file`` with its
    ``sha256``; a PTP plan records only ``parameters.robot``) is looked for, in this order: the
    recorded path as it is (absolute, or relative to the current folder), relative to the folder
    of ``plan_file`` and to each folder above it (``armgen plan`` ran in one of them), the file's
    name beside ``plan_file``, and the bundled robot of the recorded name. A file counts only
    with the recorded sha256 (the file the plan was made from). None found: a
    :class:`PlanFileError` naming every place looked in and the fix.
    """
    meta = result.metadata
    n = joint_count(result)
    where = str(plan_file) if plan_file is not None else "the plan"
    if robot is not None:
        chosen = load_robot_any(robot)
        if n and chosen.n != n:
            raise PlanFileError(f"--robot {excerpt(str(robot))}: robot '{chosen.name}' has {chosen.n} joints but {where} "
                                f"has {n}; give the robot the plan was made for")
        return chosen
    record = meta.get("robot") if isinstance(meta.get("robot"), dict) else {}
    file, name, sha = (_text(record.get(key)) for key in ("file", "name", "sha256"))
    if meta.get("planner") == "ptp":
        parameters = meta.get("parameters") if isinstance(meta.get("parameters"), dict) else {}
        file = _text(parameters.get("robot"))
        if not file:
            raise PlanFileError(f"{where}: this PTP plan names no robot, so there is no arm to draw; give one with "
                                "--robot FILE, or add robot = \"<name>\" to the task file (its joints named as the "
                                "robot's) and re-run `armgen plan`")
    if not file and not name:
        raise PlanFileError(f"{where}: plan.json names no robot (field 'robot'), so there is no arm to draw; give one "
                            "with --robot FILE or re-run `armgen plan`")
    looked: list[str] = []
    for candidate in _recorded_robot_paths(file or "", plan_file):
        shown = excerpt(str(candidate), PATH_EXCERPT_CHARS)
        try:
            present = candidate.is_file()
        except (OSError, ValueError):  # a name too long for the file system, a NUL byte (a hand-edited plan.json)
            present = False
        if not present:
            looked.append(f"{shown} (not found)")
            continue
        try:
            found = load_robot(candidate)
        except ArmgenError as exc:
            looked.append(f"{shown} (not loadable: {excerpt(str(exc), 120)})")
            continue
        if sha and found.sha256 != sha:
            looked.append(f"{shown} (another sha256 {found.sha256[:12]}…: changed since planning)")
            continue
        return found
    label = name or Path(file).stem
    if label in bundled_robots():
        found = load_robot(label)
        if not sha or found.sha256 == sha:
            return found
        looked.append(f"bundled robot '{label}' (another sha256 {found.sha256[:12]}…: changed since planning)")
    else:
        looked.append(f"the bundled robots (none named {excerpt(repr(label))})")
    recorded = f"robot {excerpt(repr(name or label))}" + (f" from {excerpt(repr(file))}" if file else "")
    raise PlanFileError(f"{where}: plan.json records {recorded}" + (f" (sha256 {sha[:12]}…)" if sha else "")
                        + f"; looked in: {'; '.join(looked)}. Give the robot file with --robot FILE, or re-run "
                        "`armgen plan`")


def _text(value: object) -> str | None:
    """A plan.json string field, or None (absent, empty or not a string: a hand-edited file)."""
    return value if isinstance(value, str) and value else None


def _recorded_robot_paths(file: str, plan_file: str | Path | None) -> list[Path]:
    """Where a recorded robot file may be now (see :func:`plan_robot`), each place once."""
    if not file:
        return []
    recorded = Path(file)
    if recorded.is_absolute():
        return [recorded]
    places = [recorded]
    if plan_file is not None:
        folder = Path(os.path.abspath(plan_file)).parent  # lexically normal: ".." is not a folder above
        places += [above / recorded for above in (folder, *folder.parents)]
        places.append(folder / recorded.name)
    unique: dict[str, Path] = {}
    for place in places:
        unique.setdefault(os.path.normpath(os.path.abspath(place)), place)
    return list(unique.values())


def limit_lines(ax: Axes, limits: list[tuple[float, float]], labels: list[str], x_end: float) -> None:
    """Each joint's lower/upper limit as a dashed line in the joint's colour; joints sharing a
    value share the line, their colours interleaved along it, labelled once at its right end.
    Lines closer than a label's height share one label of several lines (highest on top), so
    no two labels overlap (a Kinova Gen3's 120.3° and 128.9° limits)."""
    groups: dict[float, list[int]] = {}
    for i, (lo, hi) in enumerate(limits):
        for value in (lo, hi):
            groups.setdefault(round(float(value), 6), []).append(i)
    for value, members in groups.items():
        dash = 6.0
        for rank, i in enumerate(members):
            period = dash * len(members)
            ax.axhline(value, color=joint_style(i)["color"], lw=1.0,
                       ls=(rank * dash, (dash, period - dash)))
    ax.autoscale_view()
    y0, y1 = ax.get_ylim()
    line = LIMIT_LABEL_LINE_FRACTION * abs(y1 - y0)
    clusters: list[list[float]] = []
    for value in sorted(groups):  # bottom up: a cluster's label grows upwards from its top line
        if clusters and value - clusters[-1][-1] < line * len(clusters[-1]):
            clusters[-1].append(value)
        else:
            clusters.append([value])
    for cluster in clusters:
        texts = []
        for value in reversed(cluster):
            members = groups[value]
            names = labels[members[0]] if len(members) == 1 else f"{labels[members[0]]}…{labels[members[-1]]}"
            texts.append(f"{names} limit {value:g}°")
        # one colour per label: the cluster's top joint (each line is dashed in its own colours)
        ax.annotate("\n".join(texts), (x_end, cluster[-1]), xytext=(-2, 2), textcoords="offset points",
                    ha="right", va="bottom", fontsize=7, color=joint_style(groups[cluster[-1]][0])["color"])


def angles_panel(ax: Axes, result: PlanResult, n: int, t: np.ndarray) -> None:
    q = np.degrees(np.column_stack([result.column(f"q{i + 1}_rad") for i in range(n)]))
    names = [f"θ{i + 1}" for i in range(n)]
    for i in range(n):
        ax.plot(t, q[:, i], lw=1.2, label=names[i], **joint_style(i))
    qlim = result.metadata.get("robot", {}).get("qlim_rad", [])
    if len(qlim) == n:
        limit_lines(ax, [tuple(np.degrees(lim)) for lim in qlim], names, t[-1])
    ax.set(xlabel="t [s]", ylabel="joint angle [deg]", title="joint angles (limits dashed in each joint's colour)")
    ax.legend(ncol=4, fontsize=7, loc="lower left")
    ax.grid(alpha=0.3)


def velocities_panel(ax: Axes, result: PlanResult, n: int, t: np.ndarray, bound_rad_s: float | None = None,
                     bound_label: str = "") -> None:
    qd = np.degrees(np.column_stack([result.column(f"dq{i + 1}_rad_s") for i in range(n)]))
    for i in range(n):
        ax.plot(t, qd[:, i], lw=1.2, label=f"θ̇{i + 1}", **joint_style(i))
    title = "joint velocities"
    if bound_rad_s is not None:
        bound = float(np.degrees(bound_rad_s))
        for sign in (-1, 1):
            ax.axhline(sign * bound, color="k", ls="--", lw=0.9)
        ax.annotate(f"±{bound:.3g}°/s {bound_label}", (t[-1], bound), xytext=(-2, -10), textcoords="offset points",
                    ha="right", fontsize=7)
        over = np.abs(qd) > bound
        if over.any():
            k = int(np.argmax(np.any(over, axis=1)))
            ax.plot(t[np.any(over, axis=1)], np.max(np.abs(qd), axis=1)[np.any(over, axis=1)], "rx", ms=4,
                    label="beyond the bound")
            title += f" — beyond ±{bound:.3g}°/s from t = {t[k]:.2f} s"
    elif result.metadata.get("summary", {}).get("joint_speed", {}).get("max_speed_ratio") is not None:
        ratio = result.metadata["summary"]["joint_speed"]["max_speed_ratio"]
        title += f" (peak {ratio:.0%} of a joint's speed limit)"
    else:
        title += " (the robot file gives no velocity bounds)"
    ax.set(xlabel="t [s]", ylabel="joint velocity [deg/s]", title=title)
    ax.legend(ncol=4, fontsize=7)
    ax.grid(alpha=0.3)


def log_trace(ax: Axes, t: np.ndarray, values: np.ndarray, **style) -> None:
    """A log-scale trace whose exact zeros sit a decade below its smallest positive value."""
    positive = values[values > 0]
    floor = float(positive.min()) / 10 if positive.size else LOG_FLOOR
    ax.semilogy(t, np.maximum(values, floor), **style)


def task_error_panel(ax: Axes, result: PlanResult, t: np.ndarray) -> None:
    log_trace(ax, t, result.column("pos_err_m") * 1e3, label="position error [mm]")
    log_trace(ax, t, np.degrees(result.column("ori_err_rad")), label="orientation error [deg]")
    ax.set(xlabel="t [s]", title="task error (desired − executed pose)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)


def planned_tool_path(result: PlanResult, robot: Robot) -> np.ndarray | None:
    """The task's geometric path (m), rebuilt from the task stored in ``plan.json`` (validated
    by the shared path vocabulary) and the start configuration by ``robot``'s forward
    kinematics; ``None`` when the plan holds no resolved-rate path task."""
    meta = result.metadata
    task = meta.get("task")
    if not isinstance(task, dict) or not isinstance(task.get("path"), dict):
        return None
    q_start = np.asarray((meta.get("start") or {}).get("q_rad", []), dtype=float)
    if q_start.shape != (robot.n,):
        return None
    try:
        ls, as_ = unit_scales(Units.model_validate(task.get("units", {})))
        pose0 = robot.fk(q_start)
        if task["path"].get("type") == "program":
            spec = program_spec(ProgramPath.model_validate(task["path"]), str(meta.get("task_file", "plan.json")), ls,
                                as_)
            return build_program(spec, pose0, "plan.json").sample_points(2000)
        return path_geometry(RelativePath.model_validate(task["path"]), ls, as_).build(pose0).sample_points()
    except (ArmgenError, ValidationError):
        return None


def executed_tool_path(result: PlanResult, robot: Robot) -> np.ndarray:
    """Tool positions (m) by forward kinematics of the plan's joint angles."""
    n = robot.n
    q = np.column_stack([result.column(f"q{i + 1}_rad") for i in range(n)])
    return robot.fk(q)[:, :3, 3]


@dataclass(frozen=True)
class PathView:
    """A 2-D view of 3-D points: the coordinates along ``u`` (horizontal) and ``v`` (vertical)."""

    u: np.ndarray
    v: np.ndarray
    u_label: str
    v_label: str
    name: str  # for a title: "y–z plane", "x–z, edge-on", "its own plane, normal (0.71, 0, 0.71)"

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        points = np.asarray(points, dtype=float)
        return points @ self.u, points @ self.v


def _axis_view(i: int, j: int, name: str) -> PathView:
    eye = np.eye(3)
    return PathView(eye[i], eye[j], "xyz"[i], "xyz"[j], name)


def principal_views(points: np.ndarray) -> tuple[PathView, PathView]:
    """The two 2-D views that show a path best: face-on to its principal plane (the plane of
    the two largest principal axes of the points), and edge-on to it (its largest axis against
    the normal, showing how far the path leaves the plane). A plane within
    :data:`AXIS_ALIGNED_DEG` of a coordinate plane is that coordinate plane (e.g. a circle at
    constant x: "y–z plane" and "x–y, edge-on"); a straight path uses the coordinate plane it
    is longest in; any other plane its own axes, named by its normal."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    centred = points - points.mean(axis=0)
    _, spread, axes = np.linalg.svd(centred, full_matrices=False) if len(points) > 1 else (None, np.zeros(1), np.eye(3))
    extent = np.ptp(points, axis=0)
    if spread.size < 2 or spread[0] == 0 or spread[1] <= STRAIGHT_RATIO * spread[0]:
        normal_axis = min((2, 1, 0), key=lambda k: extent[k])  # ties prefer the top view
    else:
        normal = axes[2] if axes.shape[0] > 2 else np.cross(axes[0], axes[1])
        normal_axis = int(np.argmax(np.abs(normal)))
        if abs(normal[normal_axis]) < np.cos(np.radians(AXIS_ALIGNED_DEG)):  # oblique: its own axes
            # each direction's sign: its first clearly non-zero component positive
            u, v, normal = (w * np.sign(w[np.flatnonzero(np.abs(w) > 1e-6)[0]]) for w in (axes[0], axes[1], normal))
            fmt = lambda w: "(" + ", ".join(f"{c:.2f}" for c in w) + ")"  # noqa: E731
            return (PathView(u, v, f"along {fmt(u)}", f"along {fmt(v)}", f"its own plane, normal {fmt(normal)}"),
                    PathView(u, normal, f"along {fmt(u)}", f"along the normal {fmt(normal)}", "edge-on"))
    i, j = (k for k in range(3) if k != normal_axis)
    wide = i if extent[i] >= extent[j] else j
    a, b = sorted((wide, normal_axis))
    return (_axis_view(i, j, f"{'xyz'[i]}–{'xyz'[j]} plane"),
            _axis_view(a, b, f"{'xyz'[a]}–{'xyz'[b]}, edge-on"))


def equal_3d_axes(ax, points: np.ndarray) -> None:
    """Equal scales on a 3-D axes: one cube around ``points``, so an axis along which the path
    is constant spans the same range as the others (distinct tick labels, not one repeated)."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    half = max(0.5 * float(np.max(np.ptp(points, axis=0))), 1e-9)
    ax.set(xlim=(centre[0] - half, centre[0] + half), ylim=(centre[1] - half, centre[1] + half),
           zlim=(centre[2] - half, centre[2] + half))
    ax.set_box_aspect((1, 1, 1), zoom=0.8)  # zoom < 1: room for the axis labels inside the panel
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(INSET_TICKS))


def tool_path_views(fig_or_subfig, result: PlanResult, robot: Robot) -> list[Axes]:
    """Three panels in one row: the tool path in 3-D, then face-on and edge-on to the path's own
    plane (:func:`principal_views`), in mm; ``robot`` is the plan's (:func:`plan_robot`)."""
    executed = executed_tool_path(result, robot) * 1e3
    planned = planned_tool_path(result, robot)
    planned = planned * 1e3 if planned is not None else None
    grid = fig_or_subfig.add_gridspec(1, 3)
    axes = [fig_or_subfig.add_subplot(grid[0, 0], projection="3d")]
    axes += [fig_or_subfig.add_subplot(grid[0, k]) for k in (1, 2)]
    ax = axes[0]
    ax.plot(*executed.T, color="tab:red", lw=1.3, label="executed (FK of the plan's angles)")
    if planned is not None:
        ax.plot(*planned.T, "k--", lw=1.0, label="planned path")
    ax.scatter(*executed[0], color="tab:green", s=20, label="start")
    ax.set(xlabel="x [mm]", ylabel="y [mm]", zlabel="z [mm]", title="tool path, 3-D")
    everything = executed if planned is None else np.vstack([executed, planned])
    equal_3d_axes(ax, everything)
    ax.tick_params(labelsize=6)
    ax.legend(fontsize=7, loc="upper left")
    for ax, view in zip(axes[1:], principal_views(planned if planned is not None else executed)):
        ax.plot(*view.project(executed), color="tab:red", lw=1.3, label="executed")
        if planned is not None:
            ax.plot(*view.project(planned), "k--", lw=1.0, label="planned")
        ax.plot(*view.project(executed[:1]), "o", color="tab:green", ms=4, label="start")
        ax.set(xlabel=f"{view.u_label} [mm]", ylabel=f"{view.v_label} [mm]", title=f"tool path, {view.name}")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return axes


def path_summary(result: PlanResult) -> str:
    """What matters for the path: a closed path's final joint deviation, an open path's end error."""
    meta = result.metadata
    summary = meta.get("summary", {})
    path = meta.get("path", {})
    closed = path.get("type") == "circle" and float(path.get("turns", 1.0)).is_integer()
    end_mm = result.column("pos_err_m")[-1] * 1e3
    if closed and "max_final_deviation_deg" in summary:
        return f"closed path: final joint deviation {summary['max_final_deviation_deg']:.3g}°"
    if closed:
        n = joint_count(result)
        q = np.column_stack([result.column(f"q{i + 1}_rad") for i in range(n)])
        return f"closed path: final joint deviation {np.degrees(np.max(np.abs(q[-1] - q[0]))):.3g}°"
    return f"open path: end error {end_mm:.3g} mm"


def resolved_rate_figure(result: PlanResult, panels: list, title: str, rows: int, robot: Robot | None = None) -> Figure:
    """A figure with the planner's panels in a ``rows``×2 grid above one row of tool-path views.
    ``panels`` are callables ``draw(ax)``; every panel drawn has data (no empty axes). The tool
    path is drawn through ``robot``'s forward kinematics (default: :func:`plan_robot`)."""
    robot = robot if robot is not None else plan_robot(result)
    view = collision_view(result, robot)
    heights = [4.2 * rows, 4.4] + ([SCENE_HEIGHT_IN] if view is not None else [])
    fig = new_figure(14, sum(heights))
    top, bottom, *below = fig.subfigures(len(heights), 1, height_ratios=heights)
    grid = top.add_gridspec(rows, 2)
    for k, draw in enumerate(panels):
        last_alone = k == len(panels) - 1 and k % 2 == 0  # an odd last panel spans the row: no blank slot
        draw(top.add_subplot(grid[k // 2, :] if last_alone else grid[k // 2, k % 2]))
    tool_path_views(bottom, result, robot)
    if below:
        collision_row(below[0], result, view)
    fig.suptitle(title)
    return fig


def plan_joint_angles(result: PlanResult, robot: Robot) -> np.ndarray:
    """q per sample: the columns q1_rad… (resolved-rate plans) or theta_<joint>_rad (PTP plans,
    by joint name; a joint the plan does not move stays at 0)."""
    n = joint_count(result)
    if n:
        if n != robot.n:
            raise PlanFileError(f"the plan has {n} joint columns but robot '{robot.name}' has {robot.n} joints; "
                                "give the robot the plan was made for")
        return np.column_stack([result.column(f"q{i + 1}_rad") for i in range(n)])
    named = [f"theta_{joint.name}_rad" for joint in robot.joints]
    if not any(column in result.columns for column in named):
        raise PlanFileError(f"the plan has no joint columns of robot '{robot.name}' (q1_rad… or "
                            f"{', '.join(named[:2])}…); give the robot the plan was made for")
    q = np.zeros((result.data.shape[0], robot.n))
    for i, column in enumerate(named):
        if column in result.columns:
            q[:, i] = result.column(column)
    return q


@dataclass(frozen=True)
class CollisionView:
    """What the collision row draws: the plan's robot, its joint values per sample, the scene."""

    robot: Robot
    q: np.ndarray
    scene: Scene


def collision_view(result: PlanResult, robot: Robot | None = None, q: np.ndarray | None = None,
                   obstacles: tuple | None = None, indices: tuple[int, ...] | None = None) -> CollisionView | None:
    """The plan's :class:`CollisionView` when ``plan.json`` reports ``summary.collision`` (every
    plan on a robot with capsules), else None: the figure gets no collision row. ``robot`` as in
    :func:`plan_robot` (default: the one ``plan.json`` records); ``q`` the robot's joint values
    per sample (default: :func:`plan_joint_angles`); ``obstacles`` and ``indices`` as in
    :func:`~armgen.planning.collision_scene.plan_scene`."""
    if not isinstance((result.metadata.get("summary") or {}).get("collision"), dict):
        return None
    robot = robot if robot is not None else plan_robot(result)
    q = q if q is not None else plan_joint_angles(result, robot)
    scene = plan_scene(result, robot, q, obstacles, indices)
    return None if scene is None or scene.approach is None else CollisionView(robot, q, scene)


def collision_row(subfig, result: PlanResult, view: CollisionView) -> None:
    """The arm at the plan's closest approach (:mod:`.collision_scene`): its capsules, the task's
    obstacles and the marker, with the executed tool path, in two 3-D panels: the usual view and
    one across the gap."""
    frames = view.robot.frames(view.q[view.scene.approach.sample])
    tool_path = view.robot.fk(view.q)[:, :3, 3]
    clearance = result.metadata["summary"]["collision"].get("clearance_m")
    for k, across in enumerate((False, True)):
        ax = subfig.add_subplot(1, 2, k + 1, projection="3d")
        scene_panel(ax, view.scene, frames, tool_path, clearance, across=across)
