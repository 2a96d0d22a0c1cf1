"""Resolved-rate steps in CasADi SX, all with damped least squares.

The damped pseudo-inverse ``J⁺ = Jᵀ (J Jᵀ + λ² I)⁻¹`` is applied through a symbolic
LDLᵀ solve of the m×m system. ``J Jᵀ + λ² I`` is symmetric positive definite for any
``λ > 0``, so every pivot is ≥ λ²; the pivots are additionally floored at
``PIVOT_FLOOR`` so that even ``λ = 0`` at a singular pose divides by a finite number
(the result is then a large but finite velocity, which the controller's limits catch).
"""

from __future__ import annotations

import casadi as ca

# Floor of the LDLᵀ pivots: 1e-18 is below the square of any meaningful Jacobian entry
# in SI units (1e-9 m or rad), so it never alters a regular solve.
PIVOT_FLOOR = 1e-18


def spd_solve(a: ca.SX, b: ca.SX) -> ca.SX:
    """Solve ``a x = b`` for symmetric positive (semi)definite ``a`` by LDLᵀ, no pivoting."""
    m = a.shape[0]
    lower = [[None] * m for _ in range(m)]
    diag = [None] * m
    for j in range(m):
        dj = a[j, j] - sum((lower[j][k] * lower[j][k] * diag[k] for k in range(j)), ca.SX(0))
        diag[j] = ca.fmax(dj, PIVOT_FLOOR)
        for i in range(j + 1, m):
            lij = a[i, j] - sum((lower[i][k] * lower[j][k] * diag[k] for k in range(j)), ca.SX(0))
            lower[i][j] = lij / diag[j]
    y = [None] * m
    for i in range(m):  # L y = b
        y[i] = b[i] - sum((lower[i][k] * y[k] for k in range(i)), ca.SX(0))
    x = [None] * m
    for i in reversed(range(m)):  # D Lᵀ x = y
        x[i] = y[i] / diag[i] - sum((lower[k][i] * x[k] for k in range(i + 1, m)), ca.SX(0))
    return ca.vertcat(*x)


def damped_gram(j: ca.SX, damping: ca.SX, col_scale: ca.SX | None = None) -> ca.SX:
    """J S Jᵀ + λ² I (S = diag(col_scale), or I)."""
    js = j if col_scale is None else j @ ca.diag(col_scale)
    return ca.mtimes(js, j.T) + damping * damping * ca.SX.eye(j.shape[0])


def step_gpm(j: ca.SX, xdot: ca.SX, alpha: ca.SX, damping: ca.SX) -> ca.SX:
    """q̇ = J⁺ ẋ + (I − J⁺ J) α, evaluated as α + Jᵀ (J Jᵀ + λ² I)⁻¹ (ẋ − J α)."""
    return alpha + ca.mtimes(j.T, spd_solve(damped_gram(j, damping), xdot - ca.mtimes(j, alpha)))


def step_wln(j: ca.SX, xdot: ca.SX, weights: ca.SX, damping: ca.SX) -> ca.SX:
    """q̇ = W⁻¹ Jᵀ (J W⁻¹ Jᵀ + λ² I)⁻¹ ẋ with diagonal W (weights below 1 count as 1: WLN
    weights are 1 + a non-negative penalty, and the floor keeps W⁻¹ finite)."""
    w_inv = 1 / ca.fmax(weights, 1)
    return w_inv * ca.mtimes(j.T, spd_solve(damped_gram(j, damping, w_inv), xdot))
