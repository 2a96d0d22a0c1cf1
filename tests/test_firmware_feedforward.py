"""The feed-forward torque on board (issue 39): for a robot with inertials the controller computes
each command's ``tau_ff`` (gravity only, or the inverse dynamics of the command's q, q̇, q̈) in
every mode, reports it in the run's CSV, and faults TORQUE (the arm holds) when a command needs
more than a joint's taumax; a robot without inertials has no feed-forward at all.

The robot is the bundled iiwa14 (Drake's inertials, KUKA's torque limits). The reference is the
Python model (``Robot.rnea`` / ``Robot.gravity_torques``, checked against Pinocchio in
tests/test_dynamics.py) at the states the run commanded, with q̈ by the documented rule: the
mode's own acceleration (playback: the plan's polynomial ``eps`` column; MOVE_TO: its trapezoid),
else the backward difference of the commanded velocities over one tick."""

from __future__ import annotations

import copy
import dataclasses
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from armgen import firmware as fw
from armgen.cli.firmware import FEEDFORWARD_CHOICES
from armgen.cli.main import cli
from armgen.codegen import toolchain
from armgen.errors import OptionError
from armgen.firmware.configuration import (FEEDFORWARD_IDS, FirmwareTask, common_fields, task_header, template,
                                           with_feedforward)
from armgen.firmware.literals import c_reals
from armgen.planning.tasks import load_task, run_task
from armgen.robot import BUNDLED_DIR, load_robot
from armgen.verification.compare import DOUBLE_REL_BOUND, FLOAT_BOUNDS

from conftest import require_tool

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "examples"
HOST_SAN = fw.Variant("host", "double", sanitize=True, opt="-O1")
HOST_FLOAT = fw.Variant("host", "float")

# The double build's tau_ff against the Python model: the generated rnea is the CasADi graph op
# for op (the verifier's DOUBLE_REL_BOUND, of the largest torque of the sample); the CSV holds
# the commanded doubles exactly (%.17g) and the backward difference is the same two operations.
DOUBLE_RTOL = DOUBLE_REL_BOUND
# The float builds: the generated float rnea at the float commands against the double model at
# the same (exactly printed) values, the verifier's bound for rnea (of the largest torque); the
# float backward difference adds ~1e-7 of q̈, far below it.
FLOAT_RTOL = FLOAT_BOUNDS["rnea"]
# controller.c's TORQUE_RTOL: a command may need tau_max (1 + this) before TORQUE.
TORQUE_RTOL = 1e-3
# The swing played back (ptp, a quintic): a1 (the vertical axis, no gravity torque) and
# a2, a4 by these angles in SWING_S seconds from q0, at rest at both ends.
SWING_RAD = {"a1": 1.0, "a2": 0.4, "a4": 0.5}
SWING_S = 1.5  # a1 peaks at 1.25 rad/s (1.875 Δ/T), within its qdlim of 85°/s
STEP_S = 0.01


def _columns(run: fw.FirmwareRun, stem: str, unit: str, n: int) -> np.ndarray:
    return np.column_stack([run.column(f"{stem}{i + 1}_{unit}") for i in range(n)])


def _command_rows(run: fw.FirmwareRun, n: int) -> dict[str, np.ndarray]:
    """The rows of the accepted commands, tick 0, 1, … in order (the first row of each tick),
    as q, qd, tau_ff, state, fault; and the hold rows after them."""
    rows = run.by_tick()
    ticks = sorted(rows)
    data = np.array([rows[k] for k in ticks])
    index = {name: run.columns.index(name) for name in ("state", "fault")}
    q0, qd0, tau0 = (run.columns.index(c) for c in ("q1_rad", "dq1_rad_s", "tau_ff1_Nm"))
    return {"tick": np.array(ticks), "q": data[:, q0:q0 + n], "qd": data[:, qd0:qd0 + n],
            "tau": data[:, tau0:tau0 + n], "state": data[:, index["state"]].astype(int),
            "fault": data[:, index["fault"]].astype(int)}


def _backward_difference(qd: np.ndarray, dt: float) -> np.ndarray:
    """docs/firmware.md's rule where a mode has no acceleration: (q̇_k − q̇_{k−1}) / dt, from rest."""
    previous = np.vstack([np.zeros((1, qd.shape[1])), qd[:-1]])
    return (qd - previous) / dt


def _relative(got: np.ndarray, reference: np.ndarray) -> float:
    """The largest error of a row over the largest reference torque of that row (N·m)."""
    scale = np.maximum(np.max(np.abs(reference), axis=1), 1.0)
    return float(np.max(np.max(np.abs(got - reference), axis=1) / scale))


def _swing_task(robot_ref: str, robot) -> dict:
    q0 = robot.configuration("q0")
    theta = {j.name: [float(q), float(q + SWING_RAD.get(j.name, 0.0))] for j, q in zip(robot.joints, q0)}
    return {"planner": "ptp", "robot": robot_ref, "method": "quintic", "step": STEP_S,
            "waypoints": {"t": [0.0, SWING_S], "theta": theta, "omega": {j.name: [0.0, 0.0] for j in robot.joints}},
            "check": {"limits": "report"}}


def _plan(task: dict, source: str):
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    return run_task(copy.deepcopy(task), source)


def _plan_acceleration(plan, robot) -> np.ndarray:
    """The ptp plan's own q̈ per robot joint (its eps columns; 0 for a joint it holds)."""
    return np.column_stack([plan.column(f"eps_{j.name}_rad_s2") if f"eps_{j.name}_rad_s2" in plan.columns
                            else np.zeros(len(plan.data)) for j in robot.joints])


@pytest.fixture(scope="module")
def robot():
    robot = load_robot("iiwa14")
    assert robot.has_dynamics and np.all(np.isfinite(robot.taumax))
    return robot


@pytest.fixture(scope="module")
def builder(robot, tmp_path_factory):
    return fw.FirmwareBuilder(robot, tmp_path_factory.mktemp("feedforward"))


@pytest.fixture(scope="module")
def swing(robot):
    plan = _plan(_swing_task("iiwa14", robot), "swing")
    return plan, fw.task_from_plan(plan, "swing", robot)


def _sampled_task(robot, plan) -> FirmwareTask:
    """The swing's joint samples played back as a sampled table (CTRL_MODE_SAMPLED, the mode of
    snake plans: no robot with inertials has one), from the snake adapter's templates."""
    q = np.column_stack([plan.column(f"theta_{j.name}_rad") for j in robot.joints])
    samples = "\n".join(template("sampled_row.h", values=c_reals(row)) for row in q)
    tables = template("sampled_table.h", rows=len(q), samples=samples) + "\n\n"
    fields = template("sampled.h", common=common_fields(robot, "CTRL_MODE_SAMPLED", STEP_S, q[0]))
    header = task_header(robot, "swing samples", fields, "the swing's samples", tables=tables)
    return FirmwareTask(robot, "sampled", header, STEP_S, len(q) - 1, "swing samples")


def _line_task(robot) -> dict:
    """A 5 cm line of the tool from q0 in 1 s (resolved rate, as the firmware project's demo)."""
    pose = robot.fk(robot.configuration("q0"))
    return {"planner": "cartesian", "robot": "iiwa14", "start": "q0",
            "path": {"type": "line", "end": (pose[:3, 3] + [0.05, 0.0, 0.0]).tolist(), "orientation": "hold"},
            "timing": {"duration": 1.0, "law": "cubic"}, "integrator": {"method": "euler", "step": STEP_S},
            "method": {"name": "pinv"}}


# --------------------------------------------------------------------------- tau_ff = the model

@pytest.mark.parametrize("case", ["resolved_rate", "fault_tolerant", "weighted_gpm", "playback", "playback_gravity",
                                  "sampled"])
def test_tau_ff_is_the_models_torque_at_each_command(case, robot, builder, swing):
    """Host double with ASan/UBSan: every command's tau_ff is rnea(q, q̇, q̈) of that command
    (gravity(q) with feedforward = gravity), q̈ by the mode's rule (sampled playback: the centred
    second difference of the table); the hold rows after DONE hold
    gravity(q); the run ends DONE within the (bundled) torque limits."""
    if case == "resolved_rate":
        plan = _plan(_line_task(robot), case)
        task = fw.task_from_plan(plan, case, robot)
    elif case == "fault_tolerant":  # the wrist locks at 2 s: the velocities jump, a one-tick q̈
        plan = _plan(load_task(EXAMPLES / "iiwa14_fault_circle_wln.toml")[0], case)
        task = fw.task_from_plan(plan, case, robot)
    elif case == "weighted_gpm":  # the line with spec 35's secondary terms ramping in over 0.2 s
        line = dict(_line_task(robot), planner="wgpm", method={"name": "wgpm", "ramp_time": 0.2})
        line["integrator"] = {"step": STEP_S, "clik": True, "clik_gain": 10}
        plan = _plan(line, case)
        task = fw.task_from_plan(plan, case, robot)
    else:
        plan, task = swing
    if case == "sampled":  # q̇ the forward difference to the next row, q̈ the backward one of q̇
        task = _sampled_task(robot, plan)
    if case == "playback_gravity":
        task = with_feedforward(task, "gravity")
    assert task.feedforward == ("gravity" if case == "playback_gravity" else "inverse_dynamics")
    run = fw.run_host(builder.executable(HOST_SAN, task, case))
    assert (run.state, run.fault) == ("DONE", "NONE")
    c = _command_rows(run, robot.n)
    assert len(c["tick"]) == task.n_ticks + 1 and np.all(c["tick"] == np.arange(task.n_ticks + 1))
    if case == "playback_gravity":
        reference = robot.gravity_torques(c["q"])
    else:
        qdd = _plan_acceleration(plan, robot) if task.mode == "playback" else _backward_difference(c["qd"], task.dt)
        reference = robot.rnea(c["q"], c["qd"], qdd)
    assert _relative(c["tau"], reference) <= DOUBLE_RTOL
    assert np.all(np.abs(c["tau"]) <= robot.taumax)
    held = run.data[len(c["tick"]):]  # after DONE: holding the last command, at rest
    tau0 = run.columns.index("tau_ff1_Nm")
    assert len(held) >= 1 and np.allclose(held[:, 2:2 + robot.n], c["q"][-1], rtol=0, atol=0)
    assert _relative(held[:, tau0:tau0 + robot.n], robot.gravity_torques(held[:, 2:2 + robot.n])) <= DOUBLE_RTOL


def test_tau_ff_in_float_within_the_generated_codes_bound(robot, builder, swing):
    """Host float: the same run in single precision, within the float rnea's bound."""
    plan, task = swing
    run = fw.run_host(builder.executable(HOST_FLOAT, task, "swing_float"))
    assert (run.state, run.fault) == ("DONE", "NONE")
    c = _command_rows(run, robot.n)
    assert _relative(c["tau"], robot.rnea(c["q"], c["qd"], _plan_acceleration(plan, robot))) <= FLOAT_RTOL


# --------------------------------------------------------------------------- TORQUE

@pytest.fixture(scope="module")
def tight(robot, swing, tmp_path_factory):
    """iiwa14 with a1's taumax at 60 % of what the swing asks of it: (robot, plan, its task,
    the limit, the tick the controller must stop at, a builder)."""
    plan, _ = swing
    reference = robot.rnea(*(np.column_stack([plan.column(f"{kind}_{j.name}_{unit}") for j in robot.joints])
                             for kind, unit in (("theta", "rad"), ("omega", "rad_s"))), _plan_acceleration(plan, robot))
    peak = float(np.max(np.abs(reference[:, 0])))
    limit = round(0.6 * peak, 1)
    over = np.abs(reference[:, 0]) > limit * (1 + TORQUE_RTOL)
    tick = int(np.argmax(over))
    assert over.any() and tick > 0
    # no command within rounding of the threshold: the tick is the same in every precision
    assert np.min(np.abs(np.abs(reference[:, 0]) / (limit * (1 + TORQUE_RTOL)) - 1)) > 1e-4
    folder = tmp_path_factory.mktemp("tight")
    text = (BUNDLED_DIR / "iiwa14.toml").read_text(encoding="utf-8")
    assert text.count("taumax = 320\n") == 2
    (folder / "iiwa14_tight.toml").write_text(text.replace("taumax = 320\n", f"taumax = {limit}\n", 1)
                                              .replace('name = "iiwa14"', 'name = "iiwa14_tight"', 1))
    tight_robot = load_robot(folder / "iiwa14_tight.toml")
    assert tight_robot.taumax[0] == limit
    tight_plan = _plan(_swing_task(str(folder / "iiwa14_tight.toml"), tight_robot), "tight swing")
    beyond = tight_plan.metadata["summary"]["joint_torque"]["beyond_torque_limits"]
    assert [b["joint"] for b in beyond] == ["a1"]  # the planner sees it too (checked, reported)
    return (tight_robot, tight_plan, fw.task_from_plan(tight_plan, "tight swing", tight_robot), limit, tick,
            fw.FirmwareBuilder(tight_robot, folder / "fw"))


def test_a_command_beyond_taumax_faults_torque_and_the_arm_holds(tight):
    """Inverse dynamics: TORQUE (code 15, in the CSV's fault column and the summary) at the first
    command whose |tau_a1| exceeds the limit; that command is not emitted: the arm holds the
    previous one at rest, with its gravity torques."""
    robot, plan, task, limit, tick, builder = tight
    run = fw.run_host(builder.executable(HOST_SAN, task, "tight"))
    assert (run.state, run.fault) == ("FAULT", "TORQUE")
    c = _command_rows(run, robot.n)
    faulted = np.flatnonzero(c["state"] == fw.FAULT_STATE)
    assert c["tick"][faulted[0]] == tick and np.all(c["fault"][faulted] == fw.FAULT_NAMES.index("TORQUE"))
    assert np.all(run.data[-3:, -1] == 15)  # the CSV's fault column, every hold row
    before = c["q"][faulted[0] - 1]
    hold = run.data[run.data[:, 0] == tick]
    assert np.all(hold[:, 2:2 + robot.n] == before) and np.all(hold[:, 2 + robot.n:2 + 2 * robot.n] == 0)
    tau0 = run.columns.index("tau_ff1_Nm")
    assert _relative(hold[:, tau0:tau0 + robot.n], robot.gravity_torques(hold[:, 2:2 + robot.n])) <= DOUBLE_RTOL
    assert np.all(np.abs(c["tau"][:faulted[0], 0]) <= limit * (1 + TORQUE_RTOL))  # every emitted one within


def test_no_torque_fault_without_the_torques_that_exceed(tight):
    """Gravity only: the swing's a1 torque is all acceleration (a vertical axis), so the same
    limit is met and the run ends DONE; no feed-forward: nothing is checked."""
    robot, plan, task, limit, tick, builder = tight
    for choice in ("gravity", "none"):
        run = fw.run_host(builder.executable(HOST_SAN, with_feedforward(task, choice), f"tight_{choice}"))
        assert (run.state, run.fault) == ("DONE", "NONE"), choice
        tau = _columns(run, "tau_ff", "Nm", robot.n)
        assert np.all(np.abs(tau[:, 0]) <= limit) and (choice == "gravity" or np.all(tau == 0))


def test_bad_feedforward_fields_are_refused_at_init(robot, builder, swing):
    """ctrl_init validates the fields like the others: BAD_CONFIG, and no torque is put out."""
    _, task = swing
    cases = {"choice": ("CTRL_FF_INVERSE_DYNAMICS", "(ctrl_feedforward)3"),
             "negative limit": (".tau_max = {CTRL_LIT(320.0)", ".tau_max = {CTRL_LIT(-1.0)"),
             "limit beyond 1e7 N m": (".tau_max = {CTRL_LIT(320.0)", ".tau_max = {CTRL_LIT(2e7)")}
    for name, (old, new) in cases.items():
        assert task.header.count(old) == 1, name
        bad = dataclasses.replace(task, header=task.header.replace(old, new))
        run = fw.run_host(builder.executable(HOST_SAN, bad, "bad_" + "".join(ch for ch in name if ch.isalnum())))
        assert run.summary["init"] == "BAD_CONFIG" and run.fault == "BAD_CONFIG", name
        assert np.all(_columns(run, "tau_ff", "Nm", robot.n) == 0), name


# --------------------------------------------------------------------------- MOVE_TO

MOVE_TO_DRIVER = r"""
#include <stdio.h>
#include "controller.h"
#include "fw_csv.h"
#include "fw_task.h"
#include "extra.h"
int main(void) {
  static ctrl c;
  static char line[FW_CSV_LINE_MAX];
  ctrl_input in = {0};
  ctrl_output out;
  long i;
  if (ctrl_init(&c, &fw_task) != CTRL_FAULT_NONE) return 1;
  (void)fw_csv_header(line, sizeof(line));
  fputs(line, stdout);
  in.command = CTRL_CMD_MOVE_TO;
  for (i = 0; i < 16; ++i) in.target[i] = target[i];
  for (i = 0; i < 100000L; ++i) {
    (void)ctrl_tick(&c, &in, &out);
    in.command = CTRL_CMD_NONE;
    (void)fw_csv_row(line, sizeof(line), &out);
    fputs(line, stdout);
    if (out.state != CTRL_STATE_RUNNING) break;
  }
  printf("# state %s\n# fault %s\n", ctrl_state_name(out.state), ctrl_fault_name(out.fault));
  return 0;
}
"""
# controller.c's MOVE_TO trapezoid: accelerating over this fraction of T, decelerating over as much.
MOVE_TO_BLEND = 0.25


def _run_driver(builder, task, name: str, driver: str, folder: Path, extra_header: str = "") -> fw.FirmwareRun:
    """A C driver of the controller (its own main, in place of the host runner) linked with the
    builder's objects and ``task``; what it printed."""
    fw.run_host(builder.executable(HOST_SAN, task, name))  # the objects and the task's fw_task.o
    (folder / "extra.h").write_text(extra_header)
    (folder / "driver.c").write_text(driver)
    objects = [o for o in builder.objects(HOST_SAN) if o.stem != "main"]
    exe = folder / "driver"
    toolchain.run_tool([toolchain.host_cc(), *builder.cflags(HOST_SAN), f"-I{folder}", str(folder / "driver.c"),
                        *map(str, objects), str(builder.work / f"{HOST_SAN.name}_{name}" / "fw_task.o"), "-lm",
                        "-o", str(exe)], f"the {name} driver")
    proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and not proc.stderr, proc.stderr[-3000:]
    return fw.parse_output(proc.stdout)


SETPOINT_DRIVER = r"""
#include <stdio.h>
#include "controller.h"
#include "fw_csv.h"
#include "fw_task.h"
#include "extra.h"
int main(void) {
  static ctrl c;
  static char line[FW_CSV_LINE_MAX];
  ctrl_input in = {0};
  ctrl_output out;
  long i;
  int j;
  if (ctrl_init(&c, &fw_task) != CTRL_FAULT_NONE) return 1;
  (void)fw_csv_header(line, sizeof(line));
  fputs(line, stdout);
  for (i = 0; i < STOP_TICK + 10; ++i) {
    in.command = i == 0 ? CTRL_CMD_START : (i == STOP_TICK ? CTRL_CMD_STOP : (i > STOP_TICK ? CTRL_CMD_SETPOINT
                                                                                             : CTRL_CMD_NONE));
    for (j = 0; j < CTRL_NDOF && i > STOP_TICK; ++j) { /* hold where the STOP left the arm */
      in.q_ref[j] = out.q[j];
      in.qd_ref[j] = CTRL_LIT(0.0);
    }
    (void)ctrl_tick(&c, &in, &out);
    (void)fw_csv_row(line, sizeof(line), &out);
    fputs(line, stdout);
  }
  printf("# state %s\n# fault %s\n", ctrl_state_name(out.state), ctrl_fault_name(out.fault));
  return 0;
}
"""


def test_a_setpoint_after_a_stop_starts_from_rest(robot, builder, swing, tmp_path):
    """STOP in the middle of the swing (a1 at ~1 rad/s), then SETPOINTs holding that pose: the
    arm was held at rest, so their tau_ff is the gravity torques (q̈ from rest), not the
    deceleration from the velocity before the STOP (~100 rad/s² in one tick)."""
    _, task = swing
    stop = 75  # mid-swing: the fastest tick
    run = _run_driver(builder, task, "setpoint", SETPOINT_DRIVER, tmp_path, f"#define STOP_TICK {stop}L\n")
    assert (run.state, run.fault) == ("RUNNING", "NONE")
    qd = _columns(run, "dq", "rad_s", robot.n)
    assert abs(qd[stop - 1, 0]) > 1.0  # moving fast when stopped
    after = np.arange(len(run.data)) > stop
    q, tau = run.q(robot.n)[after], _columns(run, "tau_ff", "Nm", robot.n)[after]
    assert np.all(q == run.q(robot.n)[stop]) and np.all(qd[after] == 0)
    assert _relative(tau, robot.gravity_torques(q)) <= DOUBLE_RTOL


def test_move_to_tau_ff_uses_the_profiles_own_acceleration(robot, builder, tmp_path):
    """MOVE_TO from q0 to the pose of another configuration: each tick's tau_ff is rnea at the
    command with the trapezoid's q̈ = s''(t/T) Δ / T² (k, 0, −k; 0 on the last tick)."""
    q0 = robot.configuration("q0")
    hold = {"planner": "ptp", "robot": "iiwa14", "method": "3-4", "step": STEP_S,
            "waypoints": {"t": [0.0, 1.0], "omega": {j.name: [0.0, 0.0] for j in robot.joints},
                          "theta": {j.name: [float(q), float(q)] for j, q in zip(robot.joints, q0)}}}
    task = fw.task_from_plan(_plan(hold, "hold"), "hold", robot)
    target = robot.fk(q0 + np.array([0.3, 0.2, -0.2, 0.3, 0.2, -0.3, 0.2]))
    values = ", ".join(f"CTRL_LIT({float(v)!r})" for v in target.T.ravel())
    run = _run_driver(builder, task, "hold", MOVE_TO_DRIVER, tmp_path,
                      f"static const ctrl_real target[16] = {{{values}}};\n")
    assert (run.state, run.fault) == ("DONE", "NONE")
    c = _command_rows(run, robot.n)
    n = int(c["tick"][-1])
    T = n * task.dt
    delta = c["q"][-1] - q0
    t = c["tick"] * task.dt
    k = 1.0 / (MOVE_TO_BLEND * (1.0 - MOVE_TO_BLEND))
    dds = np.where(t / T < MOVE_TO_BLEND, k, np.where(t / T > 1.0 - MOVE_TO_BLEND, -k, 0.0))
    dds[c["tick"] >= n] = 0.0
    qdd = dds[:, None] * delta[None, :] / T ** 2
    assert n > 10 and _relative(c["tau"], robot.rnea(c["q"], c["qd"], qdd)) <= DOUBLE_RTOL


# --------------------------------------------------------------------------- the choice

def test_a_robot_without_inertials_has_no_feed_forward(tmp_path):
    """modular8 (no inertials): its task_params.h and CSV are as before (no field, no column);
    asking it for a feed-forward names the robot, what is missing and the fix (exit 2)."""
    robot = load_robot("modular8")
    assert not robot.has_dynamics
    task = fw.task_from_file(EXAMPLES / "modular8_ptp_two_segments.toml")
    assert task.feedforward == "none" and "feedforward" not in task.header and "tau_max" not in task.header
    assert with_feedforward(task, "none") is task
    with pytest.raises(OptionError, match="give one of none, gravity, inverse_dynamics"):
        with_feedforward(task, "full")
    for choice in ("gravity", "inverse_dynamics"):
        with pytest.raises(OptionError, match=r"modular8.*has no inertials.*mass, com and inertia"):
            with_feedforward(task, choice)
    result = CliRunner().invoke(cli, ["firmware-task", str(EXAMPLES / "modular8_ptp_two_segments.toml"),
                                      "-o", str(tmp_path / "t"), "--feedforward", "gravity"])
    assert result.exit_code == 2 and "has no inertials" in result.output and not (tmp_path / "t").exists()
    result = CliRunner().invoke(cli, ["firmware", "modular8", "-o", str(tmp_path / "p"), "--feedforward", "gravity"])
    assert result.exit_code == 2 and "has no inertials" in result.output and not (tmp_path / "p").exists()


def test_the_choice_reaches_task_params_h(tmp_path, robot):
    """iiwa14: the inverse dynamics unless asked otherwise, and the robot file's taumax."""
    assert FEEDFORWARD_CHOICES == tuple(FEEDFORWARD_IDS)  # the CLI's list is the configuration's
    source = EXAMPLES / "iiwa14_fault_circle_wln.toml"
    for choice in (None, *FEEDFORWARD_CHOICES):
        out = tmp_path / str(choice)
        args = ["firmware-task", str(source), "-o", str(out)] + (["--feedforward", choice] if choice else [])
        result = CliRunner().invoke(cli, args)
        assert result.exit_code == 0, result.output
        header = (out / "task_params.h").read_text()
        assert f".feedforward = {FEEDFORWARD_IDS[choice or 'inverse_dynamics']}," in header
        limits = ", ".join(f"CTRL_LIT({float(v)!r})" for v in robot.taumax)
        assert f".tau_max = {{{limits}}}," in header


# --------------------------------------------------------------------------- Cortex-M4F

def test_qemu_float_build_runs_with_the_inverse_dynamics(robot, builder, swing):
    """The Cortex-M4F build (float, QEMU) with feed-forward on: the swing ends DONE and its
    tau_ff is the model's within the float bound."""
    require_tool("arm-none-eabi-gcc")
    require_tool("qemu-system-arm")
    plan, task = swing
    run = fw.run_qemu(builder.executable(fw.ARM_VARIANT, task, "swing_m4"))
    assert (run.state, run.fault) == ("DONE", "NONE") and run.summary["real_bytes"] == "4"
    c = _command_rows(run, robot.n)
    assert _relative(c["tau"], robot.rnea(c["q"], c["qd"], _plan_acceleration(plan, robot))) <= FLOAT_RTOL
