"""The geometry of a tool-path program (SI units), parametrised by path length.

A program is a chain of pieces — straight lines, circular arcs, smooth sampled paths and the
rounded corners between them — each a function of its own path length ``u ∈ [0, L]``. Every
piece evaluates, for an array of ``u``, the position, the unit tangent ``dp/du``, the rotation
and the angular velocity per metre of path (base frame, rad/m), so that a tool moving at
``ṡ`` m/s has the twist ``[t ṡ; ω_s ṡ]``. :class:`Program` concatenates them and evaluates
the whole path at arrays of ``s``.

Orientation: a line or arc turns the tool from its start rotation to the move's end rotation
about one fixed axis, uniformly in path length (slerp); a sampled path uses SciPy's
:class:`~scipy.spatial.transform.RotationSpline` (angular velocity continuous); a rounded
corner slerps between the rotations where it leaves and rejoins the path.

Rounded corners: a corner with blend radius ``r`` is cut at path length ``r`` before and after
it (points A and B) and joined by the cubic Bézier ``A, A + ⅔ d_A t_A, B − ⅔ d_B t_B, B``
(``d`` the chord to the corner): tangent-continuous at A and B, and, being inside the convex
hull of four points within ``r`` of the corner, within ``r`` of it. Between two lines it is
the quadratic Bézier through the corner's tangent lines. A corner that turns back (by more
than :data:`MAX_BLEND_TURN`) cannot be rounded: the tool stops there instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicHermiteSpline, CubicSpline
from scipy.spatial.transform import Rotation, RotationSpline

# Two tangents closer than this (rad) meet smoothly: no corner, nothing to round or stop at.
CORNER_ANGLE_TOL = 1e-6
# A corner that turns the path by more than this (rad) is not rounded, whatever its blend: the
# tool stops there. The rounding's peak curvature grows as sin(θ/2) / (r cos²(θ/2)) (a cusp at
# a reversal, θ = 180°: the Bézier's speed vanishes and its arc length cannot be inverted);
# up to 170° its radius of curvature is still 0.8 % of the blend radius, which the time law's
# grid resolves (see CELLS_PER_MIN_RADIUS in .timelaw).
MAX_BLEND_TURN = math.radians(170.0)
# Three arc points closer than this to a line (relative to the chords) define no circle.
COLLINEAR_TOL = 1e-6
# A move shorter than this (m) has no direction: a pure reorientation is not a path.
MIN_MOVE_LENGTH = 1e-6
# Arc-length tables: samples per knot interval of a sampled path and per rounded corner. The
# Hermite map from path length to the curve parameter is then accurate to ~1e-9 relative.
SAMPLES_PER_KNOT = 16
SAMPLES_PER_BLEND = 256
# A poses move needs this many rows: a cubic spline with not-a-knot ends is determined by four.
MIN_POSE_ROWS = 4


class GeometryError(ValueError):
    """A program that has no valid geometry; ``move`` is the 0-based index of the culprit."""

    def __init__(self, move: int, message: str):
        super().__init__(message)
        self.move = move


def _rot_matrices(rot: Rotation, shape: tuple[int, ...]) -> np.ndarray:
    return rot.as_matrix().reshape(shape + (3, 3))


class _Slerp:
    """Rotation from ``r0`` to ``r1`` about one fixed axis, uniformly in ``x ∈ [0, 1]``."""

    def __init__(self, r0: Rotation, r1: Rotation):
        self.r0 = r0
        self.rotvec = (r0.inv() * r1).as_rotvec()
        self.omega = r0.apply(self.rotvec)  # base frame, per unit x: the axis is fixed in both frames

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return _rot_matrices(self.r0 * Rotation.from_rotvec(np.multiply.outer(x.ravel(), self.rotvec)), x.shape)


class Piece:
    """One piece of a program: its length and its move (0-based; rounded corners belong to the
    move they leave). Subclasses set both and implement :meth:`evaluate`."""

    length: float
    move: int = -1

    def evaluate(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(position, unit tangent, rotation, ω per metre) at path lengths ``u`` (1-D array)."""
        raise NotImplementedError

    def tangent(self, u: np.ndarray) -> np.ndarray:
        """The unit tangent alone (the time law's curvature needs no rotations)."""
        return self.evaluate(u)[1]

    def start(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p, t, r, _ = self.evaluate(np.array([0.0]))
        return p[0], t[0], r[0]

    def end(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p, t, r, _ = self.evaluate(np.array([self.length]))
        return p[0], t[0], r[0]


class Line(Piece):
    def __init__(self, p0: np.ndarray, p1: np.ndarray, r0: Rotation, r1: Rotation):
        delta = p1 - p0
        self.length = float(np.linalg.norm(delta))
        self.p0, self.direction = p0, delta / self.length
        self.orientation = _Slerp(r0, r1)

    def evaluate(self, u):
        x = u / self.length
        n = u.size
        return (self.p0 + np.multiply.outer(u, self.direction), np.broadcast_to(self.direction, (n, 3)),
                self.orientation(x), np.broadcast_to(self.orientation.omega / self.length, (n, 3)))


def circumcentre(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(centre, unit normal of a → b → c) of three points, None when they are (nearly) collinear."""
    u, v = b - a, c - a
    normal = np.cross(u, v)
    scale = np.linalg.norm(u) * np.linalg.norm(v)
    if scale == 0 or np.linalg.norm(normal) < COLLINEAR_TOL * scale:
        return None
    uu, vv, uv = u @ u, v @ v, u @ v
    centre = a + (vv * (uu - uv) * u + uu * (vv - uv) * v) / (2 * (uu * vv - uv * uv))
    return centre, normal / np.linalg.norm(normal)


class Arc(Piece):
    """The circular arc from ``p0`` through ``via`` to ``p1``."""

    def __init__(self, p0: np.ndarray, via: np.ndarray, p1: np.ndarray, r0: Rotation, r1: Rotation, move: int):
        circle = circumcentre(p0, via, p1)
        if circle is None:
            raise GeometryError(move, "the start, `via` and `to` points are collinear (or coincide) and define no "
                                      "circle; move `via` off the line through the other two")
        self.centre, normal = circle
        self.radius = float(np.linalg.norm(p0 - self.centre))
        self.e1 = (p0 - self.centre) / self.radius
        self.e2 = np.cross(normal, self.e1)  # via and `to` lie at positive angles in (e1, e2)
        d = p1 - self.centre
        self.sweep = math.atan2(d @ self.e2, d @ self.e1) % (2 * math.pi)
        self.length = self.radius * self.sweep
        self.orientation = _Slerp(r0, r1)

    def evaluate(self, u):
        phi = u / self.radius
        c, s = np.cos(phi), np.sin(phi)
        outer = np.multiply.outer
        p = self.centre + self.radius * (outer(c, self.e1) + outer(s, self.e2))
        t = outer(-s, self.e1) + outer(c, self.e2)
        return p, t, self.orientation(u / self.length), np.broadcast_to(self.orientation.omega / self.length,
                                                                          (u.size, 3))


class Curve(Piece):
    """A smooth curve ``p(w)``, ``w ∈ [w0, w1]``, re-parametrised by path length through a table
    of ``u(w)`` and the cubic Hermite inverse ``w(u)`` (slopes ``1/|p'(w)|``)."""

    def __init__(self, position, derivative, rotation, omega, w: np.ndarray):
        self.position, self.derivative, self.rotation, self.omega = position, derivative, rotation, omega
        speed = np.linalg.norm(derivative(w), axis=1)
        # Simpson on each table interval (midpoint speeds), far below the Hermite map's error
        mid = np.linalg.norm(derivative(0.5 * (w[1:] + w[:-1])), axis=1)
        du = np.diff(w) / 6 * (speed[1:] + 4 * mid + speed[:-1])
        u = np.concatenate([[0.0], np.cumsum(du)])
        self.length = float(u[-1])
        self.map_nodes = (u, w, 1.0 / speed)  # kept for the on-board program table
        self.to_w = CubicHermiteSpline(*self.map_nodes)

    def tangent(self, u):
        dp = self.derivative(self.to_w(u))
        return dp / np.linalg.norm(dp, axis=1)[:, None]

    def evaluate(self, u):
        w = self.to_w(u)
        dp = self.derivative(w)
        speed = np.linalg.norm(dp, axis=1)[:, None]
        return self.position(w), dp / speed, self.rotation(w), self.omega(w) / speed


class Corner(Curve):
    """The rounded corner of radius ``radius`` at ``corner``, from A = (position, tangent,
    rotation matrix) to B (see the module); ``move`` is the move it leaves. ``min_radius`` is
    its smallest radius of curvature (over its arc-length table), which sets how finely the
    time law resolves it."""

    def __init__(self, a: tuple, b: tuple, corner: np.ndarray, radius: float, move: int):
        (pa, ta, ra), (pb, tb, rb) = a, b
        self.corner, self.radius = corner, radius
        c1 = pa + 2 / 3 * np.linalg.norm(corner - pa) * ta
        c2 = pb - 2 / 3 * np.linalg.norm(pb - corner) * tb
        ctrl = np.array([pa, c1, c2, pb])
        orientation = _Slerp(Rotation.from_matrix(ra), Rotation.from_matrix(rb))
        self.control, self.orientation = ctrl, orientation  # the on-board program table encodes both

        def position(w):
            m = 1 - w
            return (np.multiply.outer(m ** 3, ctrl[0]) + np.multiply.outer(3 * m * m * w, ctrl[1])
                    + np.multiply.outer(3 * m * w * w, ctrl[2]) + np.multiply.outer(w ** 3, ctrl[3]))

        def derivative(w):
            m = 1 - w
            return 3 * (np.multiply.outer(m * m, ctrl[1] - ctrl[0]) + np.multiply.outer(2 * m * w, ctrl[2] - ctrl[1])
                        + np.multiply.outer(w * w, ctrl[3] - ctrl[2]))

        w = np.linspace(0.0, 1.0, SAMPLES_PER_BLEND + 1)
        super().__init__(position, derivative, orientation,
                         lambda w: np.broadcast_to(orientation.omega, (w.size, 3)), w)
        self.move = move
        m = 1 - w
        second = 6 * (np.multiply.outer(m, ctrl[2] - 2 * ctrl[1] + ctrl[0]) + np.multiply.outer(w, ctrl[3] - 2 * ctrl[2]
                                                                                                + ctrl[1]))
        first = derivative(w)
        curvature = np.linalg.norm(np.cross(first, second), axis=1) / np.linalg.norm(first, axis=1) ** 3
        self.min_radius = float(1.0 / curvature.max()) if curvature.max() > 0 else math.inf


def pose_spline(points: np.ndarray, rotations: Rotation, move: int) -> PoseSpline:
    """The pose spline through ``points`` and ``rotations`` (see :class:`PoseSpline`), after
    checking that the rows define one."""
    if len(points) < MIN_POSE_ROWS:
        raise GeometryError(move, f"{len(points)} poses: a poses move needs at least {MIN_POSE_ROWS} (with the "
                                  "current pose) to define a cubic spline; add rows or use a line")
    chords = np.linalg.norm(np.diff(points, axis=0), axis=1)
    k = int(np.argmin(chords))
    if chords[k] < MIN_MOVE_LENGTH:
        raise GeometryError(move, f"poses {k} and {k + 1} coincide (the path must advance from row to row); "
                                  "remove the repeated row")
    steps = np.diff(points, axis=0)
    back = np.einsum("ij,ij->i", steps[1:], steps[:-1]) < 0
    if back.any():
        k = int(np.argmax(back)) + 1
        raise GeometryError(move, f"the path doubles back at pose {k} (it turns by more than 90° between samples): "
                                  "the rows must be ordered along the path; sort them or split the move")
    return PoseSpline(np.concatenate([[0.0], np.cumsum(chords)]), points, rotations)


class PoseSpline(Curve):
    """The C² cubic spline through ``points`` (not-a-knot ends) on the chord length ``tau``, with
    the rotations interpolated by :class:`RotationSpline` on the same parameter (both kept as
    ``spline`` and ``rotation_spline`` for the on-board program table)."""

    def __init__(self, tau: np.ndarray, points: np.ndarray, rotations: Rotation):
        self.spline = CubicSpline(tau, points, bc_type="not-a-knot")
        self.rotation_spline = rot_spline = RotationSpline(tau, rotations)

        def rotation(w):
            return rot_spline(w).as_matrix().reshape(w.shape + (3, 3))

        def omega(w):
            rot = rot_spline(w)
            return rot.apply(rot_spline(w, 1))  # RotationSpline's rate is in the body frame

        within = np.arange(SAMPLES_PER_KNOT) / SAMPLES_PER_KNOT
        w = np.concatenate([(tau[:-1, None] + np.diff(tau)[:, None] * within).ravel(), tau[-1:]])
        super().__init__(self.spline, self.spline.derivative(), rotation, omega, w)


class Trimmed(Piece):
    """Part ``[u0, u1]`` of a piece (a line or arc shortened by its rounded corners)."""

    def __init__(self, piece: Piece, u0: float, u1: float):
        self.piece, self.u0 = piece, u0
        self.length = u1 - u0
        self.move = piece.move

    def evaluate(self, u):
        return self.piece.evaluate(u + self.u0)

    def tangent(self, u):
        return self.piece.tangent(u + self.u0)


@dataclass(frozen=True)
class MoveSpec:
    """One move in SI units. ``kind``: ``line`` (to ``position``/``rotation``), ``arc`` (through
    ``via``), ``poses`` (through ``points``/``rotations``). ``rotation`` None keeps the
    orientation. ``blend`` rounds the corner at the move's end (0: stop there)."""

    kind: str
    speed: float
    acceleration: float
    blend: float
    position: np.ndarray | None = None
    rotation: Rotation | None = None
    via: np.ndarray | None = None
    points: np.ndarray | None = None
    rotations: Rotation | None = None


class Program:
    """A chain of pieces from a start pose; ``evaluate(s)`` at path lengths ``s ∈ [0, length]``.

    Attributes: ``pieces``; ``starts`` (path length where each begins, plus the total);
    ``stops`` (path lengths of corners without a blend, where the tool must come to rest);
    ``moves`` (the specs); ``unrounded`` ((move, turn angle in rad) of every corner whose blend
    was not applied because it turns by more than :data:`MAX_BLEND_TURN`: a stop instead).
    """

    def __init__(self, start_position: np.ndarray, start_rotation: np.ndarray, moves: list[MoveSpec]):
        self.moves = moves
        self.unrounded: list[tuple[int, float]] = []
        raw = self._raw_pieces(start_position, Rotation.from_matrix(start_rotation), moves)
        self.pieces, stop_after = self._round_corners(raw)
        lengths = np.array([p.length for p in self.pieces])
        self.starts = np.concatenate([[0.0], np.cumsum(lengths)])
        self.length = float(self.starts[-1])
        self.stops = np.array([self.starts[k + 1] for k in stop_after])

    @staticmethod
    def _raw_pieces(p: np.ndarray, r: Rotation, moves: list[MoveSpec]) -> list[Piece]:
        pieces: list[Piece] = []
        for k, m in enumerate(moves):
            if m.kind == "poses":
                points, rotations = m.points, m.rotations
                if np.linalg.norm(points[0] - p) >= MIN_MOVE_LENGTH:  # the spline starts where the tool is
                    points = np.vstack([p, points])
                    rotations = Rotation.concatenate([r, rotations])
                elif (r.inv() * rotations[0]).magnitude() > CORNER_ANGLE_TOL:
                    raise GeometryError(k, "the first pose is at the current tool position but turns the tool by "
                                           f"{math.degrees((r.inv() * rotations[0]).magnitude()):.3g} deg: the tool "
                                           "cannot turn in place; give the current orientation or drop the row")
                piece = pose_spline(points, rotations, k)
                r_end = rotations[-1]
            else:
                r_end = m.rotation if m.rotation is not None else r
                if np.linalg.norm(m.position - p) < MIN_MOVE_LENGTH:
                    raise GeometryError(k, "`to` is the current tool position: the move has no length (a pure "
                                           "reorientation is not a path); change `to` or remove the move")
                piece = Line(p, m.position, r, r_end) if m.kind == "line" else Arc(p, m.via, m.position, r, r_end, k)
            piece.move = k
            pieces.append(piece)
            p, r = piece.end()[0], r_end
        return pieces

    def _round_corners(self, raw: list[Piece]) -> tuple[list[Piece], list[int]]:
        """Rounded corners between the moves (or stops where ``blend = 0``); returns the pieces
        and the indices of the pieces after which the tool stops."""
        cut = [[0.0, p.length] for p in raw]
        corners: list[tuple[int, float]] = []
        for k in range(len(raw) - 1):
            t_end, t_next = raw[k].end()[1], raw[k + 1].start()[1]
            angle = math.acos(float(np.clip(t_end @ t_next, -1.0, 1.0)))
            if angle <= CORNER_ANGLE_TOL:
                continue
            radius = self.moves[k].blend
            if radius > 0 and angle > MAX_BLEND_TURN:  # (nearly) a reversal: no rounding can turn back
                self.unrounded.append((k, angle))
                radius = 0.0
            corners.append((k, radius))
            if radius == 0:
                continue
            if radius < MIN_MOVE_LENGTH:
                raise GeometryError(k, f"blend = {radius:.3g} m is below {MIN_MOVE_LENGTH * 1e6:g} µm: give 0 (stop at "
                                       "the corner) or a radius of at least that")
            for j in (k, k + 1):
                if radius > raw[j].length / 2 * (1 + 1e-12):  # exactly half: the corners meet
                    raise GeometryError(k, f"blend = {radius * 1e3:.6g} mm is larger than half of move {j}'s length "
                                           f"({raw[j].length * 1e3:.6g} mm): the rounded corners would overlap; "
                                           f"give blend ≤ {raw[j].length / 2 * 1e3:.6g} mm")
                if isinstance(raw[j], Arc) and radius > raw[j].radius:
                    raise GeometryError(k, f"blend = {radius * 1e3:.6g} mm is larger than the radius of the arc of "
                                           f"move {j} ({raw[j].radius * 1e3:.6g} mm); give a smaller blend")
            cut[k][1] -= radius
            cut[k + 1][0] += radius
        pieces: list[Piece] = []
        stop_after: list[int] = []
        blends = dict(corners)
        for k, piece in enumerate(raw):
            u0, u1 = cut[k]
            if u1 - u0 > MIN_MOVE_LENGTH * 1e-3:  # a move all taken up by its two rounded corners drops out
                pieces.append(piece if (u0, u1) == (0.0, piece.length) else Trimmed(piece, u0, u1))
            if k in blends:
                if blends[k] == 0:
                    stop_after.append(len(pieces) - 1)
                else:
                    p, t, r, _ = (v[0] for v in piece.evaluate(np.array([u1])))
                    nxt = raw[k + 1]
                    q, tq, rq, _ = (v[0] for v in nxt.evaluate(np.array([cut[k + 1][0]])))
                    corner = piece.end()[0]
                    pieces.append(Corner((p, t, r), (q, tq, rq), corner, blends[k], k))
        return pieces, stop_after

    def piece_index(self, s: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(self.starts, s, side="right") - 1, 0, len(self.pieces) - 1)

    def evaluate(self, s) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(position, unit tangent, rotation, ω per metre) at path lengths ``s`` (clamped to the path)."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        flat = s.ravel()
        index = self.piece_index(flat)
        p, t, w = (np.empty((flat.size, 3)) for _ in range(3))
        r = np.empty((flat.size, 3, 3))
        for k in np.unique(index):
            mask = index == k
            piece = self.pieces[k]
            u = np.clip(flat[mask] - self.starts[k], 0.0, piece.length)
            p[mask], t[mask], r[mask], w[mask] = piece.evaluate(u)
        shape = s.shape
        return p.reshape(shape + (3,)), t.reshape(shape + (3,)), r.reshape(shape + (3, 3)), w.reshape(shape + (3,))

    def tangent(self, s: np.ndarray) -> np.ndarray:
        """Unit tangents at path lengths ``s`` (1-D, clamped to the path)."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        index = self.piece_index(s)
        out = np.empty((s.size, 3))
        for k in np.unique(index):
            mask = index == k
            out[mask] = self.pieces[k].tangent(np.clip(s[mask] - self.starts[k], 0.0, self.pieces[k].length))
        return out

    def move_at(self, s) -> np.ndarray:
        """The move (0-based) each path length belongs to (a rounded corner: the move it leaves)."""
        return np.array([self.pieces[k].move for k in self.piece_index(np.atleast_1d(s))])

    def blend_zones(self) -> list[tuple[float, float, np.ndarray, float]]:
        """(s start, s end, corner point, radius) of every rounded corner."""
        return [(float(self.starts[k]), float(self.starts[k + 1]), piece.corner, piece.radius)
                for k, piece in enumerate(self.pieces) if isinstance(piece, Corner)]

    def sample_points(self, count: int = 400) -> np.ndarray:
        return self.evaluate(np.linspace(0.0, self.length, count))[0]
