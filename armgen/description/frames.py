"""Frames: roll-pitch-yaw rotations, exact trigonometry at quarter turns, and the alignment
of a URDF joint's axis with z (which defines that joint's link frame).

The description (robot files, URDF) builds its base, tool and joint origins with these; the
symbolic core uses :func:`exact_cos_sin` so that multiples of 90° enter as exact 0/±1.
"""

from __future__ import annotations

import math

import numpy as np

# Angles this close to a multiple of 90 degrees (in units of a quarter turn) are snapped to
# it so that cos/sin become exact 0/±1 and the symbolic core drops the multiplications by
# them; 1e-12 of a quarter turn is far below any physical tolerance but above the rounding
# of a degree-to-radian conversion.
QUARTER_TURN_SNAP = 1e-12


def snap_quarter_turn(angle: float) -> float:
    """Return ``angle`` snapped to the nearest multiple of pi/2 when within QUARTER_TURN_SNAP."""
    quarters = angle / (math.pi / 2)
    nearest = round(quarters)
    if abs(quarters - nearest) < QUARTER_TURN_SNAP:
        return nearest * (math.pi / 2)
    return angle


def exact_cos_sin(angle: float) -> tuple[float, float]:
    """cos and sin, exact (0, ±1) at multiples of pi/2 so products with them vanish symbolically."""
    quarters = angle / (math.pi / 2)
    nearest = round(quarters)
    if abs(quarters - nearest) < QUARTER_TURN_SNAP:
        return [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)][nearest % 4]
    return math.cos(angle), math.sin(angle)


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = exact_cos_sin(roll)
    cp, sp = exact_cos_sin(pitch)
    cy, sy = exact_cos_sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def matrix_rpy(rot: np.ndarray) -> np.ndarray:
    """[roll, pitch, yaw] of R = Rz(yaw) Ry(pitch) Rx(roll) (pitch in [-pi/2, pi/2])."""
    pitch = math.atan2(-rot[2, 0], math.hypot(rot[0, 0], rot[1, 0]))
    yaw = math.atan2(rot[1, 0], rot[0, 0])
    roll = math.atan2(rot[2, 1], rot[2, 2])
    return np.array([roll, pitch, yaw])


# Rotations taking z onto each signed coordinate axis, exact (entries 0/±1).
_COORDINATE_ALIGNMENTS = {
    (0.0, 0.0, 1.0): np.eye(3),
    (0.0, 0.0, -1.0): np.diag([1.0, -1.0, -1.0]),
    (1.0, 0.0, 0.0): np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
    (-1.0, 0.0, 0.0): np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),
    (0.0, 1.0, 0.0): np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
    (0.0, -1.0, 0.0): np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
}


def axis_alignment(axis: tuple[float, float, float]) -> np.ndarray:
    """A 4×4 rotation whose z column is the unit ``axis`` (exact for coordinate axes)."""
    out = np.eye(4)
    key = tuple(float(v) for v in axis)
    if key in _COORDINATE_ALIGNMENTS:
        out[:3, :3] = _COORDINATE_ALIGNMENTS[key]
        return out
    z = np.array(key)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = helper - helper.dot(z) * z
    x /= np.linalg.norm(x)
    out[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return out
