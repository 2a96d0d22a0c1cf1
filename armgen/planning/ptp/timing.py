"""The PTP segment-time solver: the durations at which a segment keeps ``|ω| ≤ ω_max`` (and
``|ε| ≤ ε_max``), and the choice of one duration for all joints.

Segment-time solver (:func:`solve_segment_time`): in normalised time ``s = τ/T`` every
method's segment is ``θ(sT) = Σ b_j(T) s^j`` with ``b_j`` polynomials in ``T`` of degree ≤ 2,
so ``f(s, T) = T^m (θ^(m)(sT) ∓ c)`` is a polynomial in both. The bound ``|θ^(m)| ≤ c``
(m = 1: ``ω_max``, m = 2: ``ε_max``) can only switch at a ``T`` where a root of ``f`` in ``s``
enters or leaves ``[0, 1]``: two roots meet (the discriminant in ``s``, a polynomial in ``T``,
vanishes: an interior extremum touches the bound) or a root crosses an end. Those
polynomials' real roots (``np.roots``, Newton-polished) split the ``T`` axis; feasibility is
constant between them and tested directly at one point per piece. Reported roots are split
points verified by substituting back: the peak of ``|θ^(m)|`` there equals the bound.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np
from numpy.polynomial import polynomial as npp

from .segments import SegmentShape, peak_abs, polynomial_roots

# A bound counts as met when peak ≤ bound·(1 + FEAS_RTOL). The exact minimal duration is a
# root where the peak equals the bound; its computed value is off by a few ulps, which must
# not turn the chosen duration infeasible.
FEAS_RTOL = 1e-9
# A split point is reported as a root when substitution gives peak |θ^(m)| = bound to this
# relative accuracy (Newton-polished simple roots reach ~1e-13; a double root of a critical
# polynomial only ~1e-8 in T, but the peak is quadratic in T there).
ROOT_RTOL = 1e-7
# Polynomial roots with |imag| ≤ IMAG_RTOL·|root| are treated as real split points. A spurious
# split point only divides the T axis more finely, a missed one could hide a sign change.
IMAG_RTOL = 1e-6
# Newton steps polishing a root of a critical polynomial (quadratic convergence from the
# eigenvalue estimate: two or three steps reach rounding level).
NEWTON_STEPS = 3
# A time within this many grid steps of a grid point is that grid point, up to the rounding
# of a root (duration grid) or of t_0 + k·step (sample grid).
GRID_RTOL = 1e-9
# An end value of f(s, T) within this fraction of f's largest coefficient vanishes for every T
# (an end speed equal to ω_max up to the unit conversion).
FIXED_END_RTOL = 1e-12
# Split points closer than this (relative) are one: the same root found from two polynomials.
SPLIT_RTOL = 1e-12
# The time solver's range: segment durations from MIN_SEGMENT_S (below any controller cycle)
# to MAX_SEGMENT_S (11.6 days). Roots outside are not reported; a feasible piece reaching
# MAX_SEGMENT_S is reported with upper end inf.
MIN_SEGMENT_S = 1e-6
MAX_SEGMENT_S = 1e6
# Bisection steps to pin a feasibility switch that a computed root missed: 60 halvings of an
# interval shorter than T reach the last bit of a double.
BISECTION_STEPS = 60


@dataclass(frozen=True)
class TimeRoot:
    """A duration ``T`` where the peak of ``|θ^(m)|`` equals the bound, verified by substitution.

    ``tau`` is where the bound is touched (``θ^(m+1)(tau) = 0`` or a segment end), ``value`` is
    ``θ^(m)(tau)``, ``residual`` is ``(|value| − bound)/bound``.
    """

    duration: float
    quantity: str  # "omega" | "eps"
    tau: float
    value: float
    residual: float

    def as_dict(self) -> dict[str, Any]:
        return {"T_s": float(self.duration), "quantity": self.quantity, "tau_s": float(self.tau),
                "value": float(self.value), "residual": float(self.residual)}


@dataclass(frozen=True)
class SegmentTiming:
    """The time solver's view of one segment of one joint: roots and the feasible set of T."""

    roots: tuple[TimeRoot, ...]
    feasible: tuple[tuple[float, float], ...]  # closed intervals, hi may be inf; lo 0 means "down to 0+"

    def as_dict(self) -> dict[str, Any]:
        return {"roots": [r.as_dict() for r in self.roots], "feasible_T_s": as_interval_lists(self.feasible)}


def as_interval_lists(pieces: Sequence[tuple[float, float]]) -> list[list[float]]:
    return [[float(lo), float(hi)] for lo, hi in pieces]


@functools.lru_cache(maxsize=None)
def _discriminant_terms(degree: int) -> tuple[tuple[int, tuple[int, ...]], ...]:
    """Integer monomials of the discriminant of ``Σ_{i≤degree} a_i s^i`` in the ``a_i``."""
    import sympy

    a = sympy.symbols(f"a0:{degree + 1}")
    s = sympy.Symbol("s")
    disc = sympy.Poly(sympy.discriminant(sum(a[i] * s**i for i in range(degree + 1)), s), *a)
    return tuple((int(c), tuple(int(e) for e in m)) for m, c in disc.terms())


def _discriminant(coeffs: Sequence[np.ndarray]) -> np.ndarray:
    """Discriminant in ``s`` of ``Σ coeffs[i](x) s^i`` (polynomials in x): zero iff a double root in ``s``."""
    total = np.zeros(1)
    for c, exps in _discriminant_terms(len(coeffs) - 1):
        term = np.array([float(c)])
        for poly, e in zip(coeffs, exps):
            if e:
                term = npp.polymul(term, npp.polypow(poly, e))
        total = npp.polyadd(total, term)
    return total


def _real_roots_between(coef: np.ndarray, x_min: float, x_max: float) -> list[float]:
    """Roots of ``Σ coef[i] x^i`` in ``(x_min, x_max)`` (near-real ones included), Newton-polished."""
    dcoef = npp.polyder(coef)
    out = []
    for r in polynomial_roots(coef, x_max):
        if not x_min < r.real < x_max or abs(r.imag) > IMAG_RTOL * abs(r):
            continue
        x = r.real
        for _ in range(NEWTON_STEPS):
            slope = npp.polyval(x, dcoef)
            step = npp.polyval(x, coef) / slope if slope != 0 else math.nan
            if not abs(step) < 0.5 * x:  # keep the polish local (and NaN-safe)
                break
            x -= step
        out.append(float(x))
    return out


def _candidate_durations(shape: SegmentShape, order: int, bound: float) -> list[float]:
    """Every T where the bound on ``|θ^(order)|`` can become active or inactive.

    With ``f(s, T) = T^order (θ^(order)(sT) ∓ bound)`` and ``g`` its quotient by the roots at
    ``s = 0, 1`` that hold for every T: where a root of ``g`` crosses an end (``g(0) = 0``,
    ``g(1) = 0``), two roots meet (discriminant of ``g`` in ``s``), or the degree drops.
    """
    b = shape.normalized()
    delta = abs(shape.theta1 - shape.theta0)
    # Work in x = T / t_ref so the critical polynomials are well scaled.
    t_ref = delta / bound if delta > 0 else 1.0
    base = [math.perm(j, order) * b[j] * t_ref ** np.arange(b[j].size) for j in range(order, len(b))]
    x_pow = np.zeros(order + 1)
    x_pow[order] = t_ref**order
    polys = []
    for c in (bound, -bound):
        g = _without_fixed_end_roots([npp.polysub(base[0], c * x_pow), *base[1:]])
        polys += [g[0], functools.reduce(npp.polyadd, g), g[-1]]
        if len(g) >= 3:
            polys.append(_discriminant(g))
    return sorted(x * t_ref for poly in polys
                  for x in _real_roots_between(poly, MIN_SEGMENT_S / t_ref, MAX_SEGMENT_S / t_ref))


def _without_fixed_end_roots(f: list[np.ndarray]) -> list[np.ndarray]:
    """``f(s)`` (coefficients in s, each a polynomial in T) divided by ``s`` and ``s − 1`` while
    they divide it for every T.

    That happens when an end value equals the bound (ω_B = ω_max in the paper's segment 1):
    the end then touches the bound for every T, and the discriminant would carry the
    quotient's end value squared, a double root that np.roots finds only to ~1e-4.
    """
    scale = max(float(np.max(np.abs(p))) for p in f)
    while len(f) > 1 and np.max(np.abs(f[0])) <= FIXED_END_RTOL * scale:
        f = f[1:]
    while len(f) > 1 and np.max(np.abs(functools.reduce(npp.polyadd, f))) <= FIXED_END_RTOL * scale:
        quotient = [f[-1]]  # synthetic division by (s − 1), highest power first
        for p in f[-2:0:-1]:
            quotient.append(npp.polyadd(p, quotient[-1]))
        f = quotient[::-1]
    return f


def _touch(shape: SegmentShape, duration: float, order: int, bound: float) -> TimeRoot | None:
    """Substitute ``duration`` back: where the peak of ``|θ^(order)|`` equals the bound, if it does.

    The touch point is a zero of ``θ^(order+1)`` or a segment end; the caller keeps it as a
    root when the feasible set starts or ends there or the touch is interior.
    """
    coeffs = shape.coefficients(duration)
    p = npp.polyder(coeffs, order)
    slope = npp.polyder(p)
    points = [float(r.real) for r in polynomial_roots(slope, duration)
              if abs(r.imag) <= IMAG_RTOL * max(abs(r), duration)
              and -ROOT_RTOL * duration <= r.real <= duration * (1 + ROOT_RTOL)]
    points += [0.0, duration]  # an end (also where θ^(order) is constant: touching all along)
    if peak_abs(coeffs, duration, order) > bound * (1 + ROOT_RTOL):
        return None  # a local extremum touches the bound but the peak is elsewhere and above it
    best = None
    for tau in points:
        value = float(npp.polyval(tau, p))
        residual = (abs(value) - bound) / bound
        if abs(residual) <= ROOT_RTOL and (best is None or abs(residual) < abs(best.residual)):
            best = TimeRoot(duration, "omega" if order == 1 else "eps", tau, value, residual)
    return best


def segment_feasible(shape: SegmentShape, duration: float, omega_max: float, eps_max: float | None,
                     rtol: float = FEAS_RTOL) -> bool:
    """Whether the segment of this duration keeps |θ'| ≤ ω_max (and |θ''| ≤ ε_max), to ``rtol``."""
    coeffs = shape.coefficients(duration)
    if peak_abs(coeffs, duration, 1) > omega_max * (1 + rtol):
        return False
    return eps_max is None or peak_abs(coeffs, duration, 2) <= eps_max * (1 + rtol)


def solve_segment_time(shape: SegmentShape, omega_max: float, eps_max: float | None = None) -> SegmentTiming:
    """All roots of peak(T) = bound and the feasible set of durations of one segment.

    Parameters
    ----------
    shape : end conditions (SI).
    omega_max : bound on |θ'| inside the segment, rad/s, > 0.
    eps_max : optional bound on |θ''|, rad/s², > 0.
    """
    bounds = [(1, omega_max)] + ([(2, eps_max)] if eps_max is not None else [])
    splits: list[float] = []
    for x in sorted(x for order, bound in bounds for x in _candidate_durations(shape, order, bound)):
        if not splits or x > splits[-1] * (1 + SPLIT_RTOL):
            splits.append(x)
    edges = [0.0, *splits, math.inf]

    probes = [0.5 * (lo + min(hi, MAX_SEGMENT_S)) for lo, hi in zip(edges[:-1], edges[1:])]
    ok = [segment_feasible(shape, p, omega_max, eps_max) for p in probes]
    for i in range(1, len(edges) - 1):  # edges[i] separates pieces i - 1 and i
        if ok[i - 1] != ok[i] and not any(_touch(shape, edges[i], o, b) for o, b in bounds):
            # the split point is off (a near-double root): find the switch itself, exactly
            edges[i] = _bisect_switch(lambda T: segment_feasible(shape, T, omega_max, eps_max, rtol=0.0),
                                      probes[i - 1], probes[i], ok[i - 1])
    pieces: list[tuple[float, float]] = []
    for i, good in enumerate(ok):
        if good and pieces and pieces[-1][1] == edges[i]:
            pieces[-1] = (pieces[-1][0], edges[i + 1])
        elif good:
            pieces.append((edges[i], edges[i + 1]))
    # roots: where the feasible set starts or ends, and interior touches from below
    ends = {x for piece in pieces for x in piece}
    roots = []
    for duration in sorted(set(edges[1:-1])):
        for order, bound in bounds:
            root = _touch(shape, duration, order, bound)
            if root is not None and (duration in ends or ROOT_RTOL * duration < root.tau < duration * (1 - ROOT_RTOL)):
                roots.append(root)
    return SegmentTiming(tuple(roots), tuple(pieces))


def _bisect_switch(feasible: Callable[[float], bool], a: float, b: float, feasible_at_a: bool) -> float:
    """The point where ``feasible`` switches between ``a`` and ``b``, on its feasible side."""
    good, bad = (a, b) if feasible_at_a else (b, a)
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (good + bad)
        good, bad = (mid, bad) if feasible(mid) else (good, mid)
    return good


def intersect_feasible(sets: Sequence[Sequence[tuple[float, float]]]) -> list[tuple[float, float]]:
    """Intersection of unions of closed intervals."""
    current = list(sets[0])
    for other in sets[1:]:
        current = [(max(a0, b0), min(a1, b1)) for a0, a1 in current for b0, b1 in other if max(a0, b0) <= min(a1, b1)]
    return sorted(current)


def choose_duration(feasible: Sequence[tuple[float, float]], grid: float | None,
                    is_feasible: Callable[[float], bool]) -> float | None:
    """Smallest positive feasible duration (on the grid when given), or None.

    ``is_feasible(T)`` is the authoritative direct check. An interval's left end is a computed
    root; when rounding leaves it just outside the bound, the exact end is found by bisection
    (no grid) or the next grid point is taken.
    """
    for lo, hi in feasible:
        if grid is None:
            if lo <= 0:
                continue  # feasible down to 0+: the bound does not fix this duration
            inner = 0.5 * (lo + hi) if math.isfinite(hi) else 2.0 * lo
            if is_feasible(lo):
                return lo
            if is_feasible(inner):
                return _bisect_switch(is_feasible, inner, lo, True)
        first = max(1, math.ceil(lo / grid - GRID_RTOL))
        for g in (first * grid, (first + 1) * grid):
            if g <= hi * (1 + FEAS_RTOL) and is_feasible(g):
                return g
    return None
