"""Plot of a PTP plan: angle, velocity, acceleration and jerk over time.

With a method comparison in the metadata (task field ``compare``) the methods are drawn
side by side, one column each on shared axes, as in the paper's comparison figure; the
curves are re-evaluated from the stored segment coefficients. Without it the CSV columns
are drawn. Knots are dotted vertical lines, waypoints are dots. Angles are shown in the
task's angle unit. The task's bounds (``timing.omega_max``, ``timing.eps_max``, per joint and
segment) are drawn as dashed steps in the joint's colour on the ω and ε rows; where a curve
exceeds its bound the peak is marked with a red ×, and the column title says so. A plan on a
robot with capsules (``summary.collision``) gets a row below: the arm at its closest approach
with its capsules and the task's obstacles (:mod:`armgen.planning.collision_scene`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.polynomial import polynomial as npp

from ...robot import Robot
from ..plotting import SCENE_HEIGHT_IN, collision_row, collision_view, joint_style, new_figure
from ..result import PlanResult, read_plan
from .config import BOUND_RTOL
from .plans import PtpPlan
from .summary import joint_metrics

ROWS = (("theta", "θ", ""), ("omega", "ω", "/s"), ("eps", "ε", "/s²"), ("jerk", "jerk", "/s³"))
# Values below this (in display units) are rounding noise, shown as 0 in the panel titles.
NOISE_FLOOR = 1e-9
CURVE_POINTS = 2001  # per column when re-evaluating coefficients: smooth at print size


def _plan_from_meta(meta: dict, method: str, segments: dict) -> PtpPlan:
    joints = tuple(meta["joints"])
    coeffs = np.array([segments["coefficients"][j] for j in joints], dtype=float)
    return PtpPlan(method, np.array(meta["knot_times_s"], dtype=float), joints, tuple(segments["kinds"]), coeffs)


def _curves(plan: PtpPlan) -> tuple[np.ndarray, list[np.ndarray]]:
    """Dense times and θ…jerk per joint, segment by segment, so each knot appears twice
    (left and right limit) and a jump is drawn as a vertical step."""
    durations = np.diff(plan.knots)
    times, values = [], [[] for _ in ROWS]
    for k, duration in enumerate(durations):
        tau = np.linspace(0.0, duration, max(2, int(CURVE_POINTS * duration / durations.sum())))
        times.append(plan.knots[k] + tau)
        for order in range(len(ROWS)):
            values[order].append(np.column_stack([npp.polyval(tau, npp.polyder(plan.coeffs[j, k], order))
                                                  for j in range(len(plan.joint_names))]))
    return np.concatenate(times), [np.vstack(v) for v in values]


def _tidy(value: float) -> str:
    """Three significant digits; rounding noise (a continuous ε 'jumping' by 1e-15) shows as 0."""
    return "0" if abs(value) < NOISE_FLOOR else f"{value:.3g}"


def _bounds(meta: dict) -> dict[int, np.ndarray]:
    """Row index (1 = ω, 2 = ε) → bound array (joints, segments) in rad/s or rad/s², when the task gave one."""
    params = meta.get("parameters", {})
    out = {}
    for row, key in ((1, "omega_max_rad_s"), (2, "eps_max_rad_s2")):
        if params.get(key) is not None:
            out[row] = np.asarray(params[key], dtype=float)
    return out


def _draw_bounds(ax: Axes, t: np.ndarray, values: np.ndarray, knots: np.ndarray, bound: np.ndarray, scale: float,
                 names: tuple[str, ...]) -> list[str]:
    """Dashed ± bound steps per joint and segment; red × at each exceeding peak. Returns the violations."""
    violations = []
    for j in range(bound.shape[0]):
        style = joint_style(j)
        steps = np.repeat(bound[j], 2) * scale
        edges = np.repeat(knots, 2)[1:-1]
        for sign in (-1, 1):
            ax.plot(edges, sign * steps, color=style["color"], ls="--", lw=0.9,
                    label=f"bound {names[j]}" if sign > 0 else None)
        for k in range(bound.shape[1]):
            inside = (t >= knots[k]) & (t <= knots[k + 1])
            peak = int(np.argmax(np.abs(values[:, j]) * inside))
            if abs(values[peak, j]) > bound[j, k] * (1 + BOUND_RTOL):
                ax.plot(t[peak], values[peak, j] * scale, "x", color="red", ms=8, mew=2)
                violations.append(f"seg {k + 1}{'' if len(names) == 1 else ' ' + names[j]}")
    return violations


def plot_ptp(source: str | Path | PlanResult, robot: Robot | None = None) -> Figure:
    """The figure of a PTP plan (a ``plan.csv`` path or a :class:`PlanResult`); a plan on a
    robot with capsules (``summary.collision``) also shows the arm at its closest approach,
    drawn through ``robot``'s kinematics (default: the plan's robot)."""
    result = read_plan(source) if not isinstance(source, PlanResult) else source
    view = collision_view(result, robot)
    meta = result.metadata
    unit = meta.get("units", {}).get("task_angle_unit", "rad")
    scale = 180.0 / math.pi if unit == "deg" else 1.0
    comparison = meta.get("comparison")
    if comparison:
        panels = [(m, _plan_from_meta(meta, m, comparison["segments"][m])) for m in comparison["methods"]]
    elif "segments" in meta:
        panels = [(meta.get("method", ""), _plan_from_meta(meta, meta.get("method", ""), meta["segments"]))]
    else:
        panels = []
    ncol = max(1, len(panels))
    heights = [9.0] + ([SCENE_HEIGHT_IN] if view is not None else [])
    fig = new_figure(max(4.4 * ncol + 0.6, SCENE_HEIGHT_IN if view is not None else 0.0), sum(heights))
    top, *below = fig.subfigures(len(heights), 1, height_ratios=heights) if view is not None else [fig]
    bounds = _bounds(meta)
    axes = top.subplots(len(ROWS), ncol, sharex=True, sharey="row", squeeze=False)
    if panels:
        for col, (method, plan) in enumerate(panels):
            t, values = _curves(plan)
            peaks = [joint_metrics(plan, j) for j in range(len(plan.joint_names))]
            stats = (("peak |ω|", "peak_velocity_rad_s", "/s"), ("peak |ε|", "peak_abs_acceleration_rad_s2", "/s²"),
                     ("ε jump", "max_acceleration_jump_rad_s2", "/s²"))
            title = method + "\n" + " · ".join(
                f"{label} {_tidy(max(p[key] for p in peaks) * scale)} {unit}{per}" for label, key, per in stats)
            knot_vals = [plan.evaluate(plan.knots, order) for order in (0, 1)]
            for j, name in enumerate(plan.joint_names):
                for row in range(len(ROWS)):
                    ax = axes[row, col]
                    ax.plot(t, values[row][:, j] * scale, lw=1.3, label=name, **joint_style(j))
                    if row < 2:
                        ax.plot(plan.knots, knot_vals[row][:, j] * scale, "o", color=joint_style(j)["color"], ms=3.5)
            violations = []
            for row, bound in bounds.items():
                found = _draw_bounds(axes[row, col], t, values[row], plan.knots, bound, scale, plan.joint_names)
                violations += [f"{ROWS[row][1]} {v}" for v in found]
            if bounds:
                title += "\n" + ("bounds exceeded (×): " + ", ".join(violations) if violations else "within the bounds")
            axes[0, col].set_title(title, fontsize=9, color="red" if violations else "black")
    else:
        t = result.column("t_s")
        names = [c[len("theta_"):-len("_rad")] for c in result.columns if c.startswith("theta_")]
        for j, name in enumerate(names):
            for row, (key, _, _) in enumerate(ROWS):
                unit_sfx = {"theta": "rad", "omega": "rad_s", "eps": "rad_s2", "jerk": "rad_s3"}[key]
                axes[row, 0].plot(t, result.column(f"{key}_{name}_{unit_sfx}") * scale, lw=1.3, label=name,
                                  **joint_style(j))
    knots = meta.get("knot_times_s", [])
    for row, (_, symbol, per) in enumerate(ROWS):
        axes[row, 0].set_ylabel(f"{symbol} [{unit}{per}]")
        for col in range(ncol):
            ax = axes[row, col]
            for tk in knots:
                ax.axvline(tk, color="0.6", lw=0.7, ls=":")
            ax.axhline(0.0, color="0.8", lw=0.6)
            ax.grid(True, alpha=0.3)
    for col in range(ncol):
        axes[-1, col].set_xlabel("t [s]")
    if len(meta.get("joints", [])) > 1:
        axes[0, 0].legend(fontsize=8, loc="best")
    for row in bounds:
        axes[row, 0].legend(fontsize=7, loc="lower left")
    if below:
        collision_row(below[0], result, view)
    return fig
