"""Cartesian paths and rest-to-rest time laws (SI units).

A path maps the path parameter ``s ∈ [0, 1]`` to a position, its derivative ``dp/ds``, a
rotation and the angular velocity per unit ``ds``. A time law maps ``τ = t/T`` to
``s(τ)`` and ``ds/dτ``. Both take a number or an array (a planner evaluates the whole plan's
times at once); an array of shape S gives results of shape S, S+(3,) or S+(3, 3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import TaskFileError, excerpt

# Three circle points closer than this to a line (relative to the chord lengths) do not
# define a circle: the circumradius would exceed ~1e6 times the chord.
COLLINEAR_TOL = 1e-6
TIME_LAWS = ("cubic", "trapezoidal", "constant")


@dataclass(frozen=True)
class TimeLaw:
    kind: str = "cubic"
    blend: float = 0.2  # trapezoidal: fraction of T spent accelerating (and decelerating)

    def __post_init__(self):
        if self.kind not in TIME_LAWS:
            raise TaskFileError(f"timing.law = {excerpt(repr(self.kind))} is not one of {', '.join(TIME_LAWS)}")
        if self.kind == "trapezoidal" and not 0 < self.blend <= 0.5:
            raise TaskFileError(f"timing.blend = {self.blend} must be in (0, 0.5]")

    def __call__(self, tau):
        """(s, ds/dτ) at τ, clamped to [0, 1]."""
        tau = np.clip(tau, 0.0, 1.0)
        if self.kind == "cubic":
            return 3 * tau ** 2 - 2 * tau ** 3, 6 * tau - 6 * tau ** 2
        if self.kind == "constant":
            return tau, np.ones_like(tau)
        b = self.blend
        vmax = 1.0 / (1.0 - b)  # area under the trapezoid is 1
        acc = vmax / b
        r = 1.0 - tau
        s = np.where(tau < b, 0.5 * acc * tau ** 2,
                     np.where(tau <= 1 - b, 0.5 * acc * b ** 2 + vmax * (tau - b), 1.0 - 0.5 * acc * r ** 2))
        return s, np.where(tau < b, acc * tau, np.where(tau <= 1 - b, vmax, acc * r))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


class CirclePath:
    """Full turn through start → via → end → start, orientation held."""

    def __init__(self, start: np.ndarray, via: np.ndarray, end: np.ndarray, rotation: np.ndarray):
        a, b = via - start, end - start
        normal = np.cross(a, b)
        scale = np.linalg.norm(a) * np.linalg.norm(b)
        if scale == 0 or np.linalg.norm(normal) < COLLINEAR_TOL * scale:
            raise TaskFileError("path: the start, path.via and path.end points are collinear (or coincide), so they "
                                "define no circle; move path.via off the line through the other two")
        # circumcentre of the triangle
        aa, bb = a @ a, b @ b
        ab = a @ b
        denom = 2 * (aa * bb - ab * ab)
        centre = start + (bb * (aa - ab) * a + aa * (bb - ab) * b) / denom
        self.centre = centre
        self.radius = float(np.linalg.norm(start - centre))
        self.u = _unit(start - centre)
        n = _unit(normal)
        self.v = np.cross(n, self.u)  # via lies at a smaller positive angle than end in (u, v)
        self.rotation = rotation
        self.start = start

    def angle_of(self, point: np.ndarray) -> float:
        d = point - self.centre
        return math.atan2(d @ self.v, d @ self.u) % (2 * math.pi)

    def __call__(self, s) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        phi = 2 * math.pi * np.asarray(s)
        c, sn = np.cos(phi), np.sin(phi)
        outer = np.multiply.outer
        p = self.centre + self.radius * (outer(c, self.u) + outer(sn, self.v))
        dp = 2 * math.pi * self.radius * (outer(-sn, self.u) + outer(c, self.v))
        return p, dp, np.broadcast_to(self.rotation, phi.shape + (3, 3)), np.zeros(phi.shape + (3,))

    def sample_points(self, count: int = 360) -> np.ndarray:
        return np.array([self(k / count)[0] for k in range(count)])


def _axis_angle(rot: np.ndarray) -> tuple[np.ndarray, float]:
    """Unit axis and angle in [0, π] of a rotation matrix, via SciPy's quaternion route
    (accurate at every angle; ``acos`` of the trace loses half the digits near 0 and turns a
    9e-16 rounding of the trace into a 3e-8 rad rotation). The exact identity gives angle 0."""
    from scipy.spatial.transform import Rotation  # ~0.4 s to import: only lines that turn the tool pay it

    rotvec = Rotation.from_matrix(rot).as_rotvec()
    angle = float(np.linalg.norm(rotvec))
    if angle == 0.0:
        return np.array([0.0, 0.0, 1.0]), 0.0
    return rotvec / angle, angle


def _rodrigues(axis: np.ndarray, angle) -> np.ndarray:
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    angle = np.asarray(angle)[..., None, None]
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


class LinePath:
    """Straight line start → end; orientation held or interpolated about one fixed axis."""

    def __init__(self, start: np.ndarray, end: np.ndarray, r_start: np.ndarray, r_end: np.ndarray):
        self.start, self.delta = start, end - start
        self.r_start = r_start
        # holding the orientation is no rotation at all, not the rounding left in R0ᵀ R0
        axis_local, self.angle = ((np.array([0.0, 0.0, 1.0]), 0.0) if np.array_equal(r_start, r_end)
                                  else _axis_angle(r_start.T @ r_end))
        self.axis_local = axis_local
        self.axis_world = r_start @ axis_local

    def __call__(self, s):
        s = np.asarray(s)
        p = self.start + np.multiply.outer(s, self.delta)
        rot = self.r_start @ _rodrigues(self.axis_local, s * self.angle)
        shape = s.shape + (3,)
        return p, np.broadcast_to(self.delta, shape), rot, np.broadcast_to(self.axis_world * self.angle, shape)

    def sample_points(self, count: int = 100) -> np.ndarray:
        return np.array([self(k / count)[0] for k in range(count + 1)])
