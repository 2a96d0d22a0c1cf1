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


def _angles_panel(ax, result: PlanResult, n: int, t: np.ndarray) -> None:
    q = np.degrees(np.column_stack([result.column(f"q{i + 1}_rad") for i in range(n)]))
    limits_deg = [tuple(np.degrees(lim)) for lim in result.metadata.get("robot", {}).get("qlim_rad", [])]
    for i in range(n):
        ax.plot(t, q[:, i], label=f"θ{i + 1}")
    if limits_deg:
        for lo, hi in {tuple(np.round(lim, 6)) for lim in limits_deg}:
            ax.axhline(lo, color="k", ls="--", lw=0.8)
            ax.axhline(hi, color="k", ls="--", lw=0.8)
    ax.set(xlabel="t [s]", ylabel="joint angle [deg]", title="joint angles")
    ax.legend(ncol=4, fontsize=8)
    ax.grid(alpha=0.3)


def _velocities_panel(ax, result: PlanResult, n: int, t: np.ndarray) -> None:
    qd = np.degrees(np.column_stack([result.column(f"dq{i + 1}_rad_s") for i in range(n)]))
    for i in range(n):
        ax.plot(t, qd[:, i], label=f"θ̇{i + 1}")
    ax.set(xlabel="t [s]", ylabel="joint velocity [deg/s]", title="joint velocities")
    ax.legend(ncol=4, fontsize=8)
    ax.grid(alpha=0.3)


def _task_error_panel(ax, result: PlanResult, t: np.ndarray) -> None:
    ax.semilogy(t, np.maximum(result.column("pos_err_m") * 1e3, 1e-12), label="position error [mm]")
    ax.semilogy(t, np.maximum(np.degrees(result.column("ori_err_rad")), 1e-12), label="orientation error [deg]")
    ax.set(xlabel="t [s]", title="task error")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)


def _save(fig, out_path: str | Path) -> None:
    with atomic_open(out_path, "wb") as handle:
        fig.savefig(handle, format="png", dpi=110)
    plt.close(fig)


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
