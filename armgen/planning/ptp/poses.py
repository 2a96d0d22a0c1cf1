"""PTP waypoints given as tool poses (``waypoints.xyz`` / ``waypoints.rpy``): each pose is
solved by the inverse kinematics (:meth:`armgen.robot.Robot.ik`) from the previous waypoint's
solution, with the self-motion pulled toward it (nearest in joint space, so the arm does not
change branch between waypoints); the first from ``waypoints.seed`` (a configuration name or
joint values; default the middle of the limits). The joint splines are then planned as for
``waypoints.theta``; plan.json records the solved configurations (``ik``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ...errors import PlanningError, TaskFileError
from ...description import rpy_matrix
from ...robot import Robot

POSE_FIELDS = ("xyz", "rpy", "seed")


def _rows(source: str, value: Any, field: str, count: int | None) -> np.ndarray:
    array = np.asarray(value, dtype=float) if isinstance(value, list) else np.zeros((0,))
    if array.ndim != 2 or array.shape[1] != 3 or not np.all(np.isfinite(array)) or (count and len(array) != count):
        want = f"{count} " if count else ""
        raise TaskFileError(f"{source}: field 'waypoints.{field}' must be a list of {want}[x, y, z] triples of finite "
                            "numbers (one per waypoint)")
    return array


def solve_pose_waypoints(robot: Robot, waypoints: dict[str, Any], source: str, scale: float) -> tuple[np.ndarray, dict]:
    """(q per waypoint (waypoints × n, rad), the record for plan.json) of ``waypoints.xyz``
    (m) and ``waypoints.rpy`` (the task's angle unit, ``scale`` rad per unit)."""
    if "theta" in waypoints:
        raise TaskFileError(f"{source}: field 'waypoints': give either theta (joint angles) or xyz/rpy (tool poses), "
                            "not both")
    xyz = _rows(source, waypoints.get("xyz"), "xyz", None)
    rpy = _rows(source, waypoints["rpy"], "rpy", len(xyz)) * scale if "rpy" in waypoints else np.zeros_like(xyz)
    seed = waypoints.get("seed")
    try:
        if isinstance(seed, str):
            q = robot.configuration(seed)
        elif seed is not None:
            q = np.asarray(seed, dtype=float) * np.array([scale if j.revolute else 1.0 for j in robot.joints])
            robot.check_within_limits(q, f"{source}: field 'waypoints.seed'")
        else:
            q = robot.qmid
    except (ValueError, TypeError) as exc:
        raise TaskFileError(f"{source}: field 'waypoints.seed': {exc}; give a configuration name or "
                            f"{robot.n} joint values") from None
    solved, record = [], {"waypoints": [], "position_error_m": [], "orientation_error_rad": [], "iterations": []}
    for k, (position, angles) in enumerate(zip(xyz, rpy)):
        pose = np.eye(4)
        pose[:3, :3] = rpy_matrix(*angles)
        pose[:3, 3] = position
        result = robot.ik(pose, q, seed=q)
        if not result.success:
            raise PlanningError(f"{source}: waypoint {k} (waypoints.xyz[{k}] = {position.tolist()}) is not reachable by "
                                f"robot '{robot.name}' from the previous waypoint's configuration: the closest "
                                f"configuration found is {float(result.position_error):.3g} m / "
                                f"{float(result.orientation_error):.3g} rad away; move the pose within reach")
        q = result.q
        solved.append(q)
        record["waypoints"].append(q.tolist())
        record["position_error_m"].append(float(result.position_error))
        record["orientation_error_rad"].append(float(result.orientation_error))
        record["iterations"].append(int(result.iterations))
    return np.array(solved), record
