"""``armgen plot`` for weighted-GPM (spec 35) plans."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ..plotting import _angles_panel, _joint_count, _save, _task_error_panel, _velocities_panel
from ..result import PlanResult


def plot_wgpm(result: PlanResult, out_path: str | Path) -> None:
    """Spec 35 plans: angles (limits dashed), velocities, normalised criteria, gains, task error
    and damping, continuous weights w_c."""
    n = _joint_count(result)
    t = result.column("t_s")
    meta = result.metadata
    fig, axes = plt.subplots(3, 2, figsize=(13, 12), constrained_layout=True)
    _angles_panel(axes[0, 0], result, n, t)
    _velocities_panel(axes[0, 1], result, n, t)
    ax = axes[1, 0]
    for name in ("H_w_1", "H_M_1", "H_L_1", "H_kappa_1"):
        if name in result.columns:
            ax.semilogy(t, np.maximum(result.column(name), 1e-12), label=name[:-2])
    ax.set(xlabel="t [s]", title="criteria")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax = axes[1, 1]
    for name in ("k_w_1", "k_M_1", "k_L_1", "k_kappa_1"):
        if name in result.columns:
            ax.plot(t, result.column(name), label=name[:-2])
    if "ramp_1" in result.columns:
        ax.plot(t, result.column("ramp_1"), "k:", label="ramp")
    ax.set(xlabel="t [s]", title="online gains k_j (signed) and null-space ramp")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    _task_error_panel(axes[2, 0], result, t)
    if "damping_1" in result.columns and np.any(result.column("damping_1") > 0):
        axes[2, 0].semilogy(t, np.maximum(result.column("damping_1"), 1e-12), label="damping ρ")
        axes[2, 0].legend(fontsize=8)
    ax = axes[2, 1]
    for i in range(n):
        ax.plot(t, result.column(f"wc{i + 1}_1"), label=f"w_c{i + 1}")
    ax.set(xlabel="t [s]", title="joint-limit weights w_c (1 − W_b)", ylim=(-0.05, 1.05))
    ax.legend(ncol=4, fontsize=8)
    ax.grid(alpha=0.3)
    s = meta.get("summary", {})
    fig.suptitle(f"{meta.get('robot', {}).get('name', '')} — {meta.get('method', '')} — within limits: "
                 f"{'yes' if s.get('within_limits') else 'no'} — tracks: {'yes' if s.get('tracks') else 'no'}")
    _save(fig, out_path)
