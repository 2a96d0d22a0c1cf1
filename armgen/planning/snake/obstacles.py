"""Obstacles of the snake scenarios and the clearance of every link to them (spec 50).

A link is a tube of radius ``r`` around the segment between two joint centres; its clearance to
an obstacle is (distance from the segment to the obstacle) − ``r``; negative means contact.
All inputs SI. Obstacle types (task file ``[[obstacles]]``, lengths in the file's unit):

- ``box``: a solid axis-aligned box ``min``/``max`` (the planar wall is two boxes, above and
  below its opening, sharing one ``name``; clearances are reported per name);
- ``cylinder``: a solid infinite cylinder through ``centre`` along ``axis`` (the planar disc,
  ``axis = [0, 0, 1]``) of ``diameter``;
- ``plate``: an unbounded thin plate through ``point`` with normal ``normal`` and a circular
  ``opening_diameter`` centred at ``point`` (the tank's end wall and baffles);
- ``tank``: the inside faces of a box (``min``/``max``, ``faces`` among ``x- x+ y- y+ z- z+``);
  only the part of a link inside the box's x…z slab along the first axis counts, so the rail
  outside the tank is free.

Distances are exact for ``box`` (golden-section search of the convex distance along the segment,
to 1e-9 of a link), ``cylinder`` (closed form) and ``tank`` (linear along the clipped segment:
its ends). A ``plate`` with an opening is not convex: the segment is sampled every
:data:`PLATE_SAMPLE` plus its crossing point, then the best sample is refined by golden section.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# Plate clearance: sampling step along a link before refinement. Near the best sample the
# distance is smooth (a rim distance sqrt(h² + c²) or |h|), so refining the two sample intervals
# around the best sample finds the minimum; 5 mm is far below the 100 mm opening and the
# 104 mm link, the scales on which a second local minimum could appear.
PLATE_SAMPLE = 5e-3  # m
# Golden-section steps: shrink the search interval by 0.618^40 ≈ 4e-9 (of a link: < 1e-9 m).
GOLDEN_ITERATIONS = 40
FACES = ("x-", "x+", "y-", "y+", "z-", "z+")


@dataclass(frozen=True)
class Obstacle:
    name: str
    type: str
    a: np.ndarray  # box/tank: min; cylinder: centre; plate: point
    b: np.ndarray  # box/tank: max; cylinder: unit axis; plate: unit normal
    radius: float = 0.0  # cylinder radius, plate opening radius
    faces: tuple[str, ...] = ()

    def describe(self) -> dict:
        mm = lambda v: [round(float(x) * 1e3, 6) for x in v]  # noqa: E731
        out = {"name": self.name, "type": self.type}
        if self.type in ("box", "tank"):
            out.update(min_mm=mm(self.a), max_mm=mm(self.b))
        if self.type == "tank":
            out["faces"] = list(self.faces)
        if self.type == "cylinder":
            out.update(centre_mm=mm(self.a), axis=self.b.tolist(), diameter_mm=2e3 * self.radius)
        if self.type == "plate":
            out.update(point_mm=mm(self.a), normal=self.b.tolist(), opening_diameter_mm=2e3 * self.radius)
        return out


def _golden_min(fun, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Minimum value of the (unimodal) ``fun(tau)`` on [lo, hi], elementwise."""
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = lo.copy(), hi.copy()
    c = b - g * (b - a)
    d = a + g * (b - a)
    fc, fd = fun(c), fun(d)
    for _ in range(GOLDEN_ITERATIONS):
        left = fc < fd
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        d_new = np.where(left, c, a + g * (b - a))
        c_new = np.where(left, b - g * (b - a), d)
        f_c_new = fun(c_new)
        f_d_new = fun(d_new)
        fc, fd = np.where(left, f_c_new, fd), np.where(left, fc, f_d_new)
        c, d = c_new, d_new
    return np.minimum(np.minimum(fc, fd), np.minimum(fun(lo), fun(hi)))


def _box_distance(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.maximum(np.maximum(lo - p, 0.0), p - hi), axis=-1)


def _plate_distance(p: np.ndarray, point: np.ndarray, normal: np.ndarray, rho: float) -> np.ndarray:
    d = p - point
    h = d @ normal
    radial = np.sqrt(np.maximum(np.einsum("...i,...i->...", d, d) - h * h, 0.0))
    return np.where(radial >= rho, np.abs(h), np.hypot(h, rho - radial))


def segment_distance(obstacle: Obstacle, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Distance from each segment A→B (arrays (..., 3)) to the obstacle (0 when they meet)."""
    D = B - A

    def at(tau: np.ndarray) -> np.ndarray:
        return A + tau[..., None] * D

    shape = A.shape[:-1]
    if obstacle.type == "box":
        return _golden_min(lambda t: _box_distance(at(t), obstacle.a, obstacle.b), np.zeros(shape), np.ones(shape))
    if obstacle.type == "cylinder":
        axis = obstacle.b
        a_perp = (A - obstacle.a) - ((A - obstacle.a) @ axis)[..., None] * axis
        d_perp = D - (D @ axis)[..., None] * axis
        dd = np.einsum("...i,...i->...", d_perp, d_perp)
        with np.errstate(invalid="ignore", divide="ignore"):
            tau = np.clip(np.where(dd > 0, -np.einsum("...i,...i->...", a_perp, d_perp) / dd, 0.0), 0.0, 1.0)
        closest = np.linalg.norm(a_perp + tau[..., None] * d_perp, axis=-1)
        return np.maximum(closest - obstacle.radius, 0.0)
    if obstacle.type == "tank":
        lo, hi = obstacle.a, obstacle.b
        # clip the segment to the slab lo_x <= x <= hi_x (inside the tank along its length)
        with np.errstate(divide="ignore", invalid="ignore"):
            t_lo = (lo[0] - A[..., 0]) / D[..., 0]
            t_hi = (hi[0] - A[..., 0]) / D[..., 0]
        moving = D[..., 0] != 0
        within = (A[..., 0] >= lo[0]) & (A[..., 0] <= hi[0])
        t0 = np.clip(np.where(moving, np.minimum(t_lo, t_hi), 0.0), 0.0, 1.0)
        t1 = np.clip(np.where(moving, np.maximum(t_lo, t_hi), 1.0), 0.0, 1.0)
        out = np.full(shape, np.inf)
        inside = np.where(moving, t1 > t0, within)
        for t in (t0, t1):
            p = at(t)
            for face in obstacle.faces:
                k = "xyz".index(face[0])
                gap = p[..., k] - lo[k] if face[1] == "-" else hi[k] - p[..., k]
                out = np.where(inside, np.minimum(out, np.maximum(gap, 0.0)), out)
        return out
    if obstacle.type == "plate":
        n, point, rho = obstacle.b, obstacle.a, obstacle.radius
        length = np.linalg.norm(D, axis=-1)
        count = int(math.ceil(float(np.max(length)) / PLATE_SAMPLE)) + 1
        taus = np.linspace(0.0, 1.0, count)
        hA = (A - point) @ n
        hD = D @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t_cross = np.where(hD != 0, -hA / hD, -1.0)
        crosses = (t_cross >= 0) & (t_cross <= 1)
        samples = _plate_distance(A[..., None, :] + taus[:, None] * D[..., None, :], point, n, rho)
        best = np.argmin(samples, axis=-1)
        step = 1.0 / (count - 1)
        lo_t = np.clip(taus[best] - step, 0.0, 1.0)
        hi_t = np.clip(taus[best] + step, 0.0, 1.0)
        refined = _golden_min(lambda t: _plate_distance(at(t), point, n, rho), lo_t, hi_t)
        cross_d = np.where(crosses, _plate_distance(at(np.clip(t_cross, 0, 1)), point, n, rho), np.inf)
        return np.minimum(np.minimum(refined, cross_d), samples.min(axis=-1))
    raise ValueError(obstacle.type)


def clearances(obstacles: list[Obstacle], centres: np.ndarray, tube_radius: float) -> dict[str, np.ndarray]:
    """Clearance (samples, links) of every link to each obstacle name (SI; min over same-named parts)."""
    A, B = centres[:, :-1], centres[:, 1:]
    out: dict[str, np.ndarray] = {}
    for obs in obstacles:
        c = segment_distance(obs, A, B) - tube_radius
        out[obs.name] = np.minimum(out[obs.name], c) if obs.name in out else c
    return out
