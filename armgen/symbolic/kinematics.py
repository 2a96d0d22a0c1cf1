"""Forward kinematics and the geometric Jacobian of a serial chain in CasADi SX.

Each joint transform is split as ``pre · Rz(θ) Tz(d) · post`` with constant ``pre``/``post``:
standard DH has ``pre = I``, ``post = Tx(a) Rx(α)``; modified (Craig) DH has
``pre = Rx(α_{i-1}) Tx(a_{i-1})``, ``post = I``. A general (URDF) joint with fixed transform
``origin`` and unit ``axis`` is the same form with ``pre = origin · A`` and ``post = Aᵀ``,
where ``A`` is a constant rotation taking z onto the axis; ``post`` is folded into the next
joint's ``pre`` (or the tool), so each joint costs one constant product. The joint axis is
the z axis of the frame ``T_{i-1} · pre``, which gives the Jacobian columns directly
(``z × (p_tool − o)`` for a revolute joint, ``z`` for a prismatic one) instead of
differentiating the FK: far fewer operations than an AD Jacobian. Constant angles that are
multiples of 90° enter as exact 0/±1 (see :func:`armgen.description.frames.exact_cos_sin`), and so do the
alignments of coordinate axes, so SX drops the products with them.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..description import Joint, RobotDescription, exact_cos_sin
from ..description.frames import axis_alignment


def _const(matrix: np.ndarray) -> ca.SX:
    return ca.SX(ca.DM(matrix))


def _rot_x_trans_x(alpha: float, a: float) -> np.ndarray:
    """Rx(alpha) Tx(a) == Tx(a) Rx(alpha) (they commute)."""
    ca_, sa = exact_cos_sin(alpha)
    return np.array([[1.0, 0.0, 0.0, a], [0.0, ca_, -sa, 0.0], [0.0, sa, ca_, 0.0], [0.0, 0.0, 0.0, 1.0]])


def _joint_motion(joint: Joint, q_i: ca.SX) -> ca.SX:
    """Rz(θ) Tz(d) for the joint's variable: θ = q + offset (revolute) or d = d + q + offset."""
    if joint.revolute:
        co, so = exact_cos_sin(joint.offset)
        cq, sq = ca.cos(q_i), ca.sin(q_i)
        c = cq * co - sq * so  # cos(q + offset) without a second trig call
        s = sq * co + cq * so
        d = joint.d
    else:
        c, s = exact_cos_sin(joint.theta)
        d = joint.d + joint.offset + q_i
    out = ca.SX.eye(4)
    out[0, 0], out[0, 1] = c, -s
    out[1, 0], out[1, 1] = s, c
    out[2, 3] = d
    return out


def _mul(a: ca.SX, b: ca.SX) -> ca.SX:
    """Product of homogeneous transforms (the bottom row is known to be [0 0 0 1])."""
    out = ca.SX.eye(4)
    out[:3, :3] = ca.mtimes(a[:3, :3], b[:3, :3])
    out[:3, 3] = ca.mtimes(a[:3, :3], b[:3, 3]) + a[:3, 3]
    return out


def chain(robot: RobotDescription, q: ca.SX) -> tuple[list[ca.SX], list[ca.SX], ca.SX]:
    """Return (axis frames, joint frames, tool transform).

    ``axis_frames[i]`` is the frame whose z axis is joint i's axis (through its origin);
    ``joint_frames[i]`` is the frame after joint i (for a general joint: the axis-aligned
    frame, i.e. the URDF child frame times ``A``); the last item is base·…·tool.
    """
    current = _const(robot.base)
    axis_frames, joint_frames = [], []
    post = np.eye(4)  # the previous general joint's A^T, folded into the next constant
    for i, joint in enumerate(robot.joints):
        if joint.origin is not None:
            alignment = axis_alignment(joint.axis)
            current = _mul(current, _const(post @ joint.origin @ alignment))
            post = alignment.T
        elif robot.convention == "modified":
            current = _mul(current, _const(_rot_x_trans_x(joint.alpha, joint.a)))
        axis_frames.append(current)
        current = _mul(current, _joint_motion(joint, q[i]))
        if joint.origin is None and robot.convention == "standard":
            current = _mul(current, _const(_rot_x_trans_x(joint.alpha, joint.a)))
        joint_frames.append(current)
    tool = _mul(current, _const(post @ robot.tool))
    return axis_frames, joint_frames, tool


def geometric_jacobian(robot: RobotDescription, axis_frames: list[ca.SX], tool: ca.SX) -> ca.SX:
    """6×n geometric Jacobian, rows [v; ω] of the tool origin in the base frame."""
    p_tool = tool[:3, 3]
    columns = []
    for joint, frame in zip(robot.joints, axis_frames):
        z = frame[:3, 2]
        if joint.revolute:
            columns.append(ca.vertcat(ca.cross(z, p_tool - frame[:3, 3]), z))
        else:
            columns.append(ca.vertcat(z, ca.SX.zeros(3, 1)))
    return ca.horzcat(*columns)


def fk_and_jacobian(robot: RobotDescription, q: ca.SX) -> tuple[ca.SX, ca.SX]:
    axis_frames, _, tool = chain(robot, q)
    return tool, geometric_jacobian(robot, axis_frames, tool)
