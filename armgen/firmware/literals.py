"""Numbers as C literals of the controller's precision (``CTRL_LIT(<repr of the double>)``: the
double build holds Python's value exactly, the float build rounds it once), for the generated
task configuration and program table. Only numbers computed by armgen go in, never user text."""

from __future__ import annotations

import math

import numpy as np

from .errors import FirmwareError


# float's smallest normal number: a float literal below it (a planner's 1e-80) underflows,
# which gcc reports as an error under -Werror (-Woverflow).
FLOAT_MIN_NORMAL = 1.1754943508222875e-38


def c_real(x: float, what: str = "task parameter") -> str:
    """``CTRL_LIT(x)``; a FirmwareError naming ``what`` for a non-finite number. A number below
    float's normal range is the cast ``((ctrl_real)x)`` instead: exact in double, 0 or a
    subnormal in float, without the underflowing literal."""
    x = float(x)
    if not math.isfinite(x):
        raise FirmwareError(f"{what} {x} is not finite; it cannot run on board")
    if x != 0.0 and abs(x) < FLOAT_MIN_NORMAL:
        return f"((ctrl_real){x!r})"
    return f"CTRL_LIT({x!r})"


def c_reals(values, what: str = "task parameter") -> str:
    """A braced initialiser of :func:`c_real` literals, the values flattened in C order."""
    return "{" + ", ".join(c_real(v, what) for v in np.asarray(values, dtype=float).ravel()) + "}"


def c_ints(values) -> str:
    """A braced initialiser of integers (joint flags, task rows)."""
    return "{" + ", ".join(str(int(v)) for v in values) + "}"
