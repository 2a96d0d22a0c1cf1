"""Time-smoothed activation windows of spec 20.

A window is a per-joint weight in [0, 1] that *latches*: it opens when its joint enters the
band near a limit, ramps up over ``T_smo`` (quadratically or linearly), stays at 1 for at
least ``T_sum − T_smo`` and for as long as the joint is in the band, then ramps down over
``T_smo``; re-entering the band during the ramp-down ramps up again from the current value.
While a window is open its gradient term applies even if the joint has left the band
(literal per-step gating chatters). Windows are updated once per integration step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SHAPES = ("quadratic", "linear")

IDLE, RAMP_UP, HOLD, RAMP_DOWN = 0, 1, 2, 3


def ramp(x: float, shape: str) -> float:
    """0 → 1 over x ∈ [0, 1]."""
    x = min(max(x, 0.0), 1.0)
    return x * x if shape == "quadratic" else x


@dataclass
class JointWindows:
    n: int
    t_smo: float
    t_sum: float
    shape: str = "quadratic"

    def __post_init__(self):
        if self.shape not in SHAPES:
            raise ValueError(f"window shape {self.shape!r} is not one of {SHAPES}")
        self.state = np.full(self.n, IDLE)
        self.value = np.zeros(self.n)
        self.t_event = np.zeros(self.n)  # start of the current phase
        self.v_event = np.zeros(self.n)  # value at the start of the current phase
        self.openings = np.zeros(self.n, dtype=int)

    def update(self, t: float, in_band: np.ndarray) -> np.ndarray:
        """Advance every joint's window to time ``t``; returns the weights."""
        if not self.state.any() and not in_band.any():
            return self.value.copy()  # every window idle and no joint in its band: nothing to do
        hold_min = self.t_sum - self.t_smo
        for i in range(self.n):
            st = self.state[i]
            if st == RAMP_DOWN:  # the value reached at t, from which a re-entry ramps up
                self.value[i] = max(1.0 - ramp((t - self.t_event[i]) / self.t_smo, self.shape), 0.0)
            if st in (IDLE, RAMP_DOWN) and in_band[i]:
                self.state[i], self.t_event[i], self.v_event[i] = RAMP_UP, t, self.value[i]
                self.openings[i] += 1
                st = RAMP_UP
            if st == RAMP_UP:
                v0 = self.v_event[i]
                self.value[i] = v0 + (1 - v0) * ramp((t - self.t_event[i]) / self.t_smo, self.shape)
                if self.value[i] >= 1.0:
                    self.state[i], self.t_event[i], self.value[i] = HOLD, t, 1.0
            elif st == HOLD:
                if t - self.t_event[i] >= hold_min and not in_band[i]:
                    self.state[i], self.t_event[i], self.v_event[i] = RAMP_DOWN, t, 1.0
            elif st == RAMP_DOWN:
                if self.value[i] <= 0.0:
                    self.state[i], self.value[i] = IDLE, 0.0
        return self.value.copy()
