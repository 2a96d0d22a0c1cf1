"""Generated C of the dynamics (issue 39): for a robot with every link's inertial, `armgen gen`
emits <prefix>_gravity, _rnea, _mass_matrix and _coriolis after the kinematic functions, with
the kinematics' contract (fixed-size arrays of <PREFIX>_NDOF, no heap, true float under
<PREFIX>_USE_FLOAT), listed with their operation counts in the manifest; the C agrees with
the CasADi functions (double: to the bit in practice, bound 1e-12 relative; float: the
verifier's FLOAT_BOUNDS) and with Pinocchio, is sanitizer clean, and `armgen verify` compares
it; a robot without inertials gets none of it."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from armgen.cli.main import cli
from armgen.codegen.compiled import CompiledModel, build_library
from armgen.codegen.generate import CodegenConfig, generate, write
from armgen.codegen.toolchain import ARM_CPU_FLAGS, STRICT_FLAGS
from armgen.robot import Robot, load_robot
from armgen.symbolic.dynamics import DYNAMIC_FUNCTIONS
from armgen.symbolic.model import ALL_FUNCTIONS, SymbolicModel
from armgen.verification.compare import DOUBLE_REL_BOUND, FLOAT_BOUNDS, compare_model
from armgen.verification.harness import run_sanitized

from conftest import require_tool
from test_codegen import DOUBLE_LIBM, FORBIDDEN_SYMBOLS, REPO_GENERATED_DIR

SAMPLES = 5000
SEED = 20261127
# The C (double) against Pinocchio: the C is the CasADi graph op for op, which agrees with
# Pinocchio to 1e-10 relative (tests/test_dynamics.py's PEER_TOL, the bar).
PEER_TOL = 1e-10
PEER_SAMPLES = 200

# A 2R arm in a vertical plane with its inertials (docs/dynamics.md's example, in g and mm).
VERTICAL2 = """\
name = "vertical2"
convention = "standard"
gravity = [0, -9.81, 0]

[units]
length = "mm"
angle = "deg"
mass = "g"

[[joints]]
name = "shoulder"
type = "revolute"
a = 400
d = 0
alpha = 0
qlim = [-170, 170]
mass = 2000
com = [-200, 0, 0]
inertia = [1e5, 3e7, 3e7, 0, 0, 0]
motor_inertia = 1e5
taumax = 20

[[joints]]
name = "elbow"
type = "revolute"
a = 300
d = 0
alpha = 0
qlim = [-170, 170]
mass = 1000
com = [-100, 0, 0]
inertia = [5e4, 8e6, 8e6, 0, 0, 0]
taumax = 8
"""


def _panda_urdf() -> Path:
    from test_urdf import _example_robot_data_dir  # skips the tests that need it without Pinocchio

    return _example_robot_data_dir() / "panda_description/urdf/panda.urdf"


@pytest.fixture(scope="module")
def panda() -> Robot:
    """The Panda of example-robot-data: 7 joints, an inertial on every link."""
    robot = Robot.from_urdf(_panda_urdf(), tip_link="panda_hand")
    assert robot.n == 7 and robot.has_dynamics
    return robot


@pytest.fixture(scope="module")
def panda_dynamics_c(panda, tmp_path_factory) -> tuple[Path, dict]:
    """The Panda's dynamic functions generated alone (the kinematics are tested elsewhere)."""
    out = tmp_path_factory.mktemp("panda_dynamics")
    code = generate(CodegenConfig(panda, functions=DYNAMIC_FUNCTIONS))
    write(code, out)
    return out, code.manifest


def _write_vertical2(folder: Path) -> Path:
    path = folder / "vertical2.toml"
    path.write_text(VERTICAL2, encoding="utf-8")
    return path


def test_gen_emits_the_dynamics_after_the_kinematics(tmp_path):
    robot_file = _write_vertical2(tmp_path)
    out = CliRunner().invoke(cli, ["gen", str(robot_file), "-o", str(tmp_path / "gen")])
    assert out.exit_code == 0, out.output
    manifest = json.loads((tmp_path / "gen" / "manifest.json").read_text())
    assert manifest["options"]["functions"] == list(ALL_FUNCTIONS + DYNAMIC_FUNCTIONS)
    for name in DYNAMIC_FUNCTIONS:
        entry = manifest["functions"][name]
        assert entry["flops"] > 0 and entry["op_counts"]["mul"] > 0 and entry["work_reals"] > 0, name
    header = (tmp_path / "gen" / "vertical2.h").read_text()
    r, n = "vertical2_real", "VERTICAL2_NDOF"
    for prototype in (f"void vertical2_gravity(const {r} q[{n}], {r} tau[{n}]);",
                      f"void vertical2_rnea(const {r} q[{n}], const {r} dq[{n}], const {r} ddq[{n}], {r} tau[{n}]);",
                      f"void vertical2_mass_matrix(const {r} q[{n}], {r} M[4]);",
                      f"void vertical2_coriolis(const {r} q[{n}], const {r} dq[{n}], {r} c[{n}]);"):
        assert prototype in header
    assert "#define VERTICAL2_MASS_MATRIX_M_ROWS 2" in header and "#define VERTICAL2_MASS_MATRIX_M_COLS 2" in header


def test_function_option_selects_a_dynamic_function(tmp_path):
    robot_file = _write_vertical2(tmp_path)
    out = CliRunner().invoke(cli, ["gen", str(robot_file), "-o", str(tmp_path / "gen"), "--function", "gravity"])
    assert out.exit_code == 0, out.output
    manifest = json.loads((tmp_path / "gen" / "manifest.json").read_text())
    assert manifest["options"]["functions"] == ["gravity"] and list(manifest["functions"]) == ["gravity"]


def test_a_robot_without_inertials_emits_no_dynamics(tmp_path):
    for name in ("planar3", "modular8"):  # the checked-in code is the fresh generation (test_codegen)
        robot = load_robot(name)
        assert not robot.has_dynamics
        assert SymbolicModel(robot).selected() == ALL_FUNCTIONS
        manifest = json.loads((REPO_GENERATED_DIR / name / "manifest.json").read_text())
        assert not set(manifest["functions"]) & set(DYNAMIC_FUNCTIONS), name
    out = CliRunner().invoke(cli, ["gen", "planar3", "-o", str(tmp_path / "gen"), "--function", "rnea"])
    assert out.exit_code == 2
    assert "planar3.toml: robot 'planar3' has no inertials, so it has no dynamics" in out.output
    assert "mass, com and inertia" in out.output
    assert not (tmp_path / "gen").exists()


@pytest.mark.parametrize("precision", ["double", "float"])
def test_compiled_dynamics_match_casadi(panda, panda_dynamics_c, precision, tmp_path):
    """Built with the strict flags (build_library), SAMPLES seeded (q, q̇, q̈) per function;
    double within 1e-12 relative, float within FLOAT_BOUNDS (reasons there) at float-rounded inputs."""
    gen_dir, _ = panda_dynamics_c
    functions = {name: panda.symbolic.function(name) for name in DYNAMIC_FUNCTIONS}
    library = build_library(gen_dir, "panda", precision, tmp_path, batch=functions)
    report = compare_model(CompiledModel(library, "panda", functions, precision), functions, panda, SAMPLES, SEED)
    assert [r.name for r in report] == list(DYNAMIC_FUNCTIONS)
    for r in report:
        print(f"{r.name} ({precision}): max error {r.max_error:.3g}")
        assert r.bound == (DOUBLE_REL_BOUND if precision == "double" else FLOAT_BOUNDS[r.name])
        assert r.samples == SAMPLES and r.passed, f"{r.name} ({precision}): {r.max_error:.3g} > {r.bound:.3g}"


def test_compiled_dynamics_match_pinocchio(panda, panda_dynamics_c, tmp_path):
    """The double C against an independent implementation, not only against its own source."""
    from test_dynamics import _Pinocchio, _relative_error, _samples, pin

    gen_dir, _ = panda_dynamics_c
    functions = {name: panda.symbolic.function(name) for name in DYNAMIC_FUNCTIONS}
    compiled = CompiledModel(build_library(gen_dir, "panda", "double", tmp_path), "panda", functions, "double")
    reference = _Pinocchio(pin.buildModelFromUrdf(str(_panda_urdf())), panda)
    q, dq, ddq = _samples(panda, PEER_SAMPLES, SEED)
    worst = dict.fromkeys(DYNAMIC_FUNCTIONS, 0.0)
    for k in range(PEER_SAMPLES):
        expected = reference(q[k], dq[k], ddq[k])
        ours = {"gravity": compiled.raw["gravity"](q[k])[0], "rnea": compiled.raw["rnea"](q[k], dq[k], ddq[k])[0],
                "mass_matrix": compiled.raw["mass_matrix"](q[k])[0], "coriolis": compiled.raw["coriolis"](q[k], dq[k])[0]}
        for name in worst:
            worst[name] = max(worst[name], _relative_error(ours[name].reshape(expected[name].shape), expected[name]))
    print("C (double) vs Pinocchio: " + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()))
    assert max(worst.values()) <= PEER_TOL, worst


def _undefined_symbols(obj: Path, nm: str = "nm") -> set[str]:
    out = subprocess.run([nm, "-u", str(obj)], check=True, capture_output=True, text=True).stdout
    return {line.split()[-1] for line in out.splitlines() if line.strip()}


def test_dynamics_c_is_strict_heap_free_and_true_float(panda_dynamics_c, tmp_path):
    gen_dir, _ = panda_dynamics_c
    source = gen_dir / "panda.c"
    objects = {}
    for precision, flag in (("double", 0), ("float", 1)):
        objects[precision] = tmp_path / f"{precision}.o"
        subprocess.run(["gcc", *STRICT_FLAGS, "-O2", f"-DPANDA_USE_FLOAT={flag}", "-c", str(source), "-o",
                        str(objects[precision])], check=True, capture_output=True, text=True)
        assert not _undefined_symbols(objects[precision]) & FORBIDDEN_SYMBOLS
    assert not _undefined_symbols(objects["float"]) & DOUBLE_LIBM  # single precision throughout
    arm_gcc = require_tool("arm-none-eabi-gcc")
    m4 = tmp_path / "m4.o"
    subprocess.run([arm_gcc, *STRICT_FLAGS, "-Os", *ARM_CPU_FLAGS, "-DPANDA_USE_FLOAT=1", "-c", str(source), "-o",
                    str(m4)], check=True, capture_output=True, text=True)
    symbols = _undefined_symbols(m4, require_tool("arm-none-eabi-nm"))
    assert not [s for s in symbols if s.startswith("__aeabi_d")], symbols  # no software double on the M4F


@pytest.mark.parametrize("precision", ["double", "float"])
def test_dynamics_c_is_sanitizer_clean(panda, panda_dynamics_c, precision):
    gen_dir, _ = panda_dynamics_c
    functions = {name: panda.symbolic.function(name) for name in DYNAMIC_FUNCTIONS}
    assert run_sanitized(gen_dir, "panda", functions, precision).startswith("ok")


def test_verify_covers_the_dynamics(tmp_path, monkeypatch):
    """The callbacks stage compares what the manifest lists, the dynamic functions included."""
    monkeypatch.chdir(tmp_path)
    _write_vertical2(tmp_path)
    assert CliRunner().invoke(cli, ["gen", "vertical2.toml", "-o", "gen"]).exit_code == 0
    report = tmp_path / "verify.json"
    out = CliRunner().invoke(cli, ["verify", "vertical2.toml", "-o", "gen", "--samples", "300",
                                   "--report", str(report)])
    assert out.exit_code == 0, out.output
    (callbacks,) = [stage for stage in json.loads(report.read_text())["stages"] if stage["name"] == "callbacks"]
    compared = {(row[0], row[1]) for row in callbacks["rows"] if row[5]}
    assert {(name, precision) for name in DYNAMIC_FUNCTIONS for precision in ("double", "float")} <= compared
