"""Load generated C back into Python: build a shared library with the strict flags, bind
each function with ctypes, and wrap it as a ``casadi.Callback`` so it is a CasADi
``Function`` with the same name, inputs and outputs as the symbolic one."""

from __future__ import annotations

import ctypes
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

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
