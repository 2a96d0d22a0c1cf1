"""The compiled kernel behind the Python API (issue 41): a robot's generated C (double), built
once into a CPython extension module in the kernel store and called in-process, one call per
batch (the samples loop in C).

:func:`load_api_kernel` gives a robot's :class:`ApiKernel`, or None when the CasADi reference
is to be used instead: ``ARMGEN_KERNEL=reference`` asks for it, and it is the fallback when no
kernel can be built (no C compiler, no Python headers, a failed build or self-test), which one
warning says, once per process.

What is trusted follows :mod:`armgen.codegen.kernel_store`: an entry ``<prefix>_api-<digest>.json``
(the library's file name and SHA-256) beside the library ``<prefix>_api-<digest24>.so``, found
by a digest of everything the library is made from (armgen's sources and C templates, the
robot, the functions, the compiler and its flags, the Python ABI), read only when this user's
alone and loaded only when its bytes match the entry's digest. Loaded or just built, a library
is used only after it agrees with the CasADi reference on :data:`SELF_TEST_SAMPLES` seeded
configurations (:data:`REFERENCE_AGREEMENT`). It is built in a private folder of the store and
moved into place by ``os.replace`` (the entry last): processes building the same kernel at once
each leave a whole file, and a reader sees a whole entry or none.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.machinery
import importlib.util
import json
import os
import pickle
import re
import subprocess
import sys
import sysconfig
import tempfile
import warnings
from pathlib import Path
from types import ModuleType

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from ..data import render_template
from ..errors import ArmgenError, OptionError
from ..symbolic.model import SymbolicModel
from . import kernel_store
from .toolchain import STRICT_FLAGS, compile_shared, host_cc

# The functions the kernel holds: the Robot methods' (fk, jacobian, fk_jacobian, ik) and the
# criteria that Robot evaluates; what the robot lacks (a criterion of a robot without one) is left out.
API_FUNCTIONS = ("fk", "jacobian", "fk_jacobian", "ik", "zghal", "repetitive", "manipulability",
                 "joint_manipulability")
# The C prefix of the kernel's generated code: fixed (internal to the extension module), so any
# robot name builds (a robot called 'nan' would be a prefix armgen gen refuses).
C_PREFIX = "robot"
# ARMGEN_KERNEL selects the evaluator of the Robot methods: the compiled kernel (the default) or
# the CasADi reference.
KERNEL_ENV = "ARMGEN_KERNEL"
KERNEL_CHOICES = ("compiled", "reference")
# Bumped when the entry's layout or the extension's calling convention changes.
API_KERNEL_FORMAT = 1
# -O2: the kernel is built once per robot and machine, and every call after runs it.
# -ffp-contract=off: no fused multiply-add, so the C rounds each operation as CasADi's
# interpreter does (the same SX operations in the same order): the two agree to the bit.
OPTIMISATION = "-O2"
FLOATING_POINT_FLAGS = ("-ffp-contract=off",)
# The self-test: a kernel is used only when it agrees with the CasADi reference on this many
# seeded configurations (and one IK solve), when built and when loaded from the store.
SELF_TEST_SAMPLES = 4
SELF_TEST_SEED = 41
# How far the compiled double kernel may be from the CasADi reference, relative to
# max(1, |reference|): both evaluate the same SX operations in the same order in double without
# contraction, and call the same libm; they agree to the bit on the bundled robots. The bound
# leaves room for a libm or compiler that rounds a transcendental differently by an ulp, which
# ~10^3 dependent operations on values of order 1 keep below 1e-12.
REFERENCE_AGREEMENT = 1e-12
# The IK's iterations amplify an ulp of difference by the conditioning of each damped step: its
# joint values may differ by more than the kinematics' do, still far below the 1e-6 success tolerance.
IK_REFERENCE_AGREEMENT = 1e-9

_WARNED: list[str] = []  # the fallback's one line, said once per process
_LOADED: dict[str, ApiKernel] = {}  # kernels loaded and self-tested in this process, by digest


def kernel_choice() -> str:
    """The evaluator ``ARMGEN_KERNEL`` names (default ``compiled``); another value is an OptionError."""
    choice = os.environ.get(KERNEL_ENV, "compiled") or "compiled"
    if choice not in KERNEL_CHOICES:
        raise OptionError(f"{KERNEL_ENV}={choice!r}: set it to one of {', '.join(KERNEL_CHOICES)} (or unset it)")
    return choice


class ApiKernel:
    """One robot's compiled functions: :meth:`fk`, :meth:`jacobian`, :meth:`fk_jacobian` and
    :meth:`evaluate` with the shapes of :class:`~armgen.symbolic.numeric.NumericModel`, and
    :meth:`ik` with the outputs of :func:`armgen.symbolic.ik.solve`."""

    def __init__(self, module: ModuleType, references: dict[str, ca.Function], n: int, name: str, qmid: np.ndarray):
        self._module = module
        self._references = references
        self._n = n
        self._robot_name = name
        self._fk, self._jacobian, self._fk_jacobian = module.fk, module.jacobian, module.fk_jacobian
        self.functions = tuple(references)
        self.qmid = qmid  # the IK's default rest configuration (a description property, computed on each access)
        self.qmid.flags.writeable = False

    # One configuration: a 1-D ndarray goes to the extension as it is, which takes it when it is
    # n contiguous float64 values (and raises ValueError or BufferError otherwise: then the
    # general path converts it, or names the wrong shape). These few checks are most of a call's
    # cost beside the C; the single-call paths below avoid every other one.
    _SINGLE_MISMATCH = (ValueError, BufferError)

    def fk(self, q: ArrayLike) -> np.ndarray:
        if type(q) is np.ndarray and q.ndim == 1:
            T = np.empty((4, 4))
            try:
                self._fk(1, q, T)
                return T.T  # column-major
            except self._SINGLE_MISMATCH:
                pass
        q, count, batch = self._samples(q)
        T = np.empty(batch + (4, 4))
        self._fk(count, q, T)
        return T.swapaxes(-1, -2)

    def jacobian(self, q: ArrayLike) -> np.ndarray:
        if type(q) is np.ndarray and q.ndim == 1:
            J = np.empty((self._n, 6))
            try:
                self._jacobian(1, q, J)
                return J.T
            except self._SINGLE_MISMATCH:
                pass
        q, count, batch = self._samples(q)
        J = np.empty(batch + (self._n, 6))
        self._jacobian(count, q, J)
        return J.swapaxes(-1, -2)

    def fk_jacobian(self, q: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        if type(q) is np.ndarray and q.ndim == 1:
            T, J = np.empty((4, 4)), np.empty((self._n, 6))
            try:
                self._fk_jacobian(1, q, T, J)
                return T.T, J.T
            except self._SINGLE_MISMATCH:
                pass
        q, count, batch = self._samples(q)
        T = np.empty(batch + (4, 4))
        J = np.empty(batch + (self._n, 6))
        self._fk_jacobian(count, q, T, J)
        return T.swapaxes(-1, -2), J.swapaxes(-1, -2)

    def _samples(self, q: ArrayLike) -> tuple[np.ndarray, int, tuple[int, ...]]:
        """``q`` as contiguous float64 samples, their count and the batch shape."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 0 or q.shape[-1] != self._n:
            raise ValueError(f"q must have shape ({self._n},) or (..., {self._n}) for robot '{self._robot_name}', "
                             f"got {q.shape}")
        batch = q.shape[:-1]
        return np.ascontiguousarray(q), int(np.prod(batch, dtype=int)), batch

    def evaluate(self, name: str, q: ArrayLike, **parameters: ArrayLike) -> dict[str, np.ndarray]:
        """Function ``name`` at ``q`` (``(n,)`` or ``(..., n)``), the other inputs by name,
        broadcast against the batch: the outputs by name, batch axes in front (NumericModel.evaluate)."""
        f = self._references[name]
        q, count, batch = self._samples(q)
        names_in = f.name_in()
        if set(parameters) != set(names_in[1:]):
            raise TypeError(f"{name}: inputs {names_in[1:]} expected, got {sorted(parameters)}")
        inputs = [q]
        for k, input_name in enumerate(names_in[1:], start=1):
            own = (f.nnz_in(k),) if f.nnz_in(k) > 1 else ()
            value = np.asarray(parameters[input_name], dtype=float)
            if value.shape != own:  # carries batch axes: one value per sample
                value = np.ascontiguousarray(np.broadcast_to(value, batch + own))
            inputs.append(np.ascontiguousarray(value))
        outputs = [np.empty(batch + (f.size_out(k)[1], f.size_out(k)[0])) for k in range(f.n_out())]
        getattr(self._module, name)(count, *inputs, *outputs)
        return {f.name_out(k): _unpacked(out, *f.size_out(k)) for k, out in enumerate(outputs)}

    def ik(self, targets: np.ndarray, seeds: np.ndarray, rest: np.ndarray, use_rest: float, tol_position: float,
           tol_orientation: float, max_iterations: int) -> list[np.ndarray]:
        """The generated ``<p>_ik`` on ``targets`` (B, 4, 4) from ``seeds`` (B, n) with
        ``rest`` (B, n): the outputs as :func:`armgen.symbolic.ik.solve` gives them, each (rows, B).
        The caller checks the targets (``ik.check_targets``)."""
        count = targets.shape[0]
        outputs = [np.empty((count, self._n))] + [np.empty(count) for _ in range(4)]
        self._module.ik(count, np.ascontiguousarray(targets.transpose(0, 2, 1)), np.ascontiguousarray(seeds),
                        np.ascontiguousarray(rest),
                        *_scalar_buffers(float(use_rest), float(tol_position), float(tol_orientation),
                                         float(max_iterations)), *outputs)
        return [outputs[0].T] + [out.reshape(1, count) for out in outputs[1:]]


@functools.lru_cache(maxsize=64)
def _scalar_buffers(*values: float) -> tuple[np.ndarray, ...]:
    """One read-only buffer per scalar input (the IK's settings: a few distinct ones per program)."""
    buffers = tuple(np.array([value]) for value in values)
    for buffer in buffers:
        buffer.flags.writeable = False
    return buffers


def _unpacked(value: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """An output allocated (..., cols, rows) (column-major samples): (..., rows, cols), (..., rows)
    for a column, (...) for a scalar."""
    if cols == 1:
        return value.reshape(value.shape[:-2] + (() if rows == 1 else (rows,)))
    return value.swapaxes(-1, -2)


# -- building, storing, loading ------------------------------------------------------------------

def load_api_kernel(model: SymbolicModel) -> ApiKernel | None:
    """The robot's compiled kernel (from this process, the store, or built now), or None for the
    CasADi reference: when ``ARMGEN_KERNEL=reference``, or when no kernel can be had (the reason
    is warned once per process)."""
    if kernel_choice() == "reference":
        return None
    try:
        references = {name: model.function(name) for name in API_FUNCTIONS if name in model.available()}
        digest = _kernel_digest(model, tuple(references))
        if digest in _LOADED:
            return _LOADED[digest]
        kernel = _stored(model, references, digest) or _built(model, references, digest)
    except (ArmgenError, OSError, ImportError, subprocess.SubprocessError) as exc:
        _warn_fallback(str(exc).splitlines()[0])
        return None
    _LOADED[digest] = kernel
    return kernel


def _warn_fallback(reason: str) -> None:
    if not _WARNED:
        _WARNED.append(reason)
        warnings.warn(f"armgen: the Robot methods run on the CasADi reference (slower), no compiled kernel: {reason}",
                      RuntimeWarning, stacklevel=4)


@functools.lru_cache(maxsize=1)
def _toolchain_identity() -> str:
    """The compiler (its path and version), the flags and the Python ABI the extension is built for."""
    cc = host_cc()
    version = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=60, check=True).stdout
    return repr((os.path.realpath(cc), version.splitlines()[:1], STRICT_FLAGS, OPTIMISATION, FLOATING_POINT_FLAGS,
                 sys.version, sysconfig.get_config_var("EXT_SUFFIX"), _python_include()))


def _python_include() -> str:
    include = sysconfig.get_paths()["include"]
    if not Path(include, "Python.h").is_file():
        raise ArmgenError(f"no Python.h in {include}: install the Python headers (apt-get install -y python3-dev)")
    return include


@functools.lru_cache(maxsize=1)
def _code_fingerprint() -> str:
    """armgen's Python sources and C templates: an edit to either builds the kernel afresh."""
    digest = hashlib.sha256(f"{API_KERNEL_FORMAT} {ca.__version__} {np.__version__}".encode())
    package = Path(__file__).resolve().parents[1]
    for path in sorted([*package.rglob("*.py"), *(package / "data" / "templates").rglob("*")]):
        if path.is_file():
            digest.update(str(path.relative_to(package)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _kernel_digest(model: SymbolicModel, functions: tuple[str, ...]) -> str:
    robot = hashlib.sha256(pickle.dumps(model.robot, protocol=4)).hexdigest()
    return hashlib.sha256(repr((_code_fingerprint(), _toolchain_identity(), robot, functions)).encode()).hexdigest()[:24]


def _names(model: SymbolicModel, digest: str) -> tuple[Path, Path, str]:
    """(entry, library, module name) of the kernel ``digest`` in the store (the files named
    after the robot, for whoever lists the store)."""
    stem = re.sub(r"[^A-Za-z0-9_]", "_", model.robot.name)[:60] + "_api"
    store = kernel_store.store_dir()
    return store / f"{stem}-{digest}.json", store / f"{stem}-{digest}.so", f"armgen_api_{digest}"


def _stored(model: SymbolicModel, references: dict[str, ca.Function], digest: str) -> ApiKernel | None:
    """The kernel from the store when its entry is trusted, its library matches the entry's
    digest and it passes the self-test; else None (the caller builds it)."""
    entry_path, library, module_name = _names(model, digest)
    text = kernel_store.read_trusted(entry_path)
    try:
        entry = json.loads(text) if text is not None else None
        if entry is None or entry["library"] != library.name or entry["module"] != module_name:
            return None
        binary = kernel_store.read_trusted(library)
        if binary is None or kernel_store.digest(binary) != entry["library_sha256"]:
            return None
        kernel = ApiKernel(_import(library, module_name), references, model.n, model.robot.name, model.robot.qmid)
    except (ValueError, KeyError, TypeError, ImportError, AttributeError):
        return None
    if not _agrees_with_reference(kernel, model):
        return None
    os.utime(entry_path)  # used now: pruned last
    os.utime(library)
    return kernel


def _built(model: SymbolicModel, references: dict[str, ca.Function], digest: str) -> ApiKernel:
    """Generate, compile, self-test and store the kernel."""
    from .generate import CodegenConfig, generate, write

    entry_path, library, module_name = _names(model, digest)
    store = library.parent
    with tempfile.TemporaryDirectory(prefix="armgen-api-", dir=store) as tmp:
        work = Path(tmp)
        code = generate(CodegenConfig(model.robot, "double", C_PREFIX, tuple(references)))
        write(code, work)
        glue = work / f"{code.prefix}_api.c"
        glue.write_text(extension_source(code.prefix, module_name, references), encoding="utf-8")
        built = compile_shared([work / f"{code.prefix}.c", glue], work / library.name,
                               defines=[f"{code.prefix.upper()}_USE_FLOAT=0"],
                               extra=[f"-I{work}", f"-I{_python_include()}", *FLOATING_POINT_FLAGS], opt=OPTIMISATION)
        sha256 = kernel_store.seal(built)
        kernel = ApiKernel(_import(built, module_name), references, model.n, model.robot.name, model.robot.qmid)
        if not _agrees_with_reference(kernel, model):
            raise ArmgenError(f"the compiled kernel of robot '{model.robot.name}' disagrees with the CasADi reference "
                              f"(beyond {REFERENCE_AGREEMENT:g}); please report it")
        try:
            os.replace(built, library)  # atomic: concurrent builders each leave a whole file
            (work / "entry.json").write_text(json.dumps({"format": API_KERNEL_FORMAT, "library": library.name,
                                                         "library_sha256": sha256, "module": module_name}),
                                             encoding="utf-8")
            kernel_store.seal(work / "entry.json")
            os.replace(work / "entry.json", entry_path)  # last: the entry is whole
        except OSError:
            pass  # an unwritable store only costs the next process the build
    return kernel


def _import(library: Path, module_name: str) -> ModuleType:
    """The extension module in ``library`` (loaded without entering ``sys.modules``)."""
    loader = importlib.machinery.ExtensionFileLoader(module_name, str(library))
    spec = importlib.util.spec_from_file_location(module_name, str(library), loader=loader)
    if spec is None:
        raise ImportError(f"{library}: not an extension module")
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


def extension_source(prefix: str, module_name: str, references: dict[str, ca.Function]) -> str:
    """C99 of the extension module: for each function ``f(count, inputs…, outputs…)``
    (api_kernel.c; buffers described there)."""
    entries, methods = [], []
    for name, f in references.items():
        sizes = [f.nnz_in(k) for k in range(f.n_in())] + [f.nnz_out(k) for k in range(f.n_out())]
        scalar_input = [k < f.n_in() and size == 1 for k, size in enumerate(sizes)]
        const = ["const " if k < f.n_in() else "" for k in range(len(sizes))]
        real = f"{prefix}_real"
        parameters = [f"{const[k]}{real} *a{k}, Py_ssize_t d{k}" for k in range(len(sizes))]
        arguments = [f"a{k}[s * d{k}]" if scalar_input[k] else f"a{k} + (s * d{k})" for k in range(len(sizes))]
        call = [f"({const[k]}{real} *)views[{k}].buf, strides[{k}]" for k in range(len(sizes))]
        names = ", ".join([*f.name_in(), *f.name_out()])
        entries.append(render_template("codegen/api_kernel_entry.c", p=prefix, P=prefix.upper(), function=name,
                                       parameters=", ".join(parameters), arguments=", ".join(arguments),
                                       arity=len(sizes), sizes=", ".join(map(str, sizes)), names=names,
                                       inputs=f.n_in(), call=", ".join(call)))
        methods.append(render_template("codegen/api_kernel_method.c", p=prefix, function=name, names=names))
    return render_template("codegen/api_kernel.c", p=prefix, P=prefix.upper(), module=module_name,
                           entries="\n\n".join(entries), methods="\n".join(methods)) + "\n"


def _agrees_with_reference(kernel: ApiKernel, model: SymbolicModel) -> bool:
    """Whether every function of ``kernel`` matches the CasADi reference on seeded samples
    (:data:`REFERENCE_AGREEMENT`) and one IK solve does (:data:`IK_REFERENCE_AGREEMENT`)."""
    rng = np.random.default_rng(SELF_TEST_SEED)
    robot = model.robot
    samples = rng.uniform(robot.qmin, robot.qmax, (SELF_TEST_SAMPLES, robot.n))
    for name in kernel.functions:
        if name == "ik":
            continue
        f = model.function(name)
        # the other inputs: seeded values of their sizes (a criterion's weights, delta, q_init)
        extra = {f.name_in(k): rng.uniform(0.1, 1.0, f.nnz_in(k)).reshape((f.nnz_in(k),) if f.nnz_in(k) > 1 else ())
                 for k in range(1, f.n_in())}
        compiled = kernel.evaluate(name, samples, **extra)
        for s, q in enumerate(samples):
            reference = f.call([q, *extra.values()])
            for k in range(f.n_out()):
                expected = np.asarray(reference[k].full()).reshape(compiled[f.name_out(k)][s].shape, order="F")
                if not _close(compiled[f.name_out(k)][s], expected, REFERENCE_AGREEMENT):
                    return False
    if "ik" in kernel.functions:
        from ..symbolic import ik

        target = np.asarray(model.function("fk")(samples[0]).full())[None]
        start = robot.qmid[None]
        arguments = (0.0, ik.TOL_POSITION, ik.TOL_ORIENTATION, ik.MAX_ITERATIONS)
        compiled = kernel.ik(target, start, start, *arguments)
        reference = [np.asarray(x.full()).reshape(-1, 1) for x in model.function("ik")(target[0], start[0], start[0],
                                                                                         *arguments)]
        return all(_close(c, r, IK_REFERENCE_AGREEMENT) for c, r in zip(compiled, reference))
    return True


def _close(value: np.ndarray, reference: np.ndarray, tolerance: float) -> bool:
    return value.shape == reference.shape and bool(np.all(np.abs(value - reference)
                                                          <= tolerance * np.maximum(1.0, np.abs(reference))))
