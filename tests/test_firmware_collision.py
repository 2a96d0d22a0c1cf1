"""Issue 38 on the board: the controller's tick takes the collision criterion in every
resolved-rate mode exactly as the planners do (so the firmware reproduces a plan that bends
around an obstacle), checks every command's least distance against the task's clearance (the
COLLISION fault, the arm holds; MOVE_TO included) and reports it (ctrl_output.clearance).

The bar's task is benchmarks/data/collision/baxter_pillar_seam.toml: Baxter's left arm (not a
bundled robot) welds a seam beside a gantry column; the minimum-norm plan's forearm goes into
the column, the criterion keeps it clear. The reference distances are Robot.collision_distances
(CasADi, in Python), not the generated C the firmware runs."""

from __future__ import annotations

import copy
import dataclasses
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from armgen import firmware as fw
from armgen.codegen import toolchain
from armgen.description.collision import SphereObstacle
from armgen.planning.result import read_plan, write_plan
from armgen.planning.tasks import load_task, run_task
from armgen.verification import firmware_compare as fwcmp

from conftest import require_tool
from test_collision_planning import GAIN, line_task, robot_file  # noqa: F401  (the iiwa14 with capsules)

REPO = Path(__file__).resolve().parent.parent
BAR_TASK = REPO / "benchmarks" / "data" / "collision" / "baxter_pillar_seam.toml"
HOST_SAN = fw.Variant("host", "double", sanitize=True, opt="-O1")
# The firmware's clearance of a command and Robot.collision_distances at the plan's sample: the
# same formulas in double, through the generated C and through CasADi (to rounding).
DISTANCE_TOL = 1e-9  # m
# The bar for the Cortex-M4F float run against the plan; the float criterion's gradient
# carries ~1e-7 relative rounding (docs/collision.md), far below it (measured 5.5e-7 rad).
QEMU_FLOAT_BOUND_RAD = 1e-4
# ctrl_output.clearance without a check: the generated distance of an inactive obstacle slot.
UNCHECKED_M = 1000.0


def bar_document(**collision) -> dict:
    doc, _ = load_task(BAR_TASK)
    doc["robot"] = str(BAR_TASK.parent / doc["robot"])
    doc["collision"].update(collision)
    return doc


def least_distances(robot, q: np.ndarray, obstacles) -> np.ndarray:
    return np.array([robot.collision_distances(row, obstacles).min() for row in q])


def plan_q(plan, n: int) -> np.ndarray:
    return np.column_stack([plan.column(f"q{i + 1}_rad") for i in range(n)])


@pytest.fixture(scope="module")
def bar_plan():
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    return run_task(bar_document(), str(BAR_TASK))


@pytest.fixture(scope="module")
def baxter(bar_plan, tmp_path_factory):
    return fw.FirmwareBuilder(bar_plan.config.robot, tmp_path_factory.mktemp("fw_collision_baxter"))


def test_the_host_firmware_replays_the_plan_around_the_column(bar_plan, baxter):
    task = fw.task_from_plan(bar_plan, "bar")
    assert task.collision is not None and ".collision = &fw_task_collision" in task.header
    run = fw.run_host(baxter.executable(HOST_SAN, task, "bar"))
    cmp = fwcmp.compare_with_plan(bar_plan, run, task, "double", "bar")
    assert cmp.passed, cmp.rows
    assert cmp.max_dq <= fwcmp.FW_DOUBLE_BOUND_RAD
    # every tick's clearance is the least distance of its command, the plan's sample
    robot, obstacles = task.robot, task.collision.obstacles
    ticks = run.by_tick()
    q = plan_q(bar_plan, robot.n)
    reference = least_distances(robot, q, obstacles)
    firmware = np.array([ticks[k][run.columns.index("clearance_m")] for k in range(len(q))])
    assert np.max(np.abs(firmware - reference)) <= DISTANCE_TOL
    assert firmware.min() >= task.collision.settings.clearance
    assert firmware.min() == pytest.approx(bar_plan.metadata["summary"]["collision"]["min_clearance_m"],
                                           abs=DISTANCE_TOL)


def test_an_obstacle_on_the_path_is_the_collision_fault_and_the_arm_holds(baxter):
    """The minimum-norm plan (gain 0), written although it goes into the column: the controller
    stops with COLLISION at the first tick whose command is closer than the clearance and holds
    the previous command (compare_with_plan expects exactly that tick in double)."""
    plan = run_task(dict(bar_document(gain=0.0), check={"limits": "report"}), "plain")
    assert not plan.metadata["summary"]["collision"]["within_clearance"]
    task = fw.task_from_plan(plan, "plain")
    run = fw.run_host(baxter.executable(HOST_SAN, task, "plain"))
    cmp = fwcmp.compare_with_plan(plan, run, task, "double", "plain")
    assert cmp.passed, cmp.rows
    assert (run.state, run.fault) == ("FAULT", "COLLISION")
    robot, clearance = task.robot, task.collision.settings.clearance
    reference = least_distances(robot, plan_q(plan, robot.n), task.collision.obstacles)
    first = int(np.argmax(reference < clearance))
    assert cmp.fault_tick == first > 0
    ticks = run.by_tick()
    held, before = ticks[first], ticks[first - 1]
    assert np.array_equal(held[2:2 + robot.n], before[2:2 + robot.n])  # the arm holds the last safe command
    assert held[run.columns.index("clearance_m")] == before[run.columns.index("clearance_m")] >= clearance
    assert np.all(run.data[-1][2 + robot.n:2 + 2 * robot.n] == 0.0)  # at rest


def test_a_plan_read_from_disk_expects_the_collision_stop(baxter, tmp_path):
    """`armgen verify --run`'s way: the plan CSV and its plan.json, the task configured again from
    the recorded document, compared with the firmware's run (its COLLISION stop expected)."""
    plan = run_task(dict(bar_document(gain=0.0), check={"limits": "report"}), "plain")
    write_plan(plan, tmp_path / "plain.csv")
    read = read_plan(tmp_path / "plain.csv")
    task = fw.task_from_plan(read, str(tmp_path / "plain.csv"))
    assert task.collision is not None
    run = fw.run_host(baxter.executable(HOST_SAN, task, "plain_read"))
    cmp = fwcmp.compare_with_plan(read, run, task, "double", "plain.csv")
    assert cmp.passed, cmp.rows
    assert run.fault == "COLLISION" and any("COLLISION at tick" in str(row[3]) for row in cmp.rows)


def test_without_collision_table_nothing_is_checked_on_board(baxter):
    """A robot with capsules, a task without [collision]: the firmware neither binds the collision
    functions nor checks (docs/collision.md, "On the board"); its clearance says so."""
    doc = bar_document()
    del doc["obstacles"], doc["collision"]
    task = fw.task_from_dict(doc, "free")
    assert task.collision is None and "collision" not in task.header
    run = fw.run_host(baxter.executable(HOST_SAN, task, "free"))
    assert (run.state, run.fault) == ("DONE", "NONE")
    assert np.all(run.column("clearance_m") == UNCHECKED_M)


@pytest.mark.parametrize("field, value", [("activation", "CTRL_LIT(0.02)"), ("clearance", "CTRL_LIT(-0.01)"),
                                          ("gain", "CTRL_LIT(-1.0)")])
def test_a_broken_collision_configuration_is_refused(bar_plan, baxter, field, value):
    """ctrl_init checks the bound configuration: 0 <= clearance < activation, gain >= 0, and a
    criterion bound where the gain is above 0."""
    task = fw.task_from_plan(bar_plan, "bar")
    lines = [line for line in task.header.splitlines() if line.startswith(f"  .{field} = ")]
    assert len(lines) == 1
    broken = dataclasses.replace(task, header=task.header.replace(lines[0], f"  .{field} = {value},"))
    run = fw.run_host(baxter.executable(HOST_SAN, broken, f"broken_{field}"))
    assert (run.state, run.fault) == ("FAULT", "BAD_CONFIG")


def test_a_gain_without_a_bound_criterion_is_refused(baxter):
    """A check-only task (gain 0) binds no criterion; a gain written into it by hand is refused."""
    task = fw.task_from_dict(bar_document(gain=0.0), "check_only")
    assert "  .criterion = NULL," in task.header
    broken = dataclasses.replace(task, header=task.header.replace("  .gain = CTRL_LIT(0.0),", "  .gain = CTRL_LIT(0.01),"))
    assert broken.header != task.header
    run = fw.run_host(baxter.executable(HOST_SAN, broken, "gain_without_criterion"))
    assert (run.state, run.fault) == ("FAULT", "BAD_CONFIG")


def test_a_non_finite_obstacle_is_refused(bar_plan, baxter):
    task = fw.task_from_plan(bar_plan, "bar")
    line = next(line for line in task.header.splitlines() if line.startswith("static const ctrl_real fw_task_planes"))
    broken = dataclasses.replace(task, header=task.header.replace(line, line.replace("CTRL_LIT(-0.32)", "(CTRL_LIT(0.0) / CTRL_LIT(0.0))")))
    run = fw.run_host(baxter.executable(HOST_SAN, broken, "nan_plane"))
    assert (run.state, run.fault) == ("FAULT", "BAD_CONFIG")


MODES = [("fault_tolerant", "gpm"), ("wgpm", "wgpm"), ("cartesian", "zghal")]


@pytest.fixture(scope="module")
def mode_plans(robot_file, tmp_path_factory):  # noqa: F811
    """tests/test_collision_planning.py's scene (the iiwa14 with capsules beside a sphere its
    minimum-norm elbow passes through): each planner's avoiding plan and its firmware task, and
    one firmware builder for that robot."""
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    plans = {}
    for planner, method in MODES:
        plan = run_task(line_task(robot_file, planner, method, GAIN, limits="error"), f"{planner}.toml")
        plans[planner] = (plan, fw.task_from_plan(plan, planner))
    robot = plans["cartesian"][1].robot
    return plans, fw.FirmwareBuilder(robot, tmp_path_factory.mktemp("fw_collision_iiwa14c"))


@pytest.mark.parametrize("planner", [planner for planner, _ in MODES])
def test_every_resolved_rate_mode_descends_the_criterion_as_its_planner(mode_plans, planner):
    plans, builder = mode_plans
    plan, task = plans[planner]
    assert task.mode == {"fault_tolerant": "fault_tolerant", "wgpm": "weighted_gpm"}.get(planner, "resolved_rate")
    run = fw.run_host(builder.executable(HOST_SAN, task, planner))
    cmp = fwcmp.compare_with_plan(plan, run, task, "double", planner)
    assert cmp.passed, cmp.rows
    assert cmp.max_dq <= fwcmp.FW_DOUBLE_BOUND_RAD
    assert run.column("clearance_m").min() >= task.collision.settings.clearance


@pytest.mark.arm
@pytest.mark.parametrize("planner", [planner for planner, _ in MODES])
def test_every_resolved_rate_mode_with_the_criterion_replays_on_the_cortex_m4f(mode_plans, planner):
    """The same plans on the Cortex-M4F (float) within verify's float replay bound."""
    require_tool("arm-none-eabi-gcc")
    require_tool("qemu-system-arm")
    plans, builder = mode_plans
    plan, task = plans[planner]
    run = fw.run_qemu(builder.executable(fw.ARM_VARIANT, task, planner + "_m4"))
    cmp = fwcmp.compare_with_plan(plan, run, task, "float", planner)
    assert cmp.passed, cmp.rows
    assert cmp.max_dq <= fwcmp.FW_FLOAT_BOUND_RAD
    assert run.column("clearance_m").min() >= task.collision.settings.clearance


def test_the_bundled_pillar_example_runs_on_board_as_planned(tmp_path):
    """examples/iiwa14_weld_seam_pillar.toml (docs/collision.md's worked example): a weighted-GPM
    program on the bundled iiwa14's capsules, bent around a pillar by the criterion."""
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    doc, sha = load_task(REPO / "examples" / "iiwa14_weld_seam_pillar.toml")
    plan = run_task(doc, "iiwa14_weld_seam_pillar.toml", sha)
    task = fw.task_from_plan(plan, "pillar")
    assert task.mode == "weighted_gpm" and task.collision.settings.gain > 0
    run = fw.run_host(fw.FirmwareBuilder(task.robot, tmp_path).executable(HOST_SAN, task, "pillar"))
    cmp = fwcmp.compare_with_plan(plan, run, task, "double", "pillar")
    assert cmp.passed, cmp.rows
    assert cmp.max_dq <= fwcmp.FW_DOUBLE_BOUND_RAD
    assert run.column("clearance_m").min() == pytest.approx(
        plan.metadata["summary"]["collision"]["min_clearance_m"], abs=DISTANCE_TOL)


def test_the_firmware_project_builds_and_runs_the_bar_task(tmp_path, monkeypatch):
    """`armgen firmware --task` → the project's CMake build (CTRL_HAS_COLLISION from the robot) →
    the host demo → `armgen verify --run` against the plan (double, 1e-9 rad)."""
    from click.testing import CliRunner

    from armgen.cli.main import cli
    from test_firmware_task_project import _build_and_run, _verify_run

    require_tool("cmake")
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    out = CliRunner().invoke(cli, ["firmware", str(BAR_TASK.parent / "baxter_arm_capsules.toml"), "--task",
                                   str(BAR_TASK), "--out", str(tmp_path / "fw")])
    assert out.exit_code == 0, out.output
    assert "CTRL_HAS_COLLISION=1" in (tmp_path / "fw" / "CMakeLists.txt").read_text()
    csv = _build_and_run(tmp_path / "fw")
    assert "clearance_m" in csv.read_text()  # the demo prints the tick's clearance
    assert "DONE at 800" in _verify_run(tmp_path / "fw", monkeypatch)


MOVE_TO_DRIVER = r"""
#include <stdio.h>
#include "controller.h"
extern const ctrl_config fw_task;
#include "target.h"
int main(void) {
  static ctrl c;
  ctrl_input in = {0};
  ctrl_output out;
  long k;
  int i;
  if (ctrl_init(&c, &fw_task) != CTRL_FAULT_NONE) return 3;
  for (i = 0; i < 16; ++i) in.target[i] = target[i];
  in.command = CTRL_CMD_MOVE_TO;
  for (k = 0; k < 100000L; ++k) {
    (void)ctrl_tick(&c, &in, &out);
    in.command = CTRL_CMD_NONE;
    printf("%ld %s %s %.17g", k, ctrl_state_name(out.state), ctrl_fault_name(out.fault), (double)out.clearance);
    for (i = 0; i < CTRL_NDOF; ++i) printf(" %.17g", (double)out.q[i]);
    printf("\n");
    if (out.state == CTRL_STATE_DONE || out.state == CTRL_STATE_FAULT) break;
  }
  return 0;
}
"""
# MOVE_TO's target: the start's flange moved this far (m, base frame); a sphere of this radius (m)
# sits on the target's flange, so every configuration that reaches the pose is inside it.
MOVE_TO_OFFSET = np.array([-0.15, 0.15, 0.10])
MOVE_TO_SPHERE_RADIUS = 0.05
MOVE_TO_CLEARANCE, MOVE_TO_ACTIVATION = 0.02, 0.15  # m


def test_move_to_into_an_obstacle_faults_and_holds(bar_plan, tmp_path):
    """A ptp task that holds the start with [collision] and a sphere on the target pose's flange:
    MOVE_TO's profile stops with COLLISION before it gets there, holding a command that keeps
    the clearance."""
    robot = bar_plan.config.robot
    q0 = robot.configuration("q0")
    target = robot.fk(q0)
    target[:3, 3] += MOVE_TO_OFFSET
    # a ptp task's lengths are in m
    hold = {"planner": "ptp", "robot": str(BAR_TASK.parent / "baxter_arm_capsules.toml"), "method": "3-4",
            "step": 0.01,
            "obstacles": [{"type": "sphere", "centre": list(target[:3, 3]), "radius": MOVE_TO_SPHERE_RADIUS}],
            "collision": {"clearance": MOVE_TO_CLEARANCE, "activation": MOVE_TO_ACTIVATION},
            "waypoints": {"t": [0.0, 1.0], "omega": {j.name: [0.0, 0.0] for j in robot.joints},
                          "theta": {j.name: [float(q), float(q)] for j, q in zip(robot.joints, q0)}}}
    task = fw.task_from_plan(run_task(copy.deepcopy(hold), "hold"), "hold", robot)
    assert task.collision is not None
    builder = fw.FirmwareBuilder(robot, tmp_path / "fw")
    fw.run_host(builder.executable(HOST_SAN, task, "hold"))  # the objects and fw_task.o
    objs = [o for o in builder.objects(HOST_SAN) if o.stem != "main"]
    (tmp_path / "target.h").write_text("static const ctrl_real target[16] = {" +
                                       ", ".join(f"CTRL_LIT({float(v)!r})" for v in target.T.ravel()) + "};\n")
    (tmp_path / "driver.c").write_text(MOVE_TO_DRIVER)
    exe = tmp_path / "driver"
    proc = subprocess.run([toolchain.host_cc(), *builder.cflags(HOST_SAN), f"-I{tmp_path}", str(tmp_path / "driver.c"),
                           *map(str, objs), str(builder.work / f"{HOST_SAN.name}_hold" / "fw_task.o"), "-lm",
                           "-o", str(exe)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = subprocess.run([str(exe)], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and not out.stderr, out.stderr[-3000:]
    rows = [line.split() for line in out.stdout.splitlines()]
    states = [r[1] for r in rows]
    assert states[-1] == "FAULT" and rows[-1][2] == "COLLISION", rows[-3:]
    moved = [r for r in rows if r[1] == "RUNNING"]
    assert len(moved) > 10  # it set off, then stopped short
    held = np.array([float(v) for v in rows[-1][4:]])
    last = np.array([float(v) for v in moved[-1][4:]])
    assert np.array_equal(held, last)
    obstacle = [SphereObstacle(tuple(target[:3, 3]), MOVE_TO_SPHERE_RADIUS)]
    held_distance = robot.collision_distances(held, obstacle).min()
    assert held_distance >= MOVE_TO_CLEARANCE
    assert float(rows[-1][3]) == pytest.approx(held_distance, abs=DISTANCE_TOL)
    assert np.linalg.norm(robot.fk(held)[:3, 3] - target[:3, 3]) > MOVE_TO_SPHERE_RADIUS


@pytest.mark.arm
def test_the_cortex_m4f_float_firmware_replays_the_plan_around_the_column(bar_plan, baxter):
    require_tool("arm-none-eabi-gcc")
    require_tool("qemu-system-arm")
    task = fw.task_from_plan(bar_plan, "bar")
    run = fw.run_qemu(baxter.executable(fw.ARM_VARIANT, task, "bar_m4"))
    cmp = fwcmp.compare_with_plan(bar_plan, run, task, "float", "qemu")
    assert cmp.passed, cmp.rows
    assert cmp.max_dq <= QEMU_FLOAT_BOUND_RAD
    assert run.column("clearance_m").min() >= task.collision.settings.clearance
