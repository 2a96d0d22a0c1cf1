"""armgen: redundant-arm kinematics to verified embedded C, and trajectory planning.

The public API (imported on first use, so ``import armgen`` stays fast):

- :func:`load_robot` → :class:`Robot` (bundled name, robot TOML or URDF), :meth:`Robot.from_urdf`;
  NumPy methods ``fk``, ``jacobian``, ``manipulability`` … on ``(n,)`` or ``(..., n)`` arrays.
- :func:`plan` → :class:`Plan` (``to_pandas``, ``summary``, ``metadata``, ``plot``, ``save``).
- :func:`generate` → :class:`Generated`; :func:`verify` → :class:`VerifyReport`.

The verification layer itself is the sub-package :mod:`armgen.verification`.
"""

from __future__ import annotations

import importlib
from typing import Any

from ._version import __version__

# public name -> module that defines it. The root package imports no layer at load time (the
# types are declared in __init__.pyi); the layers take the version from armgen._version.
_EXPORTS = {
    "Robot": "armgen.robot",
    "Joint": "armgen.robot",
    "load_robot": "armgen.robot",
    "plan": "armgen.api",
    "Plan": "armgen.api",
    "generate": "armgen.api",
    "Generated": "armgen.api",
    "verify": "armgen.api",
    "VerifyReport": "armgen.api",
    "ArmgenError": "armgen.errors",
    "RobotFileError": "armgen.errors",
    "TaskFileError": "armgen.errors",
    "PlanningError": "armgen.errors",
    "ToolchainError": "armgen.errors",
    "VerificationError": "armgen.errors",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'armgen' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
