"""``armgen plot`` for cartesian (spec 20) plans: joint angles with their limits, velocities,
the criteria (H_L, H_R and the joint-limit windows), the task error, and the tool path."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ..plotting import (angles_panel, joint_count, joint_style, log_trace, path_summary, resolved_rate_figure,
                        task_error_panel, velocities_panel)
from ...robot import Robot
from ..result import PlanResult


def _criteria_panel(ax: Axes, result: PlanResult, t: np.ndarray) -> None:
    drawn = False
    if "H_L_1" in result.columns and np.any(result.column("H_L_1") > 0):
        log_trace(ax, t, result.column("H_L_1"), label="H_L (Zghal)")
        drawn = True
    if "H_R_rad2" in result.columns and np.any(result.column("H_R_rad2") > 0):
        log_trace(ax, t, result.column("H_R_rad2"), label="H_R (repetitive) [rad²]")
        drawn = True
    windows = [c for c in result.columns if c.startswith("window")]
    if windows and np.any(result.data[:, [result.columns.index(c) for c in windows]] > 0):
        target = ax.twinx() if drawn else ax
        for k, c in enumerate(windows):
            target.plot(t, result.column(c), lw=0.8, color=joint_style(k)["color"], ls=":", label=f"window θ{k + 1}")
        target.set_ylabel("joint-limit windows (dotted)")
        target.set_ylim(-0.05, 1.05)
        target.legend(fontsize=7, ncol=4, loc="lower right")
    ax.set(xlabel="t [s]", title="criteria")
    if drawn:
        ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3)


def has_criteria(result: PlanResult) -> bool:
    """Whether the method optimised any criterion (plain pinv has none: its panel would be empty)."""
    cols = ["H_L_1", "H_R_rad2"] + [c for c in result.columns if c.startswith("window")]
    return any(c in result.columns and np.any(result.column(c) > 0) for c in cols)


def plot_resolved_rate(result: PlanResult, robot: Robot | None = None) -> Figure:
    """The figure; the tool path through ``robot``'s kinematics (default: the plan's, :func:`plan_robot`)."""
    n = joint_count(result)
    t = result.column("t_s")
    meta = result.metadata
    panels = [lambda ax: angles_panel(ax, result, n, t), lambda ax: velocities_panel(ax, result, n, t)]
    if has_criteria(result):
        panels.append(lambda ax: _criteria_panel(ax, result, t))
    panels.append(lambda ax: task_error_panel(ax, result, t))
    summary = meta.get("summary", {})
    title = f"{meta.get('robot', {}).get('name', '')} — {meta.get('method', '')} — {path_summary(result)}"
    if "max_abs_q_deg" in summary:
        title += f" — max |θ| {max(summary['max_abs_q_deg']):.1f}°"
    return resolved_rate_figure(result, panels, title, rows=(len(panels) + 1) // 2, robot=robot)
