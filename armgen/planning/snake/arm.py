"""The snake arm's structure (spec 50): a rail feed then universal joints, read from the robot
file and checked against its DH table; the joint centres to universal-joint angles."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import TaskFileError, excerpt
from ...robot import Robot

# Structure check of the robot file: forward kinematics of the DH table and of the universal-joint
# chain A_i = A_{i-1} Rz(α_i) Ry(β_i) must agree to rounding (metres, dimensionless).
STRUCTURE_TOL = 1e-9


def _rz(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(a.shape + (3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1], out[..., 2, 2] = c, -s, s, c, 1.0
    return out


def uj_rotation(alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """R = Rz(α) Ry(β), vectorised."""
    ca, sa, cb, sb = np.cos(alpha), np.sin(alpha), np.cos(beta), np.sin(beta)
    R = np.empty(np.shape(alpha) + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 0, 2] = ca * cb, -sa, ca * sb
    R[..., 1, 0], R[..., 1, 1], R[..., 1, 2] = sa * cb, ca, sa * sb
    R[..., 2, 0], R[..., 2, 1], R[..., 2, 2] = -sb, 0.0, cb
    return R


def dh_frames(robot: Robot, q: np.ndarray) -> np.ndarray:
    """All DH frames after each joint, shape (samples, n, 4, 4), for ``q`` of shape (samples, n)
    (numpy, vectorised over samples; the same chain as the symbolic core)."""
    q = np.atleast_2d(q)
    N = q.shape[0]
    T = np.broadcast_to(robot.base, (N, 4, 4)).copy()
    out = np.empty((N, robot.n, 4, 4))
    for i, j in enumerate(robot.joints):
        ca_, sa_ = math.cos(j.alpha), math.sin(j.alpha)
        rx = np.array([[1, 0, 0, j.a], [0, ca_, -sa_, 0], [0, sa_, ca_, 0], [0, 0, 0, 1.0]])
        if robot.convention == "modified":
            T = T @ rx
        theta = q[:, i] + j.offset if j.revolute else np.full(N, j.theta)
        d = np.full(N, j.d) if j.revolute else j.d + j.offset + q[:, i]
        M = np.zeros((N, 4, 4))
        M[:, :3, :3] = _rz(theta)
        M[:, 2, 3] = d
        M[:, 3, 3] = 1.0
        T = T @ M
        if robot.convention == "standard":
            T = T @ rx
        out[:, i] = T
    return out


@dataclass(frozen=True)
class SnakeArm:
    """A snake arm read from a robot file: joint 1 prismatic (the rail feed), then pairs of
    revolute joints (α_i, β_i) forming universal joints with A_i = A_{i−1} Rz(α_i) Ry(β_i)."""

    robot: Robot
    n_links: int
    link: float  # m
    max_feed: float
    min_feed: float
    rail_dir: np.ndarray  # unit, robot base frame
    base0: np.ndarray  # base joint centre at feed 0, robot base frame
    A0: np.ndarray  # link-0 frame (the rail frame)
    qmin: np.ndarray  # (n_links, 2) α, β
    qmax: np.ndarray

    def q_vector(self, feed: np.ndarray, alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
        q = np.empty((feed.size, 1 + 2 * self.n_links))
        q[:, 0], q[:, 1::2], q[:, 2::2] = feed, alpha, beta
        return q

    def joint_centres(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint centres (samples, n_links + 1, 3) and link frames by forward kinematics of the
        robot's DH table (robot base frame)."""
        frames = dh_frames(self.robot, q)
        idx = [0] + [2 * i + 2 for i in range(self.n_links)]
        picked = frames[:, idx]
        return picked[:, :, :3, 3], picked[:, :, :3, :3]


def snake_arm(robot: Robot, source: str) -> SnakeArm:
    """Check that ``robot`` has the snake structure and extract its data (errors name the fix)."""
    def fail(msg: str) -> TaskFileError:
        return TaskFileError(f"{source}: field 'robot' = {excerpt(repr(robot.name))} is not a snake arm of spec 50 ({msg}); "
                             "use robot = \"snake12\" or a file of the same form (prismatic feed, then α/β pairs)")

    n = robot.n
    if n < 3 or n % 2 == 0:
        raise fail(f"{n} joints; expected 1 + 2·links")
    if robot.joints[0].revolute or not all(j.revolute for j in robot.joints[1:]):
        raise fail("joint 1 must be prismatic and the others revolute")
    n_links = (n - 1) // 2
    lengths = [robot.joints[2 * i + 2].a for i in range(n_links)]
    link = lengths[0]
    if link <= 0 or any(abs(x - link) > STRUCTURE_TOL for x in lengths):
        raise fail(f"link lengths (a of the β joints) {lengths} must be equal and positive")
    N = 3
    zero = np.zeros((1, n))
    frames0 = dh_frames(robot, zero)
    base0 = frames0[0, 0, :3, 3]
    one = zero.copy()
    one[0, 0] = 1.0
    rail_dir = dh_frames(robot, one)[0, 0, :3, 3] - base0
    A0 = frames0[0, 2, :3, :3]
    arm = SnakeArm(robot, n_links, link, robot.joints[0].qlim[1], robot.joints[0].qlim[0], rail_dir, base0, A0,
                   np.array([[robot.joints[1 + 2 * i].qlim[0], robot.joints[2 + 2 * i].qlim[0]] for i in range(n_links)]),
                   np.array([[robot.joints[1 + 2 * i].qlim[1], robot.joints[2 + 2 * i].qlim[1]] for i in range(n_links)]))
    if abs(np.linalg.norm(rail_dir) - 1.0) > STRUCTURE_TOL or np.linalg.norm(A0[:, 0] - rail_dir) > STRUCTURE_TOL:
        raise fail("at q = 0 the arm must lie straight along the feed direction")
    # the DH chain must be the universal-joint chain: compare at deterministic poses
    k = np.arange(1, N + 1)[:, None] * np.arange(1, n + 1)[None, :]
    q = 0.4 * np.sin(0.7 * k)
    centres, frames = arm.joint_centres(q)
    A = np.broadcast_to(A0, (N, 3, 3))
    x = centres[:, 0]
    if np.max(np.abs(x - (base0 + q[:, :1] * rail_dir))) > STRUCTURE_TOL:
        raise fail("joint 1 must carry the base joint centre along the feed")
    for i in range(n_links):
        A = A @ uj_rotation(q[:, 1 + 2 * i], q[:, 2 + 2 * i])
        x = x + link * A[:, :, 0]
        if np.max(np.abs(A - frames[:, i + 1])) > STRUCTURE_TOL or np.max(np.abs(x - centres[:, i + 1])) > STRUCTURE_TOL:
            raise fail(f"joints {2 + 2 * i}/{3 + 2 * i} do not form A_i = A_(i-1) Rz(α) Ry(β) with the link along x")
    if not np.allclose(robot.tool, np.eye(4)):
        raise fail("the tool frame must be the identity (the tip is the last joint centre)")
    return arm


# -- angle recovery -----------------------------------------------------------------------------
def recover_angles(arm: SnakeArm, centres: np.ndarray, rail_start: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Feed and universal-joint angles (signed form) from joint centres (samples, n+1, 3), world
    frame = robot base frame translated so the base joint at feed 0 sits at ``rail_start``:
    with ``(x, y, z)`` link i's unit axis in frame A_{i−1}, ``β = atan2(−z, hypot(x, y))``,
    ``α = atan2(y, x)``, ``A_i = A_{i−1} Rz(α) Ry(β)``."""
    N = centres.shape[0]
    feed = (centres[:, 0] - rail_start) @ arm.rail_dir
    axes = np.diff(centres, axis=1)
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    alpha = np.empty((N, arm.n_links))
    beta = np.empty((N, arm.n_links))
    A = np.broadcast_to(arm.A0, (N, 3, 3))
    for i in range(arm.n_links):
        c = np.einsum("nji,nj->ni", A, axes[:, i])
        beta[:, i] = np.arctan2(-c[:, 2], np.hypot(c[:, 0], c[:, 1]))
        alpha[:, i] = np.arctan2(c[:, 1], c[:, 0])
        A = A @ uj_rotation(alpha[:, i], beta[:, i])
    return feed, alpha, beta


def recover_angles_paper(arm: SnakeArm, centres: np.ndarray, rail_start: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper's form, for contrast: ``β = arccos(e1_i·e3_{i−1}) − π/2``,
    ``α = arccos(cos γ / cos β)`` with ``cos γ = e1_i·e1_{i−1}`` — α loses its sign."""
    N = centres.shape[0]
    feed = (centres[:, 0] - rail_start) @ arm.rail_dir
    axes = np.diff(centres, axis=1)
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    alpha = np.empty((N, arm.n_links))
    beta = np.empty((N, arm.n_links))
    A = np.broadcast_to(arm.A0, (N, 3, 3))
    for i in range(arm.n_links):
        e1 = axes[:, i]
        b = np.arccos(np.clip(np.einsum("nj,nj->n", e1, A[:, :, 2]), -1, 1)) - math.pi / 2
        cos_gamma = np.einsum("nj,nj->n", e1, A[:, :, 0])
        a = np.arccos(np.clip(cos_gamma / np.cos(b), -1, 1))
        alpha[:, i], beta[:, i] = a, b
        A = A @ uj_rotation(a, b)
    return feed, alpha, beta
