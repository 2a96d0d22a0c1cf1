"""The spherical-shoulder/wrist reach test of the fault-tolerant planner: for a 7-DOF arm whose
shoulder and wrist axes meet in points, the wrist-centre path shows before planning whether the
elbow can stretch or fold far enough."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...robot import Robot
from ..backends import Backend
from ..taskpath import TaskPath

# Tolerance of the spherical-shoulder/wrist test: axes meet within 1e-9 m.
SRS_AXIS_TOL = 1e-9


def _axes(jac: np.ndarray, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points (..., k, 3) and unit directions (..., k, 3) of the revolute joint axes from the
    geometric Jacobian (..., 6, k): with v = z × (p − o), the point p + z × v lies on the axis."""
    z = np.swapaxes(jac[..., 3:, :], -1, -2)
    points = pose[..., None, :3, 3] + np.cross(z, np.swapaxes(jac[..., :3, :], -1, -2))
    return points, z / np.linalg.norm(z, axis=-1, keepdims=True)


def _common_point(points: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares meeting point (..., 3) of lines (..., k, 3) and the largest distance of it
    from a line (inf where the lines are parallel: no single point)."""
    proj = np.eye(3) - dirs[..., :, None] * dirs[..., None, :]
    a = proj.sum(axis=-3)
    b = (proj @ points[..., None])[..., 0].sum(axis=-2)
    parallel = np.linalg.cond(a) > 1e12
    point = np.linalg.solve(np.where(parallel[..., None, None], np.eye(3), a), b[..., None])[..., 0]
    point = np.where(parallel[..., None], 0.0, point)
    err = np.linalg.norm((proj @ (point[..., None, :] - points)[..., None])[..., 0], axis=-1).max(axis=-1)
    return point, np.where(parallel, np.inf, err)


@dataclass
class ReachCheck:
    """Shoulder–wrist distance needed along the path vs the range the elbow allows."""

    elbow: str
    distance_range_m: tuple[float, float]
    needed_range_m: tuple[float, float]
    first_bad_t_s: float | None
    needed_at_bad_m: float | None

    @property
    def feasible(self) -> bool:
        return self.first_bad_t_s is None

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "spherical shoulder and wrist", "elbow": self.elbow, "feasible": self.feasible,
                "elbow_distance_range_mm": [v * 1e3 for v in self.distance_range_m],
                "needed_distance_range_mm": [v * 1e3 for v in self.needed_range_m],
                "first_infeasible_t_s": self.first_bad_t_s}


def srs_reach_check(robot: Robot, backend: Backend, q_start: np.ndarray, path: TaskPath) -> ReachCheck | None:
    """For a 7-DOF arm whose axes 1–3 meet at a shoulder point and 5–7 at a wrist centre,
    compare the shoulder–wrist distance the path needs with the elbow's range; None otherwise."""
    if robot.n != 7 or not all(j.revolute for j in robot.joints):
        return None
    pose, jac = backend.call("fk_jacobian", q_start)
    points, dirs = _axes(jac, pose)
    shoulder, err_s = _common_point(points[:3], dirs[:3])
    wrist, err_w = _common_point(points[4:], dirs[4:])
    if err_s > SRS_AXIS_TOL or err_w > SRS_AXIS_TOL:
        return None
    wrist_in_tool = pose[:3, :3].T @ (wrist - pose[:3, 3])
    lo, hi = robot.joints[3].qlim
    qs = np.tile(q_start, (721, 1))
    qs[:, 3] = np.linspace(lo, hi, 721)
    poses, jacs = (np.array(m).reshape(m.shape[0], len(qs), -1).transpose(1, 0, 2)
                   for m in backend.model.function("fk_jacobian").map(len(qs))(qs.T))
    s_q, _ = _common_point(*(part[:, :3] for part in _axes(jacs, poses)))
    distances = np.linalg.norm(poses[:, :3, 3] + poses[:, :3, :3] @ wrist_in_tool - s_q, axis=1).tolist()
    d_min, d_max = min(distances), max(distances)
    times = np.arange(801) * path.task.duration / 800
    p_d, r_d, _ = path(times)
    needed = list(zip(times.tolist(), np.linalg.norm(p_d + r_d @ wrist_in_tool - shoulder, axis=1).tolist()))
    values = [d for _, d in needed]
    bad = [(t, d) for t, d in needed if d > d_max + 1e-6 or d < d_min - 1e-6]
    return ReachCheck(robot.joints[3].name, (d_min, d_max), (min(values), max(values)),
                      bad[0][0] if bad else None, bad[0][1] if bad else None)
