"""``armgen plot`` for fault-tolerant (spec 30) plans."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ..plotting import _angles_panel, _joint_count, _save, _task_error_panel, _velocities_panel
from ..result import PlanResult


def _lock_marker(axes, result: PlanResult) -> None:
    fault = result.metadata.get("fault") or {}
    if fault.get("joints"):
        for ax in axes:
            ax.axvline(fault["time_s"], color="r", ls=":", lw=1.0)


def plot_fault_tolerant(result: PlanResult, out_path: str | Path) -> None:
    """Spec 30 plans: angles, velocities, H_M and w, each ω_i, task error, WLN weights; the
    lock time is the red dotted line."""
    n = _joint_count(result)
    t = result.column("t_s")
    meta = result.metadata
    fig, axes = plt.subplots(3, 2, figsize=(13, 12), constrained_layout=True)
    _angles_panel(axes[0, 0], result, n, t)
    _velocities_panel(axes[0, 1], result, n, t)
    ax = axes[1, 0]
    index = meta.get("parameters", {}).get("index", "omega")
    ax.plot(t, result.column("H_M_1"), label=f"H ({index})")
    ax.plot(t, result.column("w_1"), label="w (healthy columns)")
    ax.set(xlabel="t [s]", title="index H and manipulability w")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax = axes[1, 1]
    for i in range(n):
        ax.plot(t, result.column(f"omega{i + 1}_1"), label=f"ω{i + 1}")
    ax.set(xlabel="t [s]", title="per-joint index ω_i (healthy columns)")
    ax.legend(ncol=4, fontsize=8)
    ax.grid(alpha=0.3)
    _task_error_panel(axes[2, 0], result, t)
    ax = axes[2, 1]
    for i in range(n):
        ax.plot(t, result.column(f"W{i + 1}_1"), label=f"W{i + 1}")
    ax.set(xlabel="t [s]", title="WLN weights W_i", yscale="log")
    ax.legend(ncol=4, fontsize=8)
    ax.grid(alpha=0.3)
    _lock_marker(axes.ravel(), result)
    verdict = meta.get("verdict", {})
    locked = ", ".join(meta.get("fault", {}).get("joints", [])) or "none"
    fig.suptitle(f"{meta.get('robot', {}).get('name', '')} — {verdict.get('method', meta.get('method', ''))} — "
                 f"locked: {locked} — task completed: {'yes' if verdict.get('completed') else 'no'}")
    _save(fig, out_path)
