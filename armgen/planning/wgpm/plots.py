"""``armgen plot`` for weighted-GPM (spec 35) plans: angles with their limits, velocities, the
normalised criteria, the online gains and the null-space ramp, task error and damping, the
continuous joint-limit weights w_c, and the tool path."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ..plotting import (angles_panel, joint_count, joint_style, log_trace, path_summary, resolved_rate_figure,
                        task_error_panel, velocities_panel)
from ...robot import Robot
from ..result import PlanResult


def _criteria_panel(ax: Axes, result: PlanResult, t: np.ndarray) -> None:
    for name in ("H_w_1", "H_M_1", "H_L_1", "H_kappa_1"):
        if name in result.columns:
            log_trace(ax, t, result.column(name), label=name[:-2])
    ax.set(xlabel="t [s]", title="criteria")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)


def _gains_panel(ax: Axes, result: PlanResult, t: np.ndarray) -> None:
    for name in ("k_w_1", "k_M_1", "k_L_1", "k_kappa_1"):
        if name in result.columns:
            ax.plot(t, result.column(name), label=name[:-2])
    if "ramp_1" in result.columns:
        ax.plot(t, result.column("ramp_1"), "k:", label="ramp")
    ax.set(xlabel="t [s]", title="online gains k_j (signed) and null-space ramp")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)


def _error_and_damping_panel(ax: Axes, result: PlanResult, t: np.ndarray) -> None:
    task_error_panel(ax, result, t)
    if "damping_1" in result.columns and np.any(result.column("damping_1") > 0):
        log_trace(ax, t, result.column("damping_1"), label="damping ρ")
        ax.legend(fontsize=8)
        ax.set_title("task error and damping")


def _weights_panel(ax: Axes, result: PlanResult, n: int, t: np.ndarray) -> None:
    for i in range(n):
        ax.plot(t, result.column(f"wc{i + 1}_1"), lw=1.2, label=f"w_c{i + 1}", **joint_style(i))
    ax.set(xlabel="t [s]", title="joint-limit weights w_c (1 − W_b)", ylim=(-0.05, 1.05))
    ax.legend(ncol=4, fontsize=7)
    ax.grid(alpha=0.3)


def plot_wgpm(result: PlanResult, robot: Robot | None = None) -> Figure:
    """The figure; the tool path through ``robot``'s kinematics (default: the plan's, :func:`plan_robot`)."""
    n = joint_count(result)
    t = result.column("t_s")
    meta = result.metadata
    panels = [lambda ax: angles_panel(ax, result, n, t), lambda ax: velocities_panel(ax, result, n, t),
              lambda ax: _criteria_panel(ax, result, t), lambda ax: _gains_panel(ax, result, t),
              lambda ax: _error_and_damping_panel(ax, result, t), lambda ax: _weights_panel(ax, result, n, t)]
    s = meta.get("summary", {})
    title = (f"{meta.get('robot', {}).get('name', '')} — {meta.get('method', '')} — within limits: "
             f"{'yes' if s.get('within_limits') else 'no'} — tracks: {'yes' if s.get('tracks') else 'no'} — "
             f"{path_summary(result)}")
    return resolved_rate_figure(result, panels, title, rows=3, robot=robot)
