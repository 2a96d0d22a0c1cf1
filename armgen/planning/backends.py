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

import functools
import hashlib
import json
import os
import pickle
import tempfile
from pathlib import Path
from typing import Callable

import casadi as ca
import numpy as np

from ..codegen import kernel_store
from ..codegen.api_kernel import KernelFunction, load_api_kernel
from ..codegen.compiled import CCallback, CompiledModel, NativeKernel, build_library
from ..errors import TaskFileError, excerpt
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

    def __init__(self, inputs: dict[str, slice], outputs: dict[str, slice], x: np.ndarray, y: np.ndarray,
                 evaluate: Callable[[], None], keep: object = None):
        self.inputs, self.outputs = inputs, outputs
        self.x, self.y, self._eval = x, y, evaluate
        self._keep = keep  # what ``evaluate`` needs alive (the CasADi buffer, the loaded library)

    @classmethod
    def symbolic(cls, func: ca.Function, inputs: dict[str, slice], outputs: dict[str, slice]) -> Kernel:
        x, y = np.zeros(func.nnz_in()), np.zeros(func.nnz_out())
        buffer, evaluate = func.buffer()
        buffer.set_arg(0, memoryview(x))
        buffer.set_res(0, memoryview(y))
        return cls(inputs, outputs, x, y, evaluate, (func, buffer))

    @classmethod
    def native(cls, native: NativeKernel, inputs: dict[str, slice], outputs: dict[str, slice]) -> Kernel:
        return cls(inputs, outputs, native.x, native.y, native, native)

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
        (``inputs.add(name, size)``) and outputs (``outputs.add(name, expression)``).

        ``key`` must name everything ``build`` depends on besides the robot. A kernel is composed
        once per process, and once per machine: it is kept on disk (see :func:`stored_kernel`)."""
        cache_key = (self.model.robot.sha256, self.name, key)
        if cache_key not in _KERNELS:
            _KERNELS[cache_key] = stored_kernel(self.model, self.name, key, build)
        return _KERNELS[cache_key]


# -- kernels kept on disk ----------------------------------------------------------------------
# Composing a kernel (deriving the model functions, inlining them, emitting its C to find the
# compiled library) takes ~0.5 s; loading it back takes ~15 ms. That difference is what every
# new process pays per kernel: each worker of a sweep, each `armgen plan`. A stored kernel is
# found by a digest of everything it is made from: the robot (its pickled description), the
# backend, the kernel key, and the code and libraries that compose it (armgen's sources,
# CasADi's and NumPy's versions), so an edited planner or model composes afresh.
KERNEL_STORE_FORMAT = 2


@functools.lru_cache(maxsize=1)
def _code_fingerprint() -> str:
    digest = hashlib.sha256(f"{KERNEL_STORE_FORMAT} {ca.__version__} {np.__version__}".encode())
    package = Path(__file__).resolve().parents[1]
    for path in sorted(package.rglob("*.py")):
        digest.update(str(path.relative_to(package)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _kernel_digest(robot: Robot, backend: str, key: tuple) -> str:
    robot_digest = hashlib.sha256(pickle.dumps(robot, protocol=4)).hexdigest()
    return hashlib.sha256(repr((_code_fingerprint(), robot_digest, backend, key)).encode()).hexdigest()[:32]


def stored_kernel(model: SymbolicModel, backend: str, key: tuple,
                  build: Callable[[SymbolicModel, Packing, Packing], None]) -> Kernel:
    """The kernel from the on-disk store (:func:`~armgen.codegen.kernel_store.store_dir`),
    composed and stored when missing.

    An entry is ``<name>-<digest>.json`` (the packing, the sizes, the compiled library's file
    name, the SHA-256 of each file it lists) beside ``<name>-<digest>.casadi`` (the serialised
    function); the JSON is written last, so a reader sees a whole entry or none. An entry that
    is unreadable, not this user's alone, names a library outside the store, holds anything
    but an SXFunction free of code-loading classes or whose files do not match their digests is never loaded: the
    kernel is composed again and the entry replaced."""
    name = "_".join(k for k in key if isinstance(k, str) and k)
    store = kernel_store.store_dir()
    stem = store / f"{name}-{_kernel_digest(model.robot, backend, key)}"
    stored = _load_entry(stem, backend)
    if isinstance(stored, Kernel):
        return stored
    if stored is None:
        packed_in, packed_out = Packing(), Packing()
        build(model, packed_in, packed_out)
        func = ca.Function(name, [packed_in.vector()], [packed_out.vector()], ["x"], ["y"])
        inputs, outputs = packed_in.slices, packed_out.slices
    else:  # the function is stored, its compiled library is gone
        func, inputs, outputs = stored
    native = NativeKernel(func, store) if backend == "c" else None
    entry = {"inputs": {k: [v.start, v.stop] for k, v in inputs.items()},
             "outputs": {k: [v.start, v.stop] for k, v in outputs.items()},
             "n_in": func.nnz_in(), "n_out": func.nnz_out(),
             "library": native.library.name if native is not None else None,
             "library_sha256": native.sha256 if native is not None else None}
    try:
        with tempfile.TemporaryDirectory(prefix="armgen-store-", dir=store) as work:
            func.save(str(Path(work) / "f.casadi"))
            entry["function_sha256"] = kernel_store.seal(Path(work) / "f.casadi")
            Path(work, "f.json").write_text(json.dumps(entry), encoding="utf-8")
            kernel_store.seal(Path(work) / "f.json")
            os.replace(Path(work) / "f.casadi", stem.with_suffix(".casadi"))
            os.replace(Path(work) / "f.json", stem.with_suffix(".json"))  # last: the entry is whole
        kernel_store.prune(store)
    except OSError:
        pass  # an unwritable store only costs the next process the composition
    return Kernel.native(native, inputs, outputs) if native is not None else Kernel.symbolic(func, inputs, outputs)


def _load_entry(stem: Path, backend: str) -> Kernel | tuple[ca.Function, dict, dict] | None:
    """The stored kernel; or its function and packing when its library is missing (or does not
    match its digest); or None when the entry is missing or not to be trusted."""
    text = kernel_store.read_trusted(stem.with_suffix(".json"))
    try:
        entry = json.loads(text) if text is not None else None
        inputs = {k: slice(*v) for k, v in entry["inputs"].items()}
        outputs = {k: slice(*v) for k, v in entry["outputs"].items()}
        library_name = entry["library"]
        if library_name is not None and not kernel_store.LIBRARY_NAME.fullmatch(library_name):
            return None  # a path, or a name this code never gives: not an entry of ours
        if backend == "c" and library_name is not None:
            library = stem.parent / library_name
            binary = kernel_store.read_trusted(library)
            if binary is not None and kernel_store.digest(binary) == entry["library_sha256"]:
                os.utime(stem.with_suffix(".json"))  # used now (with the file it loads): pruned last
                os.utime(library)
                return Kernel.native(NativeKernel.load(library, entry["n_in"], entry["n_out"]), inputs, outputs)
        serialised = kernel_store.read_trusted(stem.with_suffix(".casadi"))
        if (serialised is None or kernel_store.digest(serialised) != entry["function_sha256"]
                or not kernel_store.sx_function_text_loads_no_code(serialised)):
            return None
        func = ca.StringDeserializer(serialised.decode("ascii")).unpack()  # the bytes checked, not the file again
        if not isinstance(func, ca.Function) or func.class_name() != "SXFunction" or func.nnz_in() != entry["n_in"] or func.nnz_out() != entry["n_out"]:
            return None
        os.utime(stem.with_suffix(".json"))
        os.utime(stem.with_suffix(".casadi"))
    except (OSError, ValueError, KeyError, TypeError, AttributeError, RuntimeError):
        return None  # not stored yet, or a partial or foreign entry
    return Kernel.symbolic(func, inputs, outputs) if backend == "symbolic" else (func, inputs, outputs)


def make_backend(robot: Robot, kind: str, functions: tuple[str, ...] = ()) -> Backend:
    """A backend; ``c`` calls the named functions in the generated C (double): from the robot's
    compiled kernel (the library Robot's methods call, built once per robot in the kernel store,
    see :mod:`armgen.codegen.api_kernel`) when it holds them all, else generated, compiled and
    loaded for this backend."""
    if kind not in BACKENDS:
        raise TaskFileError(f"backend {excerpt(repr(kind))} is not one of {', '.join(BACKENDS)}")
    model = SymbolicModel(robot, ModelOptions(functions or None))
    if kind == "symbolic" or not functions:
        return Backend(kind, model, {name: model.function(name) for name in functions})
    kernel = load_api_kernel(Robot.from_description(robot).symbolic)
    if kernel is not None and set(functions) <= set(kernel.functions):
        return Backend("c", model,
                       {name: CCallback(KernelFunction(kernel, model.function(name))) for name in functions})
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
