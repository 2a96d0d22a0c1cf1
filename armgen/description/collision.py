"""The arm's collision geometry (capsules on its links) and the cell's obstacles, in SI.

A robot file lists capsules (``[[collision]]``: a segment ``a``–``b`` in a link frame and a
radius; a sphere is a capsule with ``a = b``); a URDF's ``<collision>`` primitives become
capsules too (:mod:`armgen.description.urdf`). The frames are those of the kinematics:
frame 0 is the base frame (after ``[base]``), frame i the link frame of joint i (DH frame i;
for a URDF joint its child link frame turned so that z is the joint axis), frame n the flange.

Which pairs are checked (``docs/collision.md``): every pair of capsules on frames i and j with
``|i − j| ≥ 2``, except the pairs of ``[collision_check] ignore``. Capsules on the same frame
never move relative to each other, and capsules on ADJACENT frames (``|i − j| = 1``, the two
links joined by joint max(i, j)) meet at that joint by construction, so neither is checked.
The base's capsules (frame 0) do not move, so they are not checked against obstacles.

Obstacles (spheres, capsules, boxes, half-spaces) are the inputs of the derived collision
functions: a fixed number of slots per kind (:class:`ObstacleSlots`, ``[collision_check]
max_obstacles`` of the robot file), each slot a column of numbers with an ``active`` flag, so
the generated C has fixed-size arrays and serves every task without being generated again.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence, Union

import numpy as np

from .frames import rpy_matrix

# The most capsules a robot may have: 32 give at most 496 self pairs, beyond any arm model
# (a 7-DOF arm is enclosed by 8 to 16), and keep the generated function's output and code size
# bounded on a microcontroller.
MAX_CAPSULES = 32
# The most obstacle slots of one kind: each slot adds a distance per moving capsule to the
# generated function (a box costs ~650 operations per capsule), so 16 per kind is far beyond
# what a controller's tick can afford.
MAX_OBSTACLE_SLOTS = 16
# The distance reported for an inactive obstacle slot (m): beyond any activation distance a
# task gives (lengths are bounded by MAX_ABS_LENGTH_M), so it never contributes to the criterion.
INACTIVE_DISTANCE = 1e3

# Rows of one slot's column per obstacle kind (the input matrices are rows × slots, column-major):
# sphere: centre (3), radius, active; capsule: a (3), b (3), radius, active;
# box: centre (3), rotation (9, column-major: the box's axes), half-extents (3), active;
# plane: unit outward normal (3), offset (n·x = offset on the boundary), active.
OBSTACLE_KINDS = ("sphere", "capsule", "box", "plane")
OBSTACLE_ROWS = {"sphere": 5, "capsule": 8, "box": 16, "plane": 5}
# The input names of the generated functions, one per kind.
OBSTACLE_INPUTS = {"sphere": "spheres", "capsule": "capsules", "box": "boxes", "plane": "planes"}


@dataclass(frozen=True)
class CollisionCapsule:
    """A capsule on the arm: the segment ``a``–``b`` (m) in frame ``frame`` and a ``radius`` (m).

    ``link`` names what it is attached to in messages (``frame 3``, or the URDF link);
    ``origin`` says where it comes from: ``"robot file"`` or the URDF shape it encloses
    (``"urdf sphere"``, ``"urdf capsule"``, ``"urdf cylinder (enclosed)"``, ``"urdf box (enclosed)"``).
    """

    frame: int
    a: tuple[float, float, float]
    b: tuple[float, float, float]
    radius: float
    link: str
    origin: str = "robot file"

    @property
    def enclosed(self) -> bool:
        """The capsule encloses a URDF shape that is not a capsule (a cylinder or a box)."""
        return "enclosed" in self.origin


@dataclass(frozen=True)
class ObstacleSlots:
    """How many obstacles of each kind the collision functions take (their fixed input sizes)."""

    sphere: int = 4
    capsule: int = 4
    box: int = 2
    plane: int = 2

    def count(self, kind: str) -> int:
        return getattr(self, kind)


@dataclass(frozen=True)
class CollisionModel:
    """The arm's capsules, the pairs not checked, the obstacle slots; ``unusable`` says why the
    geometry cannot be used ("" when it can): a URDF link whose collision shape is a mesh."""

    capsules: tuple[CollisionCapsule, ...] = ()
    ignore: tuple[tuple[int, int], ...] = ()
    slots: ObstacleSlots = field(default_factory=ObstacleSlots)
    unusable: str = ""

    @property
    def usable(self) -> bool:
        return bool(self.capsules) and not self.unusable

    def self_pairs(self) -> tuple[tuple[int, int], ...]:
        """The checked pairs of capsules (i < j): frames at least two apart, not ignored."""
        ignored = set(self.ignore)
        return tuple((i, j) for i in range(len(self.capsules)) for j in range(i + 1, len(self.capsules))
                     if abs(self.capsules[i].frame - self.capsules[j].frame) >= 2 and (i, j) not in ignored)

    def moving(self) -> tuple[int, ...]:
        """The capsules checked against obstacles: those not on the base (frame 0)."""
        return tuple(i for i, capsule in enumerate(self.capsules) if capsule.frame > 0)

    def pair_labels(self) -> list[tuple[str, str]]:
        """What each entry of ``collision_distances``' output ``d`` is, in order: the self pairs
        (``capsule i``, ``capsule j``), then for each obstacle kind and slot, each moving capsule
        against it (``capsule i``, ``box 0``)."""
        labels = [(f"capsule {i}", f"capsule {j}") for i, j in self.self_pairs()]
        for kind in OBSTACLE_KINDS:
            for slot in range(self.slots.count(kind)):
                labels += [(f"capsule {i}", f"{kind} {slot}") for i in self.moving()]
        return labels


# -- obstacles --------------------------------------------------------------------------


@dataclass(frozen=True)
class SphereObstacle:
    centre: tuple[float, float, float]  # m, base frame
    radius: float  # m


@dataclass(frozen=True)
class CapsuleObstacle:
    a: tuple[float, float, float]  # m, base frame
    b: tuple[float, float, float]
    radius: float


@dataclass(frozen=True)
class BoxObstacle:
    centre: tuple[float, float, float]  # m, base frame
    size: tuple[float, float, float]  # m, full edge lengths along the box's own axes
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)  # rad, the box's axes: R = Rz(yaw) Ry(pitch) Rx(roll)


@dataclass(frozen=True)
class PlaneObstacle:
    """A half-space (a table, a wall): the solid side of the plane through ``point`` is the
    one ``normal`` points away from."""

    point: tuple[float, float, float]  # m, base frame
    normal: tuple[float, float, float]  # any length > 0, out of the solid


Obstacle = Union[SphereObstacle, CapsuleObstacle, BoxObstacle, PlaneObstacle]
_KIND = {SphereObstacle: "sphere", CapsuleObstacle: "capsule", BoxObstacle: "box", PlaneObstacle: "plane"}


def obstacle_kind(obstacle: Obstacle) -> str:
    return _KIND[type(obstacle)]


def _column(obstacle: Obstacle) -> list[float]:
    """One active slot's numbers (OBSTACLE_ROWS)."""
    if isinstance(obstacle, SphereObstacle):
        return [*obstacle.centre, obstacle.radius, 1.0]
    if isinstance(obstacle, CapsuleObstacle):
        return [*obstacle.a, *obstacle.b, obstacle.radius, 1.0]
    if isinstance(obstacle, BoxObstacle):
        rotation = rpy_matrix(*obstacle.rpy)
        return [*obstacle.centre, *rotation.T.reshape(-1), *(0.5 * np.asarray(obstacle.size)), 1.0]
    normal = np.asarray(obstacle.normal, dtype=float)
    length = float(np.linalg.norm(normal))
    if not length > 0.0:
        raise ValueError(f"plane obstacle: normal {list(obstacle.normal)} has no direction; give a non-zero normal")
    unit = normal / length
    return [*unit, float(unit @ np.asarray(obstacle.point, dtype=float)), 1.0]


def obstacle_parameters(obstacles: Sequence[Obstacle], slots: ObstacleSlots) -> dict[str, np.ndarray]:
    """The collision functions' obstacle inputs: per kind (``spheres``, ``capsules``, ``boxes``,
    ``planes``) a ``rows × slots`` matrix, the given obstacles first, the other slots inactive
    (all zero: ``active`` = 0). A kind with no slot has no input. Raises ValueError when a kind
    has more obstacles than slots."""
    out = {}
    for kind in OBSTACLE_KINDS:
        given = [o for o in obstacles if obstacle_kind(o) == kind]
        count = slots.count(kind)
        if len(given) > count:
            raise ValueError(f"{len(given)} {kind} obstacles, but the robot's collision functions take {count}; raise "
                             f"[collision_check] max_obstacles.{kind} in the robot file (at most {MAX_OBSTACLE_SLOTS})")
        if count:
            matrix = np.zeros((OBSTACLE_ROWS[kind], count))
            for slot, obstacle in enumerate(given):
                matrix[:, slot] = _column(obstacle)
            out[OBSTACLE_INPUTS[kind]] = matrix
    return out
