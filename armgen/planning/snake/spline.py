"""The tip path of spec 50: a C² cubic spline through waypoints, in Hermite form, with an
approximate arc-length parameter (chord-length knots).

Segment ``k`` runs from waypoint ``r_k`` to ``r_{k+1}``, knot spacing ``L_{k+1} = |r_{k+1} − r_k|``,
and is the cubic Hermite interpolant of the end points and the unknown knot tangents
``r'_k = dr/ds``. C² continuity at every interior knot ``i`` gives the tridiagonal system

    L_i r'_{i−1} + 2 L_i (1 + K_i) r'_i + L_i K_i r'_{i+1} = −3 r_{i−1} + 3(1 − K_i²) r_i + 3 K_i² r_{i+1},
    K_i = L_i / L_{i+1}

(the paper prints the last coefficient as 3, which leaves a jump in ``r''`` at the knots; spec 50).
Each row is divided by ``L_i`` before solving (same solution, rows of order one). End conditions:
a given unit tangent, or natural (``r'' = 0``). ``evaluate`` returns ``r``, ``r_s``, ``r_ss``
vectorised over any array of parameters; outside ``[0, length]`` the end cubics extend the path
(the solvers never use that: they check the range first).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_banded


class HermiteSpline:
    """C² cubic spline through ``points`` (shape (m+1, d), SI) parameterised by cumulative chord length."""

    def __init__(self, points: np.ndarray, start_tangent: np.ndarray | None = None,
                 end_tangent: np.ndarray | None = None):
        points = np.asarray(points, dtype=float)
        if points.ndim != 2 or points.shape[0] < 2:
            raise ValueError("a spline needs at least two points, given as rows")
        self.points = points
        chords = np.linalg.norm(np.diff(points, axis=0), axis=1)
        if np.any(chords <= 0):
            raise ValueError("consecutive spline points must differ")
        self.chords = chords  # L_1 … L_m (segment k has length chords[k])
        self.knots = np.concatenate([[0.0], np.cumsum(chords)])
        self.length = float(self.knots[-1])
        self.tangents = self._solve_tangents(start_tangent, end_tangent)
        # power-basis coefficients per segment in tau = s − s_k: r = c0 + c1 tau + c2 tau² + c3 tau³
        p0, p1 = points[:-1], points[1:]
        d0, d1 = self.tangents[:-1], self.tangents[1:]
        L = chords[:, None]
        slope = (p1 - p0) / L
        self.c0 = p0
        self.c1 = d0
        self.c2 = (3.0 * slope - 2.0 * d0 - d1) / L
        self.c3 = (d0 + d1 - 2.0 * slope) / (L * L)

    def _solve_tangents(self, start: np.ndarray | None, end: np.ndarray | None) -> np.ndarray:
        r, L = self.points, self.chords
        m = len(L)  # segments; m + 1 unknown tangents
        dim = r.shape[1]
        ab = np.zeros((3, m + 1))  # banded storage: upper, diagonal, lower
        rhs = np.zeros((m + 1, dim))
        if start is None:  # natural: 2 r'_0 + r'_1 = 3 (r_1 − r_0) / L_1
            ab[1, 0], ab[0, 1] = 2.0, 1.0
            rhs[0] = 3.0 * (r[1] - r[0]) / L[0]
        else:
            ab[1, 0] = 1.0
            rhs[0] = np.asarray(start, dtype=float) / np.linalg.norm(start)
        if end is None:  # natural: r'_{m−1} + 2 r'_m = 3 (r_m − r_{m−1}) / L_m
            ab[2, m - 1], ab[1, m] = 1.0, 2.0
            rhs[m] = 3.0 * (r[m] - r[m - 1]) / L[m - 1]
        else:
            ab[1, m] = 1.0
            rhs[m] = np.asarray(end, dtype=float) / np.linalg.norm(end)
        if m >= 2:
            i = np.arange(1, m)
            K = L[i - 1] / L[i]  # K_i = L_i / L_{i+1} (segment i−1 before knot i, segment i after)
            ab[2, i - 1] = 1.0  # coefficient of r'_{i−1} (row i divided by L_i)
            ab[1, i] = 2.0 * (1.0 + K)
            ab[0, i + 1] = K
            rhs[i] = (-3.0 * r[i - 1] + 3.0 * (1.0 - K * K)[:, None] * r[i]
                      + 3.0 * (K * K)[:, None] * r[i + 1]) / L[i - 1][:, None]
        return solve_banded((1, 1), ab, rhs)

    def segment(self, s: np.ndarray) -> np.ndarray:
        """Index of the segment holding each parameter (end segments extend beyond the range)."""
        return np.clip(np.searchsorted(self.knots, s, side="right") - 1, 0, len(self.chords) - 1)

    def evaluate(self, s, order: int = 2):
        """``(r, r_s, r_ss)`` (up to ``order``) at the parameters ``s``; each has shape ``s.shape + (d,)``."""
        s = np.asarray(s, dtype=float)
        k = self.segment(s)
        tau = (s - self.knots[k])[..., None]
        c1, c2, c3 = self.c1[k], self.c2[k], self.c3[k]
        r = self.c0[k] + tau * (c1 + tau * (c2 + tau * c3))
        if order == 0:
            return (r,)
        r_s = c1 + tau * (2.0 * c2 + 3.0 * tau * c3)
        if order == 1:
            return r, r_s
        return r, r_s, 2.0 * c2 + 6.0 * tau * c3

    def position(self, s) -> np.ndarray:
        return self.evaluate(s, 0)[0]

    def max_speed(self, samples_per_segment: int = 16) -> float:
        """max |r_s| over the path (sampled; |r_s| ≈ 1 for a chord-length parameter)."""
        u = np.linspace(0.0, 1.0, samples_per_segment + 1)
        s = (self.knots[:-1, None] + self.chords[:, None] * u[None, :]).ravel()
        return float(np.max(np.linalg.norm(self.evaluate(s, 1)[1], axis=-1)))

    def project(self, points: np.ndarray, s_guess: np.ndarray, iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
        """Closest path parameter to each point near ``s_guess`` (Newton on (r(s) − p)·r_s = 0);
        returns the parameters and the distances."""
        points = np.asarray(points, dtype=float)
        s = np.clip(np.asarray(s_guess, dtype=float).copy(), 0.0, self.length)
        for _ in range(iterations):
            r, r_s, r_ss = self.evaluate(s)
            d = r - points
            g = np.sum(d * r_s, axis=-1)
            dg = np.sum(r_s * r_s, axis=-1) + np.sum(d * r_ss, axis=-1)
            s = np.clip(s - g / np.where(dg > 0, dg, 1.0), 0.0, self.length)
        r = self.position(s)
        return s, np.linalg.norm(r - points, axis=-1)


class Track:
    """Where each joint centre of the snake lives, as a function of its coordinate ``s``.

    Joint 1 (the base's universal joint) rides the rail: the straight line from ``rail_start``
    along ``rail_dir``, ``s`` = the feed. Joints 2 … n+1 lie on the spline, ``s`` = its
    parameter. On the rail part the two coincide up to the spline's C² ringing from the first
    bend (reported as ``rail_offset``); using the exact line for the base keeps the base on the
    rail, so forward kinematics on the recovered angles reproduces every joint centre.
    """

    def __init__(self, spline: HermiteSpline, rail_start: np.ndarray, rail_dir: np.ndarray, max_feed: float):
        self.spline = spline
        self.rail_start = np.asarray(rail_start, dtype=float)
        self.rail_dir = np.asarray(rail_dir, dtype=float) / np.linalg.norm(rail_dir)
        self.max_feed = float(max_feed)

    def rail(self, s, order: int = 2):
        s = np.asarray(s, dtype=float)[..., None]
        r = self.rail_start + s * self.rail_dir
        r_s = np.broadcast_to(self.rail_dir, r.shape)
        return (r, r_s, np.zeros_like(r))[:order + 1]

    def joint(self, j: int, s, order: int = 2):
        """Position (and derivatives) of joint ``j`` (0-based: 0 is the base) at coordinates ``s``."""
        return self.rail(s, order) if j == 0 else self.spline.evaluate(s, order)

    def joints(self, s: np.ndarray, order: int = 2):
        """All joints at once: ``s`` has the joints on its last axis; outputs add a last axis of 3."""
        s = np.asarray(s, dtype=float)
        out = self.spline.evaluate(s, order)
        base = self.rail(s[..., 0], order)
        for k in range(order + 1):
            out[k][..., 0, :] = base[k]
        return out

    def rail_offset(self, s_max: float, samples: int = 4001) -> float:
        """Largest distance of the spline from the rail line over parameters [0, s_max]."""
        s = np.linspace(0.0, s_max, samples)
        d = self.spline.position(s) - self.rail_start
        along = d @ self.rail_dir
        return float(np.max(np.linalg.norm(d - along[:, None] * self.rail_dir, axis=1)))
