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
from ...description.model import MAX_ABS_ANGLE_RAD, MAX_ABS_LENGTH_M, TASK_ROWS
from ...robot import Robot
from ...symbolic.ik import TOL_ORIENTATION, TOL_POSITION

POSE_FIELDS = ("xyz", "rpy", "seed")


def uncontrolled_error(robot: Robot, pose: np.ndarray, q: np.ndarray) -> tuple[list[str], float, float]:
    """The task rows ``robot`` does not control (a planar arm's vz, wx, wy), and the error of
    ``pose`` in them at ``q``: the largest position (m) and rotation-vector (rad, base frame)
    component. The IK drives only the controlled rows, so these say what it left of the pose."""
    from scipy.spatial.transform import Rotation

    free = [k for k in range(len(TASK_ROWS)) if k not in robot.task_rows]
    reached = robot.fk(q)
    error = np.concatenate([pose[:3, 3] - reached[:3, 3],
                            Rotation.from_matrix(pose[:3, :3] @ reached[:3, :3].T).as_rotvec()])
    position = max((abs(error[k]) for k in free if k < 3), default=0.0)
    orientation = max((abs(error[k]) for k in free if k >= 3), default=0.0)
    return [TASK_ROWS[k] for k in free], float(position), float(orientation)


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
    for field, values, bound, unit in (("xyz", xyz, MAX_ABS_LENGTH_M, "m"), ("rpy", rpy, MAX_ABS_ANGLE_RAD, "rad")):
        beyond = np.abs(values) > bound
        if beyond.any():
            k = int(np.argwhere(beyond)[0][0])
            raise TaskFileError(f"{source}: field 'waypoints.{field}[{k}]' is beyond ±{bound:g} {unit}; no pose of an "
                                "arm needs that: check the value and [units]")
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
        free, off_position, off_orientation = uncontrolled_error(robot, pose, result.q)
        if off_position > TOL_POSITION or ("rpy" in waypoints and off_orientation > TOL_ORIENTATION):
            controlled = ", ".join(TASK_ROWS[r] for r in robot.task_rows)
            raise PlanningError(f"{source}: waypoint {k} (waypoints.xyz[{k}] = {position.tolist()}) asks robot "
                                f"'{robot.name}' for other values in the rows it does not control "
                                f"({', '.join(free)}): {off_position:.3g} m / {off_orientation:.3g} rad off; it "
                                f"controls only {controlled}: give poses the arm takes there (a planar arm: its plane)")
        q = result.q
        solved.append(q)
        record["waypoints"].append(q.tolist())
        record["position_error_m"].append(float(result.position_error))
        record["orientation_error_rad"].append(float(result.orientation_error))
        record["iterations"].append(int(result.iterations))
    return np.array(solved), record
