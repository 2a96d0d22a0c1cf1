"""A plan's samples as stream waypoints every 1/rate seconds: its joints (t, q, qd), or its tool
poses (t, pose, twist) from a plan's pose columns or a pose file."""

from __future__ import annotations

import re

import numpy as np
from scipy.spatial.transform import Rotation

from ..description import rpy_matrix
from .client import LinkError



class StreamFileError(LinkError):
    """A plan or pose file the stream cannot use (columns missing, a value not finite, samples off
    the rate's grid, a bad rate): exit 2, as a bad option."""

    exit_code = 2


# A plan's (and a pose file's) tool pose: position, then R = Rz(yaw) Ry(pitch) Rx(roll)
POSE_COLUMNS = ("x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad")

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
    raise StreamFileError(f"the plan has no position and velocity columns for the board's {ndof} joints "
                    "(q1_rad ... with dq1_rad_s ..., or theta_<joint>_rad with omega_<joint>_rad_s for every joint); "
                    "plan the task for the board's robot")


def plan_waypoints(columns: list[str], data: np.ndarray, ndof: int, rate_hz: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every sample of the plan on the 1/rate_hz grid from its start (and its last sample), with
    the times from 0."""
    qi, qdi = joint_columns(columns, ndof)
    t, pick = _grid(columns, data, rate_hz)
    return t[pick], data[np.ix_(pick, qi)], data[np.ix_(pick, qdi)]


def has_joints(columns: list[str], ndof: int) -> bool:
    try:
        joint_columns(columns, ndof)
    except StreamFileError:
        return False
    return True


def plan_pose_waypoints(columns: list[str], data: np.ndarray, rate_hz: float
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tool poses of a plan (its columns ``x_m y_m z_m roll_rad pitch_rad yaw_rad``) or of a
    pose file (``t_s`` and those columns) on the 1/rate_hz grid (and the last sample): times from
    0, poses (n, 4, 4) and twists (n, 6: [v; w], base frame). The twists are the central
    differences of the file's own samples (a plan's 1 ms samples: O(h^2) = 1e-6 of the motion's
    curvature), zero at the first and the last sample: a stream starts and ends at rest."""
    missing = [c for c in ("t_s",) + POSE_COLUMNS if c not in columns]
    if missing:
        raise StreamFileError(f"the file has no column {missing[0]}: a pose stream needs t_s and "
                        f"{' '.join(POSE_COLUMNS)} (a resolved-rate plan's columns)")
    t_all, pick = _grid(columns, data, rate_hz)
    pose = data[:, [columns.index(c) for c in POSE_COLUMNS]]
    if not np.all(np.isfinite(pose)):
        raise StreamFileError("a pose holds NaN or inf; give finite numbers")
    rotations = np.array([rpy_matrix(*row[3:]) for row in pose])
    twists = np.zeros((len(t_all), 6))
    if len(t_all) > 2:
        span = (t_all[2:] - t_all[:-2])[:, None]
        twists[1:-1, :3] = (pose[2:, :3] - pose[:-2, :3]) / span
        relative = Rotation.from_matrix(rotations[2:] @ rotations[:-2].transpose(0, 2, 1))
        twists[1:-1, 3:] = relative.as_rotvec() / span
    poses = np.repeat(np.eye(4)[None], len(pick), axis=0)
    poses[:, :3, :3] = rotations[pick]
    poses[:, :3, 3] = pose[pick, :3]
    return t_all[pick], poses, twists[pick]


def _grid(columns: list[str], data: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """The times from the first sample, and the samples on the 1/rate_hz grid (with the last)."""
    if not (rate_hz > 0 and np.isfinite(rate_hz)):
        raise StreamFileError(f"--rate {rate_hz}: give a positive rate in Hz")
    t = data[:, columns.index("t_s")] - data[0, columns.index("t_s")]
    phase = t * rate_hz
    on_grid = np.abs(phase - np.rint(phase)) <= GRID_TOL_S * rate_hz
    pick = np.nonzero(on_grid)[0]
    if len(pick) < 2:
        step = float(np.median(np.diff(t))) if len(t) > 1 else float("nan")
        raise StreamFileError(f"the plan's samples ({step:g} s apart) are not on a {rate_hz:g} Hz grid: choose a rate whose "
                        "period is a whole number of the plan's steps")
    if pick[-1] != len(t) - 1:
        pick = np.append(pick, len(t) - 1)
    return t, pick
