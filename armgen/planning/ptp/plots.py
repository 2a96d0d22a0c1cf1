"""Plot of a PTP plan: angle, velocity, acceleration and jerk over time.

With a method comparison in the metadata (task field ``compare``) the methods are drawn
side by side, one column each on shared axes, as in the paper's comparison figure; the
curves are re-evaluated from the stored segment coefficients. Without it the CSV columns
are drawn. Knots are dotted vertical lines, waypoints are dots. Angles are shown in the
task's angle unit.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.polynomial import polynomial as npp
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ...fileio import atomic_open
from .planner import PtpPlan, joint_metrics
from ..result import PlanResult, read_plan

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


def plot_ptp(source: str | Path | PlanResult, out_png: str | Path) -> Path:
    """Render a PTP plan (a ``plan.csv`` path or a :class:`PlanResult`) to a PNG; returns its path."""
    result = read_plan(source) if not isinstance(source, PlanResult) else source
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
    fig = Figure(figsize=(4.4 * ncol + 0.6, 9.0), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(ROWS), ncol, sharex=True, sharey="row", squeeze=False)
    colors = [f"C{i}" for i in range(10)]
    if panels:
        for col, (method, plan) in enumerate(panels):
            t, values = _curves(plan)
            peaks = [joint_metrics(plan, j) for j in range(len(plan.joint_names))]
            stats = (("peak |ω|", "peak_velocity_rad_s", "/s"), ("peak |ε|", "peak_abs_acceleration_rad_s2", "/s²"),
                     ("ε jump", "max_acceleration_jump_rad_s2", "/s²"))
            title = method + "\n" + " · ".join(
                f"{label} {_tidy(max(p[key] for p in peaks) * scale)} {unit}{per}" for label, key, per in stats)
            axes[0, col].set_title(title, fontsize=9)
            knot_vals = [plan.evaluate(plan.knots, order) for order in (0, 1)]
            for j, name in enumerate(plan.joint_names):
                for row in range(len(ROWS)):
                    ax = axes[row, col]
                    ax.plot(t, values[row][:, j] * scale, color=colors[j % 10], lw=1.3, label=name)
                    if row < 2:
                        ax.plot(plan.knots, knot_vals[row][:, j] * scale, "o", color=colors[j % 10], ms=3.5)
    else:
        t = result.column("t_s")
        names = [c[len("theta_"):-len("_rad")] for c in result.columns if c.startswith("theta_")]
        for j, name in enumerate(names):
            for row, (key, _, _) in enumerate(ROWS):
                unit_sfx = {"theta": "rad", "omega": "rad_s", "eps": "rad_s2", "jerk": "rad_s3"}[key]
                axes[row, 0].plot(t, result.column(f"{key}_{name}_{unit_sfx}") * scale, color=colors[j % 10],
                                  lw=1.3, label=name)
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
    out_png = Path(out_png)
    with atomic_open(out_png, "wb") as handle:
        fig.savefig(handle, format="png", dpi=110)
    return out_png
