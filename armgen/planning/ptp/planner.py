"""Joint-space point-to-point planning through velocity-constrained waypoints (spec 40).

Every joint passes waypoints ``θ_k`` with velocities ``ω_k`` at shared knot times ``t_k``.
Methods, selected by name behind one interface (:data:`METHODS`):

- ``cubic``: a cubic per segment from θ, ω at both ends (ε jumps at the knots);
- ``3-4`` (default): cubic first segment, then quartics that inherit the acceleration of the
  segment before (θ, ω, ε continuous, nothing preset);
- ``3-5-3``: cubic, quintic…, cubic; the quintics take their end accelerations from the
  neighbouring cubics and, at knots between two quintics, from ``waypoints.eps`` — without
  it, the single such knot of a 5-waypoint plan gets the minimum-jerk value and longer plans
  get zero;
- ``quintic``: quintics with θ, ω, ε at both ends (ε from ``waypoints.eps``, default zero).

A segment ``k`` is stored as six coefficients ``a_0 … a_5`` of ``θ(τ) = Σ a_j τ^j`` in local
time ``τ = t − t_k`` (rad, s; zero-padded), which is what the firmware evaluates.

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

from ...errors import PlanningError, RobotFileError, TaskFileError
from ...robot import load_robot
from ..result import PlanResult
from .poses import POSE_FIELDS, solve_pose_waypoints

METHODS = ("cubic", "3-4", "3-5-3", "quintic")
DEFAULT_METHOD = "3-4"
DEFAULT_STEP_S = 1e-3
NCOEF = 6  # stored coefficients per segment: a_0 … a_5 (quintic), lower degrees zero-padded
MAX_SAMPLES = 5_000_000  # a CSV beyond this is a mistaken step, not a plan
ANGLE_SCALE = {"rad": 1.0, "deg": math.pi / 180.0}

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
# Waypoint speeds equal to ω_max are allowed (the paper's segment 1); this relative slack
# absorbs the unit conversion of equal numbers.
BOUND_RTOL = 1e-12


# --------------------------------------------------------------------------- segments

@dataclass(frozen=True)
class SegmentShape:
    """End conditions of one segment; ``kind`` fixes which of them are used.

    ``cubic``: θ, ω at both ends. ``quartic``: θ, ω, ε at the start, θ, ω at the end.
    ``quintic``: θ, ω, ε at both ends. Unused accelerations are zero.
    """

    kind: str
    theta0: float
    omega0: float
    theta1: float
    omega1: float
    eps0: float = 0.0
    eps1: float = 0.0

    def normalized(self) -> list[np.ndarray]:
        """``b_j(T)`` (coefficients ascending in T) with ``θ(sT) = Σ_j b_j(T) s^j``, ``s ∈ [0, 1]``."""
        d, w0, w1, e0, e1 = self.theta1 - self.theta0, self.omega0, self.omega1, self.eps0, self.eps1
        if self.kind == "cubic":
            rows = [[self.theta0], [0.0, w0], [3 * d, -(2 * w0 + w1)], [-2 * d, w0 + w1]]
        elif self.kind == "quartic":
            rows = [[self.theta0], [0.0, w0], [0.0, 0.0, e0 / 2], [4 * d, -(3 * w0 + w1), -e0],
                    [-3 * d, 2 * w0 + w1, e0 / 2]]
        else:
            rows = [[self.theta0], [0.0, w0], [0.0, 0.0, e0 / 2],
                    [10 * d, -(6 * w0 + 4 * w1), -(3 * e0 - e1) / 2],
                    [-15 * d, 8 * w0 + 7 * w1, (3 * e0 - 2 * e1) / 2],
                    [6 * d, -3 * (w0 + w1), -(e0 - e1) / 2]]
        return [np.array(r, dtype=float) for r in rows]

    def coefficients(self, duration: float) -> np.ndarray:
        """``a_0 … a_5`` of ``θ(τ)`` for a segment of ``duration`` seconds."""
        out = np.zeros(NCOEF)
        for j, b in enumerate(self.normalized()):
            out[j] = npp.polyval(duration, b) / duration**j
        return out


def _roots(coef: np.ndarray, x_max: float) -> np.ndarray:
    """Complex roots of ``Σ coef[i] x^i`` that matter on ``[0, x_max]``.

    Leading terms whose size on ``[0, x_max]`` stays below the rounding of the largest term
    there (``|c_n| x_max^n ≤ eps · max_i |c_i| x_max^i``) are dropped: they move the roots in
    range less than rounding does, and a tiny leading coefficient (an inherited ε of 1e-17)
    would wreck the companion matrix. ``np.roots`` balances that matrix (``polyroots`` does not).
    """
    coef = np.asarray(coef, dtype=float)
    with np.errstate(divide="ignore"):
        size = np.log(np.abs(coef)) + np.arange(coef.size) * math.log(x_max)
    keep = np.flatnonzero(size > np.max(size, initial=-np.inf) + math.log(np.finfo(float).eps))
    coef = coef[: keep[-1] + 1] if keep.size else coef[:0]
    return np.roots(coef[::-1]) if coef.size >= 2 else np.array([], dtype=complex)


def _breakpoints(coef: np.ndarray, duration: float) -> np.ndarray:
    """0, T and every root's real part clipped into [0, T], sorted.

    Extra points are harmless for maxima and total variation; the real roots are all there.
    """
    inner = np.clip(np.real(_roots(coef, duration)), 0.0, duration)
    return np.unique(np.concatenate(([0.0, duration], inner)))


def _values_at_breakpoints(coeffs: np.ndarray, duration: float, order: int) -> np.ndarray:
    """``θ^(order)`` at 0, T and the zeros of ``θ^(order+1)`` in between, in time order."""
    p = npp.polyder(coeffs, order)
    return npp.polyval(_breakpoints(npp.polyder(p), duration), p)


def peak_abs(coeffs: np.ndarray, duration: float, order: int) -> float:
    """Exact max of ``|θ^(order)|`` over the segment ``[0, duration]``."""
    return float(np.max(np.abs(_values_at_breakpoints(coeffs, duration, order))))


def extremes(coeffs: np.ndarray, duration: float, order: int) -> tuple[float, float]:
    """Exact (min, max) of ``θ^(order)`` over ``[0, duration]``."""
    values = _values_at_breakpoints(coeffs, duration, order)
    return float(values.min()), float(values.max())


def total_variation(coeffs: np.ndarray, duration: float, order: int) -> float:
    """``∫ |θ^(order+1)| dτ`` over the segment: sum of |steps| between monotone pieces."""
    return float(np.sum(np.abs(np.diff(_values_at_breakpoints(coeffs, duration, order)))))


def derivative_at(coeffs: np.ndarray, tau: float, order: int) -> float:
    """``θ^(order)(tau)`` of one segment."""
    return float(npp.polyval(tau, npp.polyder(coeffs, order)))


# --------------------------------------------------------------------------- time solver

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
        return {"roots": [r.as_dict() for r in self.roots], "feasible_T_s": _intervals(self.feasible)}


def _intervals(pieces: Sequence[tuple[float, float]]) -> list[list[float]]:
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
    for r in _roots(coef, x_max):
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
    points = [float(r.real) for r in _roots(slope, duration)
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


# --------------------------------------------------------------------------- task config

@dataclass(frozen=True)
class JointWaypoints:
    """One joint's waypoints in SI: angles (rad), velocities (rad/s), optional preset ε (rad/s²)."""

    name: str
    theta: np.ndarray
    omega: np.ndarray
    eps: np.ndarray | None = None
    qlim: tuple[float, float] | None = None


@dataclass(frozen=True)
class PtpConfig:
    """A parsed ``planner = "ptp"`` task, SI units. Arrays ``omega_max``/``eps_max`` are (joints, segments)."""

    source: str
    method: str
    compare: tuple[str, ...]
    step: float
    angle_unit: str
    joints: tuple[JointWaypoints, ...]
    times: np.ndarray | None
    omega_max: np.ndarray | None
    eps_max: np.ndarray | None
    grid: float | None
    robot: str | None = None
    solved_poses: dict[str, Any] | None = None  # waypoints given as tool poses: the IK's solutions (poses.py)

    @property
    def n_waypoints(self) -> int:
        return len(self.joints[0].theta)

    @property
    def n_segments(self) -> int:
        return self.n_waypoints - 1


_TOP_FIELDS = {"planner", "description", "robot", "method", "compare", "step", "units", "waypoints", "timing"}
_WAYPOINT_FIELDS = {"t", "theta", "omega", "eps", *POSE_FIELDS}
_TIMING_FIELDS = {"omega_max", "eps_max", "grid"}


def waypoint_label(k: int) -> str:
    """``A``, ``B``, … as in the spec (``#k`` past ``Z``)."""
    return chr(ord("A") + k) if k < 26 else f"#{k}"


def segment_label(k: int) -> str:
    return f"segment {k + 1} ({waypoint_label(k)}→{waypoint_label(k + 1)})"


class _Fields:
    """Typed access to task fields; errors name the file, the field and the fix."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, field: str, message: str) -> TaskFileError:
        return TaskFileError(f"{self.source}: field '{field}' {message}")

    def number(self, value: Any, field: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(field, f"must be a number, got {value!r}")
        if not math.isfinite(value):
            raise self.fail(field, f"is {value}; give a finite number")
        return float(value)

    def positive(self, value: Any, field: str, fix: str) -> float:
        x = self.number(value, field)
        if x <= 0:
            raise self.fail(field, f"= {value} must be > 0; {fix}")
        return x

    def vector(self, value: Any, field: str, length: int | None = None) -> np.ndarray:
        if not isinstance(value, list):
            raise self.fail(field, f"must be an array of numbers, got {type(value).__name__} {value!r}")
        if length is not None and len(value) != length:
            raise self.fail(field, f"has {len(value)} entries but there are {length} waypoints; give one per waypoint")
        return np.array([self.number(v, f"{field}[{k}]") for k, v in enumerate(value)])

    def table(self, doc: dict, key: str, required: bool, allowed: set[str]) -> dict:
        if key not in doc:
            if required:
                raise self.fail(key, f"is missing; add a [{key}] table")
            return {}
        value = doc[key]
        if not isinstance(value, dict):
            raise self.fail(key, f"must be a table ([{key}])")
        unknown = set(value) - allowed
        if unknown:
            raise self.fail(key, f"has unknown field(s) {', '.join(sorted(unknown))}; allowed: {', '.join(sorted(allowed))}")
        return value


def _per_joint(fields: _Fields, value: Any, field: str, names: tuple[str, ...], single: bool) -> dict[str, Any]:
    """A per-joint table (robot) or a bare value (single joint) as ``{joint: value}``."""
    if single:
        if isinstance(value, dict):
            raise fields.fail(field, "is a table but the task names no robot; give an array for the single joint")
        return {names[0]: value}
    if not isinstance(value, dict):
        raise fields.fail(field, f"must be a table with one array per joint of the robot ({', '.join(names)}), "
                                 f"e.g. {field} = {{ {names[0]} = [...], ... }}")
    unknown = set(value) - set(names)
    missing = [n for n in names if n not in value]
    if unknown:
        raise fields.fail(field, f"names unknown joint(s) {', '.join(sorted(unknown))}; "
                                 f"the robot's joints are {', '.join(names)}")
    if missing:
        raise fields.fail(field, f"lacks joint(s) {', '.join(missing)}; give waypoints for every joint of the robot")
    return value


def _bound_array(fields: _Fields, value: Any, field: str, names: tuple[str, ...], single: bool, nseg: int,
                 scale: float, fix: str) -> np.ndarray:
    """A bound given as a number, a per-segment array, or (robot) a per-joint table of either."""
    table = _per_joint(fields, value, field, names, single) if isinstance(value, dict) else None
    out = np.empty((len(names), nseg))
    for j, name in enumerate(names):
        item, where = (table[name], f"{field}.{name}") if table is not None else (value, field)
        if isinstance(item, list):
            if len(item) != nseg:
                raise fields.fail(where, f"has {len(item)} entries but there are {nseg} segments; "
                                         "give one per segment or a single number")
            out[j] = [fields.positive(v, f"{where}[{k}]", fix) for k, v in enumerate(item)]
        else:
            out[j] = fields.positive(item, where, fix)
    return out * scale


def parse_ptp_task(task: dict[str, Any], source: str) -> PtpConfig:
    """Validate a ``planner = "ptp"`` task dict and convert it to SI (see docs/ptp.md)."""
    fields = _Fields(source)
    unknown = set(task) - _TOP_FIELDS
    if unknown:
        raise TaskFileError(f"{source}: unknown field(s) {', '.join(sorted(unknown))}; allowed: {', '.join(sorted(_TOP_FIELDS))}")
    method = task.get("method", DEFAULT_METHOD)
    if method not in METHODS:
        raise fields.fail("method", f"= {method!r} is not one of {', '.join(METHODS)}")
    compare_raw = task.get("compare", [])
    if (not isinstance(compare_raw, list) or any(m not in METHODS for m in compare_raw)
            or len(set(compare_raw)) != len(compare_raw)):
        raise fields.fail("compare", f"= {compare_raw!r} must be a list of distinct method names from {', '.join(METHODS)}")
    step = fields.positive(task.get("step", DEFAULT_STEP_S), "step", "give the CSV sample step in seconds, e.g. 0.001")
    units = fields.table(task, "units", False, {"angle"})
    angle_unit = units.get("angle", "rad")
    if angle_unit not in ANGLE_SCALE:
        raise fields.fail("units.angle", f"= {angle_unit!r} must be \"rad\" or \"deg\"")
    scale = ANGLE_SCALE[angle_unit]

    robot_name = task.get("robot")
    qlims: list[tuple[float, float] | None]
    if robot_name is None:
        names: tuple[str, ...] = ("j1",)
        qlims = [None]
    else:
        if not isinstance(robot_name, str) or not robot_name:
            raise fields.fail("robot", f"= {robot_name!r} must be a bundled robot name or a robot file path")
        try:
            robot = load_robot(robot_name)
        except RobotFileError as exc:
            raise TaskFileError(f"{source}: field 'robot': {exc}") from None
        prismatic = [j.name for j in robot.joints if not j.revolute]
        if prismatic:
            raise fields.fail("robot", f"= {robot_name!r} has prismatic joint(s) {', '.join(prismatic)}; "
                                       "the ptp planner plans revolute joints (angles) only")
        names = tuple(j.name for j in robot.joints)
        qlims = [j.qlim for j in robot.joints]
    single = robot_name is None

    wp = fields.table(task, "waypoints", True, _WAYPOINT_FIELDS)
    solved_poses = None
    if "xyz" in wp:  # tool poses: joint angles by the inverse kinematics, stopping at each unless omega is given
        if single:
            raise fields.fail("waypoints.xyz", "needs a robot (the task names none); add robot = \"<name>\"")
        q_solved, solved_poses = solve_pose_waypoints(robot, wp, source, scale)
        wp = {**wp, "theta": {name: (q_solved[:, j] / scale).tolist() for j, name in enumerate(names)}}
        wp.setdefault("omega", {name: [0.0] * len(q_solved) for name in names})
    elif any(key in wp for key in POSE_FIELDS):
        raise fields.fail("waypoints.rpy", "and waypoints.seed need waypoints.xyz (the tool positions); add it")
    for key in ("theta", "omega"):
        if key not in wp:
            raise fields.fail(f"waypoints.{key}", "is missing; give the waypoint angles (theta) and velocities (omega)")
    thetas = _per_joint(fields, wp["theta"], "waypoints.theta", names, single)
    omegas = _per_joint(fields, wp["omega"], "waypoints.omega", names, single)
    epss = _per_joint(fields, wp["eps"], "waypoints.eps", names, single) if "eps" in wp else None
    first = thetas[names[0]]
    if not isinstance(first, list) or len(first) < 2:
        where = "waypoints.theta" if single else f"waypoints.theta.{names[0]}"
        raise fields.fail(where, f"must list at least two waypoints (got {first!r}); a plan goes from A to B at least")
    n = len(first)
    joints = []
    for name, qlim in zip(names, qlims):
        sfx = "" if single else f".{name}"
        theta = fields.vector(thetas[name], f"waypoints.theta{sfx}", n) * scale
        omega = fields.vector(omegas[name], f"waypoints.omega{sfx}", n) * scale
        eps = fields.vector(epss[name], f"waypoints.eps{sfx}", n) * scale if epss is not None else None
        if qlim is not None:
            for k, q in enumerate(theta):
                if not qlim[0] <= q <= qlim[1]:
                    raise fields.fail(f"waypoints.theta{sfx}[{k}]",
                                      f"= {q / scale:.6g} {angle_unit} is outside joint '{name}' limits "
                                      f"[{qlim[0] / scale:.6g}, {qlim[1] / scale:.6g}] {angle_unit}; "
                                      "move the waypoint inside the limits")
        joints.append(JointWaypoints(name, theta, omega, eps, qlim))

    timing = fields.table(task, "timing", False, _TIMING_FIELDS)
    times = None
    if "t" in wp:
        times = fields.vector(wp["t"], "waypoints.t", n)
        for k in range(n - 1):
            if not times[k] < times[k + 1]:
                raise fields.fail(f"waypoints.t[{k + 1}]",
                                  f"= {times[k + 1]:g} s is not after waypoints.t[{k}] = {times[k]:g} s; "
                                                          "knot times must be strictly increasing")
        if "grid" in timing:
            raise fields.fail("timing.grid", "rounds computed durations, but waypoints.t is given; remove timing.grid "
                                             "or remove waypoints.t to compute the times from timing.omega_max")
    elif "omega_max" not in timing:
        raise fields.fail("waypoints.t", "is missing and there is no timing.omega_max; give the knot times or the speed bound")
    omega_max = eps_max = grid = None
    if "omega_max" in timing:
        omega_max = _bound_array(fields, timing["omega_max"], "timing.omega_max", names, single, n - 1, scale,
                                 "give the joint speed bound in angle units per second")
    if "eps_max" in timing:
        eps_max = _bound_array(fields, timing["eps_max"], "timing.eps_max", names, single, n - 1, scale,
                               "give the joint acceleration bound in angle units per second squared, or remove it")
        if omega_max is None:
            raise fields.fail("timing.eps_max", "needs timing.omega_max as well; add timing.omega_max")
    if "grid" in timing:
        grid = fields.positive(timing["grid"], "timing.grid", "give the duration grid in seconds (e.g. 1.0) or remove it")
    config = PtpConfig(source, method, tuple(compare_raw), step, angle_unit, tuple(joints), times, omega_max, eps_max,
                       grid, robot_name, solved_poses)
    if omega_max is not None:
        _check_bounds_against_waypoints(config)
    for m in dict.fromkeys([method, *compare_raw]):
        _check_method_applicable(config, m)
    return config


def _check_bounds_against_waypoints(config: PtpConfig) -> None:
    """ω_max (ε_max) must not be below a waypoint's own speed (preset acceleration)."""
    scale, unit = ANGLE_SCALE[config.angle_unit], config.angle_unit
    for j, jw in enumerate(config.joints):
        sfx = "" if len(config.joints) == 1 else f" of joint '{jw.name}'"
        for k in range(config.n_segments):
            for i in (k, k + 1):
                if abs(jw.omega[i]) > config.omega_max[j, k] * (1 + BOUND_RTOL):
                    raise TaskFileError(
                        f"{config.source}: field 'timing.omega_max' for {segment_label(k)}{sfx} is "
                        f"{config.omega_max[j, k] / scale:.6g} {unit}/s, below |waypoints.omega[{i}]| = "
                        f"{abs(jw.omega[i]) / scale:.6g} {unit}/s at waypoint {waypoint_label(i)}; "
                        "raise omega_max or lower the waypoint speed")
            if config.eps_max is not None:
                for i in (k, k + 1):
                    preset = _preset_accel(config.method, jw, i, config.n_segments)
                    if preset is not None and abs(preset) > config.eps_max[j, k] * (1 + BOUND_RTOL):
                        raise TaskFileError(
                            f"{config.source}: field 'timing.eps_max' for {segment_label(k)}{sfx} is "
                            f"{config.eps_max[j, k] / scale:.6g} {unit}/s², below the preset |waypoints.eps[{i}]| = "
                            f"{abs(preset) / scale:.6g} {unit}/s²; raise eps_max or lower the preset acceleration")


def _check_method_applicable(config: PtpConfig, method: str) -> None:
    if method == "3-5-3" and config.n_waypoints < 4:
        raise TaskFileError(f"{config.source}: method '3-5-3' needs at least 4 waypoints (cubic, quintic…, cubic), "
                            f"got {config.n_waypoints}; use '3-4' or 'cubic' (field 'method' or 'compare')")
    if (method == config.method and config.times is None and method == "3-5-3" and config.n_waypoints == 5
            and config.joints[0].eps is None):
        raise TaskFileError(f"{config.source}: field 'waypoints.t' is missing, but the 5-waypoint 3-5-3 plan chooses the "
                            "acceleration at C from both quintic durations together, so its segment times cannot be "
                            "computed one by one; give waypoints.t, or waypoints.eps, or use method '3-4' to compute the times")


# --------------------------------------------------------------------------- methods

def _preset_accel(method: str, jw: JointWaypoints, i: int, nseg: int) -> float | None:
    """The preset acceleration a method uses at waypoint ``i`` (None: determined by the segments)."""
    if method == "quintic":
        return float(jw.eps[i]) if jw.eps is not None else 0.0
    if method == "3-5-3" and 2 <= i <= nseg - 2:
        if jw.eps is not None:
            return float(jw.eps[i])
        return None if nseg == 4 else 0.0  # 5 waypoints: minimum jerk (see _min_jerk_inner_accel)
    return None


def _cubic(jw: JointWaypoints, k: int) -> SegmentShape:
    return SegmentShape("cubic", jw.theta[k], jw.omega[k], jw.theta[k + 1], jw.omega[k + 1])


def _min_jerk_inner_accel(jw: JointWaypoints, durations: Sequence[float]) -> float:
    """ε at C of a 5-waypoint 3-5-3 plan minimising ∫ jerk² over the two quintics.

    The quintics' coefficients are affine in ε_C, so the integral is a parabola in ε_C.
    """
    e_b = _end_accel(_cubic(jw, 0), durations[0])
    e_d = _start_accel(_cubic(jw, 3), durations[3])

    def quintics(e_c: float) -> list[tuple[np.ndarray, float]]:
        ends = ((e_b, e_c), (e_c, e_d))
        return [(SegmentShape("quintic", jw.theta[k], jw.omega[k], jw.theta[k + 1], jw.omega[k + 1], *ends[k - 1])
                 .coefficients(durations[k]), durations[k]) for k in (1, 2)]

    lin = quadratic = 0.0
    for (c0, dur), (c1, _) in zip(quintics(0.0), quintics(1.0)):
        j0, j1 = npp.polyder(c0, 3), npp.polyder(c1 - c0, 3)
        lin += npp.polyval(dur, npp.polyint(npp.polymul(j0, j1)))
        quadratic += npp.polyval(dur, npp.polyint(npp.polymul(j1, j1)))
    return -lin / quadratic


def _end_accel(shape: SegmentShape, duration: float) -> float:
    return derivative_at(shape.coefficients(duration), duration, 2)


def _start_accel(shape: SegmentShape, duration: float) -> float:
    return float(2.0 * shape.coefficients(duration)[2])


def segment_shape(method: str, jw: JointWaypoints, k: int, durations: Sequence[float | None],
                  previous: SegmentShape | None = None) -> SegmentShape:
    """End conditions of segment ``k`` under ``method``; needs the durations it depends on.

    ``3-4`` needs ``previous`` (segment ``k − 1``) and its duration; ``3-5-3`` the first and
    last durations (and, for the minimum-jerk knot of a 5-waypoint plan, all);
    ``cubic``/``quintic`` none.
    """
    nseg = len(jw.theta) - 1
    if method == "cubic" or (method in ("3-4", "3-5-3") and k == 0) or (method == "3-5-3" and k == nseg - 1):
        return _cubic(jw, k)
    th0, w0, th1, w1 = jw.theta[k], jw.omega[k], jw.theta[k + 1], jw.omega[k + 1]
    if method == "3-4":
        e0 = _end_accel(previous, durations[k - 1])
        return SegmentShape("quartic", th0, w0, th1, w1, e0)
    if method == "quintic":
        return SegmentShape("quintic", th0, w0, th1, w1, _preset_accel(method, jw, k, nseg),
                            _preset_accel(method, jw, k + 1, nseg))

    def knot_accel(i: int) -> float:
        if i == 1:
            return _end_accel(_cubic(jw, 0), durations[0])
        if i == nseg - 1:
            return _start_accel(_cubic(jw, nseg - 1), durations[nseg - 1])
        preset = _preset_accel(method, jw, i, nseg)
        return preset if preset is not None else _min_jerk_inner_accel(jw, durations)

    return SegmentShape("quintic", th0, w0, th1, w1, knot_accel(k), knot_accel(k + 1))


def timing_order(method: str, nseg: int) -> list[int]:
    """Order in which segment durations can be solved one at a time."""
    if method == "3-5-3":
        return [0, nseg - 1, *range(1, nseg - 1)]
    return list(range(nseg))


# --------------------------------------------------------------------------- plans

@dataclass
class PtpPlan:
    """Segment polynomials of every joint on shared knots; ``coeffs`` is (joints, segments, 6)."""

    method: str
    knots: np.ndarray
    joint_names: tuple[str, ...]
    kinds: tuple[str, ...]
    coeffs: np.ndarray

    def evaluate(self, t: np.ndarray, order: int) -> np.ndarray:
        """``θ^(order)`` of every joint at times ``t``: shape (len(t), joints).

        At an inner knot the later segment is used; at the last knot the last segment.
        """
        t = np.asarray(t, dtype=float)
        seg = np.clip(np.searchsorted(self.knots, t, side="right") - 1, 0, len(self.knots) - 2)
        tau = t - self.knots[seg]
        out = np.empty((t.size, len(self.joint_names)))
        for j in range(len(self.joint_names)):
            c = np.array([npp.polyder(row, order) for row in self.coeffs[j]], dtype=float)
            acc = np.zeros(t.size)
            for col in range(c.shape[1] - 1, -1, -1):  # Horner over the selected segments
                acc = acc * tau + c[seg, col]
            out[:, j] = acc
        return out


def plan_with_times(config: PtpConfig, method: str, knots: np.ndarray) -> PtpPlan:
    """Plan every joint with ``method`` on the given knot times."""
    durations = list(np.diff(knots))
    coeffs = np.empty((len(config.joints), config.n_segments, NCOEF))
    kinds: tuple[str, ...] = ()
    for j, jw in enumerate(config.joints):
        shapes: list[SegmentShape] = []
        for k in range(config.n_segments):
            shapes.append(segment_shape(method, jw, k, durations, shapes[-1] if shapes else None))
        kinds = tuple(s.kind for s in shapes)
        coeffs[j] = [s.coefficients(d) for s, d in zip(shapes, durations)]
    return PtpPlan(method, np.asarray(knots, dtype=float), tuple(jw.name for jw in config.joints), kinds, coeffs)


def compute_knot_times(config: PtpConfig) -> tuple[np.ndarray, list[dict[str, Any]]]:
    """Knot times from ``ω_max`` (and ``ε_max``), shared by all joints, plus the root report.

    Each segment takes the smallest duration (on the grid, if any) feasible for every joint.
    """
    nseg = config.n_segments
    durations: list[float | None] = [None] * nseg
    report: list[dict[str, Any]] = [{} for _ in range(nseg)]
    solved: dict[tuple[int, int], SegmentShape] = {}  # (joint, segment) -> shape
    for k in timing_order(config.method, nseg):
        shapes = [segment_shape(config.method, jw, k, durations, solved.get((j, k - 1)))
                  for j, jw in enumerate(config.joints)]
        solved.update({(j, k): shape for j, shape in enumerate(shapes)})
        bounds = [(config.omega_max[j, k], None if config.eps_max is None else config.eps_max[j, k]) for j in range(len(shapes))]
        timings = [solve_segment_time(s, *b) for s, b in zip(shapes, bounds)]
        common = intersect_feasible([t.feasible for t in timings])
        chosen = choose_duration(common, config.grid,
                                 lambda T: all(segment_feasible(s, T, *b) for s, b in zip(shapes, bounds)))
        joint_reports = {jw.name: t.as_dict() for jw, t in zip(config.joints, timings)}
        if chosen is None:
            raise PlanningError(_infeasible_message(config, k, common, joint_reports, shapes))
        durations[k] = chosen
        report[k] = {"segment": segment_label(k), "T_s": float(chosen),
                     "minimal_T_s": float(common[0][0]) if common[0][0] > 0 else None,
                     "feasible_T_s": _intervals(common), "joints": joint_reports}
    return np.concatenate(([0.0], np.cumsum(durations))), report


def _infeasible_message(config: PtpConfig, k: int, common: list[tuple[float, float]], joints: dict[str, Any],
                        shapes: Sequence[SegmentShape]) -> str:
    what = "|ω| ≤ timing.omega_max" + (" and |ε| ≤ timing.eps_max" if config.eps_max is not None else "")
    if common and common[0][0] == 0.0 and config.grid is None:
        return (f"{config.source}: {segment_label(k)} keeps the bounds for arbitrarily short durations (θ ends where it "
                "starts), so timing.omega_max does not fix its duration; give waypoints.t or a timing.grid")
    scale, unit = ANGLE_SCALE[config.angle_unit], config.angle_unit
    details = []
    for (name, rep), shape in zip(joints.items(), shapes):
        start = (f", starts with ε = {shape.eps0 / scale:.6g} {unit}/s² from the segment before"
                 if shape.kind != "cubic" else "")
        details.append(f"joint '{name}': feasible T {rep['feasible_T_s'] or 'none'}, roots "
                       f"{[round(r['T_s'], 6) for r in rep['roots']]}{start}")
    grid = f" on the {config.grid:g} s grid" if config.grid is not None else ""
    return (f"{config.source}: {segment_label(k)}: no duration{grid} keeps {what} for all joints ({'; '.join(details)}); "
            "raise the bounds of this segment, limit the acceleration handed on (timing.eps_max), use a finer "
            "timing.grid, change the waypoint speeds, or give waypoints.t")


def sample_times(knots: np.ndarray, step: float) -> np.ndarray:
    """``t_0 + k·step`` up to the last knot, which is appended when the grid misses it."""
    span = knots[-1] - knots[0]
    count = int(math.floor(span / step + GRID_RTOL))
    if count + 1 > MAX_SAMPLES:
        raise TaskFileError(f"field 'step' = {step:g} s gives {count + 1} samples over {span:g} s (limit {MAX_SAMPLES}); "
                            "use a larger step")
    t = knots[0] + step * np.arange(count + 1)
    if knots[-1] - t[-1] > GRID_RTOL * step:
        t = np.append(t, knots[-1])
    return t


# --------------------------------------------------------------------------- metrics

def joint_metrics(plan: PtpPlan, j: int) -> dict[str, Any]:
    """Peak velocity, peak |acceleration|, ε jumps at inner knots, ∫|ε| dt (velocity TV), θ range (SI)."""
    durations = np.diff(plan.knots)
    rows = list(zip(plan.coeffs[j], durations))
    jumps = [abs(derivative_at(rows[k][0], 0.0, 2) - derivative_at(*rows[k - 1], 2))
             for k in range(1, len(rows))]
    theta_range = [extremes(c, d, 0) for c, d in rows]
    return {
        "peak_velocity_rad_s": max(peak_abs(c, d, 1) for c, d in rows),
        "peak_abs_acceleration_rad_s2": max(peak_abs(c, d, 2) for c, d in rows),
        "acceleration_jumps_rad_s2": jumps,
        "max_acceleration_jump_rad_s2": max(jumps, default=0.0),
        "velocity_total_variation_rad_s": sum(total_variation(c, d, 1) for c, d in rows),
        "theta_min_rad": min(lo for lo, _ in theta_range),
        "theta_max_rad": max(hi for _, hi in theta_range),
    }


def waypoint_errors(config: PtpConfig, plan: PtpPlan) -> dict[str, float]:
    """Max |θ − θ_k| and |ω − ω_k| at the knots, from both adjacent segments (SI)."""
    durations = np.diff(plan.knots)
    err_theta = err_omega = 0.0
    for j, jw in enumerate(config.joints):
        for k, (c, d) in enumerate(zip(plan.coeffs[j], durations)):
            for tau, i in ((0.0, k), (d, k + 1)):
                err_theta = max(err_theta, abs(derivative_at(c, tau, 0) - jw.theta[i]))
                err_omega = max(err_omega, abs(derivative_at(c, tau, 1) - jw.omega[i]))
    return {"theta_rad": float(err_theta), "omega_rad_s": float(err_omega)}


def compare_methods(config: PtpConfig, knots: np.ndarray,
                    methods: Sequence[str] = ("cubic", "3-4", "3-5-3")) -> list[dict[str, Any]]:
    """The comparison table: one row per method and joint on the same knots (SI units)."""
    return _comparison_rows([plan_with_times(config, m, knots) for m in methods])


def _comparison_rows(plans: Sequence[PtpPlan]) -> list[dict[str, Any]]:
    rows = []
    for p in plans:
        for j, name in enumerate(p.joint_names):
            metrics = joint_metrics(p, j)
            rows.append({"method": p.method, "joint": name,
                         **{k: v for k, v in metrics.items() if not k.startswith("theta_")}})
    return rows


def bound_check(config: PtpConfig, plan: PtpPlan) -> list[dict[str, Any]]:
    """Per segment and joint: peak |ω| (|ε|) against the timing bounds, when bounds are given."""
    if config.omega_max is None:
        return []
    out = []
    for j, name in enumerate(plan.joint_names):
        for k, (c, d) in enumerate(zip(plan.coeffs[j], np.diff(plan.knots))):
            row = {"segment": segment_label(k), "joint": name, "peak_omega_rad_s": peak_abs(c, d, 1),
                   "omega_max_rad_s": float(config.omega_max[j, k])}
            ok = row["peak_omega_rad_s"] <= row["omega_max_rad_s"] * (1 + FEAS_RTOL)
            if config.eps_max is not None:
                row.update(peak_eps_rad_s2=peak_abs(c, d, 2), eps_max_rad_s2=float(config.eps_max[j, k]))
                ok = ok and row["peak_eps_rad_s2"] <= row["eps_max_rad_s2"] * (1 + FEAS_RTOL)
            row["within_bounds"] = bool(ok)
            out.append(row)
    return out


# --------------------------------------------------------------------------- entry point

def plan(config: PtpConfig) -> tuple[PtpPlan, list[dict[str, Any]]]:
    """The task's plan (knots given or computed) and the time solver's report (empty if given)."""
    if config.times is not None:
        knots, report = np.asarray(config.times, dtype=float), []
    else:
        knots, report = compute_knot_times(config)
    result = plan_with_times(config, config.method, knots)
    for j, jw in enumerate(config.joints):
        if jw.qlim is None:
            continue
        m = joint_metrics(result, j)
        for value, limit, side in ((m["theta_min_rad"], jw.qlim[0], "below"), (m["theta_max_rad"], jw.qlim[1], "above")):
            if (side == "below" and value < limit) or (side == "above" and value > limit):
                scale = ANGLE_SCALE[config.angle_unit]
                raise PlanningError(
                    f"{config.source}: joint '{jw.name}' reaches {value / scale:.6g} {config.angle_unit} between waypoints "
                    f"with method '{config.method}', {side} its limit {limit / scale:.6g} {config.angle_unit}; "
                    "move the waypoints away from the limit, lower the waypoint speeds, or add a waypoint")
    return result, report


def _plan_metadata(config: PtpConfig, result: PtpPlan, report: list[dict[str, Any]]) -> dict[str, Any]:
    per_joint = {name: joint_metrics(result, j) for j, name in enumerate(result.joint_names)}
    checks = bound_check(config, result)
    # one entry per metric, each {joint: value}: `armgen plan` prints one line per entry
    summary: dict[str, Any] = {"duration_s": float(result.knots[-1] - result.knots[0])}
    for key in per_joint[result.joint_names[0]]:
        summary[key] = {name: metrics[key] for name, metrics in per_joint.items()}
    summary["waypoint_error"] = waypoint_errors(config, result)
    summary["bound_violations"] = sum(not c["within_bounds"] for c in checks)
    meta: dict[str, Any] = {
        "method": config.method,
        "units": {"angle": "rad", "time": "s", "task_angle_unit": config.angle_unit},
        "parameters": {
            "step_s": config.step,
            "times": "given" if config.times is not None else "computed from timing.omega_max",
            "grid_s": config.grid,
            "omega_max_rad_s": None if config.omega_max is None else config.omega_max.tolist(),
            "eps_max_rad_s2": None if config.eps_max is None else config.eps_max.tolist(),
            "robot": config.robot,
        },
        "knot_times_s": result.knots.tolist(),
        "joints": list(result.joint_names),
        "segments": {
            "kinds": list(result.kinds),
            "coefficient_order": "a0..a5 of theta(tau) = sum a_j tau^j, tau = t - knot_times_s[k], rad and s",
            "coefficients": {name: result.coeffs[j].tolist() for j, name in enumerate(result.joint_names)},
        },
        "timing": {"segments": report, "bound_check": checks},
        "summary": summary,
    }
    if config.solved_poses is not None:
        meta["ik"] = {"note": "waypoints given as tool poses, solved each from the previous one (rad)",
                      **config.solved_poses}
    if config.compare:
        plans = {m: plan_with_times(config, m, result.knots) for m in config.compare}
        meta["comparison"] = {
            "methods": list(config.compare),
            "rows": _comparison_rows(list(plans.values())),
            "segments": {m: {"kinds": list(p.kinds),
                             "coefficients": {name: p.coeffs[j].tolist() for j, name in enumerate(p.joint_names)}}
                         for m, p in plans.items()},
        }
    return meta


def plan_task(task: dict[str, Any], source: str, backend: str = "symbolic") -> PlanResult:
    """``armgen plan`` entry: parse, plan, sample θ, ω, ε, jerk at ``step`` (``backend`` unused)."""
    del backend  # the polynomials are evaluated the same way by both backends
    config = parse_ptp_task(task, source)
    result, report = plan(config)
    t = sample_times(result.knots, config.step)
    columns = ["t_s"]
    blocks = [t[:, None]]
    values = [result.evaluate(t, order) for order in range(4)]
    for j, name in enumerate(result.joint_names):
        columns += [f"theta_{name}_rad", f"omega_{name}_rad_s", f"eps_{name}_rad_s2", f"jerk_{name}_rad_s3"]
        blocks.append(np.column_stack([v[:, j] for v in values]))
    return PlanResult(columns, np.hstack(blocks), _plan_metadata(config, result, report))
