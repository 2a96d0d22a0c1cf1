"""The PTP spline families, selected by name (:data:`~armgen.planning.ptp.families.METHODS`):


- ``cubic``: a cubic per segment from θ, ω at both ends (ε jumps at the knots);
- ``3-4`` (default): cubic first segment, then quartics that inherit the acceleration of the
  segment before (θ, ω, ε continuous, nothing preset);
- ``3-5-3``: cubic, quintic…, cubic; the quintics take their end accelerations from the
  neighbouring cubics and, at knots between two quintics, from ``waypoints.eps`` — without
  it, the single such knot of a 5-waypoint plan gets the minimum-jerk value and longer plans
  get zero;
- ``quintic``: quintics with θ, ω, ε at both ends (ε from ``waypoints.eps``, default zero).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.polynomial import polynomial as npp

from .schema import METHODS  # noqa: F401 (the families' names, as a task file gives them)
from .segments import SegmentShape, derivative_at


@dataclass(frozen=True)
class JointWaypoints:
    """One joint's waypoints in SI: angles (rad), velocities (rad/s), optional preset ε (rad/s²)."""

    name: str
    theta: np.ndarray
    omega: np.ndarray
    eps: np.ndarray | None = None
    qlim: tuple[float, float] | None = None


def preset_accel(method: str, jw: JointWaypoints, i: int, nseg: int) -> float | None:
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
        return SegmentShape("quintic", th0, w0, th1, w1, preset_accel(method, jw, k, nseg),
                            preset_accel(method, jw, k + 1, nseg))

    def knot_accel(i: int) -> float:
        if i == 1:
            return _end_accel(_cubic(jw, 0), durations[0])
        if i == nseg - 1:
            return _start_accel(_cubic(jw, nseg - 1), durations[nseg - 1])
        preset = preset_accel(method, jw, i, nseg)
        return preset if preset is not None else _min_jerk_inner_accel(jw, durations)

    return SegmentShape("quintic", th0, w0, th1, w1, knot_accel(k), knot_accel(k + 1))


def timing_order(method: str, nseg: int) -> list[int]:
    """Order in which segment durations can be solved one at a time."""
    if method == "3-5-3":
        return [0, nseg - 1, *range(1, nseg - 1)]
    return list(range(nseg))
