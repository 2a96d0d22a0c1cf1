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
from ..errors import ArmgenError

_CTYPE = {"double": ctypes.c_double, "float": ctypes.c_float}
_NPTYPE = {"double": np.float64, "float": np.float32}


def build_library(gen_dir: str | Path, prefix: str, precision: str, out_dir: str | Path | None = None,
                  opt: str = "-O2") -> Path:
    """Compile ``<gen_dir>/<prefix>.c`` into a shared library for the given precision."""
    gen_dir = Path(gen_dir)
    out_dir = Path(out_dir) if out_dir is not None else Path(tempfile.mkdtemp(prefix="armgen-lib-"))
    flag = 1 if precision == "float" else 0
    return compile_shared([gen_dir / f"{prefix}.c"], out_dir / f"lib{prefix}_{precision}.so",
                          defines=[f"{prefix.upper()}_USE_FLOAT={flag}"], opt=opt)


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


# -- one fused SX function as native code, called on NumPy buffers ---------------------------

def kernel_source(func: ca.Function, symbol: str) -> str:
    """C99 of a one-input, one-output dense SX function: ``void <symbol>(const double *x, double *y)``."""
    from ..symbolic.loops import find_loop
    from .c_emitter import MATH_MACROS, emit_body, emit_loop
    from .stamp import c_preamble

    em = emit_body(func, ["x"], [False], ["y"], [False], "K")
    loops = [emit_loop(find_loop(name), "K") for name in em.loops]
    macros = "\n".join(f"#define K_{m} {m.lower()}" for m in MATH_MACROS)
    helpers = "".join(f"{prototype}\n{definition}\n" for prototype, definition in loops)
    digest = hashlib.sha256((helpers + em.body).encode()).hexdigest()
    return (c_preamble(f"kernel {func.name()}", digest, f"armgen planner kernel {func.name()} "
                       f"({func.nnz_in()} inputs, {func.nnz_out()} outputs, {em.flops} flops)", "the planner")
            + "\n#include <math.h>\n\ntypedef double k_real;\n#define K_USE_FLOAT 0\n#define K_LIT(x) x\n" + macros
            + "\n\n" + helpers
            + f"void {symbol}(const k_real *x, k_real *y);\nvoid {symbol}(const k_real *x, k_real *y) {{\n"
            + em.body + "\n}\n")


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
