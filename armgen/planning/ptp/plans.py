"""The PTP plan: the segment polynomials of every joint on shared knots, built by a spline
family on given knot times."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import polynomial as npp

from .config import PtpConfig
from .families import segment_shape
from .segments import NCOEF, SegmentShape


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
