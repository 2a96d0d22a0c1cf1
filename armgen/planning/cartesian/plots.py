"""``armgen plot`` for cartesian (spec 20) plans."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ..plotting import _angles_panel, _joint_count, _save, _task_error_panel, _velocities_panel
from ..result import PlanResult


def plot_resolved_rate(result: PlanResult, out_path: str | Path) -> None:
    n = _joint_count(result)
    t = result.column("t_s")
    meta = result.metadata
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5), constrained_layout=True)
    _angles_panel(axes[0, 0], result, n, t)
    _velocities_panel(axes[0, 1], result, n, t)
    ax = axes[1, 0]
    if "H_L_1" in result.columns:
        ax.semilogy(t, result.column("H_L_1"), label="H_L (Zghal)")
    if "H_R_rad2" in result.columns:
        ax.semilogy(t, np.maximum(result.column("H_R_rad2"), 1e-16), label="H_R [rad²]")
    windows = [c for c in result.columns if c.startswith("window")]
    if windows and np.any(result.data[:, [result.columns.index(c) for c in windows]] > 0):
        ax2 = ax.twinx()
        for c in windows:
            ax2.plot(t, result.column(c), lw=0.8, ls=":")
        ax2.set_ylabel("joint-limit windows (dotted)")
        ax2.set_ylim(-0.05, 1.05)
    ax.set(xlabel="t [s]", title="criteria")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    _task_error_panel(axes[1, 1], result, t)
    summary = meta.get("summary", {})
    title = f"{meta.get('robot', {}).get('name', '')} — {meta.get('method', '')}"
    if "max_final_deviation_deg" in summary:
        title += f" — final deviation {summary['max_final_deviation_deg']:.3g}° — max |θ| {max(summary['max_abs_q_deg']):.1f}°"
    fig.suptitle(title)
    _save(fig, out_path)
