"""MOVE_TO at its edges (issue 37, items 11, 12, 16): the lower bound of the joint limits,
durations without overflow, every tick's step within qdot_max dt, targets that are not poses,
and the IK's max_iterations <= 0; both precisions, built with ASan/UBSan."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from armgen import firmware as fw
from armgen.codegen import toolchain
from armgen.planning.tasks import run_task
from armgen.robot import load_robot
from armgen.symbolic import ik

PRECISIONS = ["double", "float"]
# The controller's longest MOVE_TO (controller.c MOVE_TO_MAX_TICKS) and the profile's shape: the
# specification the lower bound of the limits follows from (ramps over a quarter of the time
# each, planned at 1 - 1e-3 of the limits).
MAX_TICKS = 2 ** 24
BLEND = 0.25
MARGIN = 1e-3
# A step may exceed qdot_max dt (the profile plans 1 - 1e-3 of it) only by the rounding of the
# two commands it compares (printed with 17 digits: exact): ~1e-16 rad in double; in float an ulp
# of the joint value at each end (|q| < 4 rad here: 2 ulp of 4 rad, 9.5e-7 rad).
STEP_TOL = {"double": 1e-14, "float": 2 * float(np.spacing(np.float32(4.0)))}
# The slow but real limits of the fast-tick move (rad/s, rad/s², s): a step of 2 µrad per tick,
# ~20 ulp of a float joint value near 1 rad; the move takes ~2e4 ticks.
SLOW_QDOT, SLOW_QDDOT, FAST_DT = 0.002, 0.002, 1e-3
SLOW_MOVE_RAD = 0.025  # the target is FK(q0 + this on every joint)

DRIVER = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "controller.h"
extern const ctrl_config fw_task;
#include "targets.h"

static ctrl c;

/* one MOVE_TO to targets[p] under cfg; after `truncate_at` ticks (>= 0) the move is cut short
 * (white box: its last tick becomes the next one, a jump the profile never plans) */
static void move(const ctrl_config *cfg, int p, long truncate_at) {
  ctrl_input in;
  ctrl_output out;
  double step = 0.0, speed = 0.0, prev[CTRL_NDOF];
  long k;
  int i;
  memset(&in, 0, sizeof in);
  if (ctrl_init(&c, cfg) != CTRL_FAULT_NONE) { printf("init %s\n", ctrl_fault_name(c.fault)); return; }
  for (i = 0; i < CTRL_NDOF; ++i) prev[i] = (double)cfg->q_start[i];
  for (i = 0; i < 16; ++i) in.target[i] = targets[p][i];
  in.command = CTRL_CMD_MOVE_TO;
  for (k = 0; k < 100000000L; ++k) {
    if (k == truncate_at) c.n_ticks = c.k + 1u;
    (void)ctrl_tick(&c, &in, &out);
    in.command = CTRL_CMD_NONE;
    for (i = 0; i < CTRL_NDOF; ++i) {
      double s = (double)out.q[i] - prev[i];
      double v = (double)out.qd[i] / (double)cfg->qdot_max[i];
      s = (s < 0 ? -s : s) - (double)cfg->qdot_max[i] * (double)cfg->dt; /* beyond qdot_max dt */
      if (s > step) step = s;
      if (v < 0) v = -v;
      if (v > speed) speed = v;
      prev[i] = (double)out.q[i];
    }
    if (out.state == CTRL_STATE_DONE || out.state == CTRL_STATE_FAULT) break;
  }
  printf("move %s %s %ld %.17g %.17g", ctrl_fault_name(out.fault), ctrl_state_name(out.state), k, step, speed);
  for (i = 0; i < CTRL_NDOF; ++i) printf(" %.17g", (double)out.q[i]);
  printf("\n");
}

/* the period dt, and the held plan's tick count to match (a playback plan spans its knots) */
static void set_dt(ctrl_config *cfg, const char *dt) {
  const ctrl_pb_config *pb = &cfg->pb;
  cfg->dt = (ctrl_real)atof(dt);
  cfg->pb.n_ticks = (int32_t)((double)(pb->knots[pb->nseg] - pb->knots[0]) / (double)cfg->dt + 0.5);
}

int main(int argc, char **argv) {
  ctrl_config cfg = fw_task;
  const char *what = argv[1];
  int i;
  if (argc < 3) return 2;
  if (strcmp(what, "init") == 0) { /* init DT QDOT QDDOT JOINT: the limits of one joint (-1: all) */
    int joint = atoi(argv[5]);
    set_dt(&cfg, argv[2]);
    for (i = 0; i < CTRL_NDOF; ++i) {
      if (joint < 0 || joint == i) {
        cfg.qdot_max[i] = (ctrl_real)atof(argv[3]);
        cfg.qddot_max[i] = (ctrl_real)atof(argv[4]);
      }
    }
    printf("init %s\n", ctrl_fault_name(ctrl_init(&c, &cfg)));
  } else if (strcmp(what, "move") == 0) { /* move P DT QDOT QDDOT TRUNCATE (QDOT 0: the task's limits) */
    set_dt(&cfg, argv[3]);
    for (i = 0; i < CTRL_NDOF; ++i) {
      if (atof(argv[4]) > 0) {
        cfg.qdot_max[i] = (ctrl_real)atof(argv[4]);
        cfg.qddot_max[i] = (ctrl_real)atof(argv[5]);
      }
    }
    move(&cfg, atoi(argv[2]), atol(argv[6]));
  } else if (strcmp(what, "ik") == 0) { /* ik P MAX_ITERATIONS: the generated IK, q_seed = q_rest = q_start */
    ctrl_real q[CTRL_NDOF], pe, oe, it, su, tol = CTRL_USE_FLOAT ? CTRL_LIT(5e-5) : CTRL_LIT(1e-9);
    int status = (int)ctrl_gen_ik(targets[atoi(argv[2])], cfg.q_start, cfg.q_start, CTRL_LIT(1.0), tol, tol,
                                  (ctrl_real)atof(argv[3]), q, &pe, &oe, &it, &su);
    printf("ik %d %.17g %.17g", status, (double)it, (double)su);
    for (i = 0; i < CTRL_NDOF; ++i) printf(" %.17g", (double)q[i]);
    printf("\n");
  }
  return 0;
}
"""


def non_poses(pose: np.ndarray) -> dict[str, np.ndarray]:
    """Targets that are not poses, each built from a reachable pose (NumPy, not the code under test)."""
    shear = np.eye(3)
    shear[0, 1] = 0.2
    out = {}
    for name, rot in (("zero", np.zeros((3, 3))), ("scaled", 2.0 * pose[:3, :3]), ("sheared", pose[:3, :3] @ shear),
                      ("mirrored", pose[:3, :3] @ np.diag([1.0, 1.0, -1.0]))):
        t = pose.copy()
        t[:3, :3] = rot
        out[name] = t
    out["all_zero"] = np.zeros((4, 4))
    t = pose.copy()
    t[3, :] = [0.0, 0.0, 0.5, 1.0]
    out["last_row"] = t
    t = pose.copy()
    t[3, 3] = 2.0
    out["last_one"] = t
    return out


def off_by(pose: np.ndarray, defect: float) -> np.ndarray:
    """The pose with its rotation stretched along its x column: max |R^T R - I| = defect exactly
    (in exact arithmetic: (1 + e)^2 - 1 = defect)."""
    t = pose.copy()
    t[:3, 0] *= np.sqrt(1.0 + defect)
    return t


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    work = tmp_path_factory.mktemp("move_to_limits")
    robot = load_robot("modular8")
    q0 = robot.configuration("q0")
    task = {"planner": "ptp", "robot": "modular8", "method": "3-4", "step": 0.01,
            "waypoints": {"t": [0.0, 1.0], "omega": {j.name: [0.0, 0.0] for j in robot.joints},
                          "theta": {j.name: [float(q), float(q)] for j, q in zip(robot.joints, q0)}}}
    ftask = fw.task_from_plan(run_task(task, "hold"), "hold", robot)  # holds q0: MOVE_TO starts there
    reachable = robot.fk(q0 + SLOW_MOVE_RAD)
    # joints through 0, where the commands' ulp is smallest and the profile's rounding
    # (a few eps |delta|) is what the step guard must allow for
    targets = {"reachable": reachable, "across_zero": robot.fk(-0.5 * q0), **non_poses(reachable)}
    for name, factor in (("inside_double", 0.5), ("outside_double", 2.0)):
        targets[name] = off_by(reachable, factor * ik.POSE_TOL)
    for name, factor in (("inside_float", 0.5), ("outside_float", 2.0)):
        targets[name] = off_by(reachable, factor * ik.FLOAT_POSE_TOL)
    nan = reachable.copy()
    nan[1, 3] = np.nan
    targets["nan_position"] = nan
    nan = reachable.copy()
    nan[2, 2] = np.nan
    targets["nan_rotation"] = nan
    builder = fw.FirmwareBuilder(robot, work)
    return builder, ftask, robot, targets, work, {}


def driver(setup, precision: str):
    """The driver built with ASan/UBSan in this precision (once)."""
    builder, ftask, robot, targets, work, built = setup
    if precision in built:
        return built[precision]
    variant = fw.Variant("host", precision, sanitize=True, opt="-O1")
    builder.executable(variant, ftask, f"hold_{precision}")  # the objects and fw_task.o
    objs = [o for o in builder.objects(variant) if o.stem != "main"]
    folder = work / precision
    folder.mkdir(exist_ok=True)
    rows = ",\n".join("{" + ", ".join(f"CTRL_LIT({float(v)!r})" if np.isfinite(v) else "(ctrl_real)NAN"
                                      for v in t.T.ravel()) + "}" for t in targets.values())
    (folder / "targets.h").write_text(f"static const ctrl_real targets[{len(targets)}][16] = {{\n{rows}\n}};\n")
    (folder / "driver.c").write_text(DRIVER)
    exe = folder / "driver"
    task_obj = builder.work / f"{variant.name}_hold_{precision}" / "fw_task.o"
    proc = subprocess.run([toolchain.host_cc(), *builder.cflags(variant), f"-I{folder}", str(folder / "driver.c"),
                           *map(str, objs), str(task_obj), "-lm", "-o", str(exe)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    built[precision] = (exe, list(targets))
    return built[precision]


def run(setup, precision: str, *args) -> list[str]:
    exe, _ = driver(setup, precision)
    out = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and not out.stderr, out.stderr[-3000:]  # a sanitizer finding fails here
    return out.stdout.split()


def index(setup, precision: str, name: str) -> int:
    return driver(setup, precision)[1].index(name)


def lowest_qdot(robot, joint: int, dt: float) -> float:
    """The smallest qdot_max ctrl_init accepts: a move over the joint's whole range at that
    peak speed ((1 - b) of the time at the peak, planned at 1 - MARGIN) lasts MAX_TICKS ticks."""
    span = robot.qmax[joint] - robot.qmin[joint]
    return span / ((1 - BLEND) * (1 - MARGIN) * MAX_TICKS * dt)


def lowest_qddot(robot, joint: int, dt: float) -> float:
    span = robot.qmax[joint] - robot.qmin[joint]
    return span / (BLEND * (1 - BLEND) * (1 - MARGIN) * (MAX_TICKS * dt) ** 2)


@pytest.mark.parametrize("precision", PRECISIONS)
def test_init_bounds_the_limits_from_below(setup, precision):
    robot = setup[2]
    dt = 0.01
    # the tiny limits: before, accepted, and a MOVE_TO overflowed its tick count
    assert run(setup, precision, "init", dt, 1e-9, 1.0, 3) == ["init", "BAD_CONFIG"]
    assert run(setup, precision, "init", dt, 1.0, 1e-12, 3) == ["init", "BAD_CONFIG"]
    # the bound, from the range and dt: 1 % inside is accepted, 1 % outside refused
    fast = 1.0  # rad/s, rad/s²: far above either bound
    assert run(setup, precision, "init", dt, 1.01 * lowest_qdot(robot, 3, dt), fast, 3) == ["init", "NONE"]
    assert run(setup, precision, "init", dt, 0.99 * lowest_qdot(robot, 3, dt), fast, 3) == ["init", "BAD_CONFIG"]
    assert run(setup, precision, "init", dt, fast, 1.01 * lowest_qddot(robot, 3, dt), 3) == ["init", "NONE"]
    assert run(setup, precision, "init", dt, fast, 0.99 * lowest_qddot(robot, 3, dt), 3) == ["init", "BAD_CONFIG"]
    # slow but real limits at a fast tick: the same limits refused at 1 MHz, accepted at 1 kHz
    assert run(setup, precision, "init", 1e-6, 0.01, 0.01, -1) == ["init", "BAD_CONFIG"]
    assert run(setup, precision, "init", 1e-3, 0.01, 0.01, -1) == ["init", "NONE"]


@pytest.mark.parametrize("precision", PRECISIONS)
def test_slow_limits_at_a_fast_tick_keep_every_step_within_qdot_max_dt(setup, precision):
    robot = setup[2]
    target = index(setup, precision, "reachable")
    out = run(setup, precision, "move", target, FAST_DT, SLOW_QDOT, SLOW_QDDOT, -1)
    fault, state, ticks, step, speed = out[1], out[2], int(out[3]), float(out[4]), float(out[5])
    q = np.array([float(v) for v in out[6:]])
    assert (fault, state) == ("NONE", "DONE")
    # the profile's duration from the limits and the move the IK chose (NumPy; float rounds it
    # from float joint values, a tick either way)
    move = np.max(np.abs(q - robot.configuration("q0")))
    duration = max(move / ((1 - BLEND) * (1 - MARGIN) * SLOW_QDOT),
                   np.sqrt(move / (BLEND * (1 - BLEND) * (1 - MARGIN) * SLOW_QDDOT)))
    assert abs(ticks - (int(duration / FAST_DT) + 1)) <= (0 if precision == "double" else 1)
    assert step <= STEP_TOL[precision] and speed <= 1.0
    reached = robot.fk(q)
    assert np.linalg.norm(reached[:3, 3] - robot.fk(robot.configuration("q0") + SLOW_MOVE_RAD)[:3, 3]) <= \
        (1e-8 if precision == "double" else 1e-4)


@pytest.mark.parametrize("precision", PRECISIONS)
def test_a_slow_move_across_zero_keeps_every_step_within_qdot_max_dt(setup, precision):
    robot = setup[2]
    out = run(setup, precision, "move", index(setup, precision, "across_zero"), FAST_DT, 0.01, 0.01, -1)
    assert out[1:3] == ["NONE", "DONE"] and float(out[4]) <= STEP_TOL[precision] and float(out[5]) <= 1.0
    q = np.array([float(v) for v in out[6:]])
    assert np.sum(np.sign(q) != np.sign(robot.configuration("q0"))) >= 3  # joints through 0 (the IK picks which)


@pytest.mark.parametrize("precision", PRECISIONS)
def test_random_moves_keep_every_step_within_qdot_max_dt(setup, precision):
    """The task's own limits (the robot file's qdlim/qddlim) and its 10 ms tick."""
    out = run(setup, precision, "move", index(setup, precision, "reachable"), 0.01, 0, 0, -1)
    assert out[1:3] == ["NONE", "DONE"] and float(out[4]) <= STEP_TOL[precision] and float(out[5]) <= 1.0


@pytest.mark.parametrize("precision", PRECISIONS)
def test_a_step_beyond_qdot_max_dt_faults_even_on_the_last_tick(setup, precision):
    """The move cut short after 5 ticks (white box): its last tick jumps to the target with
    q_dot = 0. Before, only q_dot was checked: DONE, fault NONE, a jump of ~0.02 rad."""
    robot = setup[2]
    out = run(setup, precision, "move", index(setup, precision, "reachable"), 0.01, 0, 0, 5)
    assert out[1:3] == ["SPEED", "FAULT"]
    q = np.array([float(v) for v in out[6:]])
    assert np.max(np.abs(q - robot.configuration("q0"))) < SLOW_MOVE_RAD / 2  # held short of the target


NON_POSES = ["zero", "scaled", "sheared", "mirrored", "all_zero", "last_row", "last_one"]


@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("name", NON_POSES + ["outside"])
def test_move_to_a_target_that_is_no_pose_faults_and_holds(setup, precision, name):
    """Before: OK from the IK, and MOVE_TO drove the arm (the all-zero target: the tool to the
    base origin, DONE). Now BAD_TARGET at once, the arm holds q0. (A NaN target stays
    NONFINITE_INPUT, checked before the IK.)"""
    robot = setup[2]
    name = f"outside_{precision}" if name == "outside" else name  # just beyond the build's tolerance
    out = run(setup, precision, "move", index(setup, precision, name), 0.01, 0, 0, -1)
    assert out[1:4] == ["BAD_TARGET", "FAULT", "0"]
    q = np.array([float(v) for v in out[6:]])
    assert np.array_equal(q, robot.configuration("q0").astype(np.float32 if precision == "float" else float))


@pytest.mark.parametrize("precision", PRECISIONS)
def test_generated_ik_returns_bad_target_without_a_step(setup, precision):
    bad, ok, not_converged = 3, 0, 2
    names = NON_POSES + ["nan_position", "nan_rotation", f"outside_{precision}"]
    for name in names:
        out = run(setup, precision, "ik", index(setup, precision, name), ik.MAX_ITERATIONS)
        assert int(out[1]) == bad and float(out[2]) == 0 and float(out[3]) == 0, (name, out[:4])
    for name in ["reachable", f"inside_{precision}"]:
        out = run(setup, precision, "ik", index(setup, precision, name), ik.MAX_ITERATIONS)
        assert int(out[1]) == ok and float(out[2]) >= 1, (name, out[:4])
    # max_iterations <= 0: no step (before: one), the seed back, NOT_CONVERGED
    q0 = setup[2].configuration("q0").astype(np.float32 if precision == "float" else float)
    for cap in (0, -5):
        out = run(setup, precision, "ik", index(setup, precision, "reachable"), cap)
        assert int(out[1]) == not_converged and float(out[2]) == 0 and float(out[3]) == 0
        assert np.array_equal(np.array([float(v) for v in out[4:]]), q0)  # use_rest = 1: the seed as given
