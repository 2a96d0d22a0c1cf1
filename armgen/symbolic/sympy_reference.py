"""An independent derivation in SymPy, used only to cross-check the CasADi core.

It shares nothing with :mod:`armgen.symbolic.kinematics` but the robot data: the DH
transforms are the textbook 4×4 products with ``θ = q + offset`` inside the trig
functions, a general (URDF) joint is ``origin · Rot(axis, q)`` with Rodrigues' formula
(or ``origin · Trans(q · axis)``) instead of an axis alignment, the linear Jacobian rows are the derivatives of the tool position, and the
angular rows come from ``Ṙ Rᵀ`` (the skew-symmetric angular-velocity matrix) instead of
the ``z × (p − o)`` construction. Criteria gradients are the closed forms of the specs.

The dynamics reference (:func:`sympy_lagrange_dynamics`) is Lagrange's, not Newton–Euler's:
the kinetic energy ``½ q̇ᵀ M q̇`` with ``M = Σ m J_vᵀ J_v + J_ωᵀ R I Rᵀ J_ω`` from the
derivatives of each centre of mass and of ``R`` (no recursion, no spatial algebra), the
gravity torques as ``∂V/∂q`` of the potential energy, and the Coriolis torques from the
derivatives of ``M`` (Christoffel symbols).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from ..description import RobotDescription
from ..description.frames import axis_alignment


def _rz(t):
    return sp.Matrix([[sp.cos(t), -sp.sin(t), 0, 0], [sp.sin(t), sp.cos(t), 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def _rx(t):
    return sp.Matrix([[1, 0, 0, 0], [0, sp.cos(t), -sp.sin(t), 0], [0, sp.sin(t), sp.cos(t), 0], [0, 0, 0, 1]])


def _tz(d):
    return sp.Matrix([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, d], [0, 0, 0, 1]])


def _tx(a):
    return sp.Matrix([[1, 0, 0, a], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def _general_motion(axis, q_i, revolute: bool) -> sp.Matrix:
    """Rot(axis, q) = I + sin q K + (1 − cos q) K² (Rodrigues), or a translation q · axis."""
    u = sp.Matrix(axis)
    out = sp.eye(4)
    if revolute:
        K = sp.Matrix([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
        out[:3, :3] = sp.eye(3) + sp.sin(q_i) * K + (1 - sp.cos(q_i)) * K * K
    else:
        out[:3, 3] = q_i * u
    return out


def _sympy_joint_frames(robot: RobotDescription, q: list[sp.Symbol]) -> list[sp.Matrix]:
    """base·A_1⋯A_i for each joint i, with the joint products written out literally (a general
    joint's frame is its URDF child frame)."""
    T = sp.Matrix(robot.base.tolist())
    frames = []
    for i, j in enumerate(robot.joints):
        if j.origin is not None:
            T = T * sp.Matrix(j.origin.tolist()) * _general_motion(j.axis, q[i], j.revolute)
        else:
            theta = q[i] + j.offset if j.revolute else sp.Float(j.theta)
            d = j.d if j.revolute else j.d + j.offset + q[i]
            if robot.convention == "standard":
                T = T * _rz(theta) * _tz(d) * _tx(j.a) * _rx(j.alpha)
            else:
                T = T * _rx(j.alpha) * _tx(j.a) * _rz(theta) * _tz(d)
        frames.append(T)
    return frames


def sympy_fk(robot: RobotDescription, q: list[sp.Symbol]) -> sp.Matrix:
    """Tool transform base·A_1⋯A_n·tool with the joint products written out literally."""
    frames = _sympy_joint_frames(robot, q)
    T = frames[-1] if frames else sp.Matrix(robot.base.tolist())
    return T * sp.Matrix(robot.tool.tolist())


def sympy_fk_jacobian(robot: RobotDescription):
    """Numeric (T(q), J(q)) from the SymPy derivation (lambdified, no simplification)."""
    q = list(sp.symbols(f"q0:{robot.n}", real=True))
    T = sympy_fk(robot, q)
    dT = sp.Matrix.hstack(*[T[:3, :].diff(qk) for qk in q])  # [dT/dq_1 | … ] top 3 rows
    fk = sp.lambdify([q], T, "numpy")
    dfk = sp.lambdify([q], dT, "numpy")

    def jacobian(qv) -> np.ndarray:
        R = np.array(fk(list(qv)), dtype=float)[:3, :3]
        d = np.array(dfk(list(qv)), dtype=float)
        J = np.zeros((6, robot.n))
        for k in range(robot.n):
            dk = d[:, 4 * k:4 * k + 4]
            J[:3, k] = dk[:, 3]
            omega_hat = dk[:, :3] @ R.T  # skew(ω_k) for a unit rate of joint k
            J[3:, k] = [omega_hat[2, 1], omega_hat[0, 2], omega_hat[1, 0]]
        return J

    return (lambda qv: np.array(fk(list(qv)), dtype=float)), jacobian


def zghal_gradient_closed_form(q: np.ndarray, qmin: np.ndarray, qmax: np.ndarray) -> np.ndarray:
    """∂H_L/∂q_i = (q_max − q_min)² (2q_i − q_max − q_min) / ((q_max − q_i)² (q_i − q_min)²) (spec 20)."""
    return (qmax - qmin) ** 2 * (2 * q - qmax - qmin) / ((qmax - q) ** 2 * (q - qmin) ** 2)


def zghal_closed_form(q: np.ndarray, qmin: np.ndarray, qmax: np.ndarray) -> float:
    return float(np.sum((qmax - qmin) ** 2 / ((qmax - q) * (q - qmin))))


def planar3_closed_form(q: np.ndarray, lengths: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Position (x, y) and the 2×3 position Jacobian of a planar 3R arm, by hand."""
    c = np.cumsum(q)
    x = sum(l * np.cos(a) for l, a in zip(lengths, c))
    y = sum(l * np.sin(a) for l, a in zip(lengths, c))
    J = np.zeros((2, 3))
    for k in range(3):
        J[0, k] = -sum(lengths[i] * np.sin(c[i]) for i in range(k, 3))
        J[1, k] = sum(lengths[i] * np.cos(c[i]) for i in range(k, 3))
    return np.array([x, y]), J


def sympy_lagrange_dynamics(robot: RobotDescription):
    """Numeric ``(M, c, g)`` of ``(q, dq)`` from Lagrange's equations in SymPy (lambdified).

    The inertials are given in the link frames (``Inertial``'s convention): DH frame i, or a
    URDF joint's child frame turned by the axis alignment ``A``. Every link's centre of mass
    ``p`` and rotation ``R`` are written out in the base frame; ``M = Σ m J_vᵀ J_v + J_ωᵀ R I Rᵀ
    J_ω + diag(motor inertia)``, where column k of ``J_ω`` is the axial vector of
    ``∂R/∂q_k Rᵀ``; ``g = ∂V/∂q`` with ``V = −Σ m gravityᵀ p``; and
    ``c_k = Σ_ij (∂M_kj/∂q_i − ½ ∂M_ij/∂q_k) q̇_i q̇_j``. Small arms only (2–3 links): the
    expressions are not simplified.
    """
    n = robot.n
    q = list(sp.symbols(f"q0:{n}", real=True))
    gravity = sp.Matrix(list(robot.gravity))
    M = sp.zeros(n, n)
    V = sp.Integer(0)
    for joint, T in zip(robot.joints, _sympy_joint_frames(robot, q)):
        if joint.origin is not None:
            T = T * sp.Matrix(axis_alignment(joint.axis).tolist())
        inertial = joint.inertial
        R = T[:3, :3]
        com = R * sp.Matrix(list(inertial.com)) + T[:3, 3]
        Jv = com.jacobian(q)
        Jw = sp.zeros(3, n)
        for k, qk in enumerate(q):
            W = R.diff(qk) * R.T
            Jw[:, k] = sp.Matrix([W[2, 1], W[0, 2], W[1, 0]])
        inertia = R * sp.Matrix(inertial.inertia_matrix.tolist()) * R.T
        M += inertial.mass * Jv.T * Jv + Jw.T * inertia * Jw
        V -= inertial.mass * (gravity.T * com)[0, 0]
    M += sp.diag(*[j.inertial.motor_inertia for j in robot.joints])
    g = sp.Matrix([V.diff(qk) for qk in q])
    dM = [M.diff(qk) for qk in q]
    mass_f = sp.lambdify([q], M, "numpy", cse=True)
    grav_f = sp.lambdify([q], g, "numpy", cse=True)
    dM_f = sp.lambdify([q], dM, "numpy", cse=True)

    def dynamics(qv, dqv) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        qv, dqv = list(map(float, qv)), np.asarray(dqv, dtype=float)
        derivatives = np.array(dM_f(qv), dtype=float)  # [i] = ∂M/∂q_i
        coriolis = np.einsum("ikj,i,j->k", derivatives, dqv, dqv) - 0.5 * np.einsum("kij,i,j->k", derivatives,
                                                                                     dqv, dqv)
        return (np.array(mass_f(qv), dtype=float), coriolis, np.array(grav_f(qv), dtype=float).reshape(n))

    return dynamics
