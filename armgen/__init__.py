"""armgen: redundant-arm kinematics to verified embedded C, and trajectory planning.

The public API (imported on first use, so ``import armgen`` stays fast):

- :func:`load_robot` → :class:`Robot` (bundled name, robot TOML or URDF), :meth:`Robot.from_urdf`;
  NumPy methods ``fk``, ``jacobian``, ``manipulability`` … on ``(n,)`` or ``(..., n)`` arrays.
- :func:`plan` → :class:`Plan` (``to_pandas``, ``summary``, ``metadata``, ``plot``, ``save``).
- :func:`generate` → :class:`Generated`; :func:`verify` → :class:`VerifyReport`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

# public name -> module that defines it
_EXPORTS = {
    "Robot": "armgen.robot",
    "Joint": "armgen.robot",
    "load_robot": "armgen.robot",
    "plan": "armgen.api",
    "Plan": "armgen.api",
    "generate": "armgen.api",
    "Generated": "armgen.api",
    "VerifyReport": "armgen.api",
    "ArmgenError": "armgen.errors",
    "RobotFileError": "armgen.errors",
    "TaskFileError": "armgen.errors",
    "PlanningError": "armgen.errors",
    "ToolchainError": "armgen.errors",
    "VerificationError": "armgen.errors",
}

__all__ = ["__version__", "verify", *_EXPORTS]

if TYPE_CHECKING:  # for type checkers only; __getattr__ imports these on first use
    from .api import Generated, Plan, VerifyReport, generate, plan, verify  # noqa: F401
    from .errors import (ArmgenError, PlanningError, RobotFileError, TaskFileError, ToolchainError,  # noqa: F401
                         VerificationError)
    from .robot import Joint, Robot, load_robot  # noqa: F401


def __getattr__(name: str) -> Any:
    if name == "verify":  # the subpackage armgen.verify is callable: armgen.verify(...) = api.verify
        import importlib

        return importlib.import_module("armgen.verify")
    if name in _EXPORTS:
        import importlib

        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'armgen' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
