"""Resolved-rate steps in CasADi SX, all with damped least squares.

The damped pseudo-inverse ``J⁺ = Jᵀ (J Jᵀ + λ² I)⁻¹`` is applied through a symbolic
LDLᵀ solve of the m×m system. ``J Jᵀ + λ² I`` is symmetric positive definite for any
``λ > 0``, so every pivot is ≥ λ²; the pivots are additionally floored at
``PIVOT_FLOOR_REL · a_jj + PIVOT_FLOOR`` so that even ``λ = 0`` at a singular pose divides by a
finite number (the result is then a large but finite velocity, which the controller's limits
catch), in float as in double.
"""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca

from . import criteria
from .loops import fixed_loop

# Floor of the LDLᵀ pivots: 1e-18 is below the square of any meaningful Jacobian entry
# in SI units (1e-9 m or rad), so it never alters a regular solve.
PIVOT_FLOOR = 1e-18
# And relative to the pivot's diagonal entry a_jj: a Schur complement below 1e-10 a_jj means the
# matrix is singular to 10 digits (κ > 1e10). Without it a float solve at an exact singular pose
# with λ = 0 divides rounding residues (~1e-7 a_jj) by 1e-18, and the chained multipliers
# overflow to inf − inf = NaN; with it they stay ≤ ~1e3 and the (large) result finite.
PIVOT_FLOOR_REL = 1e-10


def ldl_factor(a: ca.SX) -> tuple[list[list[ca.SX]], list[ca.SX]]:
    """(L, D) of ``a = L D Lᵀ`` for symmetric positive (semi)definite ``a``, no pivoting; the
    pivots floored (PIVOT_FLOOR_REL, PIVOT_FLOOR). ``L`` as rows, strictly lower part only."""
    m = a.shape[0]
    lower = [[None] * m for _ in range(m)]
    diag = [None] * m
    for j in range(m):
        dj = a[j, j] - sum((lower[j][k] * lower[j][k] * diag[k] for k in range(j)), ca.SX(0))
        diag[j] = ca.fmax(dj, PIVOT_FLOOR_REL * a[j, j] + PIVOT_FLOOR)
        for i in range(j + 1, m):
            lij = a[i, j] - sum((lower[i][k] * lower[j][k] * diag[k] for k in range(j)), ca.SX(0))
            lower[i][j] = lij / diag[j]
    return lower, diag


def ldl_solve(factor: tuple[list[list[ca.SX]], list[ca.SX]], b: ca.SX) -> ca.SX:
    """Solve ``L D Lᵀ x = b`` with the factor of :func:`ldl_factor`."""
    lower, diag = factor
    m = len(diag)
    y = [None] * m
    for i in range(m):  # L y = b
        y[i] = b[i] - sum((lower[i][k] * y[k] for k in range(i)), ca.SX(0))
    x = [None] * m
    for i in reversed(range(m)):  # D Lᵀ x = y
        x[i] = y[i] / diag[i] - sum((lower[k][i] * x[k] for k in range(i + 1, m)), ca.SX(0))
    return ca.vertcat(*x)


def spd_solve(a: ca.SX, b: ca.SX) -> ca.SX:
    """Solve ``a x = b`` for symmetric positive (semi)definite ``a`` by LDLᵀ, no pivoting."""
    return ldl_solve(ldl_factor(a), b)


def weighted_gram(j: ca.SX, col_scale: ca.SX | None = None) -> ca.SX:
    """J S Jᵀ (S = diag(col_scale), or I), exactly symmetric: each entry i ≤ j computed once
    and mirrored (a plain product computes both triangles, with different rounding)."""
    m = j.shape[0]
    js = j if col_scale is None else j @ ca.diag(col_scale)
    out = ca.SX(m, m)
    for r in range(m):
        for c in range(r, m):
            out[r, c] = ca.dot(js[r, :], j[c, :])
            out[c, r] = out[r, c]
    return out


def damped_gram(j: ca.SX, damping: ca.SX, col_scale: ca.SX | None = None) -> ca.SX:
    """J S Jᵀ + λ² I (S = diag(col_scale), or I)."""
    return weighted_gram(j, col_scale) + damping * damping * ca.SX.eye(j.shape[0])


def step_gpm(j: ca.SX, xdot: ca.SX, alpha: ca.SX, damping: ca.SX) -> ca.SX:
    """q̇ = J⁺ ẋ + (I − J⁺ J) α, evaluated as α + Jᵀ (J Jᵀ + λ² I)⁻¹ (ẋ − J α)."""
    return alpha + ca.mtimes(j.T, spd_solve(damped_gram(j, damping), xdot - ca.mtimes(j, alpha)))


def step_wln(j: ca.SX, xdot: ca.SX, weights: ca.SX, damping: ca.SX) -> ca.SX:
    """q̇ = W⁻¹ Jᵀ (J W⁻¹ Jᵀ + λ² I)⁻¹ ẋ with diagonal W (weights below 1 count as 1: WLN
    weights are 1 + a non-negative penalty, and the floor keeps W⁻¹ finite)."""
    w_inv = 1 / ca.fmax(weights, 1)
    return w_inv * ca.mtimes(j.T, spd_solve(damped_gram(j, damping, w_inv), xdot))


# -- spec 30/35 additions: variable damping from σ_min, masked and weighted steps -----------

# Smallest eigenvalue λ_min(J S Jᵀ) (σ_min² of the weighted Jacobian), at a fixed cost: a
# Householder reduction to tridiagonal form (backward stable) and bisection on the Sturm count.
# The interval starts as [Gershgorin lower bound, smallest diagonal entry], at most 2‖A‖ wide,
# and halves each step: 48 steps leave ≤ 2^-47 ‖A‖ ≈ 7e-15 ‖A‖, so the result is within a few
# eps·‖A‖ of λ_min (≤ 1.3e-15 ‖A‖ seen over 6000 seeded matrices, clustered and nearly
# rank-deficient ones included; tests/test_wgpm.py checks it). The steps are one loop in the C
# (armgen.symbolic.loops), not 48 unrolled copies.
# (It replaced 5 sweeps of cyclic Jacobi: same accuracy, 0.6× the operations at m = 6.)
BISECTION_STEPS = 48
# The float C stops after 24 halvings: 2^-23 ‖A‖ ≈ 1.2e-7 ‖A‖, two roundings of ‖A‖ (6e-8),
# while the float tridiagonal reduction alone is off by a few m·6e-8 ‖A‖: more steps refine
# digits the reduction does not have (26 cost 86 more instructions per call on the M4).
BISECTION_STEPS_FLOAT = 24
# Column norm² floor of the tridiagonal reduction's reflectors (relative to ‖A‖_F², plus an
# absolute part for A = 0): only guards an exactly zero column (then vᵀv = floor > 0); a
# floored entry is ≤ sqrt(floor) ≈ 1e-15 ‖A‖ + 1e-15, far below the bisection's resolution.
TRIDIAGONAL_FLOOR_REL = 1e-30
TRIDIAGONAL_FLOOR_ABS = 1e-30
# Added to each e_i² of the Sturm recurrence q_i = (d_i − x) − e_{i−1}²/q_{i−1}: a pivot q = 0
# then gives ±inf (and the next one is finite again), never 0/0; it moves an eigenvalue by at
# most sqrt(tiny) ≈ 1e-15 (‖A‖ + 1), representable in float (min normal 1.2e-38).
STURM_TINY_REL = 1e-30
STURM_TINY_ABS = 1e-30
# Smallest damping threshold ε the steps use (ε enters as 1/ε²): 1e-9 (m or rad).
EPSILON_FLOOR = 1e-9


def tridiagonal(a: ca.SX) -> tuple[list[ca.SX], list[ca.SX]]:
    """(diagonal, subdiagonal) of Qᵀ A Q for the symmetric m×m ``a``: Householder reflectors
    H_k = I − β v vᵀ zero column k below the subdiagonal, A ← H A H by the symmetric rank-2
    update A − v wᵀ − w vᵀ (w = p − ½β(vᵀp) v, p = β A v)."""
    m = a.shape[0]
    A = [[a[i, j] for j in range(m)] for i in range(m)]
    floor = TRIDIAGONAL_FLOOR_REL * ca.sumsqr(a) + TRIDIAGONAL_FLOOR_ABS
    diagonal, sub = [], []
    for k in range(m - 2):
        rows = list(range(k + 1, m))
        x = [A[r][k] for r in rows]
        signed = ca.copysign(ca.sqrt(ca.fmax(criteria.sum_of(xi * xi for xi in x), floor)), x[0])
        v = [x[0] + signed, *x[1:]]  # H x = −signed e₀
        beta = 2 / criteria.sum_of(vi * vi for vi in v)
        p = [beta * criteria.sum_of(A[r][c] * vc for c, vc in zip(rows, v)) for r in rows]
        half = 0.5 * beta * criteria.sum_of(pi * vi for pi, vi in zip(p, v))
        w = [pi - half * vi for pi, vi in zip(p, v)]
        for i, r in enumerate(rows):
            for j in range(i, len(rows)):
                c = rows[j]
                A[r][c] = A[c][r] = A[r][c] - v[i] * w[j] - w[i] * v[j]
        diagonal.append(A[k][k])
        sub.append(-signed)
    diagonal += [A[r][r] for r in range(max(m - 2, 0), m)]
    if m >= 2:
        sub.append(A[m - 1][m - 2])
    return diagonal, sub


def min_eigenvalue(a: ca.SX) -> ca.SX:
    """Smallest eigenvalue of the symmetric m×m matrix ``a``: tridiagonal reduction, then
    BISECTION_STEPS bisection steps on [Gershgorin lower bound, min diagonal]. At a trial x the Sturm
    recurrence q_i = (d_i − x) − e_{i−1}²/q_{i−1} has a negative q_i iff an eigenvalue lies below
    x (Sylvester's inertia of T − xI = L D Lᵀ, D = diag(q)). Fixed cost, no data-dependent loop."""
    m = a.shape[0]
    if m == 1:
        return a[0, 0]
    d, e = tridiagonal(a)
    tiny = STURM_TINY_REL * ca.sumsqr(a) + STURM_TINY_ABS
    e2 = [ei * ei + tiny for ei in e]
    size = [ca.fabs(ei) for ei in e] + [ca.SX(0)]
    lo, hi = d[0] - size[0], d[0]
    for i in range(1, m):
        lo = ca.fmin(lo, d[i] - size[i - 1] - size[i])
        hi = ca.fmin(hi, d[i])  # a Rayleigh quotient: λ_min ≤ every diagonal entry
    final = fixed_loop(_bisection_step(m), BISECTION_STEPS, BISECTION_STEPS_FLOAT)(ca.vertcat(lo, 0.5 * (hi - lo)), ca.vertcat(*d), ca.vertcat(*e2))
    return final[0] + final[1]


def _bisection_step(m: int) -> ca.Function:
    """One bisection step on (lo, half): the trial x = lo + half; no eigenvalue below x (every
    Sturm pivot q_i ≥ 0) → continue in the upper half; the half-width halves.

    "Every q_i ≥ 0" is tested as Σ (q_i − |q_i|) ≥ 0: each term is exactly 0 for q_i ≥ 0 and
    2q_i < 0 otherwise, and a sum of non-positive terms is 0 only if all are, so the decision is
    that of min_i q_i ≥ 0 — by a subtraction, an absolute value and an addition per pivot,
    where a NaN-aware fmin is a compare-and-branch (a third of the step on the Cortex-M4). (One
    corner differs: a pivot of exactly −0 makes the next one +inf, whose term inf − inf is NaN,
    counted as "below x"; it needs d_i − x = −0 exactly with the STURM_TINY-padded e² above.)"""
    state, d, e2 = ca.SX.sym("state", 2), ca.SX.sym("d", m), ca.SX.sym("e2", m - 1)
    lo, half = state[0], state[1]
    x = lo + half
    q = d[0] - x
    negative = q - ca.fabs(q)
    for i in range(1, m):
        q = (d[i] - x) - e2[i - 1] / q
        negative = negative + (q - ca.fabs(q))
    return ca.Function(f"bisection_step{m}", [state, d, e2], [ca.vertcat(lo + (negative >= 0) * half, 0.5 * half)],
                       ["state", "d", "e2"], ["next"])


def variable_damping_sq(lam_min: ca.SX, epsilon: ca.SX, damping_max: ca.SX) -> ca.SX:
    """ρ² = ρ_max² (1 − σ_min²/ε²) below ε, 0 above, with σ_min² = ``lam_min`` (so no sqrt);
    ε is floored at EPSILON_FLOOR."""
    eps = ca.fmax(epsilon, EPSILON_FLOOR)
    return damping_max * damping_max * ca.fmax(0, 1 - lam_min / (eps * eps))


def scaled_step(j: ca.SX, xdot: ca.SX, scale: ca.SX, z: ca.SX, damping_sq: ca.SX, gram: ca.SX) -> ca.SX:
    """q̇ = z + S Jᵀ (J S Jᵀ + ρ² I)⁻¹ (ẋ − J z), S = diag(scale ≥ 0), ``gram`` = J S Jᵀ.

    With S = W_b² this is W_b J_wb^# ẋ + N_wb z (spec 35); with S = mask ⊙ W⁻¹ and z = 0 the
    masked WLN; with S = mask and z = mask ⊙ α the masked GPM (spec 30)."""
    damped = gram + damping_sq * ca.SX.eye(j.shape[0])
    return z + scale * ca.mtimes(j.T, spd_solve(damped, xdot - ca.mtimes(j, z)))


def step_fault(j: ca.SX, xdot: ca.SX, mask: ca.SX, weights: ca.SX, alpha: ca.SX, epsilon: ca.SX,
               damping_max: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """Masked weighted GPM with variable damping (spec 30). Locked joints have mask 0.

    q̇ = μα + S Jᵀ (J S Jᵀ + λ² I)⁻¹ (ẋ − J μα), S = diag(μ / max(W, 1)), μ = mask;
    λ² = λ_max² (1 − σ²/ε²)₊ with σ² = λ_min(J S Jᵀ) (min_eigenvalue). Returns (q̇, λ, σ_min)."""
    scale = mask / ca.fmax(weights, 1)
    gram = weighted_gram(j, scale)
    lam_min = min_eigenvalue(gram)
    damping_sq = variable_damping_sq(lam_min, epsilon, damping_max)
    qdot = scaled_step(j, xdot, scale, mask * alpha, damping_sq, gram)
    return qdot, ca.sqrt(damping_sq), ca.sqrt(ca.fmax(lam_min, 0))


# The criteria of step_wgpm, in the order of its H_lo/H_hi/k_hi/k_lo/u_th/u_band inputs and
# its H/k outputs, and whether each is maximised (+1) or minimised (−1).
WGPM_CRITERIA = ("manipulability", "joint_manipulability", "zghal", "condition")
WGPM_SENSE = (1, 1, -1, -1)


def step_wgpm(j: ca.SX, vjp: Callable[[ca.SX], ca.SX], q: ca.SX, qmin, qmax, xdot: ca.SX, band: ca.SX, t_rmax: ca.SX, epsilon: ca.SX,
              rho_max: ca.SX, delta: ca.SX, ramp: ca.SX, h_lo: ca.SX, h_hi: ca.SX, k_hi: ca.SX, k_lo: ca.SX,
              u_th: ca.SX, u_band: ca.SX) -> dict[str, ca.SX]:
    """The multi-constraint weighted GPM step of spec 35, in one expression:

    w_c (continuous weights), W_b = I − W_c, J_wb = J W_b, σ_min² = λ_min(J_wb J_wbᵀ) (min_eigenvalue),
    ρ² = ρ_max² (1 − σ_min²/ε²)₊, t_r = t_rmax (w_lo − w_hi), H_j (WGPM_CRITERIA),
    H_nj = clip((H_j − H_lo)/(H_hi − H_lo)), u_j = H_nj or 1 − H_nj, k_j = ± f_norm(u_j),
    z = ramp (t_r + W_b Σ_j k_j ∇H_j/(H_hi − H_lo)),
    q̇ = W_b J_wb^# ẋ + N_wb z = z + W_b² Jᵀ (J_wb J_wbᵀ + ρ² I)⁻¹ (ẋ − J z).
    """
    lower, upper = criteria.band_parts(q, qmin, qmax, band)
    w_c = lower + upper
    w_b = 1 - w_c
    t_r = t_rmax * (lower - upper)
    d = criteria.smooth_delta(delta)
    sensitivities = criteria.manipulability_sensitivities(criteria.gram_qr(j), j, ca.DM.ones(j.shape[1]), d)
    h = ca.vertcat(sensitivities.w, criteria.sum_of(sensitivities.omega), criteria.zghal_safe(q, qmin, qmax),
                   sensitivities.condition)
    sense = ca.DM(WGPM_SENSE)
    span = ca.fmax(h_hi - h_lo, criteria.CRITERION_SPAN_FLOOR)
    h_n = ca.fmin(ca.fmax((h - h_lo) / span, 0), 1)
    u = ca.if_else(sense > 0, h_n, 1 - h_n)
    gains = sense * criteria.online_gain(u, k_hi, k_lo, u_th, u_band)
    # Σ_j k_j ∇H_j / span_j (the gains are not differentiated, as the spec's formula says): the
    # J-dependent criteria through one closed-form vector–Jacobian product, Zghal's in closed form
    c = gains / span
    combined = (vjp(sensitivities.combine(c[0], c[1], c[3]))
                + c[2] * criteria.zghal_safe_gradient(q, qmin, qmax))
    z = ramp * (t_r + w_b * combined)
    scale = w_b * w_b
    gram = weighted_gram(j, scale)
    lam_min = min_eigenvalue(gram)
    rho_sq = variable_damping_sq(lam_min, epsilon, rho_max)
    qdot = scaled_step(j, xdot, scale, z, rho_sq, gram)
    return {"qdot": qdot, "w_c": w_c, "rho": ca.sqrt(rho_sq), "sigma_min": ca.sqrt(ca.fmax(lam_min, 0)),
            "gains": gains, "H": h}
