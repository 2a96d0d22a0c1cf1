"""C generation for a robot: ``make_consistent → generate → render → write``.

Produces ``<prefix>.h``, ``<prefix>.c`` and ``manifest.json``. Output is deterministic
(no timestamps, no absolute paths): regenerating gives byte-identical files, which the
tests and ``armgen verify`` check against the checked-in ``generated/<robot>/``.

API conventions (stated once in the header):
- matrices are column-major: element (r, c) of an R×C matrix M is ``M[r + R*c]``;
- vector inputs are fixed-size arrays, scalar inputs are passed by value, scalar outputs
  by pointer; outputs must not overlap inputs;
- the kinematic and criterion functions cannot fail; the step functions return
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
from ..errors import OptionError, excerpt
from ..fileio import write_file_set
from ..robot import Robot, load_robot_any
from ..symbolic.model import (DESCRIPTIONS, FROM_JACOBIAN, IK_FUNCTIONS, JACOBIAN_FUNCTIONS, STEP_FUNCTIONS,
                              ModelOptions, SymbolicModel)
from ..symbolic import ik
from ..symbolic.loops import find_loop
from .c_emitter import (MATH_MACROS, EmittedFunction, carried_entries, describe_counts, emit_body, emit_loop,
                        read_entries)
from .stamp import c_preamble, comment_safe

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
# Outputs go where the user is: ./generated/<name>/ under the current directory (at the
# repository root that is the checked-in generated/).
GENERATED_DIR = Path("generated")


@dataclass(frozen=True)
class CodegenConfig:
    robot: Robot
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
    if prefix.startswith("_"):
        raise OptionError(f"--prefix {excerpt(repr(prefix))}: identifiers starting with '_' are reserved in C (the generated "
                          f"macros would be _<NAME>); start with a letter (e.g. --prefix arm{prefix})")
    return CodegenConfig(config.robot, config.precision, prefix, config.functions)


def _arg_decl(func: ca.Function, k: int, is_input: bool, model: SymbolicModel, p: str) -> tuple[str, bool]:
    sp = func.sparsity_in(k) if is_input else func.sparsity_out(k)
    name = func.name_in(k) if is_input else func.name_out(k)
    numel = sp.numel()
    if numel == 1:
        return (f"{p}_real {name}" if is_input else f"{p}_real *{name}"), True
    if name == "xdot":
        size = f"{p.upper()}_NTASK"
    elif sp.size2() == 1 and numel == model.n:
        size = f"{p.upper()}_NDOF"
    else:
        size = str(numel)
    return (f"const {p}_real {name}[{size}]" if is_input else f"{p}_real {name}[{size}]"), False


def _size_macros(func: ca.Function, P: str) -> list[str]:
    lines = []
    for is_input in (True, False):
        for k in range(func.n_in() if is_input else func.n_out()):
            sp = func.sparsity_in(k) if is_input else func.sparsity_out(k)
            name = (func.name_in(k) if is_input else func.name_out(k)).upper()
            if sp.numel() > 1:
                base = f"{P}_{func.name().upper()}_{name}"
                lines.append(f"#define {base}_ROWS {sp.size1()}")
                lines.append(f"#define {base}_COLS {sp.size2()}")
    return lines


def _finite_probe(values: list[str], p: str, P: str, loops: bool = False) -> list[str]:
    """Statements folding each value into ``probe``: x * 0 is ±0 for a finite x and NaN for
    NaN/inf, and a NaN survives the sum, so ``probe == probe`` is 1 iff every value is finite.
    Straight-line by default (a load and a multiply-add per value on a Cortex-M4, no loop or
    call: a tick's step runs it). With ``loops``, a whole array (name[0] … name[n-1], n of at
    least PROBE_LOOP_MIN) is one loop: the q twins of the steps, which the firmware's ticks do
    not call (they take the *_from_jacobian twins), where the flash counts and a few
    instructions do not. The IK's stays straight-line: a loop cost ~50 M4 instructions a solve,
    which took iiwa14's 1 ms budget from 68 steps to 67."""
    body, k = [], 0
    while k < len(values):
        match = re.fullmatch(r"(\w+)\[0\]", values[k]) if loops else None
        n = 1
        if match:
            while k + n < len(values) and values[k + n] == f"{match.group(1)}[{n}]":
                n += 1
        if n >= PROBE_LOOP_MIN:
            body.append(f"  for (entry = 0; entry < {n}; ++entry) {{ probe = probe + ({match.group(1)}[entry] * {P}_LIT(0.0)); }}")
            k += n
        else:
            body.append(f"  probe = probe + ({values[k]} * {P}_LIT(0.0));")
            k += 1
    looped = any(line.startswith("  for (entry") for line in body)
    return [*(["  int entry;"] if looped else []), f"  {p}_real probe = {P}_LIT(0.0);", *body]


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
    return "\n".join(["  {", *_finite_probe(values, p, P), f"  return (probe == probe) ? {P}_OK : {P}_NONFINITE;", "  }"])


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
    em.body = "\n".join([
        "  /* a target that is not a pose takes no step (the loop stops before its first) */",
        "  const int pose = " + f"{p}_is_pose(T_target);",
        f"  const {p}_real {IK_CAP} = (pose != 0) ? max_iterations : {P}_LIT(0.0);",
        em.body,
        f"  if (pose == 0) {{ return {P}_BAD_TARGET; }}",
        "  {", *_finite_probe(values, p, P), f"  if (probe != probe) {{ return {P}_NONFINITE; }}", "  }",
        f"  return (*success != {P}_LIT(0.0)) ? {P}_OK : {P}_NOT_CONVERGED;"])
    return em


def _through_jacobian_body(func: ca.Function, twin: ca.Function, n: int, p: str, P: str) -> str:
    """The body of a function of J: J = <p>_jacobian(q), then the twin (same operations as the
    function's SX, which is the twin applied to jacobian(q)). A step's status also covers q: a
    non-finite q need not reach J (a prismatic joint's value only moves points)."""
    call = f"{p}_{twin.name()}({', '.join(twin.name_in() + twin.name_out())})"
    lines = [f"  {p}_real J[6 * {P}_NDOF];"]
    if func.name() in STEP_FUNCTIONS:
        lines += [f"  {p}_status status;", f"  {p}_jacobian(q, J);", f"  status = {call};", "  {",
                  *_finite_probe([f"q[{k}]" for k in range(n)], p, P, loops=True),
                  f"  return (probe == probe) ? status : {P}_NONFINITE;", "  }"]
    else:
        lines += [f"  {p}_jacobian(q, J);", f"  {call};"]
    return "\n".join(lines)


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
        ret = f"{p}_status" if returns_status else "void"
        signature = f"{ret} {p}_{name}({', '.join(d for d, _ in in_decls + out_decls)})"
        if name in JACOBIAN_FUNCTIONS:
            twin = next(em for em in emitted if em.name == name + FROM_JACOBIAN)
            kinematics = next(em for em in emitted if em.name == "jacobian")
            em = EmittedFunction(name, _through_jacobian_body(func, functions[name + FROM_JACOBIAN], model.n, p, P),
                                 kinematics.op_counts + twin.op_counts, twin.work_reals + 6 * model.n)
            calls = f"calls {p}_jacobian and {p}_{twin.name}"
        elif name in IK_FUNCTIONS:
            em = _ik_body(func, arg_names, [s for _, s in in_decls], res_names, [s for _, s in out_decls], p, P)
            calls = ""
        else:
            em = emit_body(func, arg_names, [s for _, s in in_decls], res_names, [s for _, s in out_decls], P,
                           trig_table=True)
            calls = ""
            if returns_status:
                em.body += "\n" + _status_check(func, arg_names, [s for _, s in in_decls], res_names,
                                                 [s for _, s in out_decls], p, P)
        emitted.append(em)
        doc = (f"/* {name}: {DESCRIPTIONS[name]}.\n"
               f" * ops: {describe_counts(em.op_counts)}{' (' + calls + ')' if calls else ''}; "
               f"work: {em.work_reals} reals. */")
        protos.append("\n".join([doc, *_size_macros(func, P), f"#define {P}_{name.upper()}_WORK_REALS {em.work_reals}",
                                 signature + ";"]))
        definitions.append(f"/* {name}: {describe_counts(em.op_counts)}{'; ' + calls if calls else ''} */\n"
                           f"{signature} {{\n{em.body}\n}}\n")
    for loop_name in sorted({name for em in emitted for name in em.loops}):
        prototype, definition = emit_loop(find_loop(loop_name), P)
        protos.append(f"/* {loop_name}: a fixed-count loop the functions above call (not for direct use). */\n"
                      f"{prototype}")
        definitions.append(definition)
    robot = config.robot
    preamble = c_preamble(robot.source, robot.sha256,
                          f"armgen kinematics of robot '{comment_safe(robot.name)}' ({robot.n} DOF)")
    source = (f"{preamble}\n#include \"{p}.h\"\n\n#include <math.h>\n\n"
              "/* Every function below is straight-line code from the SX algorithm (fixed-count loops\n"
              " * are kept once, as for loops, at the end); w<k> are the algorithm's work registers.\n"
              " * Literals and math calls go through the precision macros. */\n\n"
              + "\n".join(definitions))
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
    floor = "" if "FLOOR" not in math else f"""#if {P}_USE_FLOAT
/* floor(x) by a conversion to an integer (exact: |x| >= 2^23 is already integral, and NaN,
 * inf and -0 are their own floor): no library call, whose spills cost more on a Cortex-M4F. */
static inline float {p}_floorf(float x) {{
  float r = x;
  if ((fabsf(x) < 8388608.0f) && (x != 0.0f)) {{
    const float t = (float)(long)x;
    if (t > x) {{
      r = t - 1.0f;
    }} else {{
      r = t;
    }}
  }}
  return r;
}}
#endif
"""
    return f"""/* Lean math (no library calls where the FPU or a comparison does the job). */
static inline {p}_real {p}_fmin({p}_real a, {p}_real b) {{ return ((a < b) || (b != b)) ? a : b; }}
static inline {p}_real {p}_fmax({p}_real a, {p}_real b) {{ return ((a > b) || (b != b)) ? a : b; }}
static inline {p}_real {p}_sqrt({p}_real x) {{
#if {P}_USE_FLOAT && defined(__GNUC__) && defined(__ARM_FP) && ((__ARM_FP & 4) != 0)
  {p}_real r;
  __asm__("vsqrt.f32 %0, %1" : "=t"(r) : "t"(x));
  return r;
#elif {P}_USE_FLOAT
  return sqrtf(x);
#else
  return sqrt(x);
#endif
}}
{floor}#if defined(__GNUC__)
#define {P}_TRIG_INLINE static inline __attribute__((always_inline))
#else
#define {P}_TRIG_INLINE static inline
#endif
#if {P}_USE_FLOAT && {P}_BOUNDED_TRIG
/* sin and cos of x without a branch, always inlined (gcc/clang) into the sin/cos table loop,
 * also at -Os: x = k pi/2 + r,
 * |r| <= pi/4, the polynomials of r, then the rotation by j pi/2 (j = k mod 4 in -2..2) as
 * exact factors a = cos(j pi/2), b = sin(j pi/2) in {{-1, 0, 1}}, so that a loop over angles
 * runs four lanes wide where the compiler vectorises (x86 SSE). |x| beyond {BOUNDED_TRIG_RANGE} rad is
 * outside the documented range; NaN/inf give NaN. */
{P}_TRIG_INLINE void {p}_sincos_bounded(float x, float *s, float *c) {{
  const float shifter = 12582912.0f; /* 1.5 * 2^23: adding it rounds to an integer */
  float k = (x * 0.636619772367581343f + shifter) - shifter;
  float r = ((x - k * 1.5703125f) - k * 4.837512969970703125e-4f) - k * 7.54978995489188216e-8f;
  float z = r * r;
  float sp = r + r * z * ((-1.9515295891e-4f * z + 8.3321608736e-3f) * z - 1.6666654611e-1f);
  float cp = 1.0f - 0.5f * z + z * z * ((2.443315711809948e-5f * z - 1.388731625493765e-3f) * z + 4.166664568298827e-2f);
  float j = k - 4.0f * ((k * 0.25f + shifter) - shifter);
  float aj = fabsf(j);
  float odd = aj * (2.0f - aj);                         /* 1 for j = +-1, else 0 */
  float a = (1.0f - odd) * (1.0f - aj * (aj - 1.0f));   /* 1, 0, -1 for |j| = 0, 1, 2 */
  float b = j * odd;
  *s = a * sp + b * cp;
  *c = a * cp - b * sp;
}}
/* A sin or cos outside the table (a solver's computed angle, the IK's seed and restarts): both
 * through one body, which -Os keeps out of line (inlined, each of the IK's took ~170 B of flash,
 * and separate sin and cos bodies ~240 B each). */
static inline float {p}_sincos_pick(float x, int want_cos) {{
  float s, c;
  {p}_sincos_bounded(x, &s, &c);
  return (want_cos != 0) ? c : s;
}}
static inline float {p}_sin_bounded(float x) {{ return {p}_sincos_pick(x, 0); }}
static inline float {p}_cos_bounded(float x) {{ return {p}_sincos_pick(x, 1); }}
/* atan2(y, x) without a library call (newlib's atan2f costs a call and its branches in a step
 * with a time budget, the IK's; the compiler's choice to inline or call: a call at -Os, ~10
 * instructions against ~120 B of flash per inlined copy): t = min(|x|, |y|)/max(|x|, |y|) in [0, 1], reduced above
 * tan(pi/8) by u = (t - 1)/(t + 1) (+ pi/4), Cephes' atanf polynomial of u, then the octant
 * and the quadrant by selects. Error <= {BOUNDED_ATAN2_ULP} ulp (tested); atan2(+-0, +-0) is 0 (libm: +-0
 * or +-pi); NaN or inf in give NaN. */
static inline float {p}_atan2_bounded(float y, float x) {{
  float ax = fabsf(x), ay = fabsf(y);
  float hi = (ay > ax) ? ay : ax;
  float lo = (ay > ax) ? ax : ay;
  float t = lo / ((hi > 0.0f) ? hi : 1.0f);
  float u = (t > 0.41421356237f) ? ((t - 1.0f) / (t + 1.0f)) : t;
  float z = u * u;
  float r = ((((8.05374449538e-2f * z) - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z - 3.33329491539e-1f) * z * u + u;
  r = (t > 0.41421356237f) ? (r + 0.785398163397f) : r;
  r = (ay > ax) ? (1.57079632679f - r) : r;
  r = (x < 0.0f) ? (3.14159265359f - r) : r;
  r = (y < 0.0f) ? (-r) : r;
  return r + 0.0f * (x + y); /* x + y is NaN or inf for a NaN or inf input: the product NaN */
}}
#endif
/* The sin and cos of a function's n angles, in one loop before its straight-line code (the
 * generated kinematics call it): branch-free bodies, so the loop vectorises where it can. */
{P}_TRIG_INLINE void {p}_sincos_table(const {p}_real *angle, {p}_real *s, {p}_real *c, int n) {{
  int i;
  for (i = 0; i < n; ++i) {{
#if {P}_USE_FLOAT && {P}_BOUNDED_TRIG
    {p}_sincos_bounded(angle[i], &s[i], &c[i]);
#else
    s[i] = {P}_SIN(angle[i]);
    c[i] = {P}_COS(angle[i]);
#endif
  }}
}}

"""


def _speed_limit_macros(robot, P: str) -> str:
    """``<P>_QDLIM`` / ``<P>_QDDLIM``: the joints' speed limits (SI: rad/s or m/s, per s²) as array
    initialisers, ``static const {p}_real qdlim[{P}_NDOF] = {P}_QDLIM;``. A limit the robot file
    does not give for every joint is left out (a comment says so) rather than stood in for by a
    number the drive does not have."""
    lines = []
    for name, values, what in (("QDLIM", robot.qdlim, "velocity"), ("QDDLIM", robot.qddlim, "acceleration")):
        if all(math.isfinite(v) for v in values):
            items = ", ".join(f"{P}_LIT({float(v)!r})" for v in values)
            lines.append(f"/* joint {what} limits, rad or m per s{'^2' if name == 'QDDLIM' else ''} */\n"
                         f"#define {P}_{name} {{ {items} }}")
        else:
            lines.append(f"/* no {P}_{name}: the robot file gives no joint {what} limit for every joint */")
    return "\n".join(lines)


# The math macros every header defines: sin and cos (the header's own sin/cos table) and what
# the firmware stub reads through them (ctrl_robot.h: SIN, COS, SQRT, FABS). Any other is
# defined only when the generated source calls it (MISRA 2.5: no unused macro).
HEADER_MATH_MACROS = ("SIN", "COS", "SQRT", "FABS")


def _pose_check(p: str, P: str) -> str:
    """``<p>_is_pose`` and its tolerance ``<P>_POSE_TOL`` (armgen.symbolic.ik.POSE_TOL, the
    float build's FLOAT_POSE_TOL): the target check of ``<p>_ik``, the same conditions as the
    Python side's ``ik.check_targets``."""
    return f"""
/* A pose for {p}_ik: T (4x4, column-major) with a finite position, last row 0 0 0 1 and a
 * rotation as its 3x3 part (R^T R = I, det R > 0), each entry of T(3, :) - [0 0 0 1] and of
 * R^T R - I within {P}_POSE_TOL: the default orientation tolerance in double; in float a
 * product of rotations already carries a few 1e-7 of rounding, hence the float IK tolerance.
 * 1 for a pose, 0 otherwise (NaN/inf fail every comparison). */
#if {P}_USE_FLOAT
#define {P}_POSE_TOL {P}_LIT({ik.FLOAT_POSE_TOL!r})
#else
#define {P}_POSE_TOL {P}_LIT({ik.POSE_TOL!r})
#endif
static inline int {p}_is_pose(const {p}_real T[16]) {{
  const {p}_real det = ((T[0] * ((T[5] * T[10]) - (T[6] * T[9]))) - (T[4] * ((T[1] * T[10]) - (T[2] * T[9])))) +
                       (T[8] * ((T[1] * T[6]) - (T[2] * T[5])));
  int pose = 1;
  int a;
  int b;
  if (!((det > {P}_LIT(0.0)) && ({P}_FABS(T[15] - {P}_LIT(1.0)) <= {P}_POSE_TOL))) {{ pose = 0; }}
  for (a = 0; a < 3; ++a) {{
    if (!(({P}_FABS(T[3 + (4 * a)]) <= {P}_POSE_TOL) && ((T[12 + a] * {P}_LIT(0.0)) == {P}_LIT(0.0)))) {{ pose = 0; }}
    for (b = a; b < 3; ++b) {{
      const {p}_real gram = (T[4 * a] * T[4 * b]) + (T[1 + (4 * a)] * T[1 + (4 * b)]) + (T[2 + (4 * a)] * T[2 + (4 * b)]);
      const {p}_real unit = (a == b) ? {P}_LIT(1.0) : {P}_LIT(0.0);
      if (!({P}_FABS(gram - unit) <= {P}_POSE_TOL)) {{ pose = 0; }}
    }}
  }}
  return pose;
}}
"""


def _render_header(config: CodegenConfig, model: SymbolicModel, protos: list[str], preamble: str,
                   math: list[str]) -> str:
    p, P = config.prefix, config.prefix.upper()
    guard = f"{P}_H"
    float_default = 1 if config.precision == "float" else 0
    lean = {"FMIN": f"{p}_fmin", "FMAX": f"{p}_fmax", "SQRT": f"{p}_sqrt"}
    lean_float = lean | {"FLOOR": f"{p}_floorf"}
    macros_f = "\n".join(f"#define {P}_{m} {lean_float.get(m, m.lower() + 'f')}" for m in math
                         if m not in ("SIN", "COS", "ATAN2"))
    atan2_bounded, atan2_libm = (f"\n#define {P}_ATAN2 {p}_atan2_bounded", f"\n#define {P}_ATAN2 atan2f") \
        if "ATAN2" in math else ("", "")
    macros_d = "\n".join(f"#define {P}_{m} {lean.get(m, m.lower())}" for m in math)
    return f"""{preamble}
#ifndef {guard}
#define {guard}

#ifdef __cplusplus
extern "C" {{
#endif

#define {P}_NDOF {model.n}  /* joints */
#define {P}_NTASK {model.m}  /* task-space rows used by criteria and steps */
#define {P}_ROBOT_SHA256 "{config.robot.sha256}"

/* The status probes (x * 0 is NaN only for NaN/inf), fmin/fmax and the Sturm counts rely on
 * IEEE 754 arithmetic, which -ffast-math / -ffinite-math-only give up. */
#if defined(__FAST_MATH__) || (defined(__FINITE_MATH_ONLY__) && (__FINITE_MATH_ONLY__ != 0))
#error "{p}.h needs IEEE 754 semantics: compile without -ffast-math and -ffinite-math-only"
#endif

/* The one precision switch: {P}_USE_FLOAT 1 is true single precision (sinf, f literals,
 * no promotion); 0 is double. The generator's default is below; -D{P}_USE_FLOAT=… overrides. */
#ifndef {P}_USE_FLOAT
#define {P}_USE_FLOAT {float_default}
#endif
/* {P}_BOUNDED_TRIG 1 (float only): sin/cos by the generated bounded-range polynomials
 * ({p}_sin_bounded/{p}_cos_bounded below: error <= {BOUNDED_TRIG_ULP} ulp for |x| <= {BOUNDED_TRIG_RANGE} rad,
 * tested; NaN/inf in give NaN out) instead of newlib's sinf/cosf, and atan2 by {p}_atan2_bounded
 * (<= {BOUNDED_ATAN2_ULP} ulp) instead of atan2f. Default 0. */
#ifndef {P}_BOUNDED_TRIG
#define {P}_BOUNDED_TRIG 0
#endif
#if {P}_USE_FLOAT
typedef float {p}_real;
#define {P}_LIT(x) x##f
{macros_f}
#if {P}_BOUNDED_TRIG
#define {P}_SIN {p}_sin_bounded
#define {P}_COS {p}_cos_bounded{atan2_bounded}
#else
#define {P}_SIN sinf
#define {P}_COS cosf{atan2_libm}
#endif
#else
typedef double {p}_real;
#define {P}_LIT(x) x
{macros_d}
#endif

#include <math.h>

{_speed_limit_macros(config.robot, P)}

{_lean_math(p, P, math)}/* Result of the functions that can fail. */
typedef enum {{
  {P}_OK = 0,             /* output is finite */
  {P}_NONFINITE = 1,      /* output holds NaN/inf: a non-finite input, or an overflow */
  {P}_NOT_CONVERGED = 2,  /* {p}_ik only: no q within the tolerances; the outputs hold the closest reached */
  {P}_BAD_TARGET = 3      /* {p}_ik only: T_target is not a pose ({p}_is_pose); no step taken */
}} {p}_status;
{_pose_check(p, P) if any(name in IK_FUNCTIONS for name in model.selected()) else ""}
/* Matrices are column-major: element (r, c) of an R x C matrix M is M[r + R*c].
 * Scalar inputs are passed by value, scalar outputs by pointer. Outputs must not overlap
 * inputs. No heap, no globals, reentrant; locals are the WORK_REALS scalars listed. */

{chr(10).join(protos)}

#ifdef __cplusplus
}}
#endif

#endif /* {guard} */
"""


def write(code: GeneratedCode, out_dir: str | Path) -> list[Path]:
    out_dir = Path(out_dir)
    return write_file_set({out_dir / name: text for name, text in code.files.items()})


def generate_robot(robot: Robot | str | Path, out_dir: str | Path | None = None, precision: str = "double",
                   prefix: str = "", functions: tuple[str, ...] | None = None) -> tuple[GeneratedCode, list[Path]]:
    """Library entry of ``armgen gen``: default output is ``./generated/<robot>/``."""
    robot = load_robot_any(robot)
    code = generate(CodegenConfig(robot, precision, prefix, functions))
    target = Path(out_dir) if out_dir is not None else GENERATED_DIR / robot.name
    return code, write(code, target)
