"""``armgen plot`` for resolved-rate plans: joint angles, joint velocities, criteria and task
error over time, in one figure (the layout of the spec 20 paper's figures: angles in degrees
with the ±limits dashed, velocities in deg/s)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..fileio import atomic_open  # noqa: E402
from .result import PlanResult  # noqa: E402


def _joint_count(result: PlanResult) -> int:
    return sum(1 for c in result.columns if c.startswith("q") and c.endswith("_rad") and c[1:-4].isdigit())


def plot_resolved_rate(result: PlanResult, out_path: str | Path) -> None:
    n = _joint_count(result)
    t = result.column("t_s")
    q = np.degrees(np.column_stack([result.column(f"q{i + 1}_rad") for i in range(n)]))
    qd = np.degrees(np.column_stack([result.column(f"dq{i + 1}_rad_s") for i in range(n)]))
    meta = result.metadata
    limits_deg = [tuple(np.degrees(lim)) for lim in meta.get("robot", {}).get("qlim_rad", [])]
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5), constrained_layout=True)
    ax = axes[0, 0]
    for i in range(n):
        ax.plot(t, q[:, i], label=f"θ{i + 1}")
    if limits_deg:
        for lo, hi in {tuple(np.round(lim, 6)) for lim in limits_deg}:
            ax.axhline(lo, color="k", ls="--", lw=0.8)
            ax.axhline(hi, color="k", ls="--", lw=0.8)
    ax.set(xlabel="t [s]", ylabel="joint angle [deg]", title="joint angles")
    ax.legend(ncol=4, fontsize=8)
    ax.grid(alpha=0.3)
    ax = axes[0, 1]
    for i in range(n):
        ax.plot(t, qd[:, i], label=f"θ̇{i + 1}")
    ax.set(xlabel="t [s]", ylabel="joint velocity [deg/s]", title="joint velocities")
    ax.legend(ncol=4, fontsize=8)
    ax.grid(alpha=0.3)
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
    ax = axes[1, 1]
    ax.semilogy(t, np.maximum(result.column("pos_err_m") * 1e3, 1e-12), label="position error [mm]")
    ax.semilogy(t, np.maximum(np.degrees(result.column("ori_err_rad")), 1e-12), label="orientation error [deg]")
    ax.set(xlabel="t [s]", title="task error")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    summary = meta.get("summary", {})
    title = f"{meta.get('robot', {}).get('name', '')} — {meta.get('method', '')}"
    if "max_final_deviation_deg" in summary:
        title += f" — final deviation {summary['max_final_deviation_deg']:.3g}° — max |θ| {max(summary['max_abs_q_deg']):.1f}°"
    fig.suptitle(title)
    with atomic_open(out_path, "wb") as handle:
        fig.savefig(handle, format="png", dpi=110)
    plt.close(fig)
