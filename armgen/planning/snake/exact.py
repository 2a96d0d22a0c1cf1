"""The exact geometric follow-the-leader solver (spec 50, solver 2).

Given the driven joint's coordinate, each next joint centre (in the follow direction: towards
the tip when the base is driven, towards the base when the tip is driven) is the first
intersection of the sphere of radius ``L`` (one link) around the current joint centre with the
track, beyond the current coordinate. Per link, vectorised over all output instants:

1. bracket: march ``Δ`` from ``L / max|r_s|`` (below it the chord cannot reach ``L``) in steps of
   :data:`BRACKET_STEP` link lengths until ``f(Δ) = |P(s ± Δ) − c|² − L²`` changes sign;
2. safeguarded Newton inside the bracket (a Newton step that leaves the bracket is replaced by
   bisection; the bracket shrinks with the sign of ``f`` at every iterate) until the step is
   at the rounding level of the coordinate.

No ODE: chord lengths are exact to rounding (~1e-16 m). Joint-coordinate rates follow by
differentiating the chord condition: ``(d·P'_{k}) ṡ_{k} = (d·P'_{j}) ṡ_{j}`` with
``d = P_k(s_k) − P_j(s_j)``.
"""

from __future__ import annotations

import numpy as np

from ...errors import PlanningError
from .spline import Track

# Bracketing march step, in link lengths. The first sign change of f is bracketed unless the
# track leaves and re-enters the sphere within one step (an S within 13 mm of arc at 104 mm
# links), a bend far beyond any universal joint's range, which the angle check rejects anyway.
BRACKET_STEP = 0.125
# Farthest search, in link lengths of coordinate: the chord-length parameter is within a few
# per cent of arc length, so a joint more than 3 links of path away means the path doubles back.
BRACKET_MAX = 3.0
# Newton stops when its step is below this many ulps of the coordinate (|s| ≤ a few metres):
# the chord error is then at the rounding level of the positions.
NEWTON_ULPS = 4.0
NEWTON_MAX_ITER = 60


def _next_joint(track: Track, j_known: int, s_known: np.ndarray, centre: np.ndarray, j_new: int,
                direction: int, link: float, lipschitz: float) -> np.ndarray:
    """Coordinate of joint ``j_new`` at chord distance ``link`` from ``centre`` (joint ``j_known``)."""
    n = s_known.shape[0]

    def f_and_df(delta: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p, p_s = track.joint(j_new, s_known[idx] + direction * delta, 1)
        d = p - centre[idx]
        return np.einsum("ij,ij->i", d, d) - link * link, 2.0 * direction * np.einsum("ij,ij->i", d, p_s)

    lo = np.zeros(n)
    hi = np.full(n, np.nan)
    f_lo = np.full(n, -link * link)
    f_hi = np.full(n, np.nan)
    start = link / (lipschitz * (1.0 + 1e-9))
    open_ = np.arange(n)
    delta = start
    while open_.size:
        if delta > BRACKET_MAX * link:
            k = open_[0]
            raise _NoJoint(j_new, int(k), float(s_known[k]))
        f, _ = f_and_df(np.full(open_.size, delta), open_)
        crossed = f >= 0.0
        hi[open_[crossed]] = delta
        f_hi[open_[crossed]] = f[crossed]
        keep = ~crossed
        lo[open_[keep]] = delta
        f_lo[open_[keep]] = f[keep]
        open_ = open_[keep]
        delta += BRACKET_STEP * link
    # secant start, then safeguarded Newton on every instant at once
    x = lo - f_lo * (hi - lo) / (f_hi - f_lo)
    idx = np.arange(n)
    active = np.ones(n, dtype=bool)
    for _ in range(NEWTON_MAX_ITER):
        a = idx[active]
        if a.size == 0:
            break
        f, df = f_and_df(x[a], a)
        exact = f == 0.0
        active[a[exact]] = False
        a, f, df = a[~exact], f[~exact], df[~exact]
        neg = f < 0.0
        lo[a[neg]] = x[a[neg]]
        hi[a[~neg]] = x[a[~neg]]
        with np.errstate(divide="ignore", invalid="ignore"):
            new = x[a] - f / df
        bad = ~np.isfinite(new) | (new <= lo[a]) | (new >= hi[a])
        new[bad] = 0.5 * (lo[a[bad]] + hi[a[bad]])
        moved = np.abs(new - x[a])
        x[a] = new
        done = moved <= NEWTON_ULPS * np.finfo(float).eps * (np.abs(s_known[a]) + link)
        active[a[done]] = False
    return s_known + direction * x


class _NoJoint(Exception):
    def __init__(self, joint: int, sample: int, s_known: float):
        super().__init__(joint, sample, s_known)
        self.joint, self.sample, self.s_known = joint, sample, s_known


def solve_exact(track: Track, s_driven: np.ndarray, driven: str, n_links: int, link: float) -> np.ndarray:
    """Joint coordinates, shape (samples, n_links + 1), given the driven joint's coordinates.

    ``driven`` is ``"base"`` (joint 1 driven, followers towards the tip) or ``"tip"``.
    Raises :class:`PlanningError` when a follower has no place on the track.
    """
    s_driven = np.asarray(s_driven, dtype=float)
    s = np.empty((s_driven.size, n_links + 1))
    lipschitz = max(track.spline.max_speed(), 1.0)
    order = range(n_links + 1) if driven == "base" else range(n_links, -1, -1)
    order = list(order)
    direction = 1 if driven == "base" else -1
    s[:, order[0]] = s_driven
    for j_known, j_new in zip(order[:-1], order[1:]):
        centre = track.joint(j_known, s[:, j_known], 0)[0]
        try:
            s[:, j_new] = _next_joint(track, j_known, s[:, j_known], centre, j_new, direction, link, lipschitz)
            if j_new > 0:  # on the spline: only within its waypoints (the end cubics' extension is no path)
                outside = (s[:, j_new] > track.spline.length) | (s[:, j_new] < 0.0)
                if np.any(outside):
                    k = int(np.argmax(outside))
                    raise _NoJoint(j_new, k, float(s[k, j_known]))
        except _NoJoint as exc:
            where = "beyond the path's end" if direction > 0 else "before the path's start"
            raise PlanningError(
                f"joint {exc.joint + 1} has no place on the path at sample {exc.sample}: no point of the path "
                f"{where} lies one link ({link * 1e3:g} mm) from joint {j_known + 1} at s = {exc.s_known * 1e3:.1f} mm; "
                "the path is too short for the arm plus its travel (extend path.waypoints or reduce motion.v) "
                "or it doubles back") from None
    return s


def joint_rates(track: Track, s: np.ndarray, sdot_driven: np.ndarray, driven: str) -> np.ndarray:
    """ṡ of every joint from the driven rate, by differentiating each chord condition."""
    n = s.shape[1]
    sdot = np.empty_like(s)
    order = list(range(n)) if driven == "base" else list(range(n - 1, -1, -1))
    sdot[:, order[0]] = sdot_driven
    for j, k in zip(order[:-1], order[1:]):
        p_j, ps_j = track.joint(j, s[:, j], 1)
        p_k, ps_k = track.joint(k, s[:, k], 1)
        d = p_k - p_j
        sdot[:, k] = np.einsum("ij,ij->i", d, ps_j) / np.einsum("ij,ij->i", d, ps_k) * sdot[:, j]
    return sdot
