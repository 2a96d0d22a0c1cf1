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
        # Python lists, not arrays: this runs once per integration step, and scalar access to
        # a list is several times cheaper than to a NumPy array (the same double arithmetic).
        self.state = [IDLE] * self.n
        self.value = [0.0] * self.n
        self.t_event = [0.0] * self.n  # start of the current phase
        self.v_event = [0.0] * self.n  # value at the start of the current phase
        self.openings = np.zeros(self.n, dtype=int)

    def update(self, t: float, in_band: np.ndarray) -> np.ndarray:
        """Advance every joint's window to time ``t``; returns the weights."""
        band = in_band.tolist()
        state, value, t_event, v_event = self.state, self.value, self.t_event, self.v_event
        if not any(state) and not any(band):
            return np.array(value)  # every window idle and no joint in its band: nothing to do
        hold_min, t_smo, shape = self.t_sum - self.t_smo, self.t_smo, self.shape
        for i in range(self.n):
            st = state[i]
            if st == RAMP_DOWN:  # the value reached at t, from which a re-entry ramps up
                value[i] = max(1.0 - ramp((t - t_event[i]) / t_smo, shape), 0.0)
            if (st == IDLE or st == RAMP_DOWN) and band[i]:
                state[i], t_event[i], v_event[i] = RAMP_UP, t, value[i]
                self.openings[i] += 1
                st = RAMP_UP
            if st == RAMP_UP:
                v0 = v_event[i]
                value[i] = v0 + (1 - v0) * ramp((t - t_event[i]) / t_smo, shape)
                if value[i] >= 1.0:
                    state[i], t_event[i], value[i] = HOLD, t, 1.0
            elif st == HOLD:
                if t - t_event[i] >= hold_min and not band[i]:
                    state[i], t_event[i], v_event[i] = RAMP_DOWN, t, 1.0
            elif st == RAMP_DOWN:
                if value[i] <= 0.0:
                    state[i], value[i] = IDLE, 0.0
        return np.array(value)
