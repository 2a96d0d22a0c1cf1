"""The firmware stub (firmware_stub/): host builds with sanitizers reproduce plans, faults are
explicit and never leave a NaN command, the Cortex-M4F build runs under QEMU, PTP playback
matches the Python evaluation, and the verify stages replay/target use all of it."""

import copy
import dataclasses
import json
import math
import os
import re
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
from armgen import firmware as fw
from armgen.verification import firmware_compare as fwcmp
from armgen.verification.pipeline import VerifyConfig, stage_replay, stage_target

from conftest import require_tool

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "examples"
SHORT = ["path.type=line", "path.end=[-450, 400, 900]", "timing.duration=5"]
HOST_SAN = fw.Variant("host", "double", sanitize=True, opt="-O1")
HOST_FLOAT = fw.Variant("host", "float")

PTP_MODULAR8 = EXAMPLES / "modular8_ptp_two_segments.toml"
MODULAR8_QDLIM_RAD_S = math.radians(90)  # robots/modular8.toml: qdlim = 90 (deg/s) on every joint  # eight joints, two segments, 3-4


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


def assert_never_nan(run: fw.FirmwareRun, robot="modular8") -> None:
    """Every value finite, in the CSV's columns: tick, t, q, qd, errors, windows, the feed-forward
    torques of a robot with inertials, the clearance of a robot with capsules, locked, state, fault."""
    robot = load_robot(robot) if isinstance(robot, str) else robot
    assert np.all(np.isfinite(run.data)), "the firmware wrote a non-finite value"
    assert run.data.shape[1] == 2 + (4 if robot.has_dynamics else 3) * robot.n + 5 + int(robot.has_collision)


# --------------------------------------------------------------------------- replay on the host

def test_host_double_with_sanitizers_reproduces_the_plan(builder, short_task, short_plan):
    task = fw.task_from_plan(short_plan, "short")
    run = fw.run_host(builder.executable(HOST_SAN, task, "short_san"))
    assert run.state == "DONE" and run.fault == "NONE"
    assert_never_nan(run)
    cmp = fwcmp.compare_with_plan(short_plan, run, task, "double", "host")
    assert cmp.passed, cmp.rows
    assert cmp.max_dq <= 1e-12  # the same operations in the same order: rounding level at most


def test_host_float_within_its_bound(builder, short_plan):
    task = fw.task_from_plan(short_plan, "short")
    run = fw.run_host(builder.executable(HOST_FLOAT, task, "short_float"))
    cmp = fwcmp.compare_with_plan(short_plan, run, task, "float", "host float")
    assert cmp.passed, cmp.rows
    assert 0 < cmp.max_dq < fwcmp.FW_FLOAT_BOUND_RAD


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
                              "integrator.output_every=5", "check.limits=report"]),
])
def test_every_method_replays_in_double(builder, name, overrides):
    task = example("modular8_circle_combined", [*SHORT, *overrides] if "circle" not in name else overrides)
    result = plan(task, name)
    if "windows" in name:
        w = np.column_stack([result.column(f"window{i}_1") for i in range(1, 9)])
        assert w.max() == 1.0 and (w[-1] == 0).any() and sum(result.metadata["summary"]["window_openings"]) >= 2
    ftask = fw.task_from_plan(result, name)
    run = fw.run_host(builder.executable(HOST_SAN, ftask, name.replace(" ", "_").replace(",", "").replace("+", "_")))
    cmp = fwcmp.compare_with_plan(result, run, ftask, "double", name)
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
        fw.task_from_dict(example("modular8_circle_combined", [*SHORT, "integrator.method=rk4"]), "rk4")


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
    cmp = fwcmp.compare_with_plan(result, run, task, "double", "pinv")
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
    path.write_text(PTP_MODULAR8.read_text())
    task, _ = load_task(path)
    result = plan(task, "ptp")
    ftask = fw.task_from_plan(result, "ptp")
    assert ftask.mode == "playback" and sorted(ftask.joints) == list(range(8))
    for variant, precision in ((HOST_SAN, "double"), (HOST_FLOAT, "float")):
        run = fw.run_host(builder.executable(variant, ftask, f"ptp_{precision}"))
        cmp = fwcmp.compare_with_plan(result, run, ftask, precision, precision)
        assert cmp.passed, cmp.rows
        assert run.state == "DONE"
    assert cmp.max_dq < 1e-6  # float θ


def test_ptp_beyond_the_limits_stops_at_the_limit(builder):
    """Spec 40's single-joint example goes to 250°; played on joint 1 of modular8 (±140°)."""
    result = plan(example("ptp_single_joint"), "ptp1")
    ftask = fw.task_from_plan(result, "ptp1", load_robot("modular8"))
    run = fw.run_host(builder.executable(HOST_SAN, ftask, "ptp1"))
    assert (run.state, run.fault) == ("FAULT", "JOINT_LIMIT")
    cmp = fwcmp.compare_with_plan(result, run, ftask, "double", "ptp1")
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
    cmp = fwcmp.compare_with_plan(short_plan, run, task, "float", "qemu")
    assert cmp.passed, cmp.rows
    assert_never_nan(run)
    ipt = fw.instructions_per_tick(run)
    assert 1000 < ipt["mean"] < 20000 and ipt["insns_per_systick"] == 40.0
    # the PTP playback on the target too
    path = tmp_path / "ptp.toml"
    path.write_text(PTP_MODULAR8.read_text())
    ptp_task, _ = load_task(path)
    result = plan(ptp_task, "ptp")
    ftask = fw.task_from_plan(result, "ptp")
    run = fw.run_qemu(builder.executable(fw.ARM_VARIANT, ftask, "ptp_m4"))
    cmp = fwcmp.compare_with_plan(result, run, ftask, "float", "qemu ptp")
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
    require_tool("make")
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


# --------------------------------------------------------------------------- spec 30 / 35 on board

FT_EXAMPLES = ["iiwa14_fault_circle_gpm", "iiwa14_fault_circle_wln", "modular8_fault_circle_gpm",
               "modular8_fault_circle_wln", "modular8_wgpm_demo"]
RUNTIME_LOCK = {"iiwa14": ("iiwa14_fault_circle_runtime_lock", 5, 1.38),
                "modular8": ("modular8_fault_circle_runtime_lock", 3, 1.38)}


def c_plan(task: dict, source: str):
    """A plan through the generated C (the backend `armgen verify` replays against)."""
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    return run_task(copy.deepcopy(task), source, backend="c")


@pytest.fixture(scope="module")
def builders(tmp_path_factory, builder):
    return {"modular8": builder, "iiwa14": fw.FirmwareBuilder("iiwa14", tmp_path_factory.mktemp("firmware_iiwa14"))}


@pytest.fixture(scope="module")
def ft_plans():
    return {}


def example_plan(name: str, cache: dict):
    if name not in cache:
        cache[name] = c_plan(example(name), name)
    return cache[name]


@pytest.mark.parametrize("name", FT_EXAMPLES)
def test_spec30_and_spec35_examples_replay_on_the_host_firmware(builders, ft_plans, name):
    """Double with ASan/UBSan: max |Δq| ≤ 1e-9 rad over the whole plan (or up to the guard
    the plan crosses: the elbow-locked iiwa GPM plan leaves the path by 46 mm)."""
    result = example_plan(name, ft_plans)
    task = fw.task_from_plan(result, name)
    assert task.mode == ("weighted_gpm" if "wgpm" in name else "fault_tolerant")
    run = fw.run_host(builders[task.robot.name].executable(HOST_SAN, task, f"{name}_san"))
    cmp = fwcmp.compare_with_plan(result, run, task, "double", name)
    assert cmp.passed, cmp.rows
    assert cmp.max_dq <= fwcmp.FW_DOUBLE_BOUND_RAD
    assert_never_nan(run, task.robot)
    if task.lock_tick >= 0:  # the plan's lock, reported by the drive model at its tick
        by_tick = run.by_tick()
        k = task.lock_tick
        if k in by_tick:
            assert fw.STATE_NAMES[int(by_tick[k][-2])] in ("DEGRADED", "DONE", "FAULT")
            assert int(by_tick[k][-3]) == task.lock_mask
    if name == "iiwa14_fault_circle_gpm":
        assert run.fault == "TRACKING"  # the example's own verdict: elbow locked, task not completed


@pytest.mark.arm
@pytest.mark.parametrize("name", FT_EXAMPLES)
def test_spec30_and_spec35_examples_replay_under_qemu(builders, ft_plans, name):
    require_tool("arm-none-eabi-gcc")
    require_tool("qemu-system-arm")
    result = example_plan(name, ft_plans)
    task = fw.task_from_plan(result, name)
    run = fw.run_qemu(builders[task.robot.name].executable(fw.ARM_VARIANT, task, f"{name}_m4"))
    cmp = fwcmp.compare_with_plan(result, run, task, "float", name)
    assert cmp.passed, cmp.rows
    assert cmp.max_dq <= fwcmp.FW_FLOAT_BOUND_RAD
    ipt = fw.instructions_per_tick(run)
    assert ipt["max"] <= 1.1 * ipt["mean"]  # fixed cost per tick (no data-dependent loops)


@pytest.mark.parametrize("robot_name", sorted(RUNTIME_LOCK))
def test_lock_from_the_tick_input_at_a_time_the_plan_did_not_know(builders, robot_name):
    """The plan has no fault; the drive reports joint J locked at t = 1.38 s. The controller
    freezes J exactly, runs DEGRADED, keeps the tool within the planner's completion bounds,
    and does what the planner does when it knows the lock in advance (independent run)."""
    name, joint, t_lock = RUNTIME_LOCK[robot_name]
    task_doc = example(name)
    healthy = c_plan(task_doc, name)
    assert healthy.metadata["fault"]["first_locked_step"] is None
    task = fw.schedule_lock(fw.task_from_plan(healthy, name), f"{joint}@{t_lock}")
    k, j, n = task.lock_tick, joint - 1, task.robot.n
    assert k == round(t_lock / task.dt) and task.lock_mask == 1 << j
    run = fw.run_host(builders[robot_name].executable(HOST_SAN, task, f"{name}_runtime_lock"))
    assert (run.state, run.fault) == ("DONE", "NONE")
    assert_never_nan(run, task.robot)
    rows = np.array([run.by_tick()[i] for i in range(task.n_ticks + 1)])
    state = rows[:, -2].astype(int)
    assert np.all(state[:k] == fw.STATE_NAMES.index("RUNNING"))
    assert np.all(state[k:-1] == fw.STATE_NAMES.index("DEGRADED")) and state[-1] == fw.STATE_NAMES.index("DONE")
    assert np.all(rows[k:, -3] == 1 << j) and np.all(rows[:k, -3] == 0)
    q, qd = rows[:, 2:2 + n], rows[:, 2 + n:2 + 2 * n]
    assert np.all(qd[k:, j] == 0.0) and np.all(q[k:, j] == q[k, j])  # exactly frozen
    # the planner's tracking bound (completion tolerances of the task)
    comp = healthy.metadata["completion"]
    assert np.max(run.column("pos_err_m")) <= comp["pos_tol_mm"] * 1e-3
    assert np.max(run.column("ori_err_rad")) <= math.radians(comp["ori_tol_deg"])
    # an independent reference: the planner told about this lock in advance
    # (report mode: the lock stops J within one step, beyond its qddlim)
    told = c_plan(apply_overrides(copy.deepcopy(task_doc), [f"fault.joints=[{joint}]", f"fault.time={t_lock}",
                                                            "check.limits=report"]), name)
    q_told = np.column_stack([told.column(f"q{i + 1}_rad") for i in range(n)])
    assert np.max(np.abs(q - q_told)) <= fwcmp.FW_DOUBLE_BOUND_RAD
    # velocities continuous except at the lock: per tick no larger a change than the planner's
    # own smooth motion (its peak |q̈| excludes the lock transition), the locked joint aside
    ddq_peak = math.radians(told.metadata["verdict"]["peak_ddq_deg_s2"])
    steps = np.abs(np.diff(qd, axis=0))
    others = np.delete(np.arange(n), j)
    away = np.delete(np.arange(len(steps)), k - 1)
    assert np.max(steps[np.ix_(away, others)]) <= ddq_peak * task.dt * (1 + 1e-9)
    # at the lock tick the healthy joints take over J's share of the task (bounded jump)
    jump = float(np.max(steps[k - 1, others]))
    assert jump <= math.radians(told.metadata["verdict"]["lock_jump_deg_s"]) * (1 + 1e-9) + 1e-12


def test_verify_replay_stage_runs_a_fault_tolerant_plan(ft_plans, tmp_path):
    """`armgen verify iiwa14 --plan <iiwa14_fault_circle_wln plan>`'s replay stage (it used to
    fail: "the controller runs cartesian and ptp plans")."""
    path = tmp_path / "wln.csv"
    write_plan(example_plan("iiwa14_fault_circle_wln", ft_plans), path)
    stage = stage_replay(VerifyConfig(load_robot("iiwa14"), path), tmp_path)
    assert stage.passed, stage.render()
    assert {"host firmware, double, ASan/UBSan", "host firmware, float"} <= {r[0] for r in stage.rows}


def lock_run(builder, task, args, name):
    run = fw.run_host(builder.executable(HOST_SAN, task, name), args)
    assert_never_nan(run, task.robot)
    return run


def assert_held_inside_limits(run, robot, since_tick):
    rows = run.data[run.data[:, 0] >= since_tick]
    n = robot.n
    assert np.all(rows[:, 2:2 + n] <= robot.qmax) and np.all(rows[:, 2:2 + n] >= robot.qmin)
    held = run.data[np.flatnonzero(run.column("state") == fw.FAULT_STATE)]
    assert len(held) and np.all(held[:, 2 + n:2 + 2 * n] == 0.0)
    assert np.all(held[:, 2:2 + n] == held[0, 2:2 + n])


@pytest.mark.parametrize("case, args, fault, tick", [
    ("joint that does not exist", ["--lock-tick", "30", "--lock-mask", str(1 << 8)], "LOCK_REPORT", 30),
    ("flags change every tick", ["--lock-tick", "30", "--lock-mask", "8", "--lock-toggle"], "LOCK_REPORT", 31),
    ("more locks than the redundancy", ["--lock-tick", "30", "--lock-mask", str(0b111)], "REDUNDANCY", 30),
    ("NaN task input", ["--nan-input", "40"], "NONFINITE_INPUT", 40),
    ("overrun on the START tick", ["--overrun", "0"], "OVERRUN", 0),
])
def test_fault_tolerant_bad_input_is_a_defined_fault(builders, case, args, fault, tick):
    name = "modular8_fault_circle_runtime_lock"
    task = fw.task_from_dict(example(name), name)
    run = lock_run(builders["modular8"], task, args, "runtime_lock_inject")
    assert (run.state, run.fault) == ("FAULT", fault), case
    first = int(run.data[np.argmax(run.column("state") == fw.FAULT_STATE), 0])
    assert first == tick, case
    assert_held_inside_limits(run, load_robot("modular8"), 0)


def test_two_locks_exceed_the_iiwa_redundancy_and_weighted_gpm_takes_no_lock(builders):
    iiwa = fw.task_from_dict(example(RUNTIME_LOCK["iiwa14"][0]), "iiwa")
    run = lock_run(builders["iiwa14"], iiwa, ["--lock-tick", "20", "--lock-mask", str(0b10010)], "iiwa_two")
    assert run.fault == "REDUNDANCY"
    assert_held_inside_limits(run, load_robot("iiwa14"), 0)
    one = lock_run(builders["iiwa14"], iiwa, ["--lock-tick", "20", "--lock-mask", str(0b10000)], "iiwa_two")
    assert (one.state, one.fault) == ("DONE", "NONE")  # one lock is within its redundancy
    wg = fw.task_from_dict(example("modular8_wgpm_demo", ["timing.duration=5", "method.ramp_time=1"]), "wg")
    run = lock_run(builders["modular8"], wg, ["--lock-tick", "20", "--lock-mask", "1"], "wgpm_lock")
    assert run.fault == "REDUNDANCY"


def test_planners_the_controller_does_not_run_are_refused():
    robot = load_robot("modular8")
    for overrides, what in ((["method.name=pinv"], "comparison baseline"), (["method.name=clamp"], "baseline")):
        with pytest.raises(fw.FirmwareError, match=what):
            fw.task_from_dict(example("modular8_wgpm_demo", overrides), "wg")
    with pytest.raises(fw.FirmwareError, match="sigma_min"):
        fw.task_from_dict(example("modular8_fault_circle_wln", ["method.index=sigma_min"]), "ft")
    # every armgen planner runs now (snake plans by sampled playback): a plan of another planner
    with pytest.raises(fw.FirmwareError, match="not planner 'rrt'"):
        fw.task_from_plan(type("P", (), {"metadata": {"planner": "rrt"}})(), "rrt.csv", robot)


# --------------------------------------------------------------------------- hardening (issue 11)

def with_field(task: fw.FirmwareTask, name: str, value: str) -> fw.FirmwareTask:
    """The task with one top-level field of fw_task rewritten (a careless configuration)."""
    header, count = re.subn(rf"\.{name} = (\{{[^}}]*\}}|[^,]+),", f".{name} = {value},", task.header, count=1)
    assert count == 1
    return dataclasses.replace(task, header=header)


@pytest.fixture(scope="module")
def ptp_task(tmp_path_factory):
    path = tmp_path_factory.mktemp("ptp") / "ptp.toml"
    path.write_text(PTP_MODULAR8.read_text())
    task, _ = load_task(path)
    result = plan(task, "ptp")
    return result, fw.task_from_plan(result, "ptp")


def test_playback_period_that_does_not_fit_the_knots_is_refused(builder, ptp_task):
    """dt 1.5 ms instead of the plan's 1 ms: the old controller jumped joints by 33-40° in one
    tick and ended DONE; now ctrl_init refuses it and holds the start (inside the limits)."""
    result, task = ptp_task
    for dt in ("CTRL_LIT(0.0015)", "CTRL_LIT(0.0005)"):
        run = fw.run_host(builder.executable(HOST_SAN, with_field(task, "dt", dt), "ptp_bad_dt"))
        assert (run.summary["init"], run.fault) == ("BAD_CONFIG", "BAD_CONFIG")
        assert_never_nan(run)
        q_start = [result.column(f"theta_j{i}_rad")[0] for i in range(1, 9)]
        assert np.max(np.abs(run.data[:, 2:10] - q_start)) <= 1e-15


def test_playback_enforces_each_joints_own_speed_limit(builder, ptp_task):
    """The speed guard is per joint: one joint's limit lowered below its peak speed stops the
    playback with SPEED at that joint's first too-fast sample, although the others are faster."""
    result, task = ptp_task
    omega = np.abs(np.column_stack([result.column(f"omega_j{i}_rad_s") for i in range(1, 9)]))
    slow = int(np.argmin(np.max(omega, axis=0)))  # the slowest joint: the others exceed its limit
    limit = 0.5 * float(np.max(omega[:, slow]))
    assert np.max(np.delete(omega, slow, axis=1)) > limit  # a shared limit would stop earlier
    guards = [MODULAR8_QDLIM_RAD_S] * 8
    guards[slow] = limit
    value = "{" + ", ".join(f"CTRL_LIT({g!r})" for g in guards) + "}"
    run = fw.run_host(builder.executable(HOST_SAN, with_field(task, "qdot_max", value), "ptp_slow"))
    assert (run.state, run.fault) == ("FAULT", "SPEED")
    first, before, after = held_rows(run)
    assert first == int(np.argmax(omega[:, slow] > limit))  # the slow joint's first too fast sample
    assert np.all(after[:, 2:10] == before[2:10]) and np.all(after[:, 10:18] == 0.0)


def test_speed_guard_is_the_robot_files_qdlim(ptp_task):
    """task_params.h carries each joint's qdlim of the robot file (modular8: 90 deg/s each)."""
    _, task = ptp_task
    guards = re.search(r"\.qdot_max = \{([^}]*)\}", task.header).group(1)
    values = [float(v) for v in re.findall(r"CTRL_LIT\(([^)]*)\)", guards)]
    assert values == [MODULAR8_QDLIM_RAD_S] * 8


def test_host_overrun_check_measures_real_time(builder, short_plan):
    """--period-ns: the host scheduler compares each tick's wall time with the period; a tick
    takes microseconds, so a 100 ns period overruns on the START tick, reported on tick 1."""
    exe = builder.executable(HOST_SAN, fw.task_from_plan(short_plan, "short"), "short_san_inject")
    run = fw.run_host(exe, ["--period-ns", "100"])
    assert (run.state, run.fault) == ("FAULT", "OVERRUN")
    assert int(run.data[np.argmax(run.column("state") == fw.FAULT_STATE), 0]) == 1
    relaxed = fw.run_host(exe, ["--period-ns", str(10 ** 9)])  # 1 s per tick: never late
    assert (relaxed.state, relaxed.fault) == ("DONE", "NONE")


# The MPS2 AN386 clock under QEMU is 25 MHz: a 100 µs period is 2 500 cycles.
QEMU_CYCLES_PER_100_US = 2500


@pytest.mark.arm
def test_qemu_overrun_check_counts_cycles(builder, short_plan):
    """A 100 µs period at 25 MHz is 2 500 cycles; a resolved-rate tick executes more
    instructions than that (≥ 1 cycle each): OVERRUN after the START tick."""
    require_tool("qemu-system-arm")
    task = fw.task_from_plan(short_plan, "short")
    tight = dataclasses.replace(fw.ARM_VARIANT, print_rows=True, extra=("-DFW_PERIOD_NS=100000",))
    run = fw.run_qemu(builder.executable(tight, task, "overrun_m4"))
    assert (run.state, run.fault) == ("FAULT", "OVERRUN")
    assert int(run.data[np.argmax(run.column("state") == fw.FAULT_STATE), 0]) == 1
    assert fw.instructions_per_tick(run)["max"] > QEMU_CYCLES_PER_100_US


CONFIG_MUTATION_MAIN = r"""
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "controller.h"
#include "fw_csv.h"
extern const ctrl_config fw_task;
static ctrl_config cfg; /* in RAM: the application scribbles over it after ctrl_init */
static ctrl a, b;
int main(void) {
  static char buf[FW_CSV_LINE_MAX];
  ctrl_input in;
  ctrl_output oa, ob;
  long i;
  int r;
  memcpy(&cfg, &fw_task, sizeof(cfg));
  if (ctrl_init(&a, &cfg) != CTRL_FAULT_NONE || ctrl_init(&b, &fw_task) != CTRL_FAULT_NONE) return 3;
  for (r = 0; r < CTRL_NTASK; ++r) cfg.rr.task_rows[r] = 1000000 * (r + 1);
  cfg.dt = (ctrl_real)NAN;
  cfg.rr.duration = (ctrl_real)NAN;
  cfg.mode = (ctrl_mode)77;
  cfg.q_max[0] = (ctrl_real)-1e30;
  memset(&in, 0, sizeof(in));
  in.command = CTRL_CMD_START;
  (void)fw_csv_header(buf, sizeof(buf));
  fputs(buf, stdout);
  for (i = 0; i < 300; ++i) {
    (void)ctrl_tick(&a, &in, &oa);
    (void)ctrl_tick(&b, &in, &ob);
    in.command = CTRL_CMD_NONE;
    if (memcmp(oa.q, ob.q, sizeof(oa.q)) != 0 || oa.state != ob.state || oa.fault != ob.fault) return 4;
    (void)fw_csv_row(buf, sizeof(buf), &oa);
    fputs(buf, stdout);
  }
  printf("# state %s\n# fault %s\n", ctrl_state_name(oa.state), ctrl_fault_name(oa.fault));
  return 0;
}
"""


def test_configuration_changed_after_init_is_never_used(builder, short_plan, tmp_path):
    """The controller runs its validated copy: NaN time stamps and task_rows pointing far
    outside the arrays written after ctrl_init change nothing (ASan would catch a read)."""
    task = fw.task_from_plan(short_plan, "short")
    fw.run_host(builder.executable(HOST_SAN, task, "mutation"))  # compiles the objects and fw_task.o
    objs = [o for o in builder.objects(HOST_SAN) if o.stem != "main"]
    src = tmp_path / "mutation_main.c"
    src.write_text(CONFIG_MUTATION_MAIN)
    exe = tmp_path / "mutation"
    task_obj = builder.work / f"{HOST_SAN.name}_mutation" / "fw_task.o"
    subprocess.run([toolchain.host_cc(), *builder.cflags(HOST_SAN), str(src), *map(str, objs), str(task_obj), "-lm",
                    "-o", str(exe)], check=True, capture_output=True)
    run = fw.run_host(exe)
    assert (run.state, run.fault) == ("DONE", "NONE")  # the whole motion, identical to the untouched one
    assert np.all(np.isfinite(run.data))


def test_bad_configuration_holds_a_command_inside_the_limits(builder, short_plan):
    """A NaN start for joint 1 whose range is [0.2, 1.0] rad: refused, and the held command is
    mid-range (0.6 rad; the old controller held 0, outside that range), never NaN."""
    task = fw.task_from_plan(short_plan, "short")
    header = re.sub(r"\.q_start = \{CTRL_LIT\([^)]*\)", ".q_start = {CTRL_LIT(NAN)", task.header, count=1)
    header = re.sub(r"\.q_min = \{CTRL_LIT\([^)]*\)", ".q_min = {CTRL_LIT(0.2)", header, count=1)
    header = re.sub(r"\.q_max = \{CTRL_LIT\([^)]*\)", ".q_max = {CTRL_LIT(1.0)", header, count=1)
    bad = dataclasses.replace(task, header="#include <math.h>\n" + header)
    run = fw.run_host(builder.executable(HOST_SAN, bad, "bad_start"))
    assert (run.summary["init"], run.fault) == ("BAD_CONFIG", "BAD_CONFIG")
    assert_never_nan(run)
    assert np.all(run.data[:, 2] == 0.2 + 0.5 * (1.0 - 0.2))  # lo + (hi - lo) / 2, as the controller
    q0 = load_robot("modular8").configuration("q0")
    assert np.array_equal(run.data[0, 3:10], q0[1:])  # the valid joints hold their start


# --------------------------------------------------------------------------- MISRA (issue 11)

LINK_HEADERS = {"fw_link.h", "fw_link_msgs.h"}


def misra_deviations() -> list[tuple[set[str], set[str]]]:
    """(rules, files) per row of docs/firmware.md's deviation table (the one documented list)."""
    text = (REPO / "docs" / "firmware.md").read_text(encoding="utf-8")
    section = text.split("## MISRA C:2012 deviations (firmware stub)", 1)[1]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and re.fullmatch(r"[\d.]+(, [\d.]+)*", cells[0]):
            rows.append(({r.strip() for r in cells[0].split(",")}, {f.strip() for f in cells[1].split(",")}))
    return rows


def test_misra_findings_are_all_documented_deviations(short_plan, tmp_path):
    """Both builds of the sources: modular8 (no inertials) and iiwa14 with its dynamics
    (CTRL_HAS_DYNAMICS: the feed-forward torque and the TORQUE check)."""
    cppcheck = require_tool("cppcheck")
    rows = misra_deviations()
    assert rows, "the deviation table is missing from docs/firmware.md"
    builds = {"modular8": (fw.task_from_plan(short_plan, "short"), []),
              "iiwa14": (fw.task_from_file(EXAMPLES / "iiwa14_fault_circle_wln.toml"), ["-DCTRL_HAS_DYNAMICS=1"])}
    stub = fw.FIRMWARE_DIR
    sources = [stub / "controller.c", stub / "fw_program.c", stub / "fw_csv.c", stub / "fw_task.c", stub / "host" / "main.c",
               *sorted((stub / "arm").glob("*.c"))]
    findings = set()
    for name, (task, defines) in builds.items():
        assert task.robot.has_dynamics == bool(defines)
        gen_dir = REPO / "generated" / name
        fw.write_task_files(task, tmp_path / name, gen_dir)  # task_params.h, fw_ptp.{h,c}, robot_fw.c
        proc = subprocess.run([cppcheck, "--addon=misra", "--std=c99", "-q", "--template={file}:{line}:{id}",
                               f"-DCTRL_ROBOT={name}", f"-DCTRL_ROBOT_UC={name.upper()}",
                               f'-DCTRL_ROBOT_HEADER="{name}.h"', f"-D{name.upper()}_USE_FLOAT=1", "-DFW_USE_FLOAT=1",
                               *defines, f"-I{stub}", f"-I{stub / 'arm'}", f"-I{gen_dir}", f"-I{tmp_path / name}",
                               *map(str, sources)], capture_output=True, text=True, timeout=900)
        found = {(Path(f).name, int(line), rule) for f, line, rule in
                 re.findall(r"^(.+?):(\d+):misra-c2012-([\d.]+)$", proc.stdout + proc.stderr, re.M)}
        assert found, f"cppcheck's MISRA addon reported nothing for {name}: is the addon installed?"
        # (the link runner includes the link's headers: their findings are docs/link.md's table,
        # checked by tests/test_link_codec.py with the link's sources)
        findings |= {(f, line, rule) for f, line, rule in found if f not in LINK_HEADERS}

    def covered(name: str, rule: str) -> bool:
        return any(rule in rules and name in files for rules, files in rows)

    undocumented = sorted(f"{name}:{line} rule {rule}" for name, line, rule in findings if not covered(name, rule))
    assert not undocumented, "MISRA findings outside docs/firmware.md's deviation list:\n" + "\n".join(undocumented)
    stale = [sorted(rules) for rules, files in rows
             if not any(rule in rules and name in files for name, _, rule in findings)]
    assert not stale, f"deviation rows that no finding needs any more: {stale}"
