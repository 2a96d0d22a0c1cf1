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
clearance, or overlapping. C¹ everywhere. ∇H_C = Σ_k g'(d_k) ∇d_k, each ∇d_k from the pair's witness points
moving with their links (:meth:`_Arm.gradient`): what reverse-mode AD of the distances gives
wherever they are differentiable, at a fraction of its cost.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

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


@dataclass(frozen=True)
class _Pair:
    """One entry of ``d``: its witness (:class:`~armgen.symbolic.collision_geometry.Witness`)
    between capsule ``first``'s axis and the other shape, capsule ``second`` for a self pair."""

    witness: geometry.Witness
    first: int
    second: int | None = None


class _Arm:
    """The capsules' segment ends and the joints' axes in the base frame at symbolic q."""

    def __init__(self, robot: RobotDescription, q: ca.SX):
        axis_frames, joint_frames, _ = chain(robot, q)
        frames = [ca.SX(ca.DM(robot.base)), *joint_frames]
        self.robot = robot
        self.axes = [(frame[:3, 2], frame[:3, 3]) for frame in axis_frames]
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

    def point(self, i: int, parameter: ca.SX) -> ca.SX:
        a, b = self.ends[i]
        return a if self.is_point(i) else a + parameter * (b - a)

    def self_pair(self, i: int, j: int) -> _Pair:
        (ai, bi), (aj, bj) = self.ends[i], self.ends[j]
        if self.is_point(i) and self.is_point(j):
            witness = geometry.point_point_witness(ai, aj)
        elif self.is_point(j):
            witness = geometry.point_segment_witness(aj, ai, bi)
        elif self.is_point(i):  # the point first: the witness's normal then points away from j
            other = geometry.point_segment_witness(ai, aj, bj)
            witness = geometry.Witness(other.distance, other.other_parameter, -other.normal, other.parameter)
        else:
            witness = geometry.segment_segment_witness(ai, bi, aj, bj)
        radii = self.capsules[i].radius + self.capsules[j].radius
        return _Pair(replace(witness, distance=witness.distance - radii), i, j)

    def obstacle_pair(self, i: int, kind: str, column: ca.SX) -> _Pair:
        """Capsule i to one obstacle slot (its column), INACTIVE_DISTANCE when the slot is off."""
        a, b = self.ends[i]
        if kind == "sphere":
            witness, radius = self._axis_to_segment(i, column[0:3], column[0:3]), column[3]
        elif kind == "capsule":
            witness, radius = self._axis_to_segment(i, column[0:3], column[3:6]), column[6]
        elif kind == "box":
            witness = geometry.segment_box_witness(a, b, column[0:3], ca.reshape(column[3:12], 3, 3), column[12:15])
            radius = 0.0
        else:
            witness, radius = geometry.segment_halfspace_witness(a, b, column[0:3], column[3]), 0.0
        distance = ca.if_else(column[-1] != 0, witness.distance - radius - self.capsules[i].radius, INACTIVE_DISTANCE)
        return _Pair(replace(witness, distance=distance), i)

    def _axis_to_segment(self, i: int, a: ca.SX, b: ca.SX) -> geometry.Witness:
        """Capsule i's axis to the segment [a, b] (a runtime segment, possibly of zero length)."""
        ai, bi = self.ends[i]
        if self.is_point(i):
            other = geometry.point_segment_witness(ai, a, b)
            return geometry.Witness(other.distance, ca.SX(0.0), -other.normal)
        return geometry.segment_segment_witness(ai, bi, a, b)

    def gradient(self, pairs: list[_Pair], weights: ca.SX) -> ca.SX:
        """Σ_k weights_k ∇_q d_k: each pair's witness points move with their frames (the envelope
        theorem), so ∂d_k/∂q_j = n_k · (z_j × (x_k − o_j)) for a revolute joint j below x_k's frame
        (n_k · z_j for a prismatic one), minus the same for a self pair's second point. Summed over
        the pairs per frame first, then from the flange down (suffix sums), so the cost is linear
        in pairs plus joints: joint j sees Σ w n (N) and Σ w x × n (M) of the frames it moves,
        ∂/∂q_j = z_j · (M − o_j × N)."""
        moment = [ca.SX.zeros(3, 1) for _ in range(self.robot.n + 1)]
        force = [ca.SX.zeros(3, 1) for _ in range(self.robot.n + 1)]
        for k, pair in enumerate(pairs):
            w = pair.witness
            sides = [(pair.first, w.parameter, 1.0)]
            if pair.second is not None:
                sides.append((pair.second, w.other_parameter, -1.0))
            for capsule, parameter, sign in sides:
                frame = self.capsules[capsule].frame
                if frame == 0:  # the base does not move
                    continue
                pushed = sign * weights[k] * w.normal
                moment[frame] += ca.cross(self.point(capsule, parameter), pushed)
                force[frame] += pushed
        out, total_moment, total_force = [None] * self.robot.n, ca.SX.zeros(3, 1), ca.SX.zeros(3, 1)
        for j in reversed(range(self.robot.n)):  # joint j (from 0) moves frames j + 1 … n
            total_moment, total_force = total_moment + moment[j + 1], total_force + force[j + 1]
            z, origin = self.axes[j]
            if self.robot.joints[j].revolute:
                out[j] = ca.dot(z, total_moment - ca.cross(origin, total_force))
            else:
                out[j] = ca.dot(z, total_force)
        return ca.vertcat(*out)


def _obstacle_inputs(robot: RobotDescription) -> list[tuple[str, ca.SX]]:
    """(kind, rows × slots symbol) per kind with slots."""
    slots = robot.collision.slots
    return [(kind, ca.SX.sym(OBSTACLE_INPUTS[kind], OBSTACLE_ROWS[kind], slots.count(kind)))
            for kind in OBSTACLE_KINDS if slots.count(kind)]


def _pairs(arm: _Arm, obstacles: list[tuple[str, ca.SX]]) -> list[_Pair]:
    """Every entry of d, in pair_labels' order."""
    model = arm.robot.collision
    pairs = [arm.self_pair(i, j) for i, j in model.self_pairs()]
    for kind, matrix in obstacles:
        for slot in range(matrix.shape[1]):
            pairs += [arm.obstacle_pair(i, kind, matrix[:, slot]) for i in model.moving()]
    return pairs


def _barrier_terms(d: ca.SX, clearance: ca.SX, activation: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(H_C, the slope g'(d_k) of each term) (module docstring): branch-free, ``fmax``/``fmin``."""
    span = activation - clearance
    floor = BARRIER_FLOOR * span
    room = d - clearance
    held = ca.fmax(room, floor)
    x = ca.fmax(span / held - 1.0, 0.0)
    slope = -x * span / (held * held)  # g'(room), and g'(floor) below the floor (the tangent)
    return ca.sum1(0.5 * x * x + slope * ca.fmin(room - floor, 0.0)), slope


def collision_function(robot: RobotDescription, name: str) -> ca.Function:
    """One of :data:`COLLISION_FUNCTIONS` as a named ``casadi.Function``."""
    require_collision(robot)
    q = ca.SX.sym("q", robot.n)
    obstacles = _obstacle_inputs(robot)
    arm = _Arm(robot, q)
    pairs = _pairs(arm, obstacles)
    d = ca.vertcat(*[pair.witness.distance for pair in pairs])
    inputs, labels = [q, *[m for _, m in obstacles]], ["q", *[OBSTACLE_INPUTS[k] for k, _ in obstacles]]
    # ca.cse merges the equal subexpressions the pairs build apart (a box's edges share their
    # axis' terms, every capsule's frame is shared): the same values, fewer operations
    if name == "collision_distances":
        return ca.Function(name, inputs, ca.cse([ca.densify(d)]), labels, ["d"])
    if name == "collision_criterion":
        clearance, activation = ca.SX.sym("clearance"), ca.SX.sym("activation")
        h, slopes = _barrier_terms(d, clearance, activation)
        return ca.Function(name, [*inputs, clearance, activation], ca.cse([h, ca.densify(arm.gradient(pairs, slopes))]),
                           [*labels, "clearance", "activation"], ["H_C", "grad_H_C"])
    raise KeyError(name)
