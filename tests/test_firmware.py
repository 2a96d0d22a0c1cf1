"""The firmware stub (firmware_stub/): host builds with sanitizers reproduce plans, faults are
explicit and never leave a NaN command, the Cortex-M4F build runs under QEMU, PTP playback
matches the Python evaluation, and the verify stages replay/target use all of it."""

import copy
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from armgen.codegen import toolchain
from armgen.codegen.toolchain import STRICT_FLAGS
from armgen.planning.result import write_plan
from armgen.planning.tasks import apply_overrides, load_task, run_task
from armgen.robot import load_robot
from armgen.verify import firmware as fw
from armgen.verify.pipeline import VerifyConfig, stage_replay, stage_target

from conftest import require_tool

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "examples"
SHORT = ["path.type=line", "path.end=[-450, 400, 900]", "timing.duration=5"]
HOST_SAN = fw.Variant("host", "double", sanitize=True, opt="-O1")
HOST_FLOAT = fw.Variant("host", "float")

PTP_MODULAR8 = """
planner = "ptp"
robot = "modular8"
method = "3-4"
step = 0.001
[units]
angle = "deg"
[waypoints]
t = [0, 1.5, 3]
[waypoints.theta]
j1 = [-57, -40, -30]
j2 = [-45, -50, -60]
j3 = [71, 80, 90]
j4 = [-45, -30, -20]
j5 = [32, 40, 50]
j6 = [80, 60, 40]
j7 = [34, 30, 20]
j8 = [-28, -10, 0]
[waypoints.omega]
j1 = [0, 8, 0]
j2 = [0, -8, 0]
j3 = [0, 8, 0]
j4 = [0, 8, 0]
j5 = [0, 8, 0]
j6 = [0, -8, 0]
j7 = [0, -8, 0]
j8 = [0, 8, 0]
"""


def example(name: str, overrides=()) -> dict:
    task, _ = load_task(EXAMPLES / f"{name}.toml")
    return apply_overrides(copy.deepcopy(task), list(overrides))


def plan(task: dict, source: str = "test"):
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    return run_task(copy.deepcopy(task), source)


@pytest.fixture(scope="module")
def builder(tmp_path_factory):
    return fw.FirmwareBuilder("modular8", tmp_path_factory.mktemp("firmware"))


@pytest.fixture(scope="module")
def short_task():
    return example("modular8_circle_combined", SHORT)


@pytest.fixture(scope="module")
def short_plan(short_task):
    return plan(short_task)


def assert_never_nan(run: fw.FirmwareRun, n: int = 8) -> None:
    assert np.all(np.isfinite(run.data)), "the firmware wrote a non-finite value"
    assert run.data.shape[1] == 2 + 3 * n + 5  # tick, t, q, qd, windows; errors; locked, state, fault


# --------------------------------------------------------------------------- replay on the host

def test_host_double_with_sanitizers_reproduces_the_plan(builder, short_task, short_plan):
    task = fw.task_from_plan(short_plan, "short")
    run = fw.run_host(builder.executable(HOST_SAN, task, "short_san"))
    assert run.state == "DONE" and run.fault == "NONE"
    assert_never_nan(run)
    cmp = fw.compare_with_plan(short_plan, run, task, "double", "host")
    assert cmp.passed, cmp.rows
    assert cmp.max_dq <= 1e-12  # the same operations in the same order: rounding level at most


def test_host_float_within_its_bound(builder, short_plan):
    task = fw.task_from_plan(short_plan, "short")
    run = fw.run_host(builder.executable(HOST_FLOAT, task, "short_float"))
    cmp = fw.compare_with_plan(short_plan, run, task, "float", "host float")
    assert cmp.passed, cmp.rows
    assert 0 < cmp.max_dq < fw.FW_FLOAT_BOUND_RAD


@pytest.mark.parametrize("name, overrides", [
    ("pinv", ["method.name=pinv", "timing.law=trapezoidal", "timing.blend=0.3"]),
    ("repetitive+clik+rotation", ["method.name=repetitive", "method.T_smo_R=1", "integrator.clik_gain=5",
                                  "path.orientation=interpolate", "path.end_rpy=[-80, 20, 10]"]),
    ("zghal", ["method.name=zghal", "method.rho_L=0.01"]),
    ("zghal_improved windows", ["method.name=zghal_improved", "method.theta_s=75", "method.T_smo_L=0.5",
                                "method.T_sum_L=1", "method.rho_L=0.01"]),
    ("combined windows", ["method.theta_s=75", "method.T_smo_L=0.5", "method.T_sum_L=1", "method.rho_L=0.01",
                          "method.gamma_R_ramp=1", "method.T_smo_R=1"]),
    ("circle, constant law", ["timing.duration=25", "timing.law=constant", "method.name=pinv",
                              "integrator.output_every=5"]),
])
def test_every_method_replays_in_double(builder, name, overrides):
    task = example("modular8_circle_combined", [*SHORT, *overrides] if "circle" not in name else overrides)
    result = plan(task, name)
    if "windows" in name:
        w = np.column_stack([result.column(f"window{i}_1") for i in range(1, 9)])
        assert w.max() == 1.0 and (w[-1] == 0).any() and sum(result.metadata["summary"]["window_openings"]) >= 2
    ftask = fw.task_from_plan(result, name)
    run = fw.run_host(builder.executable(HOST_SAN, ftask, name.replace(" ", "_").replace(",", "").replace("+", "_")))
    cmp = fw.compare_with_plan(result, run, ftask, "double", name)
    assert cmp.passed, cmp.rows
    assert cmp.max_dq <= 1e-11
    if "windows" in name:  # the controller's windows are the planner's, sample by sample
        wf = np.array([run.by_tick()[k][2 + 16 + 2:2 + 16 + 2 + 8] for k in range(len(result.data))])
        assert np.array_equal(wf, w)


def test_replay_refuses_plans_the_controller_cannot_run(short_plan):
    damped = copy.deepcopy(short_plan)
    damped.metadata["summary"]["damped_steps"] = 3
    assert "damping" in fw.refusal(damped)
    rk4 = copy.deepcopy(short_plan)
    rk4.metadata["integrator"]["method"] = "rk4"
    assert "Euler" in fw.refusal(rk4)
    with pytest.raises(fw.FirmwareError, match="explicit Euler"):
        fw.cartesian_task(example("modular8_circle_combined", [*SHORT, "integrator.method=rk4"]), "rk4")


# --------------------------------------------------------------------------- fault injection

def held_rows(run: fw.FirmwareRun) -> tuple[int, np.ndarray, np.ndarray]:
    """Tick of the fault, the command before it, and every row from the fault on."""
    state = run.column("state")
    first = int(np.argmax(state == 3))
    assert state[first] == 3
    return first, run.data[first - 1] if first > 0 else None, run.data[first:]


def test_nan_task_input_faults_and_holds_a_finite_command(builder, short_plan):
    task = fw.task_from_plan(short_plan, "short")
    exe = builder.executable(HOST_SAN, task, "short_san_inject")
    run = fw.run_host(exe, ["--nan-input", "100"])
    assert (run.state, run.fault) == ("FAULT", "NONFINITE_INPUT")
    assert_never_nan(run)
    first, before, after = held_rows(run)
    assert int(after[0, 0]) == 100
    assert np.array_equal(after[:, 2:10], np.repeat(before[None, 2:10], len(after), axis=0))  # held
    assert np.all(after[:, 10:18] == 0.0)  # velocity 0 while holding
    assert np.all(after[:, -1] == fw.FAULT_NAMES.index("NONFINITE_INPUT"))
    # before the fault the run is the plan's
    q_plan = np.column_stack([short_plan.column(f"q{i}_rad") for i in range(1, 9)])[:100]
    assert np.max(np.abs(run.data[:100, 2:10] - q_plan)) <= 1e-12
    # a NaN already at the START tick: the start configuration is held
    run0 = fw.run_host(exe, ["--nan-input", "0"])
    assert run0.fault == "NONFINITE_INPUT" and np.array_equal(run0.data[0, 2:10], q_plan[0])


def test_overrun_and_stop(builder, short_plan):
    exe = builder.executable(HOST_SAN, fw.task_from_plan(short_plan, "short"), "short_san_inject")
    run = fw.run_host(exe, ["--overrun", "37"])
    assert (run.state, run.fault) == ("FAULT", "OVERRUN")
    assert_never_nan(run)
    stop = fw.run_host(exe, ["--stop", "10"])
    assert (stop.state, stop.fault) == ("DONE", "NONE") and int(stop.data[-1, 0]) == 10


def test_target_driving_a_joint_into_its_limit_faults_there(builder):
    """Minimum norm around the spec-20 circle takes joint 6 past 140° at t ≈ 111 s: the
    controller must stop at exactly the plan's first sample beyond the limit."""
    result = plan(example("modular8_circle_pinv"), "pinv")
    violations = result.metadata["summary"]["limit_violations"]
    assert violations, "the minimum-norm plan leaves the limits (spec 20)"
    task = fw.task_from_plan(result, "pinv")
    run = fw.run_host(builder.executable(HOST_SAN, task, "pinv_circle"))
    assert (run.state, run.fault) == ("FAULT", "JOINT_LIMIT")
    assert_never_nan(run)
    first, before, after = held_rows(run)
    robot = load_robot("modular8")
    assert math.isclose(after[0, 1], min(v["first_t_s"] for v in violations))
    assert np.all(after[:, 2:10] <= robot.qmax) and np.all(after[:, 2:10] >= robot.qmin)
    assert np.array_equal(after[0, 2:10], before[2:10])
    cmp = fw.compare_with_plan(result, run, task, "double", "pinv")
    assert cmp.passed, cmp.rows  # the expected fault, and the plan matched up to it


def test_singular_pose_faults_with_a_finite_held_command(builder):
    """Starting stretched out (qz: rank 4 Jacobian) the exact pseudo-inverse cannot follow a line."""
    task = example("modular8_circle_combined", ['start="qz"', "path.type=line", "path.end=[-200, 100, 1200]",
                                                "timing.duration=5", "method.name=pinv"])
    run = fw.run_host(builder.executable(HOST_SAN, fw.task_from_dict(task, "singular"), "singular"))
    assert (run.state, run.fault) == ("FAULT", "SINGULAR")
    assert_never_nan(run)
    first, before, after = held_rows(run)
    assert first == 1 and np.all(after[:, 2:10] == 0.0)  # qz held


def test_bad_configuration_is_refused_at_init(builder):
    """Circle points on one line (here: via = end) define no circle: ctrl_init refuses, nothing moves."""
    task = example("modular8_circle_combined", ["path.via=[0, 424, 850]"])
    run = fw.run_host(builder.executable(HOST_SAN, fw.task_from_dict(task, "collinear"), "collinear"))
    assert (run.summary["init"], run.state, run.fault) == ("BAD_CONFIG", "FAULT", "BAD_CONFIG")
    assert_never_nan(run)
    q0 = load_robot("modular8").configuration("q0")
    assert np.allclose(run.data[:, 2:10], q0, atol=0, rtol=0)


# --------------------------------------------------------------------------- PTP playback

def test_ptp_playback_matches_the_python_evaluation(builder, tmp_path):
    path = tmp_path / "ptp.toml"
    path.write_text(PTP_MODULAR8)
    task, _ = load_task(path)
    result = plan(task, "ptp")
    ftask = fw.task_from_plan(result, "ptp")
    assert ftask.mode == "playback" and sorted(ftask.joints) == list(range(8))
    for variant, precision in ((HOST_SAN, "double"), (HOST_FLOAT, "float")):
        run = fw.run_host(builder.executable(variant, ftask, f"ptp_{precision}"))
        cmp = fw.compare_with_plan(result, run, ftask, precision, precision)
        assert cmp.passed, cmp.rows
        assert run.state == "DONE"
    assert cmp.max_dq < 1e-6  # float θ


def test_ptp_beyond_the_limits_stops_at_the_limit(builder):
    """Spec 40's single-joint example goes to 250°; played on joint 1 of modular8 (±140°)."""
    result = plan(example("ptp_single_joint"), "ptp1")
    ftask = fw.task_from_plan(result, "ptp1", load_robot("modular8"))
    run = fw.run_host(builder.executable(HOST_SAN, ftask, "ptp1"))
    assert (run.state, run.fault) == ("FAULT", "JOINT_LIMIT")
    cmp = fw.compare_with_plan(result, run, ftask, "double", "ptp1")
    assert cmp.passed, cmp.rows
    assert_never_nan(run)
    theta = result.column("theta_j1_rad")
    assert cmp.fault_tick == int(np.argmax(theta > math.radians(140)))


# --------------------------------------------------------------------------- Cortex-M4F under QEMU

def test_qemu_float_run_matches_the_plan(builder, short_plan, tmp_path):
    require_tool("arm-none-eabi-gcc")
    require_tool("qemu-system-arm")
    task = fw.task_from_plan(short_plan, "short")
    run = fw.run_qemu(builder.executable(fw.ARM_VARIANT, task, "short_m4"))
    assert run.summary["real_bytes"] == "4"
    cmp = fw.compare_with_plan(short_plan, run, task, "float", "qemu")
    assert cmp.passed, cmp.rows
    assert_never_nan(run)
    ipt = fw.instructions_per_tick(run)
    assert 1000 < ipt["mean"] < 20000 and ipt["insns_per_systick"] == 40.0
    # the PTP playback on the target too
    path = tmp_path / "ptp.toml"
    path.write_text(PTP_MODULAR8)
    ptp_task, _ = load_task(path)
    result = plan(ptp_task, "ptp")
    ftask = fw.task_from_plan(result, "ptp")
    run = fw.run_qemu(builder.executable(fw.ARM_VARIANT, ftask, "ptp_m4"))
    cmp = fw.compare_with_plan(result, run, ftask, "float", "qemu ptp")
    assert cmp.passed, cmp.rows


def test_fast_sinf_cosf_of_the_m4_build_are_accurate(tmp_path):
    """arm/fw_fastmath.c (linked with --wrap on the M4) within 2 ulp of double sin/cos on
    [-8, 8], exact sign of sin(-0), and newlib/libm beyond its range."""
    driver = tmp_path / "fm.c"
    driver.write_text(r"""
#include <math.h>
#include <stdio.h>
float fw_fast_sinf(float x);
float fw_fast_cosf(float x);
static double ulps(float got, double ref) {
  int e;
  float r = (float)ref;
  if (r == 0.0f) return fabs((double)got - ref) / ldexp(1.0, -149);
  (void)frexp((double)r, &e);
  return fabs((double)got - ref) / ldexp(1.0, e - 24);
}
int main(void) {
  double worst = 0.0;
  long i, n = 2000000;
  for (i = 0; i <= n; ++i) {
    float x = (float)(-8.0 + 16.0 * (double)i / (double)n);
    double a = ulps(fw_fast_sinf(x), sin((double)x)), b = ulps(fw_fast_cosf(x), cos((double)x));
    worst = fmax(worst, fmax(a, b));
  }
  printf("%.6f %d %d %d\n", worst, signbit(fw_fast_sinf(-0.0f)) != 0,
         fw_fast_sinf(100.0f) == sinf(100.0f), isnan(fw_fast_cosf(NAN)) != 0);
  return 0;
}
""")
    exe = tmp_path / "fm"
    toolchain.run_tool(["gcc", *STRICT_FLAGS, "-O2", "-DFW_FASTMATH_SELFTEST", str(REPO / "firmware_stub/arm/fw_fastmath.c"),
                        str(driver), "-lm", "-o", str(exe)], "fast trig test")
    worst, neg_zero, fallback, nan = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split()
    assert float(worst) <= 2.0 and neg_zero == "1" and fallback == "1" and nan == "1"


def test_makefile_host_arm_qemu_size(tmp_path):
    if shutil.which("make") is None:
        pytest.skip("make not installed (apt-get install -y make)")
    build = tmp_path / "build"
    args = ["make", "-C", str(REPO / "firmware_stub"), f"BUILD={build}", f"PYTHON={sys.executable}",
            "SET=--set path.type=line --set path.end=[-450,400,900] --set timing.duration=2"]
    proc = subprocess.run([*args, "host"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    csv = (build / "host.csv").read_text().splitlines()
    assert csv[0].startswith("tick,t_s,q1_rad") and len(csv) == 1 + 101 + 2
    assert "# state DONE" in (build / "host.summary").read_text()
    require_tool("arm-none-eabi-gcc")
    require_tool("qemu-system-arm")
    proc = subprocess.run([*args, "arm", "qemu", "size"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    run = fw.parse_output((build / "qemu.out").read_text())
    host = fw.parse_output((build / "host.out").read_text())
    assert run.state == "DONE" and run.data.shape == host.data.shape
    assert np.max(np.abs(run.data[:, 2:10] - host.data[:, 2:10])) < 1e-5
    for what in ("tick_resolved_rate", "modular8_step_gpm", "stack use"):
        assert what in proc.stdout


# --------------------------------------------------------------------------- verify stages

def test_replay_stage_runs_the_firmware(tmp_path, short_plan):
    path = tmp_path / "plan.csv"
    write_plan(short_plan, path)
    stage = stage_replay(VerifyConfig(load_robot("modular8"), path), tmp_path)
    assert stage.passed, stage.render()
    runs = {r[0] for r in stage.rows}
    assert {"host firmware, double, ASan/UBSan", "host firmware, float"} <= runs
    # a plan that used damping is refused, and the stage says why
    meta = json.loads(path.with_suffix(".json").read_text())
    meta["summary"]["damped_steps"] = 2
    path.with_suffix(".json").write_text(json.dumps(meta))
    stage = stage_replay(VerifyConfig(load_robot("modular8"), path, precisions=("double",)), tmp_path / "d")
    assert not stage.passed and any("damping" in str(r[2]) for r in stage.rows)


def test_target_stage_passes_under_qemu(tmp_path, short_plan):
    require_tool("arm-none-eabi-gcc")
    require_tool("qemu-system-arm")
    path = tmp_path / "plan.csv"
    write_plan(short_plan, path)
    stage = stage_target(VerifyConfig(load_robot("modular8"), path, target="cortex-m4"), tmp_path)
    assert stage.passed, stage.render()
    assert any(r[1].startswith("instructions per tick") for r in stage.rows)


def test_target_stage_fails_naming_the_packages_without_the_toolchain(tmp_path, monkeypatch, short_plan):
    real_which = toolchain.shutil.which
    monkeypatch.setattr(toolchain.shutil, "which",
                        lambda name, *a, **k: None if name.startswith(("arm-none-eabi", "qemu")) else real_which(name))
    path = tmp_path / "plan.csv"
    write_plan(short_plan, path)
    stage = stage_target(VerifyConfig(load_robot("modular8"), path, target="cortex-m4"), tmp_path)
    assert not stage.passed
    assert "gcc-arm-none-eabi" in stage.message and "qemu-system-arm" in stage.message
    assert "libnewlib-arm-none-eabi" in stage.render()
