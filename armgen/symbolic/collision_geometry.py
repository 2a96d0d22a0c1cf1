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

    Outside: the squared distance of the segment's point ``p(t)`` from the box,
    ``f(t) = Σ_i max(|p_i(t)| − h_i, 0)²``, is convex and C¹ in t, and its slope ``f'`` is piecewise
    linear with its kinks where a coordinate crosses a face's plane (``p_i = ±h_i``). So the
    slope at the two ends and the six crossings (clamped to the segment) brackets its root
    between two neighbouring parameters with no kink between them, where one linear
    interpolation finds it exactly. Inside, ``max_i(|p_i| − h_i)`` is convex and piecewise
    linear along the segment, so its least value is at an end or a kink: where a coordinate
    crosses 0, or where two of ``±p_i − h_i`` meet (15 parameters, each clamped and evaluated).
    """
    p0 = ca.mtimes(rotation.T, a - centre)
    direction = ca.mtimes(rotation.T, b - a)
    nearest = _outside_parameter(p0, direction, half)
    point = p0 + nearest * direction
    outside, away = _between(point - ca.fmin(ca.fmax(point, -half), half))
    # the deepest point: the ends (where the face it is nearest gives the direction) and the kinks
    # (an interior kink: its mix of two faces; one clamped to an end: that end's face)
    deepest, deepest_at, kink, at_kink = _box_depth(p0, half), ca.SX(0.0), ca.SX.zeros(3, 1), ca.SX(0.0)
    for raw, mix in [(ca.SX(1.0), ca.SX.zeros(3, 1))] + _kinks(p0, direction, half):
        t = _clamp01(raw)
        depth = _box_depth(p0 + t * direction, half)
        deeper = depth < deepest
        deepest, deepest_at = ca.if_else(deeper, depth, deepest), ca.if_else(deeper, t, deepest_at)
        kink = ca.if_else(deeper, mix, kink)
        at_kink = ca.if_else(deeper, (raw > 0) * (raw < 1), at_kink)
    inside = deepest < 0  # the axis enters the box exactly when its deepest point is inside
    inward = ca.if_else(at_kink, kink, _face_normal(p0 + deepest_at * direction, half))
    normal = ca.if_else(inside, inward, away)
    return Witness(ca.if_else(inside, deepest, outside), ca.if_else(inside, deepest_at, nearest),
                   ca.mtimes(rotation, normal))


def segment_box(a: ca.SX, b: ca.SX, centre: ca.SX, rotation: ca.SX, half: ca.SX) -> ca.SX:
    return segment_box_witness(a, b, centre, rotation, half).distance


def _outside_parameter(p0: ca.SX, direction: ca.SX, half: ca.SX) -> ca.SX:
    """The t ∈ [0, 1] of the segment's point nearest the box (box frame), the root of the slope
    of the squared distance bracketed by its values at the ends and the face crossings."""
    def slope(t: ca.SX) -> ca.SX:
        point = p0 + t * direction
        return 2 * sum(ca.sign(point[k]) * ca.fmax(ca.fabs(point[k]) - half[k], 0.0) * direction[k] for k in range(3))

    candidates = [ca.SX(0.0), ca.SX(1.0)] + [_clamp01(_crossing(p0[k] - side * half[k], direction[k]))
                                             for k in range(3) for side in (-1.0, 1.0)]
    slopes = [slope(t) for t in candidates]
    lo, hi, slope_lo, slope_hi = ca.SX(0.0), ca.SX(1.0), slopes[0], slopes[1]
    for t, value in zip(candidates, slopes):  # the last parameter with slope ≤ 0, the first with slope ≥ 0
        down, up = value <= 0, value >= 0
        lo, slope_lo = ca.if_else(down * (t >= lo), t, lo), ca.if_else(down * (t >= lo), value, slope_lo)
        hi, slope_hi = ca.if_else(up * (t <= hi), t, hi), ca.if_else(up * (t <= hi), value, slope_hi)
    # the slope is linear on [lo, hi]; a flat slope (0 on both sides) keeps lo, where f is least too
    return _clamp01(lo - slope_lo * (hi - lo) / ca.fmax(slope_hi - slope_lo, DIVISION_FLOOR))


def _box_depth(p: ca.SX, half: ca.SX) -> ca.SX:
    """``min(max_i(|p_i| − h_i), 0)``: minus the depth of ``p`` (box frame) inside the box, 0 outside."""
    return ca.fmin(ca.fmax(ca.fmax(ca.fabs(p[0]) - half[0], ca.fabs(p[1]) - half[1]), ca.fabs(p[2]) - half[2]), 0.0)


def _face_normal(p: ca.SX, half: ca.SX) -> ca.SX:
    """The outward normal of the face nearest the inside point ``p`` (box frame): ``sign(p_k) e_k``
    for the k of the largest ``|p_k| − h_k``, the direction in which its depth falls fastest."""
    excess = [ca.fabs(p[k]) - half[k] for k in range(3)]
    first = (excess[0] >= excess[1]) * (excess[0] >= excess[2])
    second = (1 - first) * (excess[1] >= excess[2])
    third = 1 - first - second
    return ca.vertcat(first * ca.sign(p[0]), second * ca.sign(p[1]), third * ca.sign(p[2]))


def _crossing(offset: ca.SX, slope: ca.SX) -> ca.SX:
    """The root t of ``offset + t slope`` (a large number of the right sign when slope is 0,
    which the clamp to the segment then takes to an end)."""
    return -offset * slope / ca.fmax(slope * slope, DIVISION_FLOOR)


def _kinks(p0: ca.SX, direction: ca.SX, half: ca.SX) -> list[tuple[ca.SX, ca.SX]]:
    """The parameters where ``max_i(|p_i(t)| − h_i)`` may kink: where two of its pieces
    ``L = σ_i p_i − h_i`` meet, ``p_i = 0`` (3) and ``σ_i p_i − h_i = σ_j p_j − h_j`` for i < j and
    signs σ (12); each with the direction in which the kink's value grows as the point moves,
    ``(s₂ n₁ − s₁ n₂)/(s₂ − s₁)`` for the pieces' normals ``n = σ e_i`` and slopes along the segment
    ``s = σ d_i``: at a kink the least value moves along the segment with it, so its derivative
    is that mix of the two pieces' (0 where ``p_i = 0``: the two faces balance)."""
    def unit(axis: int, sign: float) -> ca.SX:
        out = ca.SX.zeros(3, 1)
        out[axis] = sign
        return out

    kinks = [(_crossing(p0[k], direction[k]), ca.SX.zeros(3, 1)) for k in range(3)]
    for i, j in ((0, 1), (0, 2), (1, 2)):
        for si in (-1.0, 1.0):
            for sj in (-1.0, 1.0):
                first, second = si * direction[i], sj * direction[j]
                spread = second - first
                mix = (second * unit(i, si) - first * unit(j, sj)) * spread / ca.fmax(spread * spread, DIVISION_FLOOR)
                kinks.append((_crossing(si * p0[i] - sj * p0[j] - half[i] + half[j], -spread), mix))
    return kinks
