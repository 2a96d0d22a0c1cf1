"""armgen: redundant-arm kinematics to verified embedded C, and trajectory planning.

The public API (imported on first use, so ``import armgen`` stays fast):

- :func:`load_robot` → :class:`Robot` (bundled name, robot TOML or URDF), :meth:`Robot.from_urdf`;
  NumPy methods ``fk``, ``jacobian``, ``manipulability`` … on ``(n,)`` or ``(..., n)`` arrays.
- :func:`plan` → :class:`Plan` (``to_pandas``, ``summary``, ``metadata``, ``plot``, ``save``).
- :func:`generate` → :class:`Generated`; :func:`verify` → :class:`VerifyReport`.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import Any

__version__ = "0.1.0"

# public name -> module that defines it. The root package imports nothing of its own at load
# time (the types are declared in __init__.pyi), so a module of any layer may import
# __version__ from here without depending on the layers above it (tests/test_layers.py).
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

def __getattr__(name: str) -> Any:
    if name == "verify":  # the subpackage armgen.verify is callable: armgen.verify(...) = api.verify
        return importlib.import_module("armgen.verify")
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'armgen' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)


class _VerifyPackage(types.ModuleType):
    """The subpackage ``armgen.verify``, callable as the API function :func:`armgen.api.verify`."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return importlib.import_module("armgen.api").verify(*args, **kwargs)


class _Root(types.ModuleType):
    def __setattr__(self, name: str, value: Any) -> None:
        # The import system binds an imported subpackage to its name here. The verification
        # subpackage shares its name with the API function armgen.verify(...), and binding it
        # would hide the function, so the package itself is made callable.
        if name == "verify" and isinstance(value, types.ModuleType):
            value.__class__ = _VerifyPackage
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Root
