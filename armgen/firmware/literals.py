"""Numbers as C literals of the controller's precision (``CTRL_LIT(<repr of the double>)``: the
double build holds Python's value exactly, the float build rounds it once), for the generated
task configuration and program table. Only numbers computed by armgen go in, never user text."""

from __future__ import annotations

import math

import numpy as np

from .errors import FirmwareError


def c_real(x: float, what: str = "task parameter") -> str:
    """``CTRL_LIT(x)``; a FirmwareError naming ``what`` for a non-finite number."""
    x = float(x)
    if not math.isfinite(x):
        raise FirmwareError(f"{what} {x} is not finite; it cannot run on board")
    return f"CTRL_LIT({x!r})"


def c_reals(values, what: str = "task parameter") -> str:
    """A braced initialiser of :func:`c_real` literals, the values flattened in C order."""
    return "{" + ", ".join(c_real(v, what) for v in np.asarray(values, dtype=float).ravel()) + "}"
