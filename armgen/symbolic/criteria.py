"""Redundancy criteria in CasADi SX (angles in rad, lengths in m).

- Zghal joint-limit criterion ``H_L`` (spec 20; no 1/4 factor, as the spec writes it).
- Repetitive criterion ``H_R = ½‖q − q_init‖²``.
- Joint manipulability ``ω_i`` (spec 30): the manipulability left when joint i locks,
  ``ω_i = sqrt(det(J₋ᵢ J₋ᵢᵀ) + δ²)`` — the smooth form with an explicit ``δ``; for a square
  ``J₋ᵢ`` this is ``sqrt(det(J₋ᵢ)² + δ²)``, and ``δ`` when ``J₋ᵢ`` has fewer columns than rows.
- Manipulability ``w = sqrt(det(J Jᵀ) + δ²)``.
- Continuous weights ``w_c`` (spec 35).

Determinants come from one LDLᵀ factorisation of the m×m Gram matrix ``G = A Aᵀ``
(cost O(m² n + m³), so the criteria grow linearly with the number of joints):
``det G = Π d_k``, and each ``ω_i`` by the rank-one downdate
``det(G − a_i a_iᵀ) = det G · (1 − a_iᵀ G⁻¹ a_i)`` with ``a_iᵀ G⁻¹ a_i = Σ_k y_k² / d_k``,
``L y = a_i``. Every pivot is floored at ``GRAM_PIVOT_FLOOR_REL · tr(G) + GRAM_PIVOT_FLOOR_ABS``:
that is the exact LDLᵀ of ``G + E`` for a small diagonal ``E ≥ 0`` (modified Cholesky), so
``G + E ⪰ a_i a_iᵀ`` keeps ``0 ≤ Σ y_k²/d_k ≤ 1``, every ``|L_ij| ≤ sqrt(G_ii / d_j)`` and
``|y_k| ≤ sqrt(d_k)`` are bounded, and nothing divides by a vanishing number at an exact
singular pose (the determinants there are the floored, ≥ 0, tiny values; ``1 − s`` is
clipped at 0 against rounding). Gradients are CasADi reverse-mode AD of this construction.
Accuracy: away from singular poses the relative error of ``det(G − a_i a_iᵀ)`` is about
``ε (1 + ‖a_i‖² / σ_min(A₋ᵢ)²)`` (the downdate's cancellation), see tests/test_criteria_scaling.py.
"""

from __future__ import annotations

import casadi as ca

# Smallest damping-band fraction Ω used in w_c: keeps the band division finite when a
# caller passes Ω = 0 (a band of 1e-6 of the range is a step function for practical purposes).
MIN_BAND_FRACTION = 1e-6

# Pivot floor of the Gram LDLᵀ, relative to tr(G): 1e-15 is at double rounding level (pivots
# of a singular G come out as ±1e-16·tr(G) noise anyway), so it never alters a regular
# determinant, and it bounds 1/d_k ≤ 1e15 / tr(G) so that reverse-mode gradients stay finite.
GRAM_PIVOT_FLOOR_REL = 1e-15
# Absolute part of that floor, for G = 0 (every column masked): 1e-18 is below the square of
# any meaningful Jacobian entry in SI units (1e-9 m or rad), as steps.PIVOT_FLOOR.
GRAM_PIVOT_FLOOR_ABS = 1e-18


def gram_ldl(g: ca.SX) -> tuple[list[list[ca.SX]], list[ca.SX], list[ca.SX]]:
    """LDLᵀ of the symmetric positive semidefinite ``g`` with floored pivots:
    (unit lower L as nested lists, pivots d, reciprocals 1/d)."""
    m = g.shape[0]
    trace = ca.sum1(ca.diag(g))
    floor = GRAM_PIVOT_FLOOR_REL * trace + GRAM_PIVOT_FLOOR_ABS
    lower = [[None] * m for _ in range(m)]
    diag, inv = [None] * m, [None] * m
    for j in range(m):
        dj = g[j, j] - sum((lower[j][k] * lower[j][k] * diag[k] for k in range(j)), ca.SX(0))
        diag[j] = ca.fmax(dj, floor)
        inv[j] = 1 / diag[j]
        for i in range(j + 1, m):
            lower[i][j] = (g[i, j] - sum((lower[i][k] * lower[j][k] * diag[k] for k in range(j)), ca.SX(0))) * inv[j]
    return lower, diag, inv


def gram_determinants(a: ca.SX) -> tuple[ca.SX, list[ca.SX]]:
    """(det(A Aᵀ), [det(A₋ᵢ A₋ᵢᵀ) for each column i]) from one floored LDLᵀ of A Aᵀ."""
    m, n = a.shape
    if m > n:
        return ca.SX(0), [ca.SX(0)] * n
    lower, diag, inv = gram_ldl(ca.mtimes(a, a.T))
    full = diag[0]
    for k in range(1, m):
        full = full * diag[k]
    if m > n - 1:
        return full, [ca.SX(0)] * n
    reduced = []
    for i in range(n):
        y: list[ca.SX] = []
        leverage = ca.SX(0)
        for r in range(m):
            y.append(a[r, i] - sum((lower[r][k] * y[k] for k in range(r)), ca.SX(0)))
            leverage = leverage + y[r] * y[r] * inv[r]
        reduced.append(full * ca.fmax(1 - leverage, 0))
    return full, reduced


def zghal(q: ca.SX, qmin, qmax) -> ca.SX:
    """H_L = Σ (q_max − q_min)² / ((q_max − q)(q − q_min))."""
    terms = [(hi - lo) ** 2 / ((hi - q[i]) * (q[i] - lo)) for i, (lo, hi) in enumerate(zip(qmin, qmax))]
    return ca.sum1(ca.vertcat(*terms))


def repetitive(q: ca.SX, q_init: ca.SX) -> ca.SX:
    e = q - q_init
    return 0.5 * ca.dot(e, e)


def smoothstep(d):
    """g(d) = −2d³ + 3d² (g(0)=0, g(1)=1, zero slope at both ends)."""
    return d * d * (3 - 2 * d)


def continuous_weights(q: ca.SX, qmin, qmax, band: ca.SX) -> ca.SX:
    """w_c(q_i) of spec 35: 1 beyond a limit, smoothstep in the damping bands, 0 in the free band.

    ``band`` is Ω, the damping-band width as a fraction of each joint's range (0 < Ω < ½).
    """
    band = ca.fmax(band, MIN_BAND_FRACTION)
    out = []
    for i, (lo, hi) in enumerate(zip(qmin, qmax)):
        t_lo = lo + band * (hi - lo)  # (1−Ω) q_min + Ω q_max
        t_hi = hi - band * (hi - lo)  # Ω q_min + (1−Ω) q_max
        width = band * (hi - lo)
        d_lo = ca.fmin(ca.fmax((t_lo - q[i]) / width, 0), 1)
        d_hi = ca.fmin(ca.fmax((q[i] - t_hi) / width, 0), 1)
        # At most one of d_lo, d_hi is non-zero since the bands do not overlap (Ω < ½).
        out.append(smoothstep(d_lo) + smoothstep(d_hi))
    return ca.vertcat(*out)


# -- spec 30/35 additions ------------------------------------------------------------------

# Smallest δ of the smooth forms sqrt(det + δ²) used by the fault-tolerant and weighted-GPM
# functions: their gradients divide by sqrt(det + δ²) ≥ δ, so δ = 0 (or below 1e-9, in the
# unit of ω: m³ for a 6-row task) counts as 1e-9.
MIN_SMOOTH_DELTA = 1e-9
# Zghal's (q_max − q)(q − q_min) is floored at this fraction of the squared range, i.e. the
# barrier saturates ~1e-6 of the range from a limit (and stays finite beyond it).
ZGHAL_GAP_FLOOR = 1e-6
# Floors of the normalisation span H_hi − H_lo and of the gain band λ (divisors).
CRITERION_SPAN_FLOOR = 1e-12
GAIN_BAND_FLOOR = 1e-6
# Floors of ω_floor and of the smooth-WLN velocity band (divisors), rad/s or index units.
OMEGA_FLOOR_MIN = 1e-12
VELOCITY_BAND_FLOOR = 1e-9


def smooth_delta(delta: ca.SX) -> ca.SX:
    return ca.fmax(delta, MIN_SMOOTH_DELTA)


def zghal_safe(q: ca.SX, qmin, qmax) -> ca.SX:
    """Zghal H_L with each (q_max − q)(q − q_min) floored at ZGHAL_GAP_FLOOR · range²: the same
    value inside the limits (away from the last 1e-6 of the range), finite everywhere."""
    terms = []
    for i, (lo, hi) in enumerate(zip(qmin, qmax)):
        span2 = (hi - lo) ** 2
        terms.append(span2 / ca.fmax((hi - q[i]) * (q[i] - lo), ZGHAL_GAP_FLOOR * span2))
    return ca.sum1(ca.vertcat(*terms))


def condition_index(j: ca.SX, det_jjt: ca.SX, delta: ca.SX) -> ca.SX:
    """Smooth condition index κ_s = tr(J Jᵀ) / (m (det(J Jᵀ) + δ²)^{1/m}): the ratio of the
    arithmetic to the geometric mean of the σ_i², 1 for an isotropic J, growing without bound
    toward a singularity (κ_s ≤ κ² = (σ_max/σ_min)²), differentiable everywhere for δ > 0."""
    m = j.shape[0]
    trace = ca.sum1(ca.sum2(j * j))
    return trace / (m * (det_jjt + delta * delta) ** (1.0 / m))


def band_parts(q: ca.SX, qmin, qmax, band: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(g(d_lo), g(d_hi)) per joint: the lower and upper damping-band parts of w_c (spec 35);
    w_c = lower + upper and the repulsive field is t_rmax (lower − upper)."""
    band = ca.fmax(band, MIN_BAND_FRACTION)
    lower, upper = [], []
    for i, (lo, hi) in enumerate(zip(qmin, qmax)):
        t_lo = lo + band * (hi - lo)
        t_hi = hi - band * (hi - lo)
        width = band * (hi - lo)
        lower.append(smoothstep(ca.fmin(ca.fmax((t_lo - q[i]) / width, 0), 1)))
        upper.append(smoothstep(ca.fmin(ca.fmax((q[i] - t_hi) / width, 0), 1)))
    return ca.vertcat(*lower), ca.vertcat(*upper)


def online_gain(u: ca.SX, k_hi: ca.SX, k_lo: ca.SX, u_th: ca.SX, u_band: ca.SX) -> ca.SX:
    """f_norm(u) = k_hi − (k_hi − k_lo) g((u − u_th)/λ) clipped: k_hi for u ≤ u_th, k_lo for
    u ≥ u_th + λ, the zero-slope cubic between (λ floored at GAIN_BAND_FLOOR)."""
    d = ca.fmin(ca.fmax((u - u_th) / ca.fmax(u_band, GAIN_BAND_FLOOR), 0), 1)
    return k_hi - (k_hi - k_lo) * smoothstep(d)


def wln_weights(grad: ca.SX, omega: ca.SX, qdot_prev: ca.SX, mask: ca.SX, b: ca.SX, omega_floor: ca.SX,
                v_band: ca.SX) -> tuple[ca.SX, ca.SX]:
    """WLN weights of spec 30: W_i = 1 + b |∂H/∂q_i| / max(ω_i, ω_floor) · a_i (locked joints: 1).

    Activation a_i: the plain rule (v_band ≤ 0) is 1 when (∂H/∂q_i) q̇_i,prev < 0 (the joint
    moved so as to lower H), else 0. The smooth rule (v_band > 0) ramps a_i = g(v/v_band),
    v = −sign(∂H/∂q_i) q̇_i,prev clipped to [0, v_band] (the joint's speed against the
    gradient): a_i is continuous in q̇_prev, and W is continuous where ∂H/∂q_i changes sign
    because the penalty is multiplied by |∂H/∂q_i|."""
    plain = grad * qdot_prev < 0
    v = -ca.sign(grad) * qdot_prev
    smooth = smoothstep(ca.fmin(ca.fmax(v / ca.fmax(v_band, VELOCITY_BAND_FLOOR), 0), 1))
    active = ca.if_else(v_band > 0, smooth, plain)
    floor = ca.fmax(omega_floor, OMEGA_FLOOR_MIN)
    weights = 1 + mask * b * ca.fabs(grad) / ca.fmax(omega, floor) * active
    return weights, mask * active
