"""``armgen plot`` for snake plans (spec 50): the arm drawn along its path at several instants
(like the paper's figures: top view, plus a side view when the path leaves the plane), the
universal-joint angles over time with their limits, and the accuracy traces (tip deviation,
worst chord error, smallest clearance).

The arm is redrawn from the CSV's feed and joint angles by the robot's forward kinematics (the
same numpy chain the planner checks against), so the figure shows what the angles do, not what
the solver intended; the path is the spline through the waypoints stored in ``plan.json``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Rectangle

from ...errors import ArmgenError
from ...fileio import atomic_open
from ...robot import load_robot
from ..result import PlanResult
from .spline import HermiteSpline

INSTANTS = 6  # arm poses drawn, evenly spaced over the motion
PLANAR_TOL = 1e-9  # m: a path whose z spread is below this is drawn in one (top) view
FLOOR = 1e-14  # mm, floor of the log-scale accuracy traces (exact solver: ~1e-13 mm)


def _arm_centres(result: PlanResult, meta: dict) -> np.ndarray:
    from .planner import snake_arm

    robot_meta = meta.get("robot", {})
    try:
        robot = load_robot(robot_meta.get("file") or robot_meta["name"])
    except (ArmgenError, KeyError):
        robot = load_robot(robot_meta.get("name", "snake12"))
    arm = snake_arm(robot, "plan.json")
    n = arm.n_links
    feed = result.column("feed_m")
    alpha = np.column_stack([result.column(f"a{i + 1}_rad") for i in range(n)])
    beta = np.column_stack([result.column(f"b{i + 1}_rad") for i in range(n)])
    place = np.asarray(meta["rail"]["start_m"], dtype=float) - arm.base0
    return arm.joint_centres(arm.q_vector(feed, alpha, beta))[0] + place


def _draw_obstacles(ax, obstacles: list[dict], view: tuple[int, int]) -> None:
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


def plot_snake(result: PlanResult, out_path: str | Path) -> None:
    meta = result.metadata
    if "rail" not in meta or "path" not in meta:
        raise ArmgenError("plan.json lacks the snake planner's rail/path metadata; re-run `armgen plan`")
    t = result.column("t_s")
    centres = _arm_centres(result, meta) * 1e3
    path = meta["path"]
    wp = np.asarray(path["waypoints_m"], dtype=float)
    spline = HermiteSpline(wp, path.get("start_tangent"), path.get("end_tangent"))
    dense = spline.position(np.linspace(0, spline.length, 4000)) * 1e3
    planar = np.ptp(wp[:, 2]) < PLANAR_TOL
    views = [((0, 1), "top view (x–y)")] if planar else [((0, 1), "top view (x–y)"), ((0, 2), "side view (x–z)")]
    n = sum(1 for c in result.columns if c.startswith("a") and c.endswith("_rad"))
    fig = Figure(figsize=(14, 10), constrained_layout=True)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(2, 2, height_ratios=[1.15, 1])
    instants = np.unique(np.linspace(0, t.size - 1, INSTANTS).round().astype(int))
    for v, (view, title) in enumerate(views):
        ax = fig.add_subplot(grid[0, :] if planar else grid[0, v])
        i, j = view
        ax.plot(dense[:, i], dense[:, j], color="k", lw=0.8, ls="--", label="path (spline)")
        ax.plot(wp[:, i] * 1e3, wp[:, j] * 1e3, ".", color="k", ms=3, label="waypoints")
        for rank, k in enumerate(instants):  # later poses thinner, so the earlier ones stay visible
            width = 4.5 - 3.5 * rank / max(len(instants) - 1, 1)
            line, = ax.plot(centres[k, :, i], centres[k, :, j], "-o", ms=2.5, lw=width, alpha=0.85,
                            label=f"t = {t[k]:.1f} s")
            ax.plot(centres[k, 0, i], centres[k, 0, j], "s", ms=6, color=line.get_color())
            ax.plot(centres[k, -1, i], centres[k, -1, j], "*", ms=10, color=line.get_color())
        ax.set_aspect("equal", adjustable="datalim")
        ax.autoscale_view()
        _draw_obstacles(ax, meta.get("obstacles", []), view)
        ax.set(xlabel=f"{'xyz'[i]} [mm]", ylabel=f"{'xyz'[j]} [mm]", title=f"arm along the path — {title} (■ base joint, ★ tip)")
        ax.grid(alpha=0.3)
        if v == 0:
            ax.legend(fontsize=7, ncol=2, loc="best")
    ax = fig.add_subplot(grid[1, 0])
    for i in range(n):
        ax.plot(t, np.degrees(result.column(f"a{i + 1}_rad")), lw=1.0, label=f"α{i + 1}")
    for i in range(n):
        ax.plot(t, np.degrees(result.column(f"b{i + 1}_rad")), lw=1.0, ls=":", label=f"β{i + 1}")
    qlim = meta.get("robot", {}).get("qlim_rad", [])
    if len(qlim) > 1:
        lo, hi = np.degrees(min(q[0] for q in qlim[1:])), np.degrees(max(q[1] for q in qlim[1:]))
        ax.axhline(lo, color="k", ls="--", lw=0.8)
        ax.axhline(hi, color="k", ls="--", lw=0.8)
    ax.set(xlabel="t [s]", ylabel="joint angle [deg]", title="universal-joint angles (α solid, β dotted; limits dashed)")
    ax.legend(fontsize=6, ncol=6)
    ax.grid(alpha=0.3)
    ax = fig.add_subplot(grid[1, 1])
    ax.semilogy(t, np.maximum(result.column("tip_dev_m") * 1e3, FLOOR), label="tip deviation from the path [mm]")
    ax.semilogy(t, np.maximum(result.column("chord_err_max_m") * 1e3, FLOOR), label="worst chord error [mm]")
    clear = result.column("clearance_min_m")
    if np.all(np.isfinite(clear)):
        ax2 = ax.twinx()
        ax2.plot(t, clear * 1e3, color="tab:green", lw=1.0)
        ax2.set_ylabel("smallest clearance [mm] (green)")
    ax.set(xlabel="t [s]", title="accuracy (forward kinematics on the recovered angles)")
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3)
    summary = meta.get("summary", {})
    fig.suptitle(f"{meta.get('robot', {}).get('name', '')} — {summary.get('solver', '')} solver, {summary.get('driven', '')} "
                 f"driven — max tip deviation {summary.get('max_tip_deviation_mm', float('nan')):.3g} mm — max |angle| "
                 f"{summary.get('max_abs_joint_angle_deg', float('nan')):.1f}°")
    with atomic_open(out_path, "wb") as handle:
        fig.savefig(handle, format="png", dpi=100)
