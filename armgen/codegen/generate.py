"""C generation for a robot: ``make_consistent → generate → render → write``.

Produces ``<prefix>.h``, ``<prefix>.c`` and ``manifest.json``; their fixed C text is in the
templates ``armgen/data/templates/codegen/`` (filled by ``armgen.data.render_template``), Python
supplies the names, sizes and the emitted function bodies. Output is deterministic
(no timestamps, no absolute paths): regenerating gives byte-identical files, which the
tests and ``armgen verify`` check against the checked-in ``generated/<robot>/``.

API conventions (stated once in the header):
- matrices are column-major: element (r, c) of an R×C matrix M is ``M[r + R*c]``;
- vector inputs are fixed-size arrays, scalar inputs are passed by value, scalar outputs
  by pointer; outputs must not overlap inputs;
- the kinematic, criterion and dynamic functions cannot fail; the step functions return
  ``<P>_OK`` or ``<P>_NONFINITE`` (then the output holds a non-finite value: a non-finite
  input, or an overflow the damping could not prevent); ``<p>_ik`` returns ``<P>_OK``,
  ``<P>_NOT_CONVERGED`` (the closest configuration reached is in the outputs), ``<P>_NONFINITE``
  or ``<P>_BAD_TARGET`` (the target is not a pose, ``<p>_is_pose``: no step taken).
"""

from __future__ import annotations

import hashlib
import math
import json
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import sympy

from .._version import __version__
from ..data import render_template
from ..errors import OptionError, excerpt
from ..fileio import write_file_set
from ..description import RobotDescription, load_description
from ..symbolic.model import (DESCRIPTIONS, FROM_JACOBIAN, IK_FUNCTIONS, JACOBIAN_FUNCTIONS, STEP_FUNCTIONS,
                              ModelOptions, SymbolicModel)
from ..symbolic import ik
from ..symbolic.loops import find_loop
from .c_emitter import (MATH_MACROS, EmittedFunction, carried_entries, describe_counts, emit_body, emit_loop,
                        read_entries)
from .stamp import c_file, c_preamble, comment_safe

PRECISIONS = ("double", "float")
# Identifiers a prefix must not be (or, for the generated <prefix>_<name> and <PREFIX>_…
# names, must not collide with): the C99 keywords and the standard-library names that the
# generated code includes or that a caller's translation unit commonly does (math.h functions,
# the standard headers' own names).
C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto if inline int long "
    "register restrict return short signed sizeof static struct switch typedef union unsigned void volatile while "
    "_Bool _Complex _Imaginary".split())
STANDARD_NAMES = frozenset(
    "assert complex ctype errno fenv float inttypes iso646 limits locale math setjmp signal stdarg stdbool stddef "
    "stdint stdio stdlib string tgmath time wchar wctype "
    "sin cos tan asin acos atan atan2 sinh cosh tanh exp log log10 pow sqrt hypot fabs floor ceil fmod fmin fmax "
    "copysign round trunc nan isnan isfinite isinf signbit abs div exit free malloc calloc realloc printf main "
    "errno_t size_t ptrdiff_t null".split())
# Prefixes whose generated result code <PREFIX>_OK is a POSIX macro: <unistd.h>'s access() modes
# (F_OK, R_OK, W_OK, X_OK), which a caller's translation unit (Python.h among them) often includes.
POSIX_CLASHES = frozenset("f r w x".split())
# Outputs go where the user is: ./generated/<name>/ under the current directory (at the
# repository root that is the checked-in generated/).
GENERATED_DIR = Path("generated")


@dataclass(frozen=True)
class CodegenConfig:
    robot: RobotDescription
    precision: str = "double"  # the header's default; -D<P>_USE_FLOAT=0/1 overrides it
    prefix: str = ""  # default: the robot name
    functions: tuple[str, ...] | None = None  # default: all the robot supports


@dataclass
class GeneratedCode:
    prefix: str
    files: dict[str, str]  # file name -> text
    manifest: dict
    emitted: list[EmittedFunction] = field(default_factory=list)
    generation_seconds: float = 0.0


def make_consistent(config: CodegenConfig) -> CodegenConfig:
    """Fill defaults and validate the options; errors name the option and the fix."""
    if config.precision not in PRECISIONS:
        raise OptionError(f"--precision {excerpt(repr(config.precision))}: choose one of {', '.join(PRECISIONS)}")
    prefix = config.prefix or re.sub(r"[^0-9a-zA-Z_]", "_", config.robot.name).lower()
    if not re.fullmatch(r"[a-z_][a-z0-9_]{0,30}", prefix):
        raise OptionError(f"--prefix {excerpt(repr(prefix))}: use a C identifier in lower case of at most 31 characters "
                          "(letters, digits, _; not starting with a digit)")
    if prefix in C_KEYWORDS or prefix in STANDARD_NAMES:
        raise OptionError(f"--prefix {excerpt(repr(prefix))} is a C keyword or a standard-library name: choose another "
                          f"(e.g. --prefix {prefix}_arm)")
    if prefix in POSIX_CLASHES:
        raise OptionError(f"--prefix {excerpt(repr(prefix))}: the generated {prefix.upper()}_OK is a POSIX macro (<unistd.h>'s "
                          f"access() mode); choose a longer prefix (e.g. --prefix {prefix}_arm)")
    if prefix.startswith("_"):
        raise OptionError(f"--prefix {excerpt(repr(prefix))}: identifiers starting with '_' are reserved in C (the generated "
                          f"macros would be _<NAME>); start with a letter (e.g. --prefix arm{prefix})")
    return CodegenConfig(config.robot, config.precision, prefix, config.functions)


def _arg_decl(func: ca.Function, k: int, is_input: bool, model: SymbolicModel, p: str) -> tuple[str, bool]:
    sp = func.sparsity_in(k) if is_input else func.sparsity_out(k)
    name = func.name_in(k) if is_input else func.name_out(k)
    numel = sp.numel()
    if numel == 1:
        template = "codegen/input_scalar.c" if is_input else "codegen/output_scalar.c"
        return render_template(template, p=p, name=name), True
    if name == "xdot":
        size = f"{p.upper()}_NTASK"
    elif sp.size2() == 1 and numel == model.n:
        size = f"{p.upper()}_NDOF"
    else:
        size = str(numel)
    template = "codegen/input_array.c" if is_input else "codegen/output_array.c"
    return render_template(template, p=p, name=name, size=size), False


def _size_macros(func: ca.Function, P: str) -> list[str]:
    """<P>_<FUNCTION>_<ARGUMENT>_ROWS and _COLS of each matrix argument, inputs first."""
    blocks = []
    for is_input in (True, False):
        for k in range(func.n_in() if is_input else func.n_out()):
            sp = func.sparsity_in(k) if is_input else func.sparsity_out(k)
            name = (func.name_in(k) if is_input else func.name_out(k)).upper()
            if sp.numel() > 1:
                blocks.append(render_template("codegen/size_macros.h", P=P, function=func.name().upper(), argument=name,
                                              rows=sp.size1(), cols=sp.size2()))
    return blocks


def _finite_probe(values: list[str], p: str, P: str, loops: bool = False) -> str:
    """Statements folding each value into ``probe``: x * 0 is ±0 for a finite x and NaN for
    NaN/inf, and a NaN survives the sum, so ``probe == probe`` is 1 iff every value is finite.
    Straight-line by default (a load and a multiply-add per value on a Cortex-M4, no loop or
    call: a tick's step runs it). With ``loops``, a whole array (name[0] … name[n-1], n of at
    least PROBE_LOOP_MIN) is one loop: the q twins of the steps, which the firmware's ticks do
    not call (they take the *_from_jacobian twins), where the flash counts and a few
    instructions do not. The IK's stays straight-line: a loop cost ~50 M4 instructions a solve,
    which took iiwa14's 1 ms budget from 68 steps to 67."""
    body, k, looped = [], 0, False
    while k < len(values):
        match = re.fullmatch(r"(\w+)\[0\]", values[k]) if loops else None
        n = 1
        if match:
            while k + n < len(values) and values[k + n] == f"{match.group(1)}[{n}]":
                n += 1
        if n >= PROBE_LOOP_MIN:
            body.append(render_template("codegen/probe_array.c", P=P, count=n, array=match.group(1)))
            looped = True
            k += n
        else:
            body.append(render_template("codegen/probe_value.c", P=P, value=values[k]))
            k += 1
    start = render_template("codegen/probe_start_looped.c" if looped else "codegen/probe_start.c", p=p, P=P)
    return "\n".join([start, *body])


# The shortest array a looped probe scans by a loop (-Os: a loop of 4 is as long as 4 loads
# and multiply-adds, longer arrays are shorter as loops).
PROBE_LOOP_MIN = 4


def _values(names: list[str], scalars: list[bool], sizes: list[int], pointer: str) -> list[str]:
    """The C lvalues of every element of the named arguments (scalar outputs are pointers)."""
    out = []
    for name, scalar, size in zip(names, scalars, sizes):
        out += [f"{pointer}{name}"] if scalar else [f"{name}[{k}]" for k in range(size)]
    return out


def _status_check(func: ca.Function, arg_names: list[str], arg_scalar: list[bool], res_names: list[str],
                  res_scalar: list[bool], p: str, P: str) -> str:
    """The status of a step function: <P>_NONFINITE when an output is non-finite or an input
    value the function reads is. The probe scans every output, and those read inputs that
    may not reach one: an entry with a path to an output through arithmetic that carries a
    NaN/inf (c_emitter.carried_entries: J, ẋ, mask, α of the steps) shows there already, while
    one behind fmax, a comparison or a denominator (a weight, ε, the damping) is scanned. On
    the Cortex-M4 that halves a step's probe; tests/test_lean_c.py puts NaN/±inf in each
    carried entry in turn."""
    carried = carried_entries(func)
    values = []
    for k, (name, scalar) in enumerate(zip(arg_names, arg_scalar)):
        scanned = sorted(read_entries(func, k) - {e for i, e in carried if i == k})
        if scalar:
            values += [name] if scanned else []
        else:
            values += [f"{name}[{e}]" for e in scanned]
    values += _values(res_names, res_scalar, [func.sparsity_out(k).numel() for k in range(func.n_out())], "*")
    return render_template("codegen/status_check.c", P=P, probe=_finite_probe(values, p, P))


# The ik's cap on its steps inside its body: max_iterations, or 0 (no step) for a target that is
# not a pose. A local, so that the parameter is never written (MISRA 17.8).
IK_CAP = "iteration_cap"


def _ik_body(func: ca.Function, arg_names: list[str], arg_scalar: list[bool], res_names: list[str],
             res_scalar: list[bool], p: str, P: str) -> EmittedFunction:
    """<p>_ik: the pose check of T_target first (<p>_is_pose in the header); the solver's loop
    then runs with max_iterations, or with 0 for a target that is not a pose (it stops before
    its first step: the SX's initial state is stopped unless max_iterations >= 1). The status:
    <P>_BAD_TARGET for such a target; else <P>_NONFINITE when another input or an output is
    non-finite (a finite target is what the pose check passed, so the probe leaves it out);
    else <P>_OK when it converged (success = 1), else <P>_NOT_CONVERGED (the outputs hold the
    closest configuration reached)."""
    cap = arg_names.index("max_iterations")
    em = emit_body(func, [IK_CAP if k == cap else name for k, name in enumerate(arg_names)], arg_scalar, res_names,
                   res_scalar, P, trig_table=True)
    target = arg_names.index("T_target")
    probed = [name for k, name in enumerate(arg_names) if k != target]
    values = _values(probed, [s for k, s in enumerate(arg_scalar) if k != target],
                     [func.sparsity_in(k).numel() for k in range(func.n_in()) if k != target], "")
    values += _values(res_names, res_scalar, [func.sparsity_out(k).numel() for k in range(func.n_out())], "*")
    em.body = render_template("codegen/ik_body.c", p=p, P=P, cap=IK_CAP, body=em.body, probe=_finite_probe(values, p, P))
    return em


def _through_jacobian_body(func: ca.Function, twin: ca.Function, n: int, p: str, P: str) -> str:
    """The body of a function of J: J = <p>_jacobian(q), then the twin (same operations as the
    function's SX, which is the twin applied to jacobian(q)). A step's status also covers q: a
    non-finite q need not reach J (a prismatic joint's value only moves points)."""
    values = {"p": p, "P": P, "twin": twin.name(), "arguments": ", ".join(twin.name_in() + twin.name_out())}
    if func.name() in STEP_FUNCTIONS:
        probe = _finite_probe([f"q[{k}]" for k in range(n)], p, P, loops=True)
        return render_template("codegen/through_jacobian_step.c", **values, probe=probe)
    return render_template("codegen/through_jacobian.c", **values)


def generate(config: CodegenConfig) -> GeneratedCode:
    """Derive the model and render the C files (nothing is written)."""
    config = make_consistent(config)
    started = time.perf_counter()
    model = SymbolicModel(config.robot, ModelOptions(config.functions))
    functions = model.functions()
    p, P = config.prefix, config.prefix.upper()
    emitted: list[EmittedFunction] = []
    protos: list[str] = []
    definitions: list[str] = []
    for name, func in functions.items():
        arg_names = [func.name_in(k) for k in range(func.n_in())]
        res_names = [func.name_out(k) for k in range(func.n_out())]
        in_decls = [_arg_decl(func, k, True, model, p) for k in range(func.n_in())]
        out_decls = [_arg_decl(func, k, False, model, p) for k in range(func.n_out())]
        returns_status = name in STEP_FUNCTIONS or name in IK_FUNCTIONS
        signature = render_template("codegen/signature.c", returns=f"{p}_status" if returns_status else "void", p=p,
                                    function=name, parameters=", ".join(d for d, _ in in_decls + out_decls))
        if name in JACOBIAN_FUNCTIONS:
            twin = next(em for em in emitted if em.name == name + FROM_JACOBIAN)
            kinematics = next(em for em in emitted if em.name == "jacobian")
            em = EmittedFunction(name, _through_jacobian_body(func, functions[name + FROM_JACOBIAN], model.n, p, P),
                                 kinematics.op_counts + twin.op_counts, twin.work_reals + 6 * model.n)
            through = twin.name  # the twin it calls after <p>_jacobian
        elif name in IK_FUNCTIONS:
            em = _ik_body(func, arg_names, [s for _, s in in_decls], res_names, [s for _, s in out_decls], p, P)
            through = ""
        else:
            em = emit_body(func, arg_names, [s for _, s in in_decls], res_names, [s for _, s in out_decls], P,
                           trig_table=True)
            through = ""
            if returns_status:
                em.body += "\n" + _status_check(func, arg_names, [s for _, s in in_decls], res_names,
                                                 [s for _, s in out_decls], p, P)
        emitted.append(em)
        ops = describe_counts(em.op_counts)
        if through:
            doc = render_template("codegen/prototype_doc_through_jacobian.h", p=p, function=name, twin=through,
                                  description=DESCRIPTIONS[name], ops=ops, work_reals=em.work_reals)
            definition = render_template("codegen/definition_through_jacobian.c", p=p, function=name, twin=through,
                                         ops=ops, signature=signature, body=em.body)
        else:
            doc = render_template("codegen/prototype_doc.h", function=name, description=DESCRIPTIONS[name], ops=ops,
                                  work_reals=em.work_reals)
            definition = render_template("codegen/definition.c", function=name, ops=ops, signature=signature,
                                         body=em.body)
        protos.append("\n".join([doc, *_size_macros(func, P), render_template(
            "codegen/prototype.h", P=P, FUNCTION=name.upper(), work_reals=em.work_reals, signature=signature)]))
        definitions.append(definition)
    for loop_name in sorted({name for em in emitted for name in em.loops}):
        prototype, definition = emit_loop(find_loop(loop_name), P)
        protos.append(render_template("codegen/loop_prototype.h", loop=loop_name, prototype=prototype))
        definitions.append(definition)
    robot = config.robot
    preamble = c_preamble(robot.source, robot.sha256,
                          render_template("codegen/robot_title.txt", robot=comment_safe(robot.name), dof=robot.n))
    source = c_file(preamble, render_template("codegen/robot.c", p=p, definitions="\n\n".join(definitions)))
    math = [m for m in MATH_MACROS if m in HEADER_MATH_MACROS or f"{P}_{m}(" in source]
    header = _render_header(config, model, protos, preamble, math)
    files = {f"{p}.h": header, f"{p}.c": source}
    manifest = {
        "generator": f"armgen {__version__}",
        "robot": {"name": robot.name, "file": robot.source, "sha256": robot.sha256, "dof": robot.n,
                  "task_rows": list(robot.task_rows)},
        "versions": {"armgen": __version__, "casadi": ca.__version__, "sympy": sympy.__version__},
        "options": {"precision": config.precision, "prefix": p, "functions": list(functions)},
        "functions": {em.name: {"op_counts": dict(sorted(em.op_counts.items())), "flops": em.flops,
                                "work_reals": em.work_reals} for em in emitted},
        "files": {name: hashlib.sha256(text.encode()).hexdigest() for name, text in sorted(files.items())},
    }
    files["manifest.json"] = json.dumps(manifest, indent=2) + "\n"
    return GeneratedCode(p, files, manifest, emitted, time.perf_counter() - started)


# The bounded-range sine/cosine of the float build: 3-part Cody–Waite reduction by π/2 (the
# Cephes constants; exact products for |k| < 2^16) and Cephes' minimax polynomials on
# [−π/4, π/4]. Documented (and tested in tests/test_lean_c.py) error bound and range:
BOUNDED_TRIG_ULP = 2
BOUNDED_TRIG_RANGE = 100
# The bounded atan2 of the same switch (one division, Cephes' atanf polynomial on |u| ≤ tan π/8,
# octant and quadrant by selects): its documented (and tested) error bound, for any finite
# (y, x); results below 2⁻¹⁰ rad in ulp(2⁻¹⁰). Cephes gives its polynomial a peak relative error
# of 1.9e-7; 3.03 ulp is the largest seen (near atan2 = 0.5, where the reduction by tan π/8 starts).
BOUNDED_ATAN2_ULP = 4


def _lean_math(p: str, P: str, math: list[str]) -> str:
    """Static inline math of the generated header (also used by the firmware through <P>_SQRT …):
    fmin/fmax (C99 semantics: a NaN operand yields the other) need no library call; sqrt is the
    FPU's vsqrt.f32 on a Cortex-M with a single-precision FPU (no errno path); the float floor
    (when the source calls floor) by a conversion to an integer, exact (the call and its spills
    cost more than the arithmetic on a Cortex-M4F); the optional branch-free bounded-range
    sin/cos, and the sin/cos table the kinematics fill first. Everything else goes to libm."""
    blocks = [render_template("codegen/lean_math.h", p=p, P=P)]
    if "FLOOR" in math:
        blocks.append(render_template("codegen/floorf.h", p=p, P=P))
    blocks.append(render_template("codegen/trig.h", p=p, P=P, trig_range=BOUNDED_TRIG_RANGE, atan2_ulp=BOUNDED_ATAN2_ULP))
    return "\n".join(blocks)


def _speed_limit_macros(robot, P: str) -> str:
    """``<P>_QDLIM`` / ``<P>_QDDLIM``: the joints' speed limits (SI: rad/s or m/s, per s²) as array
    initialisers, ``static const {p}_real qdlim[{P}_NDOF] = {P}_QDLIM;``. A limit the robot file
    does not give for every joint is left out (a comment says so) rather than stood in for by a
    number the drive does not have."""
    blocks = []
    for macro, values, quantity, per in (("QDLIM", robot.qdlim, "velocity", "s"),
                                         ("QDDLIM", robot.qddlim, "acceleration", "s^2")):
        if all(math.isfinite(v) for v in values):
            limits = ", ".join(render_template("codegen/literal.c", P=P, value=repr(float(v))) for v in values)
            blocks.append(render_template("codegen/speed_limits.h", P=P, macro=macro, quantity=quantity, per=per,
                                          limits=limits))
        else:
            blocks.append(render_template("codegen/no_speed_limits.h", P=P, macro=macro, quantity=quantity))
    return "\n".join(blocks)


# The math macros every header defines: sin and cos (the header's own sin/cos table) and what
# the firmware stub reads through them (ctrl_robot.h: SIN, COS, SQRT, FABS). Any other is
# defined only when the generated source calls it (MISRA 2.5: no unused macro).
HEADER_MATH_MACROS = ("SIN", "COS", "SQRT", "FABS")


def _pose_check(p: str, P: str) -> str:
    """``<p>_is_pose`` and its tolerance ``<P>_POSE_TOL`` (armgen.symbolic.ik.POSE_TOL, the
    float build's FLOAT_POSE_TOL): the target check of ``<p>_ik``, the same conditions as the
    Python side's ``ik.check_targets``."""
    return render_template("codegen/pose_check.h", p=p, P=P, pose_tolerance=repr(ik.POSE_TOL),
                           float_pose_tolerance=repr(ik.FLOAT_POSE_TOL))


def _render_header(config: CodegenConfig, model: SymbolicModel, protos: list[str], preamble: str,
                   math: list[str]) -> str:
    p, P = config.prefix, config.prefix.upper()
    lean = {"FMIN": f"{p}_fmin", "FMAX": f"{p}_fmax", "SQRT": f"{p}_sqrt"}
    lean_float = lean | {"FLOOR": f"{p}_floorf"}
    trig = ["SIN", "COS", *(["ATAN2"] if "ATAN2" in math else [])]

    def macros(functions: dict[str, str]) -> str:
        return "\n".join(render_template("codegen/math_macro.h", P=P, macro=m, function=f) for m, f in functions.items())

    # a blank line either side of the pose check, which only an arm with the IK has
    pose_check = "\n" + _pose_check(p, P) + "\n" if any(name in IK_FUNCTIONS for name in model.selected()) else ""
    body = render_template(
        "codegen/robot.h", p=p, P=P, ndof=model.n, ntask=model.m, robot_sha256=config.robot.sha256,
        float_default=1 if config.precision == "float" else 0, trig_ulp=BOUNDED_TRIG_ULP, trig_range=BOUNDED_TRIG_RANGE,
        atan2_ulp=BOUNDED_ATAN2_ULP,
        float_math_macros=macros({m: lean_float.get(m, m.lower() + "f") for m in math if m not in ("SIN", "COS", "ATAN2")}),
        bounded_trig_macros=macros({m: f"{p}_{m.lower()}_bounded" for m in trig}),
        libm_trig_macros=macros({m: m.lower() + "f" for m in trig}),
        double_math_macros=macros({m: lean.get(m, m.lower()) for m in math}),
        speed_limits=_speed_limit_macros(config.robot, P), lean_math=_lean_math(p, P, math), pose_check=pose_check,
        prototypes="\n".join(protos))
    return c_file(preamble, body)


def write(code: GeneratedCode, out_dir: str | Path) -> list[Path]:
    out_dir = Path(out_dir)
    return write_file_set({out_dir / name: text for name, text in code.files.items()})


def generate_robot(robot: RobotDescription | str | Path, out_dir: str | Path | None = None, precision: str = "double",
                   prefix: str = "", functions: tuple[str, ...] | None = None) -> tuple[GeneratedCode, list[Path]]:
    """Library entry of ``armgen gen``: default output is ``./generated/<robot>/``."""
    robot = robot if isinstance(robot, RobotDescription) else load_description(robot)
    code = generate(CodegenConfig(robot, precision, prefix, functions))
    target = Path(out_dir) if out_dir is not None else GENERATED_DIR / robot.name
    return code, write(code, target)
