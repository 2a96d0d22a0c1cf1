"""The compiled kernel (issue 41): generated C built into a CPython extension module in the
kernel store and called in-process, one call per batch (the samples loop in C).

One build serves every caller of the same C bytes: :func:`kernel_library` names a build by the
digest of what it is made from (the ``.c`` and ``.h`` bytes, the prefix, the precision, the
extension's entries, the compiler, its flags and the Python ABI), so the double build of a
robot's default generated code is at once the robot's API kernel (:func:`load_api_kernel`, what
``Robot.fk``, ``ik``, the criteria, dynamics and collision functions and the ``c`` planning
backend call) and the library ``armgen verify``'s callbacks stage checks for the folder that
``armgen gen`` wrote with its default options (the same bytes): built by whichever comes first,
taken from the store by the other (its SHA-256 checked; a mismatch is built again).

:func:`load_api_kernel` gives a robot's :class:`ApiKernel`, or None when the CasADi reference
is to be used instead: ``ARMGEN_KERNEL=reference`` asks for it, and it is the fallback when no
kernel can be built (no C compiler, no Python headers, a failed build or self-test), which one
warning says, once per process. Finding a robot's build without generating its C first (~0.5 s
for a 7-DOF arm) takes an entry ``<robot>_api-<digest>.json``, found by a digest of the robot's
description (but where it was read from), armgen's sources and templates and the toolchain,
read only when this user's alone: it names the build and its SHA-256, the functions'
signatures and the self-test. A build is used by the API only after it reproduces the CasADi
reference on :data:`SELF_TEST_SAMPLES` seeded inputs per function (:data:`REFERENCE_AGREEMENT`;
:func:`reference_cases`): when the entry is made, the reference is evaluated then and its
values recorded in the entry, so that loading runs the same self-test against them without
building a CasADi function (~2 ms rather than ~0.3 s, what a one-pose ``armgen ik`` would pay).
Builds and entries are made in private folders of the store and moved into place by
``os.replace`` (the entry last), so a reader sees a whole file or none; processes making the
same one take turns on a lock (:func:`~armgen.codegen.kernel_store.build_lock`).
"""

from __future__ import annotations

import dataclasses
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

# The C prefix of a robot's API kernel is armgen gen's default (the robot's name), so that its build
# is the one of the robot's default generated folder; a name that is no C prefix (a robot called
# 'nan', a C keyword) gets this one instead (only the extension module sees it).
FALLBACK_PREFIX = "robot"
# ARMGEN_KERNEL selects the evaluator of the Robot methods: the compiled kernel (the default) or
# the CasADi reference.
KERNEL_ENV = "ARMGEN_KERNEL"
KERNEL_CHOICES = ("compiled", "reference")
# Bumped when the entry's layout or the extension's calling convention changes.
API_KERNEL_FORMAT = 2
# -O1: as fast as -O2 on these straight-line functions (panda: fk_jacobian 0.81 µs a call from
# Python either way, the IK 4.7 against 5.1 µs a pose in a batch) for 30–40 % less compile time
# (modular8's whole C: 1.06 against 1.66 CPU-s), which every robot's first use and a cold
# `armgen verify` pay. The strict flags' warnings stay on (-Wmaybe-uninitialized runs from -O1;
# the firmware's cross builds compile the same C at -O2 with the same flags).
# -ffp-contract=off: no fused multiply-add, so the C rounds each operation as CasADi's
# interpreter does (the same SX operations in the same order): the two agree to the bit.
OPTIMISATION = "-O1"
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


@dataclasses.dataclass(frozen=True)
class Signature:
    """A function's inputs and outputs: (name, rows, cols) each, in order (column-major values)."""

    inputs: tuple[tuple[str, int, int], ...]
    outputs: tuple[tuple[str, int, int], ...]

    @classmethod
    def of(cls, f: ca.Function) -> Signature:
        return cls(tuple((f.name_in(k), *f.size_in(k)) for k in range(f.n_in())),
                   tuple((f.name_out(k), *f.size_out(k)) for k in range(f.n_out())))

    @classmethod
    def from_json(cls, value: dict) -> Signature:
        return cls(*(tuple((str(name), int(rows), int(cols)) for name, rows, cols in value[side])
                     for side in ("inputs", "outputs")))

    def sizes(self) -> list[int]:
        """Values per sample of each argument, inputs then outputs."""
        return [rows * cols for _, rows, cols in (*self.inputs, *self.outputs)]


class ApiKernel:
    """One robot's compiled functions: :meth:`fk`, :meth:`jacobian`, :meth:`fk_jacobian` and
    :meth:`evaluate` with the shapes of :class:`~armgen.symbolic.numeric.NumericModel`, and
    :meth:`ik` with the outputs of :func:`armgen.symbolic.ik.solve`."""

    def __init__(self, module: ModuleType, signatures: dict[str, Signature], n: int, name: str, qmid: np.ndarray):
        self._module = module
        self.signatures = signatures
        self._n = n
        self._robot_name = name
        self._fk, self._jacobian, self._fk_jacobian = module.fk, module.jacobian, module.fk_jacobian
        self.functions = tuple(signatures)
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
        signature = self.signatures[name]
        q, count, batch = self._samples(q)
        names_in = [input_name for input_name, _, _ in signature.inputs]
        if set(parameters) != set(names_in[1:]):
            raise TypeError(f"{name}: inputs {names_in[1:]} expected, got {sorted(parameters)}")
        inputs = [q]
        for input_name, rows, cols in signature.inputs[1:]:
            own = (rows * cols,) if rows * cols > 1 else ()
            value = np.asarray(parameters[input_name], dtype=float)
            if value.shape != own:  # carries batch axes: one value per sample
                value = np.broadcast_to(value, batch + own)
            inputs.append(np.ascontiguousarray(value))
        outputs = [np.empty(batch + (cols, rows)) for _, rows, cols in signature.outputs]
        getattr(self._module, name)(count, *inputs, *outputs)
        return {output_name: _unpacked(out, rows, cols)
                for (output_name, rows, cols), out in zip(signature.outputs, outputs)}

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


class KernelFunction:
    """One function of a kernel called one sample at a time with the calling convention of
    :class:`~armgen.codegen.compiled.CompiledFunction` (what :class:`~armgen.codegen.compiled.CCallback`
    wraps as a ``casadi.Function``): positional inputs, outputs as (rows, cols) matrices."""

    def __init__(self, kernel: ApiKernel, reference: ca.Function):
        self.reference = reference
        self.name = reference.name()
        self._call = getattr(kernel._module, self.name)
        self._signature = kernel.signatures[self.name]
        if Signature.of(reference) != self._signature:
            raise ArmgenError(f"{self.name}: the kernel's signature differs from the reference's; rebuild the kernel")

    def __call__(self, *args) -> list[np.ndarray]:
        if len(args) != len(self._signature.inputs):
            raise TypeError(f"{self.name} takes {len(self._signature.inputs)} inputs, got {len(args)}")
        inputs = [np.ascontiguousarray(np.asarray(value, dtype=float).reshape(-1, order="F")) for value in args]
        outputs = [np.empty(rows * cols) for _, rows, cols in self._signature.outputs]
        self._call(1, *inputs, *outputs)
        return [out.reshape((rows, cols), order="F") for out, (_, rows, cols) in zip(outputs, self._signature.outputs)]


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


# -- one build of generated C, shared by every caller of the same bytes --------------------------

# The extension's buffers per precision: (the buffer format the C checks, its NumPy type).
BUFFER_TYPES = {"double": ("d", np.float64), "float": ("f", np.float32)}


@dataclasses.dataclass(frozen=True)
class KernelLibrary:
    """One build of generated C (:func:`kernel_library`): the library file, its module and the
    signatures of the functions it holds, in one precision."""

    path: Path
    module: ModuleType
    precision: str
    signatures: dict[str, Signature]

    def batch(self, name: str, inputs: list[np.ndarray]) -> list[np.ndarray]:
        """Function ``name`` on ``n`` samples in one call: ``inputs[k]`` has shape ``(n, size_k)``
        (each row a sample's input, column-major); outputs ``(n, rows, cols)`` in double."""
        real = BUFFER_TYPES[self.precision][1]
        count = len(inputs[0])
        buffers = [np.ascontiguousarray(np.asarray(value, dtype=float).reshape(count, -1), dtype=real)
                   for value in inputs]
        outputs = [np.empty((count, rows * cols), dtype=real) for _, rows, cols in self.signatures[name].outputs]
        getattr(self.module, name)(count, *buffers, *outputs)
        return [out.astype(float).reshape(count, cols, rows).transpose(0, 2, 1)
                for out, (_, rows, cols) in zip(outputs, self.signatures[name].outputs)]


def kernel_library(sources: dict[str, bytes], prefix: str, precision: str, signatures: dict[str, Signature],
                   again: bool = False) -> tuple[KernelLibrary, bool]:
    """``<prefix>.c`` and ``<prefix>.h`` (``sources``: their bytes) built in ``precision`` with the
    batched entry of each function of ``signatures`` into an extension module, with the strict
    flags: the store's build of the same bytes, compiler, flags and entries when it holds one
    whose SHA-256 matches (and not ``again``), else built now and stored; and whether it was built now."""
    key = hashlib.sha256(repr((API_KERNEL_FORMAT, _toolchain_identity(), precision, prefix,
                               extension_source(prefix, "armgen_kernel", signatures, precision),
                               sorted(sources.items()))).encode()).hexdigest()
    module_name = f"armgen_kernel_{key[:24]}"  # the key names the module: the glue itself needs no key

    def build(folder: Path) -> Path:
        for name, data in sources.items():  # the bytes the key digests, whatever the caller's folder holds now
            (folder / name).write_bytes(data)
        glue = folder / f"{prefix}_kernel.c"
        glue.write_text(extension_source(prefix, module_name, signatures, precision), encoding="utf-8")
        return compile_shared([folder / f"{prefix}.c", glue], folder / f"{module_name}.so",
                              defines=[f"{prefix.upper()}_USE_FLOAT={int(precision == 'float')}"],
                              extra=[f"-I{folder}", f"-I{_python_include()}", *FLOATING_POINT_FLAGS], opt=OPTIMISATION)

    path, built = kernel_store.stored_file(f"kernel_{prefix}_{precision}", key, ".so", build, again)
    return KernelLibrary(path, _import(path, module_name), precision, signatures), built


def folder_sources(folder: Path, prefix: str) -> dict[str, bytes]:
    """The bytes :func:`kernel_library` builds from, of a folder ``armgen gen`` wrote."""
    return {name: (folder / name).read_bytes() for name in (f"{prefix}.c", f"{prefix}.h")}


# -- a robot's API kernel: found by the robot, self-tested ---------------------------------------

def load_api_kernel(model: SymbolicModel) -> ApiKernel | None:
    """The robot's compiled kernel (from this process, the store, or built now), or None for the
    CasADi reference: when ``ARMGEN_KERNEL=reference``, or when no kernel can be had (the reason
    is warned once per process)."""
    if kernel_choice() == "reference":
        return None
    try:
        digest = _kernel_digest(model)
        if digest in _LOADED:
            return _LOADED[digest]
        kernel = _stored(model, digest)
        if kernel is None:
            with kernel_store.build_lock(_entry_path(model, digest).with_suffix(".lock")):
                kernel = _stored(model, digest) or _built(model, digest)  # (another process's, meanwhile)
    # (a robot the generator cannot take, CasADi's RuntimeError, a failed compile or import: the
    # reference still evaluates it)
    except (ArmgenError, OSError, ImportError, subprocess.SubprocessError, ValueError, KeyError, RuntimeError) as exc:
        _warn_fallback(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        return None
    _LOADED[digest] = kernel
    return kernel


def _warn_fallback(reason: str) -> None:
    if not _WARNED:
        _WARNED.append(reason)
        warnings.warn(f"armgen: the Robot methods run on the CasADi reference (slower), no compiled kernel: {reason}",
                      RuntimeWarning, stacklevel=6)  # the caller of Robot.fk, jacobian, ik (through _kernel)


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
def code_fingerprint() -> str:
    """armgen's Python sources and C templates: an edit to either builds the kernel afresh."""
    digest = hashlib.sha256(f"{API_KERNEL_FORMAT} {ca.__version__} {np.__version__}".encode())
    package = Path(__file__).resolve().parents[1]
    for path in sorted([*package.rglob("*.py"), *(package / "data" / "templates").rglob("*")]):
        if path.is_file():
            digest.update(str(path.relative_to(package)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


# The description's fields that say where it was read from, not what it computes: the same arm
# read from another file (a copy, a test's temporary folder) shares the kernel.
PLACE_FIELDS = frozenset({"source", "sha256", "description", "units", "urdf", "path"})


def _kernel_digest(model: SymbolicModel) -> str:
    fields = {f.name: getattr(model.robot, f.name) for f in dataclasses.fields(model.robot)
              if f.name not in PLACE_FIELDS}
    robot = hashlib.sha256(pickle.dumps(fields, protocol=4)).hexdigest()
    identity = repr((code_fingerprint(), _toolchain_identity(), robot))
    return hashlib.sha256(identity.encode()).hexdigest()[:24]


def _entry_path(model: SymbolicModel, digest: str) -> Path:
    """The robot's entry in the store (named after the robot, for whoever lists the store)."""
    stem = re.sub(r"[^A-Za-z0-9_]", "_", model.robot.name)[:60] + "_api"
    return kernel_store.store_dir() / f"{stem}-{digest}.json"


def _stored(model: SymbolicModel, digest: str) -> ApiKernel | None:
    """The kernel from the store when the robot's entry is trusted, the build it names matches
    the entry's SHA-256 and reproduces the reference values the entry recorded; else None (the
    caller makes it). No CasADi function is built: the entry holds the signatures and the cases."""
    entry_path = _entry_path(model, digest)
    text = kernel_store.read_trusted(entry_path)
    try:
        entry = json.loads(text) if text is not None else None
        if (entry is None or entry["format"] != API_KERNEL_FORMAT
                or not kernel_store.LIBRARY_NAME.fullmatch(entry["library"])
                or not re.fullmatch(r"armgen_kernel_[0-9a-f]{24}", entry["module"])):
            return None
        library = entry_path.parent / entry["library"]
        binary = kernel_store.read_trusted(library)
        if binary is None or kernel_store.digest(binary) != entry["library_sha256"]:
            return None
        signatures = {name: Signature.from_json(value) for name, value in entry["signatures"].items()}
        kernel = ApiKernel(_import(library, entry["module"]), signatures, model.n, model.robot.name, model.robot.qmid)
        if not _reproduces(kernel, entry["self_test"]):
            return None
    except (ValueError, KeyError, TypeError, ImportError, AttributeError):
        return None
    os.utime(entry_path)  # used now: pruned last
    os.utime(library)
    return kernel


def _built(model: SymbolicModel, digest: str) -> ApiKernel:
    """Generate the robot's C as ``armgen gen`` does by default (double, every function), take its
    build from the store or build it (:func:`kernel_library`), self-test it against the CasADi
    reference evaluated now, and store the robot's entry."""
    code = _generated(model)
    functions = tuple(code.manifest["options"]["functions"])
    references = {name: model.function(name) for name in functions}
    signatures = {name: Signature.of(f) for name, f in references.items()}
    sources = {name: code.files[name].encode("utf-8") for name in (f"{code.prefix}.c", f"{code.prefix}.h")}
    library, _ = kernel_library(sources, code.prefix, "double", signatures)
    cases = reference_cases(model, references)
    kernel = ApiKernel(library.module, signatures, model.n, model.robot.name, model.robot.qmid)
    if not _reproduces(kernel, cases):
        raise ArmgenError(f"the compiled kernel of robot '{model.robot.name}' disagrees with the CasADi reference "
                          f"(beyond {REFERENCE_AGREEMENT:g}); please report it")
    entry = {"format": API_KERNEL_FORMAT, "library": library.path.name,
             "library_sha256": kernel_store.digest(library.path.read_bytes()),
             "module": library.module.__name__,
             "signatures": {name: {"inputs": sig.inputs, "outputs": sig.outputs} for name, sig in signatures.items()},
             "self_test": cases}
    entry_path = _entry_path(model, digest)
    try:
        with tempfile.TemporaryDirectory(prefix="armgen-api-", dir=entry_path.parent) as tmp:
            staged = Path(tmp) / "entry.json"
            staged.write_text(json.dumps(entry), encoding="utf-8")
            kernel_store.seal(staged)
            os.replace(staged, entry_path)  # the entry appears whole
    except OSError:
        pass  # an unwritable store only costs the next process the generation
    return kernel


def _generated(model: SymbolicModel):
    """The robot's C as ``armgen gen`` writes it with its default options (the prefix is the robot's
    name, :data:`FALLBACK_PREFIX` for a name that is no C prefix)."""
    from .generate import CodegenConfig, generate, make_consistent

    try:
        config = make_consistent(CodegenConfig(model.robot))
    except OptionError:
        config = CodegenConfig(model.robot, prefix=FALLBACK_PREFIX)
    return generate(config)


def _import(library: Path, module_name: str) -> ModuleType:
    """The extension module in ``library`` (loaded without entering ``sys.modules``)."""
    loader = importlib.machinery.ExtensionFileLoader(module_name, str(library))
    spec = importlib.util.spec_from_file_location(module_name, str(library), loader=loader)
    if spec is None:
        raise ImportError(f"{library}: not an extension module")
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


def extension_source(prefix: str, module_name: str, signatures: dict[str, Signature], precision: str) -> str:
    """C99 of the extension module: for each function ``f(count, inputs…, outputs…)`` on buffers
    of the precision's type (api_kernel.c; buffers described there)."""
    entries, methods = [], []
    for name, signature in signatures.items():
        sizes = signature.sizes()
        n_in = len(signature.inputs)
        scalar_input = [k < n_in and size == 1 for k, size in enumerate(sizes)]
        const = ["const " if k < n_in else "" for k in range(len(sizes))]
        real = f"{prefix}_real"
        parameters = [f"{const[k]}{real} *a{k}, Py_ssize_t d{k}" for k in range(len(sizes))]
        arguments = [f"a{k}[s * d{k}]" if scalar_input[k] else f"a{k} + (s * d{k})" for k in range(len(sizes))]
        call = [f"({const[k]}{real} *)views[{k}].buf, strides[{k}]" for k in range(len(sizes))]
        names = ", ".join(argument for argument, _, _ in (*signature.inputs, *signature.outputs))
        entries.append(render_template("codegen/api_kernel_entry.c", p=prefix, P=prefix.upper(), function=name,
                                       parameters=", ".join(parameters), arguments=", ".join(arguments),
                                       arity=len(sizes), sizes=", ".join(map(str, sizes)), names=names,
                                       inputs=n_in, call=", ".join(call)))
        methods.append(render_template("codegen/api_kernel_method.c", p=prefix, function=name, names=names))
    buffer_format, real_type = BUFFER_TYPES[precision]
    return render_template("codegen/api_kernel.c", p=prefix, P=prefix.upper(), module=module_name,
                           precision=precision, format=buffer_format, dtype=np.dtype(real_type).name,
                           entries="\n\n".join(entries), methods="\n".join(methods)) + "\n"


def reference_cases(model: SymbolicModel, references: dict[str, ca.Function]) -> dict[str, list[dict]]:
    """The self-test: per function, the CasADi reference's outputs on :data:`SELF_TEST_SAMPLES`
    seeded inputs (configurations inside the limits; every other input, a criterion's weights,
    a step's task velocity, a twin's J, in [0.1, 1]); the IK's on one pose (the FK of the first configuration, from the middle of the
    limits). Each case: ``inputs`` and ``outputs``, the flat column-major values of each argument."""
    rng = np.random.default_rng(SELF_TEST_SEED)
    robot = model.robot
    samples = rng.uniform(robot.qmin, robot.qmax, (SELF_TEST_SAMPLES, robot.n))
    arguments: dict[str, list[list[np.ndarray]]] = {}
    for name, f in references.items():
        if name == "ik":
            from ..symbolic import ik

            target = np.asarray(model.function("fk")(samples[0]).full())
            settings = [np.array([x]) for x in (0.0, ik.TOL_POSITION, ik.TOL_ORIENTATION, ik.MAX_ITERATIONS)]
            # (none when the robot's FK is not a pose, a base with det -1 built past the loader:
            # the C refuses such a target, which the CasADi function does not check, nor Robot.ik take)
            arguments[name] = [[target, robot.qmid, robot.qmid, *settings]] if _is_pose(target) else []
        else:
            # (shaped as the input: a matrix, such as a twin's J or a collision function's obstacle slots, too)
            arguments[name] = [[q if f.name_in(k) == "q" else
                                rng.uniform(0.1, 1.0, f.nnz_in(k)).reshape(f.size_in(k), order="F")
                                for k in range(f.n_in())] for q in samples]
    return {name: [{"inputs": [np.ravel(x, order="F").tolist() for x in inputs],
                    "outputs": [np.ravel(np.asarray(y.full()), order="F").tolist()
                                for y in references[name].call(inputs)]}
                   for inputs in cases]
            for name, cases in arguments.items()}


def _is_pose(target: np.ndarray) -> bool:
    from ..symbolic import ik

    try:
        ik.check_targets(target[None])
    except ValueError:
        return False
    return True


def _reproduces(kernel: ApiKernel, cases: dict[str, list[dict]]) -> bool:
    """Whether the kernel holds exactly the functions of ``cases`` and gives their outputs:
    within :data:`REFERENCE_AGREEMENT` (:data:`IK_REFERENCE_AGREEMENT` for the IK)."""
    if set(cases) != set(kernel.functions):
        return False
    for name, function_cases in cases.items():
        tolerance = IK_REFERENCE_AGREEMENT if name == "ik" else REFERENCE_AGREEMENT
        for case in function_cases:
            outputs = [np.empty(len(values)) for values in case["outputs"]]
            getattr(kernel._module, name)(1, *[np.array(values, dtype=float) for values in case["inputs"]], *outputs)
            if not all(_close(out, np.array(expected, dtype=float), tolerance)
                       for out, expected in zip(outputs, case["outputs"])):
                return False
    return True


def _close(value: np.ndarray, reference: np.ndarray, tolerance: float) -> bool:
    return value.shape == reference.shape and bool(np.all(np.abs(value - reference)
                                                          <= tolerance * np.maximum(1.0, np.abs(reference))))
