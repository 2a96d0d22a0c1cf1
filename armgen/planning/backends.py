"""Kinematics backends for the planners: the same planner code runs on the CasADi
interpreter (``symbolic``) or on generated C (``c``).

Two kinds of call:

- :meth:`Backend.call` — a named model function (``fk_jacobian`` …) returning NumPy arrays,
  for the few calls a planner makes outside its integration loop. With ``c`` the functions
  listed to :func:`make_backend` are the generated C loaded back as ``casadi.Callback`` s;
  other names fall back to the symbolic model.
- :meth:`Backend.kernel` — one fused function per integration step (the whole right-hand
  side: FK and Jacobian, criteria, null-space term, the step), composed from the model's
  functions by name, with every input packed in one vector and every output in another.
  ``symbolic`` evaluates it by CasADi's virtual machine through ``Function.buffer``; ``c``
  emits it with armgen's C emitter, compiles it (cached on disk) and calls it by ctypes.
  Either way one call per step on fixed NumPy buffers.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Callable

import casadi as ca
import numpy as np

from ..codegen.compiled import CompiledModel, NativeKernel, build_library
from ..errors import TaskFileError
from ..robot import Robot
from ..symbolic.model import ModelOptions, SymbolicModel

BACKENDS = ("symbolic", "c")


class Packing:
    """Named slices of one flat vector (a kernel's input or output)."""

    def __init__(self):
        self.slices: dict[str, slice] = {}
        self.parts: list[ca.SX] = []
        self.size = 0

    def add(self, name: str, value: ca.SX | int) -> ca.SX:
        """Register a part: a size creates (and returns) a symbol, an SX expression is an output."""
        part = ca.SX.sym(name, value) if isinstance(value, int) else ca.densify(ca.vec(value))
        self.slices[name] = slice(self.size, self.size + part.numel())
        self.size += part.numel()
        self.parts.append(part)
        return part

    def vector(self) -> ca.SX:
        return ca.vertcat(*self.parts)


class Kernel:
    """A fused step: write inputs into ``x`` (by name through ``set``), call, read ``y``."""

    def __init__(self, func: ca.Function, inputs: Packing, outputs: Packing, kind: str):
        self.inputs, self.outputs = inputs.slices, outputs.slices
        if kind == "c":
            native = NativeKernel(func)
            self.x, self.y, self._eval = native.x, native.y, native
        else:
            self.x, self.y = np.zeros(func.nnz_in()), np.zeros(func.nnz_out())
            self._buffer, self._eval = func.buffer()
            self._buffer.set_arg(0, memoryview(self.x))
            self._buffer.set_res(0, memoryview(self.y))

    def set(self, name: str, value) -> None:
        self.x[self.inputs[name]] = value

    def out(self, name: str) -> np.ndarray:
        return self.y[self.outputs[name]]

    def __call__(self) -> None:
        self._eval()


# Kernels built in this process, by (robot file hash, backend, kernel key): a sweep plans many
# tasks of one robot in one worker and composes and compiles each kernel once.
# (The planners run one after another, so sharing a kernel's buffers is safe.)
_KERNELS: dict[tuple[str, str, tuple], Kernel] = {}


class Backend:
    def __init__(self, name: str, model: SymbolicModel, functions: dict[str, ca.Function]):
        self.name = name
        self.model = model
        self.functions = functions

    def call(self, function: str, *args) -> list[np.ndarray]:
        func = self.functions.get(function) or self.model.function(function)
        out = func(*args)
        out = out if isinstance(out, tuple) else (out,)
        return [np.array(o, dtype=float) for o in out]

    def kernel(self, key: tuple, build: Callable[[SymbolicModel, Packing, Packing], None]) -> Kernel:
        """The fused kernel ``key``; ``build(model, inputs, outputs)`` declares its inputs
        (``inputs.add(name, size)``) and outputs (``outputs.add(name, expression)``)."""
        cache_key = (self.model.robot.sha256, self.name, key)
        if cache_key not in _KERNELS:
            inputs, outputs = Packing(), Packing()
            build(self.model, inputs, outputs)
            name = "_".join(k for k in key if isinstance(k, str) and k)
            func = ca.Function(name, [inputs.vector()], [outputs.vector()], ["x"], ["y"])
            _KERNELS[cache_key] = Kernel(func, inputs, outputs, self.name)
        return _KERNELS[cache_key]


def make_backend(robot: Robot, kind: str, functions: tuple[str, ...] = ()) -> Backend:
    """A backend; ``c`` generates, compiles (double) and loads the named functions."""
    if kind not in BACKENDS:
        raise TaskFileError(f"backend {kind!r} is not one of {', '.join(BACKENDS)}")
    model = SymbolicModel(robot, ModelOptions(functions or None))
    if kind == "symbolic" or not functions:
        return Backend(kind, model, {name: model.function(name) for name in functions})
    from ..codegen.generate import CodegenConfig, generate, write  # SymPy-heavy: only for whole-model C

    references = model.functions()
    # The loaded library stays mapped after its folder is removed.
    with tempfile.TemporaryDirectory(prefix="armgen-backend-") as tmp:
        work = Path(tmp)
        code = generate(CodegenConfig(robot, "double", "", functions))
        write(code, work)
        library = build_library(work, code.prefix, "double", work)
        compiled = CompiledModel(library, code.prefix, references, "double")
    return Backend("c", model, dict(compiled.callbacks))
