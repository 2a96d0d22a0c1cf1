"""PTP waypoints given as tool poses (``waypoints.xyz`` / ``waypoints.rpy``): each pose is
solved by the inverse kinematics (:meth:`armgen.robot.Robot.ik`) from the previous waypoint's
solution, with the self-motion pulled toward it (nearest in joint space, so the arm does not
change branch between waypoints); the first from ``waypoints.seed`` (a configuration name or
joint values; default the middle of the limits). The joint splines are then planned as for
``waypoints.theta``; plan.json records the solved configurations (``ik``). The schema
checks the fields' shapes and magnitudes (:mod:`.schema`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import PlanningError, TaskFileError
from ...description import rpy_matrix
from ...description.model import TASK_ROWS
from ...robot import Robot
from ...symbolic.ik import TOL_ORIENTATION, TOL_POSITION
from ..common.collision import TaskCollision, ik_arguments
from ..common.start import joint_values

METRES = 1.0  # a ptp task has no [units] length: its tool positions are in m


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


@dataclass(frozen=True)
class SolvedPoses:
    """Tool-pose waypoints solved by the inverse kinematics: the configurations (waypoints × n,
    rad) and, per waypoint, the IK's position and orientation errors and its iterations."""

    q: np.ndarray
    position_error_m: tuple[float, ...]
    orientation_error_rad: tuple[float, ...]
    iterations: tuple[int, ...]

    def record(self) -> dict[str, Any]:
        """The record plan.json keeps under ``ik``."""
        return {"waypoints": self.q.tolist(), "position_error_m": list(self.position_error_m),
                "orientation_error_rad": list(self.orientation_error_rad), "iterations": list(self.iterations)}


def _seed_configuration(robot: Robot, seed: str | list[float] | None, source: str, scale: float) -> np.ndarray:
    """The configuration the first pose is solved from: a name, joint values (angles in the task's
    unit, ``scale`` rad per unit; lengths in m), or the middle of the limits."""
    try:
        if isinstance(seed, str):
            return robot.configuration(seed)
        if seed is not None:
            q = joint_values(seed, robot, "waypoints.seed", source, METRES, scale)
            robot.check_within_limits(q, f"{source}: field 'waypoints.seed'")
            return q
        return robot.qmid
    except (ValueError, TypeError) as exc:
        raise TaskFileError(f"{source}: field 'waypoints.seed': {exc}; give a configuration name or "
                            f"{robot.n} joint values") from None


def solve_pose_waypoints(robot: Robot, xyz: np.ndarray, rpy: np.ndarray | None, seed: str | list[float] | None,
                         source: str, scale: float, collision: TaskCollision | None = None) -> SolvedPoses:
    """The configurations of tool-pose waypoints: positions ``xyz`` (waypoints × 3, m) and
    orientations ``rpy`` (waypoints × 3, rad; None: the base frame's, and the orientation is
    free where the robot does not control it), each solved from the one before, the first from
    ``seed`` (a configuration name or joint values in the task's angle unit, ``scale`` rad per
    unit); each clear of ``collision``'s obstacles and of the arm itself at its clearance."""
    q = _seed_configuration(robot, seed, source, scale)
    solved, position_errors, orientation_errors, iterations = [], [], [], []
    for k, (position, angles) in enumerate(zip(xyz, rpy if rpy is not None else np.zeros_like(xyz))):
        pose = np.eye(4)
        pose[:3, :3] = rpy_matrix(*angles)
        pose[:3, 3] = position
        result = robot.ik(pose, q, seed=q, **ik_arguments(collision))
        if result.colliding:
            raise PlanningError(f"{source}: waypoint {k} (waypoints.xyz[{k}] = {position.tolist()}): every "
                                f"configuration of robot '{robot.name}' the inverse kinematics found that reaches it "
                                f"comes closer than the clearance (the best: least distance "
                                f"{float(result.clearance) * 1e3:.1f} mm); move the pose or the obstacles, or lower "
                                "[collision] clearance")
        if not result.success:
            raise PlanningError(f"{source}: waypoint {k} (waypoints.xyz[{k}] = {position.tolist()}) is not reachable by "
                                f"robot '{robot.name}' from the previous waypoint's configuration: the closest "
                                f"configuration found is {float(result.position_error):.3g} m / "
                                f"{float(result.orientation_error):.3g} rad away; move the pose within reach")
        free, off_position, off_orientation = uncontrolled_error(robot, pose, result.q)
        if off_position > TOL_POSITION or (rpy is not None and off_orientation > TOL_ORIENTATION):
            controlled = ", ".join(TASK_ROWS[r] for r in robot.task_rows)
            raise PlanningError(f"{source}: waypoint {k} (waypoints.xyz[{k}] = {position.tolist()}) asks robot "
                                f"'{robot.name}' for other values in the rows it does not control "
                                f"({', '.join(free)}): {off_position:.3g} m / {off_orientation:.3g} rad off; it "
                                f"controls only {controlled}: give poses the arm takes there (a planar arm: its plane)")
        q = result.q
        solved.append(q)
        position_errors.append(float(result.position_error))
        orientation_errors.append(float(result.orientation_error))
        iterations.append(int(result.iterations))
    return SolvedPoses(np.array(solved), tuple(position_errors), tuple(orientation_errors), tuple(iterations))
