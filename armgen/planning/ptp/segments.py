"""Polynomial segments of the PTP planner: end conditions, coefficients and exact extrema.

A segment ``k`` is stored as six coefficients ``a_0 … a_5`` of ``θ(τ) = Σ a_j τ^j`` in local
time ``τ = t − t_k`` (rad, s; zero-padded), which is what the firmware evaluates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import polynomial as npp

NCOEF = 6  # stored coefficients per segment: a_0 … a_5 (quintic), lower degrees zero-padded


@dataclass(frozen=True)
class SegmentShape:
    """End conditions of one segment; ``kind`` fixes which of them are used.

    ``cubic``: θ, ω at both ends. ``quartic``: θ, ω, ε at the start, θ, ω at the end.
    ``quintic``: θ, ω, ε at both ends. Unused accelerations are zero.
    """

    kind: str
    theta0: float
    omega0: float
    theta1: float
    omega1: float
    eps0: float = 0.0
    eps1: float = 0.0

    def normalized(self) -> list[np.ndarray]:
        """``b_j(T)`` (coefficients ascending in T) with ``θ(sT) = Σ_j b_j(T) s^j``, ``s ∈ [0, 1]``."""
        d, w0, w1, e0, e1 = self.theta1 - self.theta0, self.omega0, self.omega1, self.eps0, self.eps1
        if self.kind == "cubic":
            rows = [[self.theta0], [0.0, w0], [3 * d, -(2 * w0 + w1)], [-2 * d, w0 + w1]]
        elif self.kind == "quartic":
            rows = [[self.theta0], [0.0, w0], [0.0, 0.0, e0 / 2], [4 * d, -(3 * w0 + w1), -e0],
                    [-3 * d, 2 * w0 + w1, e0 / 2]]
        else:
            rows = [[self.theta0], [0.0, w0], [0.0, 0.0, e0 / 2],
                    [10 * d, -(6 * w0 + 4 * w1), -(3 * e0 - e1) / 2],
                    [-15 * d, 8 * w0 + 7 * w1, (3 * e0 - 2 * e1) / 2],
                    [6 * d, -3 * (w0 + w1), -(e0 - e1) / 2]]
        return [np.array(r, dtype=float) for r in rows]

    def coefficients(self, duration: float) -> np.ndarray:
        """``a_0 … a_5`` of ``θ(τ)`` for a segment of ``duration`` seconds."""
        out = np.zeros(NCOEF)
        for j, b in enumerate(self.normalized()):
            out[j] = npp.polyval(duration, b) / duration**j
        return out


def polynomial_roots(coef: np.ndarray, x_max: float) -> np.ndarray:
    """Complex roots of ``Σ coef[i] x^i`` that matter on ``[0, x_max]``.

    Leading terms whose size on ``[0, x_max]`` stays below the rounding of the largest term
    there (``|c_n| x_max^n ≤ eps · max_i |c_i| x_max^i``) are dropped: they move the roots in
    range less than rounding does, and a tiny leading coefficient (an inherited ε of 1e-17)
    would wreck the companion matrix. ``np.roots`` balances that matrix (``polyroots`` does not).
    """
    coef = np.asarray(coef, dtype=float)
    with np.errstate(divide="ignore"):
        size = np.log(np.abs(coef)) + np.arange(coef.size) * math.log(x_max)
    keep = np.flatnonzero(size > np.max(size, initial=-np.inf) + math.log(np.finfo(float).eps))
    coef = coef[: keep[-1] + 1] if keep.size else coef[:0]
    return np.roots(coef[::-1]) if coef.size >= 2 else np.array([], dtype=complex)


def _breakpoints(coef: np.ndarray, duration: float) -> np.ndarray:
    """0, T and every root's real part clipped into [0, T], sorted.

    Extra points are harmless for maxima and total variation; the real roots are all there.
    """
    inner = np.clip(np.real(polynomial_roots(coef, duration)), 0.0, duration)
    return np.unique(np.concatenate(([0.0, duration], inner)))


def _values_at_breakpoints(coeffs: np.ndarray, duration: float, order: int) -> np.ndarray:
    """``θ^(order)`` at 0, T and the zeros of ``θ^(order+1)`` in between, in time order."""
    p = npp.polyder(coeffs, order)
    return npp.polyval(_breakpoints(npp.polyder(p), duration), p)


def peak_abs(coeffs: np.ndarray, duration: float, order: int) -> float:
    """Exact max of ``|θ^(order)|`` over the segment ``[0, duration]``."""
    return float(np.max(np.abs(_values_at_breakpoints(coeffs, duration, order))))


def extremes(coeffs: np.ndarray, duration: float, order: int) -> tuple[float, float]:
    """Exact (min, max) of ``θ^(order)`` over ``[0, duration]``."""
    values = _values_at_breakpoints(coeffs, duration, order)
    return float(values.min()), float(values.max())


def total_variation(coeffs: np.ndarray, duration: float, order: int) -> float:
    """``∫ |θ^(order+1)| dτ`` over the segment: sum of |steps| between monotone pieces."""
    return float(np.sum(np.abs(np.diff(_values_at_breakpoints(coeffs, duration, order)))))


def derivative_at(coeffs: np.ndarray, tau: float, order: int) -> float:
    """``θ^(order)(tau)`` of one segment."""
    return float(npp.polyval(tau, npp.polyder(coeffs, order)))
