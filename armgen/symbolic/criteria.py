"""Redundancy criteria in CasADi SX (angles in rad, lengths in m).

- Zghal joint-limit criterion ``H_L`` (spec 20; no 1/4 factor, as the spec writes it).
- Repetitive criterion ``H_R = ½‖q − q_init‖²``.
- Joint manipulability ``ω_i`` (spec 30): the manipulability left when joint i locks,
  ``ω_i = sqrt(det(J₋ᵢ J₋ᵢᵀ) + δ²)`` — the smooth form with an explicit ``δ``; for a square
  ``J₋ᵢ`` this is ``sqrt(det(J₋ᵢ)² + δ²)``, and ``δ`` when ``J₋ᵢ`` has fewer columns than rows.
- Manipulability ``w = sqrt(det(J Jᵀ) + δ²)``.
- Continuous weights ``w_c`` (spec 35).

Determinants come from one Householder QR of ``Aᵀ`` (n×m, A = J with masked columns zeroed),
never from the Gram matrix ``A Aᵀ`` (forming it squares the condition number, and the
rank-one downdate ``det G (1 − a_iᵀ G⁻¹ a_i)`` then cancels; in float that cost 1e-1
relative on the bundled arms). With ``Aᵀ = Q R`` (Q n×n orthogonal, R₁ the m×m upper block):
``det(A Aᵀ) = Π r_kk²``, and with ``Q₂`` the last n − m columns of Q,
``det(A₋ᵢ A₋ᵢᵀ) = det(A Aᵀ) · ‖row i of Q₂‖²`` (``1 − a_iᵀ(AAᵀ)⁻¹a_i = 1 − ‖row i of Q₁‖²``,
the rows of Q being unit vectors), which is a sum of squares: no cancellation. The rows of
``Q₂`` are the columns of ``[0 I] H_{m−1} ⋯ H_0`` (the reflectors applied to n − m unit rows),
so the cost is O(n m²) for R plus O((n − m) m n) for Q₂: at fixed task size m, at most
quadratic in the number of joints. Backward stability of Householder QR makes the relative
error of each determinant about ``ε κ`` of the matrix involved (not ``ε κ²``).

Division safety: each column norm² ``s_k`` that builds a reflector is floored at
``QR_NORM_FLOOR_REL · ‖A‖_F² + QR_NORM_FLOOR_ABS`` before its square root. The reflector
``H = I − 2 v vᵀ / (vᵀ v)`` with ``v = x + sign(x₀) sqrt(max(s, floor)) e₀`` is then exactly
orthogonal for every input (``vᵀ v ≥ floor > 0``), so nothing divides by a vanishing number at
an exact singular pose, ``‖row i of Q₂‖² ≤ 1``, and reverse-mode AD gradients (CasADi, of this
construction) stay finite; the determinants use the unfloored ``s_k``, so a regular value is
never altered (a column below the floor, ≤ 1e-15 ‖A‖_F², only arises at a singular pose).
"""

from __future__ import annotations

import casadi as ca

# Smallest damping-band fraction Ω used in w_c: keeps the band division finite when a
# caller passes Ω = 0 (a band of 1e-6 of the range is a step function for practical purposes).
MIN_BAND_FRACTION = 1e-6

# Floor of a column norm² inside the QR, relative to ‖A‖_F²: 1e-15 is at double rounding
# level (a column that vanishes comes out as ~1e-16 ‖A‖_F² noise anyway), so it never alters a
# regular reflector, and it bounds 1/(vᵀv) ≤ 1e15 / ‖A‖_F² so that reverse-mode gradients stay finite.
QR_NORM_FLOOR_REL = 1e-15
# Absolute part of that floor, for A = 0 (every column masked): 1e-18 is below the square of
# any meaningful Jacobian entry in SI units (1e-9 m or rad), as steps.PIVOT_FLOOR.
QR_NORM_FLOOR_ABS = 1e-18


def _reflect(rows: list[ca.SX], v: list[ca.SX], beta: ca.SX) -> list[ca.SX]:
    """(I − β v vᵀ) applied to the vector ``rows`` (same length as v)."""
    dot = v[0] * rows[0]
    for vk, rk in zip(v[1:], rows[1:]):
        dot = dot + vk * rk
    scale = beta * dot
    return [rk - scale * vk for rk, vk in zip(rows, v)]


def gram_determinants(a: ca.SX) -> tuple[ca.SX, list[ca.SX]]:
    """(det(A Aᵀ), [det(A₋ᵢ A₋ᵢᵀ) for each column i]) from one floored Householder QR of Aᵀ."""
    m, n = a.shape
    if m > n:
        return ca.SX(0), [ca.SX(0)] * n
    floor = QR_NORM_FLOOR_REL * ca.sumsqr(a) + QR_NORM_FLOOR_ABS
    # columns of Aᵀ (= rows of A), each a list of n entries; reduced in place
    cols = [[a[r, i] for i in range(n)] for r in range(m)]
    reflectors: list[tuple[list[ca.SX], ca.SX]] = []
    full = ca.SX(1)
    for k in range(m):
        x = cols[k][k:]
        s = x[0] * x[0]
        for xi in x[1:]:
            s = s + xi * xi
        full = full * s  # r_kk² = ‖x‖²
        norm = ca.sqrt(ca.fmax(s, floor))
        v = [x[0] + ca.if_else(x[0] < 0, -norm, norm), *x[1:]]
        # vᵀv summed from v itself (≥ v₀² ≥ norm² ≥ floor): not s + norm² + 2|x₀|·norm, whose
        # |x₀| would differentiate with sign(0) = 0 where v₀ uses the + branch, an inconsistent
        # (wrong) derivative of the reflector at x₀ = 0
        vtv = v[0] * v[0]
        for vi in v[1:]:
            vtv = vtv + vi * vi
        beta = 2 / vtv
        reflectors.append((v, beta))
        for c in range(k + 1, m):
            cols[c] = cols[c][:k] + _reflect(cols[c][k:], v, beta)
    if m > n - 1:
        return full, [ca.SX(0)] * n
    # rows of [0 I] H_{m−1} ⋯ H_0 (each H symmetric): row j starts as e_{m+j}ᵀ
    complement = [[ca.SX(1) if i == m + j else ca.SX(0) for i in range(n)] for j in range(n - m)]
    for k in reversed(range(m)):
        v, beta = reflectors[k]
        for j, row in enumerate(complement):
            complement[j] = row[:k] + _reflect(row[k:], v, beta)
    reduced = []
    for i in range(n):
        weight = complement[0][i] * complement[0][i]
        for row in complement[1:]:
            weight = weight + row[i] * row[i]
        reduced.append(full * weight)
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
