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

Hyper-redundant chains (``n − m > m``, :attr:`GramQR.wide`) use ``Q₁`` instead, which is
already there for the gradients: ``ρ_i = 1 − ‖row i of Q₁‖²`` and the projection onto the
complement ``y Q₂ Q₂ᵀ = y − (y Q₁) Q₁ᵀ``, O(m² n) in all (linear in the joints) where ``Q₂``
would cost O(m n (n − m)) twice over (snake12: 0.4× the operations, and the host compile
below the bar). The price is an absolute error ``ε`` in ``ρ_i`` (relative ``ε/ρ_i``) instead
of a relative one: away from singularities (σ_min(A₋ᵢ) ≥ 1e-2 σ_max(A)) ``ρ_i =
1/(1 + a_iᵀ(A₋ᵢA₋ᵢᵀ)⁻¹a_i) ≥ 1/(1 + 1e4)``, so double keeps ≤ 2.2e-12 relative; a joint
whose loss makes the chain singular (ρ_i → 0) has ω_i to ``sqrt(ε det)`` absolute, below δ
for δ ≥ 1e-7 sqrt(det) in double (in float, ε = 6e-8: documented in docs/snake.md). The
projection has the same absolute error, ``ε ‖y‖``, either way.

Division safety: each column norm² ``s_k`` that builds a reflector is floored at
``QR_NORM_FLOOR_REL · ‖A‖_F² + QR_NORM_FLOOR_ABS`` before its square root. The reflector
``H = I − 2 v vᵀ / (vᵀ v)`` with ``v = x + sign(x₀) sqrt(max(s, floor)) e₀`` is then exactly
orthogonal for every input (``vᵀ v ≥ floor > 0``), so nothing divides by a vanishing number at
an exact singular pose and ``‖row i of Q₂‖² ≤ 1``; the determinants use the unfloored ``s_k``, so
a regular value is never altered (a column below the floor, ≤ 1e-15 ‖A‖_F², only arises at a
singular pose).

Derivatives in closed form, not by AD through the QR: ``∂/∂A`` from the adjugate
``Z = adj(A Aᵀ) A`` and Sherman–Morrison (:class:`Sensitivities`), then ``∂/∂q`` through the
geometric Jacobian by :func:`jacobian_vjp` in O(n). Every division is by ``w`` or ``ω_i ≥ δ``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

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


def sum_of(terms) -> ca.SX:
    """t₀ + t₁ + … left to right (the order the C evaluates)."""
    terms = list(terms)
    out = terms[0]
    for t in terms[1:]:
        out = out + t
    return out


@dataclass
class GramQR:
    """One floored Householder QR of ``Aᵀ`` (A m×n, m ≤ n): ``Aᵀ = Q [R; 0]``.

    ``det`` = det(A Aᵀ) = Π r_kk² (from the unfloored column norms); ``r`` the m×m upper
    triangle with the floored diagonal; ``reflectors`` the (v, β) of H_0 … H_{m−1}."""

    a: ca.SX
    det: ca.SX
    r: list[list[ca.SX]]
    reflectors: list[tuple[list[ca.SX], ca.SX]]

    @cached_property
    def complement(self) -> list[list[ca.SX]]:
        """The n − m rows of ``Q₂ᵀ``: rows of ``[0 I] H_{m−1} ⋯ H_0`` (each H symmetric)."""
        m, n = self.a.shape
        rows = [[ca.SX(1) if i == m + j else ca.SX(0) for i in range(n)] for j in range(n - m)]
        for k in reversed(range(m)):
            v, beta = self.reflectors[k]
            rows = [row[:k] + _reflect(row[k:], v, beta) for row in rows]
        return rows

    @cached_property
    def q1_rows(self) -> list[list[ca.SX]]:
        """The m rows of ``Q₁ᵀ`` (= R⁻ᵀ A): row i is e_iᵀ H_i ⋯ H_0 (H_k e_i = e_i for k > i)."""
        m, n = self.a.shape
        rows = []
        for i in range(m):
            row = [ca.SX(1) if c == i else ca.SX(0) for c in range(n)]
            for k in reversed(range(i + 1)):
                v, beta = self.reflectors[k]
                row = row[:k] + _reflect(row[k:], v, beta)
            rows.append(row)
        return rows

    @property
    def wide(self) -> bool:
        """n − m > m: Q₂ would be the larger factor, so the Q₁ forms are used (module docstring)."""
        m, n = self.a.shape
        return n - m > m

    @cached_property
    def leverage_complement(self) -> list[ca.SX]:
        """ρ_i = ‖row i of Q₂‖² = 1 − a_iᵀ (A Aᵀ)⁻¹ a_i, a sum of squares (no cancellation);
        wide: 1 − ‖row i of Q₁‖², floored at 0 (rounding may take it below at a singular pose)."""
        m, n = self.a.shape
        if n == m:
            return [ca.SX(0)] * n
        if self.wide:
            return [ca.fmax(1 - sum_of(row[i] * row[i] for row in self.q1_rows), 0) for i in range(n)]
        return [sum_of(row[i] * row[i] for row in self.complement) for i in range(n)]

    def weighted_projection(self, z: ca.SX, c: list[ca.SX], k: ca.SX) -> ca.SX:
        """k Z C Q₂ Q₂ᵀ (C = diag(c)): the rows of Z C projected onto the null space of A; 0
        when m = n. Wide: k (Y − (Y Q₁) Q₁ᵀ) with Y = Z C."""
        m, n = self.a.shape
        if n == m:
            return ca.SX(m, n)
        if self.wide:
            q1t = ca.vertcat(*[ca.horzcat(*row) for row in self.q1_rows])  # Q₁ᵀ, m×n
            y = z @ ca.diag(ca.vertcat(*c))
            return k * (y - ca.mtimes(ca.mtimes(y, q1t.T), q1t))
        q2 = ca.horzcat(*[ca.vertcat(*row) for row in self.complement])
        return ca.mtimes(k * ca.mtimes(z, ca.diag(ca.vertcat(*c)) @ q2), q2.T)

    @cached_property
    def reduced(self) -> list[ca.SX]:
        """det(A₋ᵢ A₋ᵢᵀ) = det(A Aᵀ) · ρ_i for each column i."""
        return [self.det * rho for rho in self.leverage_complement]

    @cached_property
    def adjugate_product(self) -> ca.SX:
        """Z = adj(A Aᵀ) A = det(A Aᵀ) (A Aᵀ)⁻¹ A (m×n), the derivative ½ ∂det(A Aᵀ)/∂A.

        With A = Rᵀ Q₁ᵀ: Z = (det · R⁻¹) Q₁ᵀ. ``det · R⁻¹`` is a polynomial in the entries of R
        (no division: see :func:`_det_times_inverse`) and Q₁ᵀ comes from the reflectors (rows of
        norm 1, no division either), so Z is finite everywhere and has the relative error of
        the QR, ≈ ε κ. (The forward substitution R⁻ᵀ A, cheaper by a third, divides by the
        smallest pivot: in float it raised the gradients' error from 5e-5 to 2e-3.)"""
        m, n = self.a.shape
        w = self.q1_rows
        scaled = _det_times_inverse(self.r)
        z = ca.SX(m, n)
        for i in range(m):
            for c in range(n):
                z[i, c] = sum_of(scaled[i][j] * w[j][c] for j in range(i, m))
        return z


def _det_times_inverse(r: list[list[ca.SX]]) -> list[list[ca.SX]]:
    """det(R)² R⁻¹ for upper-triangular R, without division.

    (R⁻¹)_ij = u_ij / Π_{l=i..j} r_ll with u_ii = 1 and
    u_ij = −Σ_{k=i+1..j} r_ik u_kj Π_{l=i+1..k−1} r_ll (back substitution, denominators cleared),
    so det(R)² (R⁻¹)_ij = u_ij · Π_{l∉[i,j]} r_ll² · Π_{l∈[i,j]} r_ll."""
    m = len(r)
    u = [[ca.SX(0)] * m for _ in range(m)]
    for j in range(m):
        u[j][j] = ca.SX(1)
        for i in reversed(range(j)):
            acc, between = ca.SX(0), ca.SX(1)
            for k in range(i + 1, j + 1):
                acc = acc - r[i][k] * u[k][j] * between
                between = between * r[k][k]
            u[i][j] = acc
    squares = [r[l][l] * r[l][l] for l in range(m)]
    out = [[ca.SX(0)] * m for _ in range(m)]
    for i in range(m):
        for j in range(i, m):
            factor = u[i][j]
            for l in range(m):
                factor = factor * (r[l][l] if i <= l <= j else squares[l])
            out[i][j] = factor
    return out


def gram_qr(a: ca.SX) -> GramQR | None:
    """The floored Householder QR of ``Aᵀ``; None when m > n (then det(A Aᵀ) = 0)."""
    m, n = a.shape
    if m > n:
        return None
    floor = QR_NORM_FLOOR_REL * ca.sumsqr(a) + QR_NORM_FLOOR_ABS
    # columns of Aᵀ (= rows of A), each a list of n entries; reduced in place
    cols = [[a[r, i] for i in range(n)] for r in range(m)]
    reflectors: list[tuple[list[ca.SX], ca.SX]] = []
    diagonal = []
    full = ca.SX(1)
    for k in range(m):
        x = cols[k][k:]
        s = sum_of(xi * xi for xi in x)
        full = full * s  # r_kk² = ‖x‖²
        norm = ca.sqrt(ca.fmax(s, floor))
        signed = ca.if_else(x[0] < 0, -norm, norm)
        v = [x[0] + signed, *x[1:]]
        # vᵀv summed from v itself (≥ v₀² ≥ norm² ≥ floor): not s + norm² + 2|x₀|·norm, whose
        # |x₀| would differentiate with sign(0) = 0 where v₀ uses the + branch, an inconsistent
        # (wrong) derivative of the reflector at x₀ = 0
        beta = 2 / sum_of(vi * vi for vi in v)
        reflectors.append((v, beta))
        diagonal.append(-signed)  # H x = −sign(x₀) ‖x‖ e₀
        for c in range(k + 1, m):
            cols[c] = cols[c][:k] + _reflect(cols[c][k:], v, beta)
    r = [[diagonal[i] if c == i else (cols[c][i] if c > i else ca.SX(0)) for c in range(m)] for i in range(m)]
    return GramQR(a, full, r, reflectors)


def jacobian_vjp(robot_revolute: list[bool], jac: ca.SX, g: ca.SX) -> ca.SX:
    """∇_q Σ_ij G_ij J_ij(q) for the geometric Jacobian J (6×n, rows [v; ω]) and a G (6×n)
    held constant: the gradient of any function of J by the chain rule, in O(n).

    The kinematic Hessian of the geometric Jacobian needs only J (z_k = ω_k of a revolute k):
    for i ≥ k and a revolute joint k, ∂J_i/∂q_k = [z_k × v_i; z_k × ω_i] (everything from axis
    k on turns about it); for i < k, ∂v_i/∂q_k = z_i × v_k for a revolute i (the tool point
    moves by v_k) and 0 otherwise; a prismatic joint k moves the tool and axes i > k together,
    so only the i < k terms remain. By the scalar triple product
    ∂/∂q_k = [k revolute] z_k · Σ_{i≥k} (v_i × g_v,i + ω_i × g_ω,i) + v_k · Σ_{i<k, revolute} g_v,i × z_i,
    a suffix and a prefix sum."""
    n = jac.shape[1]
    v = [jac[0:3, i] for i in range(n)]
    w = [jac[3:6, i] for i in range(n)]
    gv = [g[0:3, i] for i in range(n)]
    gw = [g[3:6, i] for i in range(n)]
    suffix: list[ca.SX] = [None] * n
    acc = ca.SX.zeros(3, 1)
    for i in reversed(range(n)):
        acc = acc + ca.cross(v[i], gv[i]) + (ca.cross(w[i], gw[i]) if robot_revolute[i] else 0)
        suffix[i] = acc
    grad = []
    prefix = ca.SX.zeros(3, 1)
    for k in range(n):
        term = ca.dot(v[k], prefix)
        if robot_revolute[k]:
            term = term + ca.dot(w[k], suffix[k])
            prefix = prefix + ca.cross(gv[k], w[k])
        grad.append(term)
    return ca.vertcat(*grad)


@dataclass
class Sensitivities:
    """The manipulability family of A (m×n) and its derivatives with respect to A, from one QR.

    ``w = sqrt(det(A Aᵀ) + δ²)``, ``omega`` the ω_i = sqrt(det(A₋ᵢ A₋ᵢᵀ) + δ²) and
    ``H = Σ weights_i ω_i``. With Z = adj(A Aᵀ) A (``GramQR.adjugate_product``), ∂w/∂A = Z / w;
    by Sherman–Morrison on A₋ᵢ A₋ᵢᵀ = A Aᵀ − a_i a_iᵀ, adj(A₋ᵢ A₋ᵢᵀ) A₋ᵢ = ρ_i Z + Z e_i (P − I)_i
    (P = Q₁ Q₁ᵀ, I − P = Q₂ Q₂ᵀ), so ∂H/∂A = Σ c_i adj(A₋ᵢA₋ᵢᵀ)A₋ᵢ = s Z − (Z C Q₂) Q₂ᵀ with
    c_i = weights_i / ω_i, C = diag(c), s = Σ c_i ρ_i: O(m n (n − m)) (O(m² n) for a wide A,
    :meth:`GramQR.weighted_projection`), no division but by w and ω_i ≥ δ. The smooth condition
    index is :func:`condition_index`."""

    a: ca.SX
    det: ca.SX
    z: ca.SX
    w: ca.SX
    omega: list[ca.SX]
    c: list[ca.SX]  # weights_i / ω_i
    s: ca.SX  # Σ c_i ρ_i
    qr: GramQR | None  # None when m > n (every determinant 0)
    delta: ca.SX

    @property
    def grad_w(self) -> ca.SX:
        return self.z / self.w

    @property
    def grad_h(self) -> ca.SX:
        return self.combine(0, 1, 0)

    @cached_property
    def _condition(self) -> tuple[ca.SX, ca.SX, ca.SX]:
        """(κ_s, α, β) with ∂κ_s/∂A = α A − β Z (see :func:`condition_index`)."""
        return condition_index(self.a, self.det, self.delta)

    @property
    def condition(self) -> ca.SX:
        return self._condition[0]

    @property
    def grad_condition(self) -> ca.SX:
        return self.combine(0, 0, 1)

    def combine(self, k_w, k_h, k_condition) -> ca.SX:
        """k_w ∂w/∂A + k_h ∂H/∂A + k_condition ∂κ_s/∂A, the scalars folded first: one m×n
        combination of Z and A plus the rank-(n − m) correction of ∂H/∂A."""
        _, alpha, beta = self._condition if not _is_zero(k_condition) else (None, 0, 0)
        out = (k_w / self.w + k_h * self.s - k_condition * beta) * self.z
        if not _is_zero(k_condition):
            out = out + (k_condition * alpha) * self.a
        if self.qr is not None and not _is_zero(k_h):
            out = out - self.qr.weighted_projection(self.z, self.c, k_h)
        return out


def _is_zero(value) -> bool:
    return isinstance(value, (int, float)) and value == 0


def manipulability_sensitivities(qr: GramQR | None, a: ca.SX, weights: ca.SX, delta: ca.SX) -> Sensitivities:
    """:class:`Sensitivities` of A for the ω_i weights ``weights`` (m > n: every determinant 0)."""
    m, n = a.shape
    if qr is None:
        zero = ca.SX(m, n)
        return Sensitivities(a, ca.SX(0), zero, delta, [delta] * n, [ca.SX(0)] * n, ca.SX(0), None, delta)
    w = ca.sqrt(qr.det + delta * delta)
    omega = [ca.sqrt(g + delta * delta) for g in qr.reduced]
    c = [weights[i] / omega[i] for i in range(n)]
    s = sum_of(ci * rho for ci, rho in zip(c, qr.leverage_complement))
    return Sensitivities(a, qr.det, qr.adjugate_product, w, omega, c, s, qr, delta)


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


def zghal_safe_gradient(q: ca.SX, qmin, qmax) -> ca.SX:
    """∇ of :func:`zghal_safe` in closed form: ∂/∂q_i of r²/g with g = (q_max − q)(q − q_min) is
    r² (2q − q_max − q_min)/g², and 0 where the floor holds g (the barrier is flat there).
    Fewer operations than reverse-mode AD of the quotient (one division a joint instead of
    two), so cheaper in every step that descends on it; checked against SymPy's derivative."""
    rows = []
    for i, (lo, hi) in enumerate(zip(qmin, qmax)):
        span2 = (hi - lo) ** 2
        gap = (hi - q[i]) * (q[i] - lo)
        rows.append(ca.if_else(gap > ZGHAL_GAP_FLOOR * span2, span2 * (2 * q[i] - (hi + lo)) / (gap * gap), 0))
    return ca.vertcat(*rows)


def condition_index(j: ca.SX, det_jjt: ca.SX, delta: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """Smooth condition index κ_s = tr(J Jᵀ) / (m (det(J Jᵀ) + δ²)^{1/m}) and (α, β) with
    ∂κ_s/∂J = α J − β adj(J Jᵀ) J: the ratio of the arithmetic to the geometric mean of the
    σ_i², 1 for an isotropic J, growing without bound toward a singularity
    (κ_s ≤ κ² = (σ_max/σ_min)²), differentiable everywhere for δ > 0. With D = det + δ² and
    ∂det/∂J = 2 adj(J Jᵀ) J: α = 2 / (m D^{1/m}), β = α tr / (m D)."""
    m = j.shape[0]
    trace = ca.sumsqr(j)
    total = det_jjt + delta * delta
    power = ca.exp(ca.log(total) / m)
    alpha = 2 / (m * power)
    return trace / (m * power), alpha, alpha * trace / (m * total)


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
