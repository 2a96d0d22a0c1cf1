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
  input, or an overflow the damping could not prevent).
"""

from __future__ import annotations

import hashlib
import json
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import sympy

from .. import __version__
from ..errors import OptionError
from ..fileio import write_file_set
from ..robot import Robot, load_robot_any
from ..symbolic.model import DESCRIPTIONS, STEP_FUNCTIONS, ModelOptions, SymbolicModel
from .c_emitter import MATH_MACROS, EmittedFunction, describe_counts, emit_body
from .stamp import c_preamble

PRECISIONS = ("double", "float")
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
        raise OptionError(f"--precision {config.precision!r}: choose one of {', '.join(PRECISIONS)}")
    prefix = config.prefix or re.sub(r"[^0-9a-zA-Z_]", "_", config.robot.name).lower()
    if not re.fullmatch(r"[a-z_][a-z0-9_]*", prefix):
        raise OptionError(f"--prefix {prefix!r}: use a C identifier in lower case (letters, digits, _; not starting with a digit)")
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
        em = emit_body(func, arg_names, [s for _, s in in_decls], res_names, [s for _, s in out_decls], P)
        emitted.append(em)
        returns_status = name in STEP_FUNCTIONS
        ret = f"{p}_status" if returns_status else "void"
        signature = f"{ret} {p}_{name}({', '.join(d for d, _ in in_decls + out_decls)})"
        doc = (f"/* {name}: {DESCRIPTIONS[name]}.\n"
               f" * ops: {describe_counts(em.op_counts)}; work: {em.work_reals} reals. */")
        protos.append("\n".join([doc, *_size_macros(func, P), f"#define {P}_{name.upper()}_WORK_REALS {em.work_reals}",
                                 signature + ";"]))
        body = em.body
        if returns_status:
            out = res_names[0]
            numel = func.sparsity_out(0).numel()
            body += (f"\n  {{\n    int k;\n    for (k = 0; k < {numel}; ++k) {{\n"
                     f"      if (!isfinite({out}[k])) return {P}_NONFINITE;\n    }}\n  }}\n  return {P}_OK;")
        definitions.append(f"/* {name}: {describe_counts(em.op_counts)} */\n{signature} {{\n{body}\n}}\n")
    robot = config.robot
    preamble = c_preamble(robot.source, robot.sha256, f"armgen kinematics of robot '{robot.name}' ({robot.n} DOF)")
    header = _render_header(config, model, protos, preamble)
    source = (f"{preamble}\n#include \"{p}.h\"\n\n#include <math.h>\n\n"
              "/* Every function below is straight-line code from the SX algorithm; w<k> are the\n"
              " * algorithm's work registers. Literals and math calls go through the precision macros. */\n\n"
              + "\n".join(definitions))
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


def _render_header(config: CodegenConfig, model: SymbolicModel, protos: list[str], preamble: str) -> str:
    p, P = config.prefix, config.prefix.upper()
    guard = f"{P}_H"
    float_default = 1 if config.precision == "float" else 0
    macros_f = "\n".join(f"#define {P}_{m} {m.lower()}f" for m in MATH_MACROS)
    macros_d = "\n".join(f"#define {P}_{m} {m.lower()}" for m in MATH_MACROS)
    return f"""{preamble}
#ifndef {guard}
#define {guard}

#ifdef __cplusplus
extern "C" {{
#endif

#define {P}_NDOF {model.n}  /* joints */
#define {P}_NTASK {model.m}  /* task-space rows used by criteria and steps */
#define {P}_ROBOT_SHA256 "{config.robot.sha256}"

/* The one precision switch: {P}_USE_FLOAT 1 is true single precision (sinf, f literals,
 * no promotion); 0 is double. The generator's default is below; -D{P}_USE_FLOAT=… overrides. */
#ifndef {P}_USE_FLOAT
#define {P}_USE_FLOAT {float_default}
#endif
#if {P}_USE_FLOAT
typedef float {p}_real;
#define {P}_LIT(x) x##f
{macros_f}
#else
typedef double {p}_real;
#define {P}_LIT(x) x
{macros_d}
#endif

/* Result of the functions that can fail. */
typedef enum {{
  {P}_OK = 0,        /* output is finite */
  {P}_NONFINITE = 1  /* output holds NaN/inf: a non-finite input, or an overflow */
}} {p}_status;

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
