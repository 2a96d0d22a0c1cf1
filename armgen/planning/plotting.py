"""Figure building blocks shared by every planner's plots, and the one way figures are saved.

Every ``plot_*`` function of a planner's ``plots`` module takes a :class:`PlanResult` and
RETURNS a :class:`matplotlib.figure.Figure` built with the object-oriented API (no pyplot
state, safe in threads and notebooks); :func:`save_figure` writes it in the format its
extension names (``.png``, ``.svg``, ``.pdf``), atomically.

Shared panels (the layout of the spec 20 paper's figures): joint angles in degrees with each
joint's own limits dashed in the joint's colour and labelled, joint velocities in deg/s with
their bounds when the plan has any, the task error, and the tool path in 3-D, top and side
view — planned (the task's geometric path rebuilt from ``plan.json``) against executed (forward
kinematics of the plan's joint angles, NumPy DH chain of the robot named in ``plan.json``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.colors import to_hex
from matplotlib.figure import Figure

from ..errors import ArmgenError
from ..fileio import atomic_open
from ..robot import Robot, load_robot
from .result import PlanResult

FORMATS = {".png": "png", ".svg": "svg", ".pdf": "pdf"}
DPI = 110  # raster output: legible 8-pt legends at the figure sizes used here
LOG_FLOOR = 1e-12  # where a log-scale trace of only zeros is drawn (a zero would vanish from the axis)
# 25 distinct colours: tab10, then the dark and the mid shades of tab20b's five hue groups, then
# tab20c's dark shades; with a line style that changes every 10 joints, 25+ joints stay apart.
JOINT_COLOURS = ([to_hex(c) for c in colormaps["tab10"].colors]
                 + [to_hex(colormaps["tab20b"].colors[k]) for k in (0, 4, 8, 12, 16, 2, 6, 10, 14, 18)]
                 + [to_hex(colormaps["tab20c"].colors[k]) for k in (0, 4, 8, 12, 16)])
JOINT_LINESTYLES = ("-", "--", "-.")


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
        raise FigureOutputError(f"output {str(out_path)!r} is not a file name; give e.g. -o plan.png "
                                f"(formats: {', '.join(FORMATS)})")
    if path.is_dir():  # as for every other output: an existing directory in the way is exit 4
        raise FigureWriteError(f"cannot write {path}: is a directory; choose a file name such as plan.png")
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise FigureOutputError(f"output {str(out_path)!r}: unknown figure format {path.suffix or '(no extension)'!r}; "
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


def plan_robot(result: PlanResult) -> Robot:
    """The robot named in ``plan.json``: its file when that path exists and still has the
    recorded sha256, else the bundled robot of that name."""
    robot_meta = result.metadata.get("robot") or {}
    file, name, sha = robot_meta.get("file"), robot_meta.get("name"), robot_meta.get("sha256")
    if file and Path(file).is_file():
        robot = load_robot(file)
        if not sha or robot.sha256 == sha:
            return robot
    if not name:
        raise ArmgenError("plan.json names no robot (field 'robot.name'); re-run `armgen plan` to rewrite it")
    return load_robot(name)


def dh_frames(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Frames of the base, after each joint, and of the tool: shape (samples, n + 2, 4, 4)
    for ``q`` of shape (samples, n) (NumPy DH chain, the same as the symbolic core's)."""
    from .snake.planner import dh_frames as joint_frames

    q = np.atleast_2d(np.asarray(q, dtype=float))
    joints = joint_frames(robot, q)
    base = np.broadcast_to(robot.base, (q.shape[0], 1, 4, 4))
    tool = (joints[:, -1] @ robot.tool)[:, None]
    return np.concatenate([base, joints, tool], axis=1)


def limit_lines(ax: Axes, limits: list[tuple[float, float]], labels: list[str], x_end: float) -> None:
    """Each joint's lower/upper limit as a dashed line in the joint's colour; joints sharing a
    value share the line, their colours interleaved along it, labelled once at its right end."""
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
        names = labels[members[0]] if len(members) == 1 else f"{labels[members[0]]}…{labels[members[-1]]}"
        ax.annotate(f"{names} limit {value:g}°", (x_end, value), xytext=(-2, 2), textcoords="offset points",
                    ha="right", va="bottom", fontsize=7, color=joint_style(members[0])["color"])


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
    """The task's geometric path (m), rebuilt from the task stored in ``plan.json`` and the
    start pose by forward kinematics; ``None`` when the plan holds no resolved-rate path task."""
    from .cartesian.planner import parse_path_and_timing, parse_robot_and_start
    from .paths import CirclePath, LinePath

    meta = result.metadata
    task = meta.get("task")
    if not isinstance(task, dict) or "path" not in task:
        return None
    if isinstance(task["path"], dict) and task["path"].get("type") == "program":
        return _planned_program(meta, task, robot)
    try:
        _, q_start, _, ls, as_ = parse_robot_and_start(task, "plan.json")
        path_type, via, end, end_rotation, _, _ = parse_path_and_timing(task, "plan.json", ls, as_)
    except ArmgenError:
        return None
    if "start" in meta and "q_rad" in meta["start"]:
        q_start = np.asarray(meta["start"]["q_rad"], dtype=float)
    pose0 = dh_frames(robot, q_start[None])[0, -1]
    p0, r0 = pose0[:3, 3], pose0[:3, :3]
    offset = p0 if meta.get("path", {}).get("relative") else np.zeros(3)
    if path_type == "circle":
        path = CirclePath(p0, via + offset, end + offset, r0)
    else:
        path = LinePath(p0, end + offset, r0, end_rotation if end_rotation is not None else r0)
    return path.sample_points()


def _planned_program(meta: dict, task: dict, robot: Robot) -> np.ndarray | None:
    """A program's geometry from the plan's task and start (a poses file relative to the task file)."""
    from .cartesian.planner import ANGLE_SCALE, LENGTH_SCALE
    from .toolpath.task import build_program, parse_program

    q_start = np.asarray(meta.get("start", {}).get("q_rad", []), dtype=float)
    units = task.get("units", {})
    if q_start.shape != (robot.n,) or not isinstance(units, dict):
        return None
    try:
        spec = parse_program(task["path"], str(meta.get("task_file", "plan.json")),
                             LENGTH_SCALE[units.get("length", "m")], ANGLE_SCALE[units.get("angle", "rad")])
        return build_program(spec, dh_frames(robot, q_start[None])[0, -1], "plan.json").sample_points(2000)
    except (ArmgenError, KeyError, TypeError):
        return None


def executed_tool_path(result: PlanResult, robot: Robot) -> np.ndarray:
    """Tool positions (m) by forward kinematics of the plan's joint angles."""
    n = robot.n
    q = np.column_stack([result.column(f"q{i + 1}_rad") for i in range(n)])
    return dh_frames(robot, q)[:, -1, :3, 3]


def tool_path_views(fig_or_subfig, result: PlanResult) -> list[Axes]:
    """Three panels in one row: the tool path in 3-D, top view (x–y) and side view (x–z), in mm."""
    robot = plan_robot(result)
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
    ax.set_aspect("equal")
    ax.tick_params(labelsize=6)
    ax.legend(fontsize=7, loc="upper left")
    for ax, (i, j), name in ((axes[1], (0, 1), "top view (x–y)"), (axes[2], (0, 2), "side view (x–z)")):
        ax.plot(executed[:, i], executed[:, j], color="tab:red", lw=1.3, label="executed")
        if planned is not None:
            ax.plot(planned[:, i], planned[:, j], "k--", lw=1.0, label="planned")
        ax.plot(executed[0, i], executed[0, j], "o", color="tab:green", ms=4, label="start")
        ax.set(xlabel=f"{'xyz'[i]} [mm]", ylabel=f"{'xyz'[j]} [mm]", title=f"tool path, {name}")
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


def resolved_rate_figure(result: PlanResult, panels: list, title: str, rows: int) -> Figure:
    """A figure with the planner's panels in a ``rows``×2 grid above one row of tool-path views.
    ``panels`` are callables ``draw(ax)``; every panel drawn has data (no empty axes)."""
    fig = new_figure(14, 4.2 * rows + 4.4)
    top, bottom = fig.subfigures(2, 1, height_ratios=[4.2 * rows, 4.4])
    grid = top.add_gridspec(rows, 2)
    for k, draw in enumerate(panels):
        last_alone = k == len(panels) - 1 and k % 2 == 0  # an odd last panel spans the row: no blank slot
        draw(top.add_subplot(grid[k // 2, :] if last_alone else grid[k // 2, k % 2]))
    tool_path_views(bottom, result)
    fig.suptitle(title)
    return fig
