"""The robot description, below every other layer: what a robot file or URDF says, in SI.

- :mod:`~armgen.description.model`: :class:`Joint` and :class:`RobotDescription` (joints,
  DH or URDF geometry, limits, speed limits ``qdlim``/``qddlim``, torque limits ``taumax``,
  base and tool, named configurations, task rows, gravity) and :class:`Inertial` (a link's
  mass, centre of mass and inertia in its link frame);
- :mod:`~armgen.description.frames`: roll-pitch-yaw rotations, exact quarter-turn
  trigonometry, the axis alignment of a URDF joint's link frame;
- :mod:`~armgen.description.inertia`: the validity of an inertia tensor, lumping bodies;
- :mod:`~armgen.description.collision`: the arm's capsules (:class:`CollisionModel`: which
  pairs are checked, the obstacle slots) and the obstacles (:class:`SphereObstacle`,
  :class:`CapsuleObstacle`, :class:`BoxObstacle`, :class:`PlaneObstacle`) in SI;
- :mod:`~armgen.description.files`: the robot TOML reader and the bundled robots;
- :mod:`~armgen.description.urdf`: the URDF chain reader; :mod:`~armgen.description.schema`:
  the robot file's pydantic schema.

It imports nothing from the symbolic core, code generation, planning, firmware or
verification (``tests/test_layers.py``). The symbolic core builds its models from a
:class:`RobotDescription`; :class:`armgen.robot.Robot` adds the NumPy methods on top.
"""

from .collision import (BoxObstacle, CapsuleObstacle, CollisionCapsule, CollisionModel, PlaneObstacle,
                        SphereObstacle)
from .files import BUNDLED_DIR, bundled_robots, load_description, parse_description, read_urdf, resolve_robot_path
from .frames import exact_cos_sin, matrix_rpy, rpy_matrix, snap_quarter_turn
from .model import TASK_ROWS, Inertial, Joint, RobotDescription, describe

__all__ = ["BUNDLED_DIR", "TASK_ROWS", "BoxObstacle", "CapsuleObstacle", "CollisionCapsule", "CollisionModel",
           "Inertial", "Joint", "PlaneObstacle", "RobotDescription", "SphereObstacle", "bundled_robots", "describe",
           "exact_cos_sin", "load_description", "matrix_rpy", "parse_description", "read_urdf", "resolve_robot_path",
           "rpy_matrix", "snap_quarter_turn"]
