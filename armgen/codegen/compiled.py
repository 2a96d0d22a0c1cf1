"""Load generated C back into Python: build a shared library with the strict flags, bind
each function with ctypes, and wrap it as a ``casadi.Callback`` so it is a CasADi
``Function`` with the same name, inputs and outputs as the symbolic one (the verifier's
view); and :class:`NativeKernel`, one fused SX function compiled and called by ctypes
straight on NumPy buffers (the planners' per-step call)."""

from __future__ import annotations

import ctypes
import hashlib
import os
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from .kernel_store import seal
from .toolchain import compile_shared
from ..data import render_template
from ..errors import ArmgenError

_CTYPE = {"double": ctypes.c_double, "float": ctypes.c_float}
_NPTYPE = {"double": np.float64, "float": np.float32}


def batch_source(prefix: str, references: dict[str, ca.Function]) -> str:
    """C99 of ``<prefix>_batch_<name>(n, inputs…, outputs…)`` for each function: the generated
    function called on ``n`` samples stored one after another (each column-major), so the
    verifier evaluates thousands of samples with one ctypes call. Verification harness only:
    compiled into the verifier's library (same strict flags), never part of the generated code."""
    p = prefix
    entries = []
    for name, f in references.items():
        ins = [f.sparsity_in(k).numel() for k in range(f.n_in())]
        outs = [f.sparsity_out(k).numel() for k in range(f.n_out())]
        params = [render_template("codegen/batch_input.c", p=p, k=k) for k in range(len(ins))] + \
                 [render_template("codegen/batch_output.c", p=p, k=k) for k in range(len(outs))]
        # sample s of each argument: a scalar input by value, an array by its first element
        args = [f"in{k}[s]" if size == 1 else f"in{k} + s * {size}L" for k, size in enumerate(ins)] + \
               [f"out{k} + s * {size}L" for k, size in enumerate(outs)]
        entries.append(render_template("codegen/batch_entry.c", p=p, function=name, parameters=", ".join(params),
                                       arguments=", ".join(args)))
    return render_template("codegen/batch.c", p=p, entries="\n\n".join(entries)) + "\n"


def build_library(gen_dir: str | Path, prefix: str, precision: str, out_dir: str | Path | None = None,
                  opt: str = "-O2", batch: dict[str, ca.Function] | None = None) -> Path:
    """Compile ``<gen_dir>/<prefix>.c`` into a shared library for the given precision; with
    ``batch`` (the functions' references) also the batched entries of :func:`batch_source`."""
    gen_dir = Path(gen_dir)
    out_dir = Path(out_dir) if out_dir is not None else Path(tempfile.mkdtemp(prefix="armgen-lib-"))
    flag = 1 if precision == "float" else 0
    sources = [gen_dir / f"{prefix}.c"]
    if batch:
        sources.append(out_dir / f"{prefix}_batch_{precision}.c")
        sources[-1].write_text(batch_source(prefix, batch), encoding="utf-8")
    return compile_shared(sources, out_dir / f"lib{prefix}_{precision}.so",
                          defines=[f"{prefix.upper()}_USE_FLOAT={flag}"], extra=[f"-I{gen_dir}"], opt=opt)


class CompiledFunction:
    """A generated C function called through ctypes with the symbolic function's signature."""

    def __init__(self, lib: ctypes.CDLL, prefix: str, reference: ca.Function, precision: str):
        self.reference = reference
        self.precision = precision
        self.name = reference.name()
        try:
            self._fn = getattr(lib, f"{prefix}_{self.name}")
        except AttributeError:
            raise ArmgenError(f"library has no function {prefix}_{self.name}; regenerate the C code") from None
        real = _CTYPE[precision]
        self._np = _NPTYPE[precision]
        self._in_scalar = [reference.sparsity_in(k).numel() == 1 for k in range(reference.n_in())]
        self._fn.argtypes = [real if s else ctypes.POINTER(real) for s in self._in_scalar] + \
                            [ctypes.POINTER(real)] * reference.n_out()
        self._fn.restype = ctypes.c_int  # status of the step functions; garbage for void ones, unused there
        self._out_shapes = [reference.sparsity_out(k).shape for k in range(reference.n_out())]
        self._batch = getattr(lib, f"{prefix}_batch_{self.name}", None)  # only in a library built with batch=
        if self._batch is not None:
            self._batch.argtypes = [ctypes.c_long] + [ctypes.c_void_p] * (reference.n_in() + reference.n_out())
            self._batch.restype = None

    def batch(self, inputs: list[np.ndarray]) -> list[np.ndarray]:
        """Evaluate ``n`` samples in one call: ``inputs[k]`` has shape ``(n, numel_k)`` (each row
        a sample's input, column-major); returns outputs of shape ``(n, rows, cols)``."""
        if self._batch is None:
            raise ArmgenError(f"{self.name}: the library has no batched entry; build it with build_library(batch=…)")
        n = len(inputs[0])
        bufs = [np.ascontiguousarray(np.asarray(a, dtype=float).reshape(n, -1), dtype=self._np) for a in inputs]
        outs = [np.zeros((n, r * c), dtype=self._np) for r, c in self._out_shapes]
        self._batch(n, *[b.ctypes.data for b in bufs], *[o.ctypes.data for o in outs])
        return [o.astype(float).reshape(n, c, r).transpose(0, 2, 1) for o, (r, c) in zip(outs, self._out_shapes)]

    def __call__(self, *args) -> list[np.ndarray]:
        if len(args) != len(self._in_scalar):
            raise TypeError(f"{self.name} takes {len(self._in_scalar)} inputs, got {len(args)}")
        c_args = []
        keep = []
        for value, scalar in zip(args, self._in_scalar):
            if scalar:
                c_args.append(float(np.asarray(value, dtype=float).reshape(-1)[0]))
            else:
                buf = np.ascontiguousarray(np.asarray(value, dtype=float).reshape(-1, order="F"), dtype=self._np)
                keep.append(buf)
                c_args.append(buf.ctypes.data_as(self._fn.argtypes[len(c_args)]))
        outs = [np.zeros(r * c, dtype=self._np) for r, c in self._out_shapes]
        self._fn(*c_args, *[o.ctypes.data_as(self._fn.argtypes[-1]) for o in outs])
        return [o.astype(float).reshape((r, c), order="F") for o, (r, c) in zip(outs, self._out_shapes)]


class CCallback(ca.Callback):
    """A compiled function as a CasADi Function (numeric evaluation only: no derivatives)."""

    def __init__(self, compiled: CompiledFunction):
        ca.Callback.__init__(self)
        self.compiled = compiled
        ref = compiled.reference
        self._ref = ref
        self.construct(ref.name(), {"enable_fd": False})

    def get_n_in(self):
        return self._ref.n_in()

    def get_n_out(self):
        return self._ref.n_out()

    def get_name_in(self, k):
        return self._ref.name_in(k)

    def get_name_out(self, k):
        return self._ref.name_out(k)

    def get_sparsity_in(self, k):
        return self._ref.sparsity_in(k)

    def get_sparsity_out(self, k):
        return self._ref.sparsity_out(k)

    def eval(self, args):
        return [ca.DM(o) for o in self.compiled(*[np.array(a) for a in args])]


class CompiledModel:
    """All generated functions of one library, as ctypes wrappers and CasADi callbacks."""

    def __init__(self, library: str | Path, prefix: str, references: dict[str, ca.Function], precision: str):
        self.library_path = Path(library)
        self._lib = ctypes.CDLL(str(self.library_path))
        self.precision = precision
        self.raw = {name: CompiledFunction(self._lib, prefix, ref, precision) for name, ref in references.items()}
        self.callbacks = {name: CCallback(fn) for name, fn in self.raw.items()}

    def function(self, name: str) -> ca.Function:
        return self.callbacks[name]

    def batch(self, name: str, inputs: list[np.ndarray]) -> list[np.ndarray]:
        """Function ``name`` on many samples in one call (:meth:`CompiledFunction.batch`)."""
        return self.raw[name].batch(inputs)


# -- one fused SX function as native code, called on NumPy buffers ---------------------------

def kernel_source(func: ca.Function, symbol: str) -> str:
    """C99 of a one-input, one-output dense SX function: ``void <symbol>(const double *x, double *y)``."""
    from ..symbolic.loops import find_loop
    from .c_emitter import MATH_MACROS, emit_body, emit_loop
    from .stamp import c_file, c_preamble

    em = emit_body(func, ["x"], [False], ["y"], [False], "K")
    helpers = [prototype + "\n" + definition
               for prototype, definition in (emit_loop(find_loop(name), "K") for name in em.loops)]
    macros = "\n".join(render_template("codegen/math_macro.h", P="K", macro=m, function=m.lower()) for m in MATH_MACROS)
    digest = hashlib.sha256(("".join(helper + "\n\n" for helper in helpers) + em.body).encode()).hexdigest()
    title = render_template("codegen/kernel_title.txt", function=func.name(), inputs=func.nnz_in(), outputs=func.nnz_out(),
                            flops=em.flops)
    entry = render_template("codegen/kernel_entry.c", symbol=symbol, body=em.body)
    return c_file(c_preamble(f"kernel {func.name()}", digest, title, "the planner"),
                  render_template("codegen/kernel.c", macros=macros, functions="\n\n".join([*helpers, entry])))


class NativeKernel:
    """``func`` (one dense input vector, one dense output vector) compiled to a shared library
    in the kernel store folder ``store`` and called by ctypes on two fixed NumPy buffers.

    It always compiles: a library already in the store is loaded only through :meth:`load`,
    after its entry's digest matched (see :mod:`armgen.codegen.kernel_store`)."""

    # -O1 keeps the compile of these long straight-line functions (tens of thousands of
    # statements for the wgpm clamp kernel) short; the first run pays it, later runs load the
    # stored library.
    def __init__(self, func: ca.Function, store: Path, opt: str = "-O1"):
        source = kernel_source(func, "armgen_kernel")
        key = hashlib.sha256((source + opt).encode()).hexdigest()[:24]
        library = store / f"{func.name()}-{key}.so"
        with tempfile.TemporaryDirectory(prefix="armgen-kernel-", dir=store) as work:
            c_file = Path(work) / f"{func.name()}.c"
            c_file.write_text(source, encoding="utf-8")
            built = compile_shared([c_file], Path(work) / library.name, opt=opt)
            self.sha256 = seal(built)
            os.replace(built, library)  # atomic: concurrent builders leave one complete file
        self._load(library, func.nnz_in(), func.nnz_out())

    @classmethod
    def load(cls, library: str | Path, n_in: int, n_out: int) -> NativeKernel:
        """A kernel compiled before (the ``library`` of an earlier instance), without its function."""
        kernel = cls.__new__(cls)
        kernel._load(Path(library), n_in, n_out)
        return kernel

    def _load(self, library: Path, n_in: int, n_out: int) -> None:
        self.library = library
        self._lib = ctypes.CDLL(str(library))
        self._fn = self._lib.armgen_kernel
        self._fn.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
        self._fn.restype = None
        self.x = np.zeros(n_in)
        self.y = np.zeros(n_out)
        self._args = (self.x.ctypes.data, self.y.ctypes.data)

    def __call__(self) -> None:
        self._fn(*self._args)
