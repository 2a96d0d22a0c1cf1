"""A plan's joint samples as stream waypoints: (t, q, qd) every 1/rate seconds."""

from __future__ import annotations

import re

import numpy as np

from .client import LinkError

# On-grid test of the plan's sample times against the waypoint period: the CSV holds the times
# to 17 digits, so a grid point is off by ~1e-15 s at most; 1e-9 s is still far below a tick.
GRID_TOL_S = 1e-9


def joint_columns(columns: list[str], ndof: int) -> tuple[list[int], list[int]]:
    """The columns of the joint positions and velocities, in joint order: ``q<k>_rad|m`` with
    ``dq<k>_rad_s|m_s`` (the resolved-rate planners), or ``theta_<joint>_rad|m`` with
    ``omega_<joint>_rad_s|m_s`` (the PTP planner, joints in the order of the columns)."""
    def find(pattern: str) -> list[int]:
        return [i for i, c in enumerate(columns) if re.fullmatch(pattern, c)]

    q = [find(rf"q{k}_(rad|m)") for k in range(1, ndof + 1)]
    qd = [find(rf"dq{k}_(rad_s|m_s)") for k in range(1, ndof + 1)]
    if all(len(x) == 1 for x in q + qd):
        return [x[0] for x in q], [x[0] for x in qd]
    theta, omega = find(r"theta_.+_(rad|m)"), find(r"omega_.+_(rad_s|m_s)")
    if len(theta) == len(omega) == ndof:
        return theta, omega
    raise LinkError(f"the plan has no position and velocity columns for the board's {ndof} joints "
                    "(q1_rad ... with dq1_rad_s ..., or theta_<joint>_rad with omega_<joint>_rad_s for every joint); "
                    "plan the task for the board's robot")


def plan_waypoints(columns: list[str], data: np.ndarray, ndof: int, rate_hz: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every sample of the plan on the 1/rate_hz grid from its start (and its last sample), with
    the times from 0."""
    if not (rate_hz > 0 and np.isfinite(rate_hz)):
        raise LinkError(f"--rate {rate_hz}: give a positive rate in Hz")
    qi, qdi = joint_columns(columns, ndof)
    t = data[:, columns.index("t_s")] - data[0, columns.index("t_s")]
    phase = t * rate_hz
    on_grid = np.abs(phase - np.rint(phase)) <= GRID_TOL_S * rate_hz
    pick = np.nonzero(on_grid)[0]
    if len(pick) < 2:
        step = float(np.median(np.diff(t))) if len(t) > 1 else float("nan")
        raise LinkError(f"the plan's samples ({step:g} s apart) are not on a {rate_hz:g} Hz grid: choose a rate whose "
                        "period is a whole number of the plan's steps")
    if pick[-1] != len(t) - 1:
        pick = np.append(pick, len(t) - 1)
    return t[pick], data[np.ix_(pick, qi)], data[np.ix_(pick, qdi)]
