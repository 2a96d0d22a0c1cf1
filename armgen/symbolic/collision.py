"""The collision functions of a robot with capsules: the distances of the checked pairs and the
smooth collision criterion H_C with its gradient, as named ``casadi.Function``s.

Inputs: ``q``, then one matrix per obstacle kind with slots (``spheres`` 5×K, ``capsules`` 8×K,
``boxes`` 16×K, ``planes`` 5×K; the rows of
:data:`armgen.description.collision.OBSTACLE_ROWS`, each column one slot with an ``active``
flag), so the generated C has fixed sizes and serves every task. ``collision_criterion`` also
takes ``clearance`` and ``activation`` (m).

``d`` holds, in the order of :meth:`~armgen.description.collision.CollisionModel.pair_labels`,
the signed distance (m; coal's convention: negative when overlapping) of every checked self
pair, then of every moving capsule against every obstacle slot (an inactive slot gives
:data:`~armgen.description.collision.INACTIVE_DISTANCE`). The geometry is in
:mod:`armgen.symbolic.collision_geometry`.

The criterion (``docs/collision.md``), for clearance c and activation ρ > c, with the room
u = d − c, the band s = ρ − c and the floor f = BARRIER_FLOOR · s::

    H_C = Σ_k g(d_k − c),   g(u) = ½ x(u)²,   x(u) = max(s / u − 1, 0)          for u ≥ f
                            g(u) = g(f) + g'(f) (u − f),  g'(f) = −x(f) s / f²   for u < f

0 at and beyond the activation distance with a zero slope there, growing like 1/(d − c)² toward
the clearance (x = (ρ − d)/(d − c)), and continued below c + f by its tangent: finite, with a
continuous gradient of the largest magnitude, for a configuration close to or beyond the
clearance, or overlapping. C¹ everywhere. ∇H_C is the reverse derivative of that expression (CasADi AD
through the kinematics and the clamps).
"""

from __future__ import annotations

import casadi as ca

from ..description import RobotDescription
from ..description.collision import (INACTIVE_DISTANCE, OBSTACLE_INPUTS, OBSTACLE_KINDS, OBSTACLE_ROWS,
                                     CollisionCapsule)
from ..errors import RobotFileError
from . import collision_geometry as geometry
from .kinematics import chain

COLLISION_FUNCTIONS = ("collision_distances", "collision_criterion")
# Below c + BARRIER_FLOOR (ρ − c) the barrier goes on along its tangent, so value and gradient
# stay finite and continuous for a configuration already beyond the clearance. At the floor the
# value is ½ (1/BARRIER_FLOOR − 1)² = 180, dominating the other criteria (of order 1 to 10), and
# the slope (1/BARRIER_FLOOR − 1)/(BARRIER_FLOOR² (ρ − c)) = 7600/(ρ − c) per metre: in single
# precision a distance's rounding (~1e-7 m per metre of reach) moves the gradient by ≤ 1e-3/(ρ − c),
# where a floor of 1e-3 (slope 1e9/(ρ − c)) let rounding alone give gradients of 60 (measured).
BARRIER_FLOOR = 0.05


def require_collision(robot: RobotDescription) -> None:
    """Raise a clear error when the robot has no usable capsules."""
    if robot.has_collision:
        return
    why = robot.collision.unusable or "it has no capsules"
    raise RobotFileError(
        f"{robot.source or '<in memory>'}: robot '{robot.name}' has no collision model ({why}), so it has no collision "
        "functions (collision_distances, collision_criterion); give the arm's capsules as [[collision]] tables in the "
        "robot file (docs/collision.md)")


class _Arm:
    """The capsules' segment ends in the base frame at symbolic q."""

    def __init__(self, robot: RobotDescription, q: ca.SX):
        _, joint_frames, _ = chain(robot, q)
        frames = [ca.SX(ca.DM(robot.base)), *joint_frames]
        self.capsules = robot.collision.capsules
        self.ends = [self._ends(frames[c.frame], c) for c in self.capsules]

    @staticmethod
    def _ends(frame: ca.SX, capsule: CollisionCapsule) -> tuple[ca.SX, ca.SX]:
        a = ca.mtimes(frame[:3, :3], ca.DM(capsule.a)) + frame[:3, 3]
        if capsule.a == capsule.b:  # a sphere: one point, and the point formulas
            return a, a
        return a, ca.mtimes(frame[:3, :3], ca.DM(capsule.b)) + frame[:3, 3]

    def is_point(self, i: int) -> bool:
        return self.capsules[i].a == self.capsules[i].b

    def axis_to_segment(self, i: int, a: ca.SX, b: ca.SX) -> ca.SX:
        """Capsule i's axis to the segment [a, b] (a runtime segment, possibly of zero length)."""
        ai, bi = self.ends[i]
        return geometry.point_segment(ai, a, b) if self.is_point(i) else geometry.segment_segment(ai, bi, a, b)

    def self_distance(self, i: int, j: int) -> ca.SX:
        (ai, bi), (aj, bj) = self.ends[i], self.ends[j]
        radii = self.capsules[i].radius + self.capsules[j].radius
        if self.is_point(i) and self.is_point(j):
            return geometry.point_point(ai, aj) - radii
        if self.is_point(i):
            return geometry.point_segment(ai, aj, bj) - radii
        if self.is_point(j):
            return geometry.point_segment(aj, ai, bi) - radii
        return geometry.segment_segment(ai, bi, aj, bj) - radii

    def obstacle_distance(self, i: int, kind: str, column: ca.SX) -> ca.SX:
        """Capsule i to one obstacle slot (its column), INACTIVE_DISTANCE when the slot is off."""
        a, b = self.ends[i]
        radius = self.capsules[i].radius
        if kind == "sphere":
            distance = self.axis_to_segment(i, column[0:3], column[0:3]) - column[3] - radius
        elif kind == "capsule":
            distance = self.axis_to_segment(i, column[0:3], column[3:6]) - column[6] - radius
        elif kind == "box":
            distance = geometry.segment_box(a, b, column[0:3], ca.reshape(column[3:12], 3, 3), column[12:15]) - radius
        else:
            distance = geometry.segment_halfspace(a, b, column[0:3], column[3]) - radius
        return ca.if_else(column[-1] != 0, distance, INACTIVE_DISTANCE)


def _obstacle_inputs(robot: RobotDescription) -> list[tuple[str, ca.SX]]:
    """(kind, rows × slots symbol) per kind with slots."""
    slots = robot.collision.slots
    return [(kind, ca.SX.sym(OBSTACLE_INPUTS[kind], OBSTACLE_ROWS[kind], slots.count(kind)))
            for kind in OBSTACLE_KINDS if slots.count(kind)]


def distances(robot: RobotDescription, q: ca.SX, obstacles: list[tuple[str, ca.SX]]) -> ca.SX:
    """The column of signed distances (pair_labels' order) at symbolic q and obstacle inputs."""
    arm = _Arm(robot, q)
    model = robot.collision
    entries = [arm.self_distance(i, j) for i, j in model.self_pairs()]
    for kind, matrix in obstacles:
        for slot in range(matrix.shape[1]):
            entries += [arm.obstacle_distance(i, kind, matrix[:, slot]) for i in model.moving()]
    return ca.vertcat(*entries)


def barrier(d: ca.SX, clearance: ca.SX, activation: ca.SX) -> ca.SX:
    """The criterion H_C of the distances ``d`` (module docstring): branch-free, ``fmax``/``fmin``."""
    span = activation - clearance
    floor = BARRIER_FLOOR * span
    room = d - clearance
    held = ca.fmax(room, floor)
    x = ca.fmax(span / held - 1.0, 0.0)
    # below the floor (room < floor, held = floor) the tangent: g(f) − g'(f) (f − room)
    return ca.sum1(0.5 * x * x - x * span / (held * held) * ca.fmin(room - floor, 0.0))


def collision_function(robot: RobotDescription, name: str) -> ca.Function:
    """One of :data:`COLLISION_FUNCTIONS` as a named ``casadi.Function``."""
    require_collision(robot)
    q = ca.SX.sym("q", robot.n)
    obstacles = _obstacle_inputs(robot)
    d = distances(robot, q, obstacles)
    inputs, labels = [q, *[m for _, m in obstacles]], ["q", *[OBSTACLE_INPUTS[k] for k, _ in obstacles]]
    # ca.cse merges the equal subexpressions the pairs build apart (a box's edges share their
    # axis' terms, every capsule's frame is shared): the same values, 13-30 % fewer operations
    if name == "collision_distances":
        return ca.Function(name, inputs, ca.cse([ca.densify(d)]), labels, ["d"])
    if name == "collision_criterion":
        clearance, activation = ca.SX.sym("clearance"), ca.SX.sym("activation")
        h = barrier(d, clearance, activation)
        return ca.Function(name, [*inputs, clearance, activation], ca.cse([h, ca.densify(ca.gradient(h, q))]),
                           [*labels, "clearance", "activation"], ["H_C", "grad_H_C"])
    raise KeyError(name)
