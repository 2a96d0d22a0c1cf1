"""``armgen plot`` for fault-tolerant (spec 30) plans: angles with their limits, velocities with
the completion test's speed bound, the index H and manipulability w, each ω_i, the task error,
the WLN weights (WLN plans only: a GPM plan has none to draw), and the tool path. The lock time
is the red dotted line in every time panel."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ..plotting import (angles_panel, joint_count, joint_style, path_summary, resolved_rate_figure, task_error_panel,
                        velocities_panel)
from ...robot import Robot
from ..result import PlanResult


def _lock_marker(ax: Axes, result: PlanResult) -> None:
    fault = result.metadata.get("fault") or {}
    if fault.get("joints"):
        ax.axvline(fault["time_s"], color="r", ls=":", lw=1.0, label=f"lock of {', '.join(fault['joints'])}")


def _with_lock(draw, result: PlanResult):
    def panel(ax: Axes) -> None:
        draw(ax)
        _lock_marker(ax, result)
    return panel


def _index_panel(ax: Axes, result: PlanResult, t: np.ndarray) -> None:
    index = result.metadata.get("parameters", {}).get("index", "omega")
    ax.plot(t, result.column("H_M_1"), label=f"H ({index})")
    ax.plot(t, result.column("w_1"), label="w (healthy columns)")
    ax.set(xlabel="t [s]", title="index H and manipulability w")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)


def _omega_panel(ax: Axes, result: PlanResult, n: int, t: np.ndarray) -> None:
    for i in range(n):
        ax.plot(t, result.column(f"omega{i + 1}_1"), lw=1.2, label=f"ω{i + 1}", **joint_style(i))
    ax.set(xlabel="t [s]", title="per-joint index ω_i (healthy columns)")
    ax.legend(ncol=4, fontsize=7)
    ax.grid(alpha=0.3)


def _weights_panel(ax: Axes, result: PlanResult, n: int, t: np.ndarray) -> None:
    for i in range(n):
        ax.plot(t, result.column(f"W{i + 1}_1"), lw=1.2, label=f"W{i + 1}", **joint_style(i))
    ax.set(xlabel="t [s]", title="WLN weights W_i", yscale="log")
    ax.legend(ncol=4, fontsize=7)
    ax.grid(alpha=0.3)


def uses_weights(result: PlanResult, n: int) -> bool:
    """A WLN plan's weights move; a GPM plan's stay at 1 (their panel would show nothing)."""
    weights = np.column_stack([result.column(f"W{i + 1}_1") for i in range(n)]) if "W1_1" in result.columns else None
    return weights is not None and bool(np.ptp(weights) > 0)


def plot_fault_tolerant(result: PlanResult, robot: Robot | None = None) -> Figure:
    """The figure; the tool path through ``robot``'s kinematics (default: the plan's, :func:`plan_robot`)."""
    n = joint_count(result)
    t = result.column("t_s")
    meta = result.metadata
    speed = (meta.get("completion") or {}).get("max_joint_speed_deg_s")
    bound = math.radians(speed) if speed else None
    panels = [lambda ax: angles_panel(ax, result, n, t),
              lambda ax: velocities_panel(ax, result, n, t, bound, "(completion test)"),
              lambda ax: _index_panel(ax, result, t),
              lambda ax: _omega_panel(ax, result, n, t),
              lambda ax: task_error_panel(ax, result, t)]
    if uses_weights(result, n):
        panels.append(lambda ax: _weights_panel(ax, result, n, t))
    verdict = meta.get("verdict", {})
    locked = ", ".join(meta.get("fault", {}).get("joints", [])) or "none"
    completed = "yes" if verdict.get("completed") else f"no ({verdict.get('why_not', '')})"
    title = (f"{meta.get('robot', {}).get('name', '')} — {verdict.get('method', meta.get('method', ''))} — locked: "
             f"{locked} — task completed: {completed} — {path_summary(result)}")
    return resolved_rate_figure(result, [_with_lock(p, result) for p in panels], title, rows=(len(panels) + 1) // 2,
                                robot=robot)
