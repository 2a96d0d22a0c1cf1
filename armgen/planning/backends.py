"""Kinematics backends for the planners: the same planner code runs on the CasADi
interpreter (``symbolic``) or on the generated C loaded back as ``casadi.Callback``s (``c``).

Both hand out ``casadi.Function`` objects with the same names, inputs and outputs; the
planner calls them through :meth:`Backend.call`, which returns NumPy arrays.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from ..codegen.generate import CodegenConfig, generate, write
from ..errors import TaskFileError
from ..robot import Robot
from ..symbolic.model import ModelOptions, SymbolicModel
from ..codegen.compiled import CompiledModel, build_library

BACKENDS = ("symbolic", "c")


class Backend:
    def __init__(self, name: str, functions: dict[str, ca.Function]):
        self.name = name
        self.functions = functions

    def call(self, function: str, *args) -> list[np.ndarray]:
        out = self.functions[function](*args)
        out = out if isinstance(out, tuple) else (out,)
        return [np.array(o, dtype=float) for o in out]


def make_backend(robot: Robot, kind: str, functions: tuple[str, ...]) -> Backend:
    """A backend with the named functions; ``c`` generates, compiles (double) and loads them."""
    if kind not in BACKENDS:
        raise TaskFileError(f"backend {kind!r} is not one of {', '.join(BACKENDS)}")
    model = SymbolicModel(robot, ModelOptions(functions))
    references = model.functions()
    if kind == "symbolic":
        return Backend("symbolic", references)
    # The loaded library stays mapped after its folder is removed.
    with tempfile.TemporaryDirectory(prefix="armgen-backend-") as tmp:
        work = Path(tmp)
        code = generate(CodegenConfig(robot, "double", "", functions))
        write(code, work)
        library = build_library(work, code.prefix, "double", work)
        compiled = CompiledModel(library, code.prefix, references, "double")
    return Backend("c", dict(compiled.callbacks))
