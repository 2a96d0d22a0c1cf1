"""Generated C: checked-in copy up to date, deterministic, strict-flag clean in both
precisions, sanitizer clean, no heap/printf, true single precision, and numerically equal
to the CasADi interpreter over 10 000 seeded samples per function."""

import json
import re
import subprocess
from pathlib import Path

import casadi as ca
import pytest
import sympy

from armgen.codegen.generate import CodegenConfig, generate, generate_robot
from armgen.codegen.toolchain import ARM_CPU_FLAGS, STRICT_FLAGS
from armgen.errors import ArmgenError
from armgen.robot import load_robot
from armgen.symbolic.model import SymbolicModel
from armgen.verification.compare import compare_model
from armgen.codegen.compiled import CompiledModel, build_library
from armgen.verification.harness import run_sanitized

from conftest import KINEMATIC_ROBOTS, require_tool

REPO_GENERATED_DIR = Path(__file__).resolve().parent.parent / "generated"  # the checked-in code

SAMPLES = 10_000
FORBIDDEN_SYMBOLS = {"malloc", "calloc", "realloc", "free", "printf", "fprintf", "puts"}
DOUBLE_LIBM = {"sin", "cos", "tan", "sqrt", "pow", "exp", "log", "fabs", "fmax", "fmin", "atan2", "hypot"}


@pytest.mark.parametrize("name", KINEMATIC_ROBOTS)
def test_checked_in_code_is_fresh(name, tmp_path):
    """Regenerate into a temp dir: byte-identical to generated/<robot>/ (update with
    `armgen gen <robot>`)."""
    recorded = json.loads((REPO_GENERATED_DIR / name / "manifest.json").read_text())["versions"]
    installed = {"casadi": ca.__version__, "sympy": sympy.__version__}
    # CasADi's simplifier shapes the code (3.8.0 and 3.8.1 already differ) and the manifest
    # records both versions: a byte comparison needs the ones generated/ was made with
    assert {k: recorded[k] for k in installed} == installed, (
        f"generated/{name} was made with {recorded}, this environment has {installed}: install those "
        f"versions, or regenerate with `armgen gen {name}` and review the diff")
    _, paths = generate_robot(name, tmp_path)
    for path in paths:
        checked_in = REPO_GENERATED_DIR / name / path.name
        assert checked_in.is_file(), f"{checked_in} missing: run `armgen gen {name}`"
        assert checked_in.read_bytes() == path.read_bytes(), f"{checked_in} is stale: run `armgen gen {name}`"


def test_generation_is_deterministic_and_stamped():
    robot = load_robot("planar3")
    a = generate(CodegenConfig(robot)).files
    b = generate(CodegenConfig(robot)).files
    assert a == b
    for name in ("planar3.h", "planar3.c"):
        head = a[name][:400]
        assert f"from planar3.toml (sha256 {robot.sha256})" in head and "Do not edit" in head
        assert not re.search(r"20\d\d-\d\d-\d\d", a[name]), "no timestamps in generated files"


def test_bad_options_are_rejected():
    robot = load_robot("planar3")
    with pytest.raises(ArmgenError, match="--prefix"):
        generate(CodegenConfig(robot, prefix="9bad"))
    with pytest.raises(ArmgenError, match="--precision"):
        generate(CodegenConfig(robot, precision="half"))


def _compile_object(src: Path, out: Path, define: str, cc="gcc", extra=()):
    subprocess.run([cc, *STRICT_FLAGS, "-O2", *extra, f"-D{define}", "-c", str(src), "-o", str(out)],
                   check=True, capture_output=True, text=True)
    return out


def _undefined_symbols(obj: Path, nm="nm") -> set[str]:
    out = subprocess.run([nm, "-u", str(obj)], check=True, capture_output=True, text=True).stdout
    return {line.split()[-1] for line in out.splitlines() if line.strip()}


@pytest.mark.parametrize("name", KINEMATIC_ROBOTS)
def test_strict_flags_and_symbols(name, tmp_path):
    src = REPO_GENERATED_DIR / name / f"{name}.c"
    P = name.upper()
    double_obj = _compile_object(src, tmp_path / "d.o", f"{P}_USE_FLOAT=0")
    float_obj = _compile_object(src, tmp_path / "f.o", f"{P}_USE_FLOAT=1")
    for obj in (double_obj, float_obj):
        assert not (_undefined_symbols(obj) & FORBIDDEN_SYMBOLS)
    # float really is single precision: no double libm entry points are referenced
    assert not (_undefined_symbols(float_obj) & DOUBLE_LIBM)
    # gcc may fuse sinf+cosf of one angle into sincosf (a glibc extension it knows)
    assert _undefined_symbols(float_obj) & {"sinf", "cosf", "sincosf"}


@pytest.mark.parametrize("name", ["modular8", "panda"])
def test_cortex_m4f_object_has_no_soft_double(name, tmp_path):
    arm_gcc = require_tool("arm-none-eabi-gcc")
    src = REPO_GENERATED_DIR / name / f"{name}.c"
    obj = _compile_object(src, tmp_path / "m4.o", f"{name.upper()}_USE_FLOAT=1", cc=arm_gcc,
                          extra=("-Os", *ARM_CPU_FLAGS))
    symbols = _undefined_symbols(obj, nm=require_tool("arm-none-eabi-nm"))
    assert not [s for s in symbols if s.startswith("__aeabi_d")], symbols
    assert not (symbols & FORBIDDEN_SYMBOLS)


FUSED_OPS = ("vfma.f32", "vfms.f32", "vfnma.f32", "vfnms.f32")


def test_only_the_float_ik_loop_fuses_multiply_adds(tmp_path):
    """The IK loop (Loop.fused_float) lets gcc contract a·b + c in the float build: on the
    Cortex-M4F its disassembly holds fused multiply-adds, no other function's does (ISO C keeps
    -ffp-contract=off), and the double build never asks for contraction."""
    arm_gcc = require_tool("arm-none-eabi-gcc")
    objdump = require_tool("arm-none-eabi-objdump")
    src = REPO_GENERATED_DIR / "panda" / "panda.c"
    obj = _compile_object(src, tmp_path / "m4.o", "PANDA_USE_FLOAT=1", cc=arm_gcc,
                          extra=(*ARM_CPU_FLAGS, "-ffunction-sections"))
    listing = subprocess.run([objdump, "-d", str(obj)], check=True, capture_output=True, text=True).stdout
    fused = {}
    for block in listing.split("\n\n"):
        header = re.search(r"<(\w+)>:", block)
        if header:
            fused[header.group(1)] = sum(block.count(op) for op in FUSED_OPS)
    ik_loop = [name for name in fused if name.startswith("panda_ik_step_") and name.endswith("_loop")]
    assert len(ik_loop) == 1 and fused[ik_loop[0]] > 0, fused
    assert sum(count for name, count in fused.items() if name != ik_loop[0]) == 0, fused
    double = subprocess.run(["gcc", "-E", "-DPANDA_USE_FLOAT=0", "-I", str(src.parent), str(src)], check=True,
                            capture_output=True, text=True).stdout
    assert "fp-contract" not in double


@pytest.mark.parametrize("precision", ["double", "float"])
@pytest.mark.parametrize("name", ["planar3", "modular8"])
def test_sanitizers_clean(name, precision):
    functions = SymbolicModel(load_robot(name)).functions()
    out = run_sanitized(REPO_GENERATED_DIR / name, name, functions, precision)
    assert out.startswith("ok")


@pytest.mark.slow
@pytest.mark.parametrize("precision", ["double", "float"])
@pytest.mark.parametrize("name", KINEMATIC_ROBOTS)
def test_compiled_matches_interpreter(name, precision, tmp_path):
    robot = load_robot(name)
    functions = SymbolicModel(robot).functions()
    lib = build_library(REPO_GENERATED_DIR / name, name, precision, tmp_path, batch=functions)
    compiled = CompiledModel(lib, name, functions, precision)
    report = compare_model(compiled, functions, robot, SAMPLES, seed=20261122)
    assert {r.name for r in report} == set(functions)
    for r in report:
        assert r.samples >= SAMPLES
        assert r.passed, f"{r.name} ({precision}): max error {r.max_error:.3g} > {r.bound:.3g} at sample {r.worst_sample}"


def test_callback_is_a_casadi_function(tmp_path):
    """The compiled function wrapped as casadi.Callback keeps the names and evaluates like
    the symbolic one inside a CasADi expression graph."""
    import casadi as ca
    import numpy as np

    robot = load_robot("planar3")
    functions = SymbolicModel(robot).functions()
    compiled = CompiledModel(build_library(REPO_GENERATED_DIR / "planar3", "planar3", "double", tmp_path),
                             "planar3", functions, "double")
    cb = compiled.function("fk_jacobian")
    assert cb.name_in() == ["q"] and cb.name_out() == ["T", "J"]
    q = ca.MX.sym("q", 3)
    graph = ca.Function("g", [q], [cb(q)[1] @ q])
    qv = np.array([0.3, -0.2, 0.5])
    expected = np.array(functions["jacobian"](qv)) @ qv
    np.testing.assert_array_equal(np.array(graph(qv)).ravel(), expected.ravel())


def test_checked_in_ptp_evaluator_is_fresh(tmp_path):
    from armgen.codegen.ptp_c import generate_ptp_evaluator

    for path in generate_ptp_evaluator(tmp_path):
        checked_in = REPO_GENERATED_DIR / "ptp" / path.name
        assert checked_in.is_file() and checked_in.read_bytes() == path.read_bytes(), \
            f"{checked_in} is stale or missing: run `armgen gen-ptp`"


def test_sanitizer_driver_catches_an_out_of_bounds_write_and_names_the_line(tmp_path):
    """The driver is built without debug information (it changes nothing the sanitizers
    check); a failing run is rebuilt with -g, so the error names the source line."""
    import shutil

    from armgen.errors import ToolchainError

    copy = tmp_path / "planar3"
    shutil.copytree(REPO_GENERATED_DIR / "planar3", copy)
    source = (copy / "planar3.c").read_text()
    head = "void planar3_fk(const planar3_real q[PLANAR3_NDOF], planar3_real T[16]) {"
    assert head in source
    (copy / "planar3.c").write_text(source.replace(head, head + " { volatile int k = 16; T[k] = T[0]; }", 1))
    functions = SymbolicModel(load_robot("planar3")).functions()
    with pytest.raises(ToolchainError, match=r"(?s)stack-buffer-overflow.*planar3\.c:\d+"):
        run_sanitized(copy, "planar3", functions, "double")


def test_loop_step_branches_keep_casadi_values_to_the_bit(tmp_path):
    """A loop step's selects become if/else blocks (c_emitter._branched): what one side alone
    reads moves into it, selects on one condition share a block, a lone if_else_zero is a
    select too, and the compiled loop gives CasADi's values bit for bit, signed zeros and NaN
    included (CasADi's if_else is if_else_zero(c, x) + if_else_zero(!c, y): −0 comes out +0)."""
    require_tool("gcc")
    import numpy as np

    from armgen.codegen.c_emitter import emit_loop_step
    from armgen.codegen.compiled import NativeKernel
    from armgen.symbolic.loops import find_loop, fixed_loop

    state, c = ca.SX.sym("state", 4), ca.SX.sym("c")
    taken = state[0] > c
    only_then = ca.floor(state[1] * 3.7) - ca.sqrt(ca.fabs(state[2]))  # read by the then sides only
    nxt = ca.vertcat(ca.if_else(taken, only_then, state[1] * state[2]),
                     ca.if_else(taken, only_then * state[3], state[2]),  # the same condition: one block
                     ca.if_else(state[1] < 0, ca.exp(state[3]) - state[1], 0),  # a lone if_else_zero
                     ca.if_else(state[2] > state[3], state[3], state[2]) * 0.5 + c)
    step = ca.Function("test_branched_step", [state, c], [nxt], ["state", "c"], ["next"])
    loop_call = fixed_loop(step, 3)
    x = ca.SX.sym("x", 5)
    func = ca.Function("branched", [x], [loop_call(x[:4], x[4])])
    body = emit_loop_step(find_loop("test_branched_step_loop"), "K").body
    assert "if (" in body and "else" in body
    floor_line = next(line for line in body.splitlines() if "K_FLOOR" in line)
    assert len(floor_line) - len(floor_line.lstrip()) > 4  # inside a branch, not at the step's top level
    # the step starts from one register per instruction; the emitted locals are shared again
    # (one local per instruction makes cppcheck's analysis of the IK step take minutes)
    locals_declared = len(set(re.findall(r"\bw\d+\b", body)))
    assert locals_declared < find_loop("test_branched_step_loop").step.n_instructions() / 2
    kernel = NativeKernel(func, tmp_path)
    rng = np.random.default_rng(5)
    special = [0.0, -0.0, np.nan, np.inf, -np.inf, 1e-300, -2.5]
    for trial in range(300):
        value = rng.normal(size=5) * 3
        if trial % 3 == 0:
            value[rng.integers(0, 5, 2)] = rng.choice(special, 2)
        kernel.x[:] = value
        kernel()
        expected = np.asarray(func(value)).ravel()
        np.testing.assert_array_equal(kernel.y, expected)
        assert np.array_equal(np.signbit(kernel.y), np.signbit(expected))
