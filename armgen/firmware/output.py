"""What a firmware run printed: its CSV and its ``# key value`` summary, parsed."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .errors import FirmwareError

FAULT_NAMES = ("NONE", "BAD_CONFIG", "NONFINITE_INPUT", "NONFINITE_OUTPUT", "JOINT_LIMIT", "SINGULAR", "OVERRUN",
               "TRACKING", "PLAYBACK", "BAD_ARGS", "LOCK_REPORT", "REDUNDANCY", "SPEED", "UNREACHABLE", "BAD_TARGET",
               "TORQUE", "STALE", "COLLISION")
STATE_NAMES = ("IDLE", "RUNNING", "DONE", "FAULT", "DEGRADED")
FAULT_STATE = STATE_NAMES.index("FAULT")


@dataclass
class FirmwareRun:
    """The CSV a firmware printed, and its '# key value' summary."""

    columns: list[str]
    data: np.ndarray
    summary: dict[str, str]
    text: str = ""

    def column(self, name: str) -> np.ndarray:
        return self.data[:, self.columns.index(name)]

    @property
    def state(self) -> str:
        return self.summary.get("state", "?")

    @property
    def fault(self) -> str:
        return self.summary.get("fault", "?")

    def by_tick(self) -> dict[int, np.ndarray]:
        """The first row of each tick index (later rows of the same tick show the hold)."""
        out: dict[int, np.ndarray] = {}
        for row in self.data:
            out.setdefault(int(row[0]), row)
        return out

    def q(self, n: int) -> np.ndarray:
        return self.data[:, 2:2 + n]


def _real(token: str) -> float:
    token = token.strip()
    return float.fromhex(token) if "0x" in token else float(token)


def parse_output(text: str) -> FirmwareRun:
    columns: list[str] | None = None
    rows, summary = [], {}
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("tick,"):
            columns = line.split(",")
        elif line.startswith("# "):
            key, _, value = line[2:].partition(" ")
            summary[key] = value.strip()
        elif columns is not None and line[:1].isdigit():
            cells = line.split(",")
            if len(cells) == len(columns):
                rows.append([_real(c) for c in cells])
    if columns is None:
        raise FirmwareError(f"the firmware printed no CSV header:\n{text[-2000:]}")
    data = np.array(rows, dtype=float).reshape(len(rows), len(columns))
    return FirmwareRun(columns, data, summary, text)


def instructions_per_tick(run: FirmwareRun) -> dict[str, float]:
    """From the QEMU run's SysTick counts (needs -icount shift=0): mean and max per tick."""
    s = {k: float(v) for k, v in run.summary.items() if re.fullmatch(r"-?\d+(\.\d+)?", v)}
    ipt = s["calib_insns"] / s["calib_ticks"]
    n = s["ticks"]
    return {"insns_per_systick": ipt, "ticks": n,
            "mean": (s["tick_systicks_sum"] - s["stub_systicks_sum"]) * ipt / n,
            "max": s["tick_systicks_max"] * ipt - s["stub_systicks_sum"] * ipt / n,
            "min": s["tick_systicks_min"] * ipt - s["stub_systicks_sum"] * ipt / n,
            "resolution": ipt}

