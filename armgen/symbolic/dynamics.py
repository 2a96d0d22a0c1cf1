"""Rigid-body dynamics of a serial chain in CasADi SX: gravity torques, inverse dynamics
(recursive Newton–Euler), the joint-space mass matrix (composite rigid body) and the
Coriolis/centrifugal torques.

Frames. Every link is handled in its MOVING FRAME ``J_i = axis_frames[i] · Rz(θ) Tz(d)`` of
:func:`armgen.symbolic.kinematics.chain`: the axis frame carried along by the joint's motion.
Its z axis is the joint axis and its origin lies on it, so the joint's motion is a rotation
about z (revolute) or a translation along z (prismatic) in every convention, and each step
from ``J_{i-1}`` to ``J_i`` is one constant transform (``fixed``) followed by the joint's
``Rz(θ) Tz(d)`` (``motion``). The link frame in which the description stores the
:class:`~armgen.description.Inertial` (``joint_frames[i]``) is ``J_i · post_i`` with a
constant ``post_i``: identity for URDF joints and modified (Craig) DH, ``Tx(a) Rx(α)`` for
standard DH. Each inertial is moved once, in floating point at derivation time, from the link
frame to ``J_i`` (the COM by ``post_i``, the inertia tensor rotated). ``J_{-1}`` is the base
transform ``robot.base``; the robot's gravity vector (given in the frame the forward
kinematics is expressed in, the "base frame" of ``fk``) is rotated into it.

Body-frame quantities (the recursions of Luh, Walker and Paul and of Featherstone's CRBA)
rather than base-frame ones: every vector of link i is expressed in ``J_i``, where the joint
axis is the constant ``e_z``, the inertia tensor is constant and the joint's own rotation is
the only q-dependent factor between neighbours; the SX graph stays O(n) with exact zeros
dropped. Gravity enters as an upward acceleration ``−g`` of the base (the usual RNEA trick).

Conventions: τ = M(q) q̈ + c(q, q̇) + g(q), with ``c = C(q, q̇) q̇`` the Coriolis and
centrifugal torques and ``g`` the gravity torques (the torque that holds the arm still).
A joint's ``motor_inertia`` (reflected rotor inertia) adds ``I_m q̈_i`` to τ_i and ``I_m`` to
``M_ii`` (the rotor's gyroscopic coupling is neglected, as Pinocchio's ``armature`` does).
SI units: N·m (N for a prismatic joint), kg·m², m/s².
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..description import RobotDescription
from ..description.frames import axis_alignment
from ..errors import RobotFileError
from .kinematics import _joint_motion, _rot_x_trans_x  # chain's own factors: the same frames

DYNAMIC_FUNCTIONS = ("gravity", "rnea", "mass_matrix", "coriolis")

_EZ = ca.SX(ca.DM([0.0, 0.0, 1.0]))


@dataclass(frozen=True)
class _Transform:
    """A frame's pose in its parent: rotation ``R`` (columns: the frame's axes) and origin ``p``."""

    R: ca.SX  # 3×3
    p: ca.SX  # 3×1

    @classmethod
    def constant(cls, matrix: np.ndarray) -> _Transform:
        return cls(ca.SX(ca.DM(matrix[:3, :3])), ca.SX(ca.DM(matrix[:3, 3])))

    def rotate_in(self, vector: ca.SX) -> ca.SX:
        """A parent-frame vector in this frame's axes: ``Rᵀ v``."""
        return ca.mtimes(self.R.T, vector)

    def rotate_out(self, vector: ca.SX) -> ca.SX:
        """A vector of this frame in the parent's axes: ``R v``."""
        return ca.mtimes(self.R, vector)


@dataclass(frozen=True)
class _Link:
    """One joint and the body it moves, in the body's moving frame ``J_i``."""

    revolute: bool
    fixed: _Transform  # the axis frame in J_{i-1} (constant)
    mass: float
    com: ca.SX  # 3×1, m, in J_i
    inertia: ca.SX  # 3×3 about the COM, J_i axes
    motor_inertia: float


def require_dynamics(robot: RobotDescription) -> None:
    """Raise a clear error when some joint's link has no inertial."""
    missing = [j.name for j in robot.joints if j.inertial is None]
    if missing:
        which = "" if len(missing) == robot.n else f" for joint(s) {', '.join(missing)}"
        raise RobotFileError(
            f"{robot.source or '<in memory>'}: robot '{robot.name}' has no inertials{which}, so it has no dynamics "
            "(gravity, rnea, mass_matrix, coriolis); give every joint's link mass, com and inertia in the robot file, "
            "or an <inertial> on every moving link of the URDF (docs/dynamics.md)")


def _links(robot: RobotDescription) -> tuple[_Transform, list[_Link]]:
    """The base transform and each link's constant data, mirroring :func:`kinematics.chain`'s frames.

    chain's frames: ``axis_i = link_{i-1} · pre_i``, ``link_i = axis_i · Rz Tz · post_i``; here
    ``J_i = axis_i · Rz Tz``, so ``J_{i-1} → axis_i`` is ``post_{i-1} · pre_i``.
    """
    links = []
    pending = np.eye(4)  # chain's folded A^T of the previous general joint
    previous_post = np.eye(4)  # the previous joint's post (standard DH), from J_{i-1} to link_{i-1}
    for joint in robot.joints:
        if joint.origin is not None:
            alignment = axis_alignment(joint.axis)
            pre = pending @ joint.origin @ alignment
            pending = alignment.T
        elif robot.convention == "modified":
            pre = _rot_x_trans_x(joint.alpha, joint.a)
        else:
            pre = np.eye(4)
        post = (_rot_x_trans_x(joint.alpha, joint.a) if joint.origin is None and robot.convention == "standard"
                else np.eye(4))
        inertial = joint.inertial
        rotation, offset = post[:3, :3], post[:3, 3]
        com = rotation @ np.asarray(inertial.com, dtype=float) + offset
        inertia = rotation @ inertial.inertia_matrix @ rotation.T
        links.append(_Link(joint.revolute, _Transform.constant(previous_post @ pre), float(inertial.mass),
                           ca.SX(ca.DM(com)), ca.SX(ca.DM(inertia)), float(inertial.motor_inertia)))
        previous_post = post
    return _Transform.constant(robot.base), links


def _motions(robot: RobotDescription, q: ca.SX) -> list[_Transform]:
    """Each ``J_i`` in its axis frame: chain's ``Rz(θ) Tz(d)`` of the joint's variable."""
    motions = [_joint_motion(joint, q[i]) for i, joint in enumerate(robot.joints)]
    return [_Transform(motion[:3, :3], motion[:3, 3]) for motion in motions]


def _child_acceleration(frame: _Transform, omega: ca.SX, domega: ca.SX, acc: ca.SX) -> ca.SX:
    """Linear acceleration of a point rigidly attached at ``frame.p``, in ``frame``'s axes."""
    p = frame.p
    return frame.rotate_in(acc + ca.cross(domega, p) + ca.cross(omega, ca.cross(omega, p)))


class _Chain:
    """The chain's links and motions at symbolic q: the recursions share them."""

    def __init__(self, robot: RobotDescription, q: ca.SX):
        require_dynamics(robot)
        self.base, self.links = _links(robot)
        self.motions = _motions(robot, q)
        self.gravity = self.base.rotate_in(ca.SX(ca.DM(np.asarray(robot.gravity, dtype=float))))

    def to_parent(self, i: int, force: ca.SX, moment: ca.SX) -> tuple[ca.SX, ca.SX]:
        """A force and moment about ``J_i``'s origin, as force and moment about ``J_{i-1}``'s origin."""
        for frame in (self.motions[i], self.links[i].fixed):
            force = frame.rotate_out(force)
            moment = frame.rotate_out(moment) + ca.cross(frame.p, force)
        return force, moment

    def rnea(self, dq: ca.SX, ddq: ca.SX, gravity: bool) -> ca.SX:
        """τ of the recursive Newton–Euler algorithm (forward: velocities and accelerations of
        each J_i; backward: forces and moments); ``gravity`` False leaves g out."""
        zero = ca.SX.zeros(3, 1)
        omega, domega = zero, zero
        acc = -self.gravity if gravity else zero
        wrenches = []
        for i, (link, motion) in enumerate(zip(self.links, self.motions)):
            # through the constant transform into the axis frame (rigid with the parent) …
            acc = _child_acceleration(link.fixed, omega, domega, acc)
            omega, domega = link.fixed.rotate_in(omega), link.fixed.rotate_in(domega)
            # … then through the joint's motion into J_i
            acc = _child_acceleration(motion, omega, domega, acc)
            omega, domega = motion.rotate_in(omega), motion.rotate_in(domega)
            if link.revolute:
                domega = domega + ca.cross(omega, _EZ * dq[i]) + _EZ * ddq[i]
                omega = omega + _EZ * dq[i]
            else:  # the origin slides along z: Coriolis and relative acceleration
                acc = acc + 2 * ca.cross(omega, _EZ * dq[i]) + _EZ * ddq[i]
            com_acc = acc + ca.cross(domega, link.com) + ca.cross(omega, ca.cross(omega, link.com))
            force = link.mass * com_acc
            moment = (ca.mtimes(link.inertia, domega) + ca.cross(omega, ca.mtimes(link.inertia, omega))
                      + ca.cross(link.com, force))
            wrenches.append((force, moment))
        tau = [None] * len(self.links)
        force, moment = zero, zero
        for i in reversed(range(len(self.links))):
            link = self.links[i]
            force, moment = force + wrenches[i][0], moment + wrenches[i][1]
            tau[i] = (moment[2] if link.revolute else force[2]) + link.motor_inertia * ddq[i]
            force, moment = self.to_parent(i, force, moment)
        return ca.vertcat(*tau)

    def mass_matrix(self) -> ca.SX:
        """M of the composite rigid body algorithm: each composite body's inertia (mass, first
        moment h = m c, rotational inertia about the frame origin) accumulated tip to base; column
        i is the momentum of composite i moving at a unit rate of joint i, carried to each joint
        j ≤ i and projected on its axis."""
        n = len(self.links)
        M = ca.SX.zeros(n, n)
        mass, first, second = 0.0, ca.SX.zeros(3, 1), ca.SX.zeros(3, 3)
        for i in reversed(range(n)):
            link = self.links[i]
            mass = mass + link.mass
            first = first + link.mass * link.com
            second = second + link.inertia - link.mass * _skew2(link.com)
            if link.revolute:  # unit rotation about z through J_i's origin
                linear, angular = ca.cross(_EZ, first), ca.mtimes(second, _EZ)
            else:  # unit translation along z
                linear, angular = mass * _EZ, ca.cross(first, _EZ)
            for j in reversed(range(i + 1)):
                M[j, i] = angular[2] if self.links[j].revolute else linear[2]
                if j > 0:
                    linear, angular = self.to_parent(j, linear, angular)
            M[i, i] = M[i, i] + link.motor_inertia
            if i > 0:  # the composite inertia, moved into J_{i-1} for the next link down
                mass, first, second = self._inertia_to_parent(i, mass, first, second)
        for i in range(n):
            for j in range(i):
                M[i, j] = M[j, i]
        return M

    def _inertia_to_parent(self, i: int, mass: ca.SX, first: ca.SX, second: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        """(m, h, I_o) about J_i's origin → about J_{i-1}'s origin, J_{i-1} axes:
        h' = R h + m p, I_o' = R I_o Rᵀ − m [p]×² − [p]×[R h]× − [R h]×[p]×."""
        for frame in (self.motions[i], self.links[i].fixed):
            rotated = frame.rotate_out(first)
            second = (ca.mtimes(frame.R, ca.mtimes(second, frame.R.T)) - mass * _skew2(frame.p)
                      - ca.mtimes(ca.skew(frame.p), ca.skew(rotated)) - ca.mtimes(ca.skew(rotated), ca.skew(frame.p)))
            first = rotated + mass * frame.p
        return mass, first, second


def _skew2(vector: ca.SX) -> ca.SX:
    """[v]×² = v vᵀ − |v|² I: −m [c]×² is the parallel-axis term of a point mass at c."""
    return ca.mtimes(ca.skew(vector), ca.skew(vector))


def dynamic_function(robot: RobotDescription, name: str) -> ca.Function:
    """One of :data:`DYNAMIC_FUNCTIONS` as a named ``casadi.Function`` (inputs ``q``, ``dq``,
    ``ddq``; outputs ``tau``, ``M`` or ``c``)."""
    n = robot.n
    q, dq, ddq = ca.SX.sym("q", n), ca.SX.sym("dq", n), ca.SX.sym("ddq", n)
    body = _Chain(robot, q)
    zeros = ca.SX.zeros(n)
    if name == "gravity":
        return ca.Function("gravity", [q], [ca.densify(body.rnea(zeros, zeros, True))], ["q"], ["tau"])
    if name == "rnea":
        return ca.Function("rnea", [q, dq, ddq], [ca.densify(body.rnea(dq, ddq, True))], ["q", "dq", "ddq"], ["tau"])
    if name == "mass_matrix":
        return ca.Function("mass_matrix", [q], [ca.densify(body.mass_matrix())], ["q"], ["M"])
    if name == "coriolis":
        return ca.Function("coriolis", [q, dq], [ca.densify(body.rnea(dq, zeros, False))], ["q", "dq"], ["c"])
    raise KeyError(name)
