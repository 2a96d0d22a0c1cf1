"""Figure panels shared by the resolved-rate planners' plots (cartesian, fault-tolerant, weighted GPM): joint angles, joint velocities and task error over time (the layout of the spec 20 paper's figures: angles in degrees
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
