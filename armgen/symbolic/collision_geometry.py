"""Distances between a capsule and the primitive shapes, in CasADi SX, branch-light.

A capsule is a segment ``[a, b]`` swept by a ball of radius ``r``; a sphere is a capsule of
zero length. Every function here returns the distance between the segment (the capsule's
axis) and the other shape, so a capsule's distance is that minus its radius. Clamps are
``fmin``/``fmax`` and the one choice is a select (``if_else``), so the C has no data-dependent
branch. Divisions are guarded by explicit floors, so every value and every derivative is
finite for any input (a segment of zero length, parallel segments, a zero half-extent).

Sign convention (coal's, ``docs/collision.md``): positive when apart, zero when touching,
negative when overlapping. Capsule–capsule, capsule–sphere and capsule–plane distances are
the exact signed distances (the penetration depth, negated, when overlapping). Capsule–box is
exact while the capsule's axis stays outside the box; once the axis enters, it is ``−r`` minus
the depth of the axis' deepest point, which is at least coal's signed distance (coal's depth
is the shortest translation that separates the two, and the whole axis must come out).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

# Divisions are by fmax(x, DIVISION_FLOOR): a zero-length segment (a sphere given as an
# obstacle capsule) divides 0 by it and gets 0, never 0/0. Far below any squared length that
# matters (1e-30 m² is a femtometre squared) and a normal number in single precision (≥ 1.2e-38).
DIVISION_FLOOR = 1e-30
# Two segments count as parallel when sin²(angle) < SEGMENT_PARALLEL_EPSILON: then the first
# closest-point parameter is taken as 0 (Ericson's choice) rather than from a quotient by the
# vanishing a·e − b² = |d1|²|d2|² sin². Either way the two clamped projections that follow give
# the closest points, so the threshold only decides where the quotient's rounding would start to
# matter: the squared distance's error is below min(L² sin², ε² L²/sin²) (L the segments'
# length, ε the precision), at most ε L² wherever the threshold sits; 1e-14 keeps the quotient
# for every angle above 1e-7 rad.
SEGMENT_PARALLEL_EPSILON = 1e-14
# The axis distance's square is floored at DISTANCE_FLOOR² before its square root, so the
# gradient 1/(2 sqrt) stays finite when two axes cross (a deep overlap); 1e-12 m changes no
# distance that matters and its square is a normal number in single precision.
DISTANCE_FLOOR = 1e-12


def _dot(u: ca.SX, v: ca.SX) -> ca.SX:
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _clamp01(x: ca.SX) -> ca.SX:
    return ca.fmin(ca.fmax(x, 0.0), 1.0)


def _root(squared: ca.SX) -> ca.SX:
    return ca.sqrt(ca.fmax(squared, DISTANCE_FLOOR ** 2))


@dataclass(frozen=True)
class Witness:
    """A distance with where it is measured: ``distance`` (signed) between the point ``point``
    of the first shape's axis (``parameter`` along it: ``a + parameter (b − a)``) and the second
    shape, growing fastest when ``point`` moves along the unit ``normal``; for a second shape
    that moves too, ``other`` is its point (at ``other_parameter``), whose motion along
    ``normal`` shrinks the distance. The gradient of the distance is that of the two points
    moving with their bodies (the envelope theorem: the closest points' own motion along the
    shapes does not change the distance to first order)."""

    distance: ca.SX
    parameter: ca.SX
    normal: ca.SX
    other_parameter: ca.SX | None = None


def _between(gap: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(|gap| floored, the unit direction of gap, or a shorter vector below the floor)."""
    length = _root(_dot(gap, gap))
    return length, gap / length


def segment_segment_witness(a1: ca.SX, b1: ca.SX, a2: ca.SX, b2: ca.SX) -> Witness:
    """The distance (≥ 0) between the segments ``a1 + s d1`` and ``a2 + t d2``, s, t ∈ [0, 1].

    Ericson, *Real-Time Collision Detection* (2005), 5.1.9, with the branches as clamps: the
    unconstrained s (0 for parallel segments), t projected from it and clamped, s projected back
    from t and clamped. Projecting s back whatever t was gives Ericson's s in every case (when
    t needed no clamp, the projection returns s itself), so no branch is needed.
    """
    d1, d2 = b1 - a1, b2 - a2
    r = a1 - a2
    a, e, b = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2)
    c, f = _dot(d1, r), _dot(d2, r)
    denominator = ca.fmax(a * e - b * b, SEGMENT_PARALLEL_EPSILON * a * e + DIVISION_FLOOR)
    s = _clamp01((b * f - c * e) / denominator)
    t = _clamp01((b * s + f) / ca.fmax(e, DIVISION_FLOOR))
    s = _clamp01((b * t - c) / ca.fmax(a, DIVISION_FLOOR))
    length, normal = _between(r + s * d1 - t * d2)
    return Witness(length, s, normal, t)


def point_segment_witness(p: ca.SX, a: ca.SX, b: ca.SX) -> Witness:
    """The distance (≥ 0) between the segment ``a + t (b − a)`` (first) and the point ``p``."""
    d = b - a
    t = _clamp01(_dot(p - a, d) / ca.fmax(_dot(d, d), DIVISION_FLOOR))
    length, normal = _between(a + t * d - p)
    return Witness(length, t, normal, ca.SX(0.0))


def point_point_witness(p: ca.SX, q: ca.SX) -> Witness:
    length, normal = _between(p - q)
    return Witness(length, ca.SX(0.0), normal, ca.SX(0.0))


def segment_segment(a1: ca.SX, b1: ca.SX, a2: ca.SX, b2: ca.SX) -> ca.SX:
    """The distance (≥ 0) between the segments ``[a1, b1]`` and ``[a2, b2]``."""
    return segment_segment_witness(a1, b1, a2, b2).distance


def point_segment(p: ca.SX, a: ca.SX, b: ca.SX) -> ca.SX:
    """The distance (≥ 0) between the point ``p`` and the segment ``[a, b]``."""
    return point_segment_witness(p, a, b).distance


def segment_halfspace_witness(a: ca.SX, b: ca.SX, normal: ca.SX, offset: ca.SX) -> Witness:
    """The signed distance of the segment ``[a, b]`` from the half-space ``{x : n·x ≤ offset}``
    (``n`` a unit normal pointing out of the solid): the nearer end's height above the boundary,
    negative below it."""
    height_a, height_b = _dot(normal, a), _dot(normal, b)
    return Witness(ca.fmin(height_a, height_b) - offset, ca.if_else(height_b < height_a, 1.0, 0.0), normal)


def segment_halfspace(a: ca.SX, b: ca.SX, normal: ca.SX, offset: ca.SX) -> ca.SX:
    return segment_halfspace_witness(a, b, normal, offset).distance


def segment_box_witness(a: ca.SX, b: ca.SX, centre: ca.SX, rotation: ca.SX, half: ca.SX) -> Witness:
    """The signed distance of the segment ``[a, b]`` from the box (``centre``, ``rotation`` whose
    columns are the box's axes, half-extents ``half``): the distance while the segment is
    outside the box, and the box's signed distance of the segment's deepest point (negative)
    once it enters.

    In the box frame the segment is ``p(t) = p0 + t d``; per axis k, with ``σ_k = ±1`` the sign of
    ``d_k`` (+1 for 0), ``y_k(t) = σ_k p_k(t) = u_k + s_k t`` rises at ``s_k = |d_k|``.

    Outside: the squared distance ``f(t) = Σ_k max(|p_k(t)| − h_k, 0)²`` is convex and C¹; its slope
    ``f'(t)/2 = Σ_k s_k² (t − clamp(t, lo_k, hi_k))`` is nondecreasing and piecewise linear, with
    its kinks at the ends ``lo_k, hi_k`` of the parameters where the segment is within axis k's
    slab (``|p_k| ≤ h_k``). So the slope at the segment's ends and the six slab ends (clamped to
    the segment) brackets its root between two neighbouring parameters with no kink between
    them, where one linear interpolation finds it exactly.

    Inside: the box's signed distance of ``p(t)``, ``g(t) = max_k(|p_k(t)| − h_k)``, is the upper
    envelope of three rising lines ``y_k − h_k`` and three falling ones ``−y_k − h_k``, so its least
    value on [0, 1] is the greatest, over the nine (rising i, falling j) pairs, of the pair's own
    least value: ``max`` of the two lines at their crossing, clamped to the segment (Helly's
    theorem in one dimension: intervals that meet pairwise all meet; a pair of two rising or two
    falling lines is never greater than a rising–falling pair).
    """
    p0 = ca.mtimes(rotation.T, a - centre)
    direction = ca.mtimes(rotation.T, b - a)
    sigma = [2.0 * (direction[k] >= 0) - 1.0 for k in range(3)]
    rise = [sigma[k] * direction[k] for k in range(3)]
    start = [sigma[k] * p0[k] for k in range(3)]
    nearest = _outside_parameter(start, rise, half)
    point = p0 + nearest * direction
    outside, away = _between(point - ca.fmin(ca.fmax(point, -half), half))
    deepest, deepest_at, inward = _deepest(start, rise, sigma, half)
    inside = deepest < 0  # the axis enters the box exactly when its deepest point is inside
    normal = ca.if_else(inside, inward, away)
    return Witness(ca.if_else(inside, deepest, outside), ca.if_else(inside, deepest_at, nearest),
                   ca.mtimes(rotation, normal))


def segment_box(a: ca.SX, b: ca.SX, centre: ca.SX, rotation: ca.SX, half: ca.SX) -> ca.SX:
    return segment_box_witness(a, b, centre, rotation, half).distance


def _outside_parameter(start: list[ca.SX], rise: list[ca.SX], half: ca.SX) -> ca.SX:
    """The t ∈ [0, 1] of the segment's point nearest the box (box frame, per axis ``y = start +
    rise t``), the root of the slope of the squared distance bracketed by its values at the ends
    and the slab ends."""
    inverse = [1.0 / ca.fmax(rise[k], DIVISION_FLOOR) for k in range(3)]
    slab = [((-half[k] - start[k]) * inverse[k], (half[k] - start[k]) * inverse[k]) for k in range(3)]
    weight = [rise[k] * rise[k] for k in range(3)]

    def slope(t: ca.SX) -> ca.SX:
        return sum(weight[k] * (t - ca.fmin(ca.fmax(t, slab[k][0]), slab[k][1])) for k in range(3))

    candidates = [ca.SX(0.0), ca.SX(1.0)] + [_clamp01(end) for pair in slab for end in pair]
    slopes = [slope(t) for t in candidates]
    # the slope is nondecreasing: the last parameter where it is ≤ 0 and the first where it is ≥ 0
    lo = hi = None
    for t, value in zip(candidates, slopes):
        below, above = (value <= 0) * t, 1.0 - (value >= 0) * (1.0 - t)
        lo, hi = (below, above) if lo is None else (ca.fmax(lo, below), ca.fmin(hi, above))
    slope_lo, slope_hi = slope(lo), slope(hi)
    # the slope is linear on [lo, hi]; a flat slope (0 on both sides) keeps lo, where f is least too
    return _clamp01(lo - slope_lo * (hi - lo) / ca.fmax(slope_hi - slope_lo, DIVISION_FLOOR))


def _deepest(start: list[ca.SX], rise: list[ca.SX], sigma: list[ca.SX], half: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """(the least of ``g(t) = max_k(|p_k(t)| − h_k)`` on [0, 1], its t, the direction in which it
    grows as the point at t moves; box frame) from the nine rising–falling pairs of lines.

    At a crossing inside the segment the least value moves with the point along the mix
    ``(s_j n_i + s_i n_j)/(s_i + s_j)`` of the two faces' normals (``n_i = σ_i e_i`` rising,
    ``n_j = −σ_j e_j`` falling; 0 for the two faces of one axis, which balance); at a crossing
    clamped to an end it is the greater line's face normal. Only the winning pair's axes are
    carried through the nine comparisons; its crossing, weight and normal are computed once."""
    best = best_i = best_j = None  # the greatest pair value; only its axes go through the selects
    for i in range(3):
        for j in range(3):
            _, _, rising, falling = _meet(start[i], start[j], rise[i], rise[j], half[i], half[j])
            value = ca.fmax(rising, falling)
            if best is None:
                best, best_i, best_j = value, ca.SX(i), ca.SX(j)
                continue
            greater = value > best
            best, best_i, best_j = ca.fmax(value, best), ca.if_else(greater, i, best_i), ca.if_else(greater, j, best_j)
    is_i, is_j = [best_i == k for k in range(3)], [best_j == k for k in range(3)]

    def pick(mask: list[ca.SX], values: list[ca.SX] | ca.SX) -> ca.SX:
        return mask[0] * values[0] + mask[1] * values[1] + mask[2] * values[2]

    rise_i, rise_j = pick(is_i, rise), pick(is_j, rise)
    at, t, rising, falling = _meet(pick(is_i, start), pick(is_j, start), rise_i, rise_j, pick(is_i, half),
                                   pick(is_j, half))
    # the rising face's share of the normal: s_j / (s_i + s_j) inside the segment, 1 or 0 at an end
    weight = ca.if_else((at > 0) * (at < 1), rise_j / ca.fmax(rise_i + rise_j, DIVISION_FLOOR), rising >= falling)
    normal = ca.vertcat(*[sigma[k] * (weight * is_i[k] - (1.0 - weight) * is_j[k]) for k in range(3)])
    return best, t, normal


def _meet(start_i: ca.SX, start_j: ca.SX, rise_i: ca.SX, rise_j: ca.SX, half_i: ca.SX,
          half_j: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    """Where the rising line ``y_i − h_i`` meets the falling ``−y_j − h_j`` (the parameter, and
    clamped to the segment) and the two lines' values at the clamped parameter."""
    at = (half_i - half_j - start_i - start_j) / ca.fmax(rise_i + rise_j, DIVISION_FLOOR)
    t = _clamp01(at)
    return at, t, start_i - half_i + rise_i * t, -start_j - half_j - rise_j * t
