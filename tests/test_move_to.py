"""MOVE_TO (issue 26): a tool pose at run time → the generated IK on board → a joint-space
profile within each joint's speed and acceleration limits; an unreachable pose is the fault
UNREACHABLE and the arm holds."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from armgen import firmware as fw
from armgen.codegen import toolchain
from armgen.planning.tasks import run_task
from armgen.robot import load_robot

N_POSES = 100
SEED = 26
# The targets are the FK (Python, NumPy) of random configurations within this distance (rad,
# per joint) of the start: reachable by construction, and near enough that the IK seeded at the
# held command finds one of them (a redundant arm has many; any one reaching the pose will do).
SPREAD_RAD = 0.5
MAX_TICKS = 100_000
# Reached: the double build solves to 1e-9 (MOVE_TO_TOL) and its FK differs from NumPy's by
# rounding only; 1e-8 leaves an order of margin. Float: the 1e-4 m / 1e-4 rad (the IK
# runs to 5e-5 in float; float FK rounding is a few 1e-7).
REACHED_TOL = {"double": 1e-8, "float": 1e-4}
# Speeds and accelerations are planned at (1 - 1e-3) of the limits (MOVE_TO_MARGIN); a finite
# difference of float commands carries rounding of ~ulp(q)/dt² on the acceleration.
LIMIT_RTOL = {"double": 1e-9, "float": 1e-3}
ACC_ABS = {"double": 1e-6, "float": 0.5}  # rad/s²: 2 ulp(3 rad) / (0.01 s)² in float
# Every tick's step from the previous command within qdot_max dt (the profile plans 1 - 1e-3 of
# it), up to the rounding of the two commands: ~1e-16 rad in double, an ulp of |q| < 4 rad at
# each end in float.
STEP_ABS = {"double": 1e-14, "float": 2 * float(np.spacing(np.float32(4.0)))}

DRIVER = r"""
#include <stdio.h>
#include "controller.h"
extern const ctrl_config fw_task;
#include "targets.h"
int main(void) {
  static ctrl c;
  ctrl_input in = {0};
  ctrl_output out;
  int p, i;
  long k;
  for (p = 0; p < N_TARGETS; ++p) {
    ctrl_real prev[CTRL_NDOF] = {0}, speed = 0, acc = 0, outside = 0;
    double last[CTRL_NDOF], step = 0.0;
    if (ctrl_init(&c, &fw_task) != CTRL_FAULT_NONE) return 3;
    for (i = 0; i < 16; ++i) in.target[i] = targets[p][i];
    for (i = 0; i < CTRL_NDOF; ++i) last[i] = (double)fw_task.q_start[i];
    in.command = CTRL_CMD_MOVE_TO;
    for (k = 0; k < MAX_TICKS; ++k) {
      (void)ctrl_tick(&c, &in, &out);
      in.command = CTRL_CMD_NONE;
      for (i = 0; i < CTRL_NDOF; ++i) {
        ctrl_real s = out.qd[i] / fw_task.qdot_max[i];
        ctrl_real a = (out.qd[i] - prev[i]) / fw_task.dt - fw_task.qddot_max[i];
        ctrl_real a_neg = (prev[i] - out.qd[i]) / fw_task.dt - fw_task.qddot_max[i];
        if (s < 0) s = -s;
        if (s > speed) speed = s;
        if (a > acc) acc = a;
        if (a_neg > acc) acc = a_neg;
        if (out.q[i] < fw_task.q_min[i] || out.q[i] > fw_task.q_max[i]) outside += 1;
        prev[i] = out.qd[i];
        {
          double d = (double)out.q[i] - last[i];
          d = (d < 0 ? -d : d) - (double)fw_task.qdot_max[i] * (double)fw_task.dt;
          if (d > step) step = d;
          last[i] = (double)out.q[i];
        }
      }
      if (out.state == CTRL_STATE_DONE || out.state == CTRL_STATE_FAULT) break;
    }
    printf("%d %s %ld %.17g %.17g %.0f %.17g", p, ctrl_fault_name(out.fault), k, (double)speed, (double)acc,
           (double)outside, step);
    for (i = 0; i < CTRL_NDOF; ++i) printf(" %.17g", (double)out.q[i]);
    printf("\n");
  }
  return 0;
}
"""


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    work = tmp_path_factory.mktemp("move_to")
    robot = load_robot("modular8")
    task = {"planner": "ptp", "robot": "modular8", "method": "3-4", "step": 0.01,
            "waypoints": {"t": [0.0, 1.0], "omega": {j.name: [0.0, 0.0] for j in robot.joints},
                          "theta": {j.name: [float(q), float(q)] for j, q in
                                                       zip(robot.joints, robot.configuration("q0"))}}}
    ftask = fw.task_from_plan(run_task(task, "hold"), "hold", robot)  # holds q0: MOVE_TO starts there
    rng = np.random.default_rng(SEED)
    q0 = robot.configuration("q0")
    qs = np.clip(q0 + rng.uniform(-SPREAD_RAD, SPREAD_RAD, (N_POSES, robot.n)), robot.qmin, robot.qmax)
    targets = robot.fk(qs)
    far = robot.fk(q0)
    far[:3, 3] += 10.0  # 10 m away: no configuration reaches it
    targets = np.concatenate([targets, far[None]])
    return fw.FirmwareBuilder(robot, work), ftask, robot, targets, work


def _run(setup, precision: str):
    builder, ftask, robot, targets, work = setup
    variant = fw.Variant("host", precision, sanitize=precision == "double", opt="-O1" if precision == "double" else "-O2")
    fw.run_host(builder.executable(variant, ftask, f"hold_{precision}"))  # objects and fw_task.o
    objs = [o for o in builder.objects(variant) if o.stem != "main"]
    folder = work / precision
    folder.mkdir(exist_ok=True)
    rows = ",\n".join("{" + ", ".join(f"CTRL_LIT({float(v)!r})" for v in t.T.ravel()) + "}" for t in targets)
    (folder / "targets.h").write_text(f"#define N_TARGETS {len(targets)}\n#define MAX_TICKS {MAX_TICKS}L\n"
                                      f"static const ctrl_real targets[N_TARGETS][16] = {{\n{rows}\n}};\n")
    (folder / "driver.c").write_text(DRIVER)
    exe = folder / "driver"
    task_obj = builder.work / f"{variant.name}_hold_{precision}" / "fw_task.o"
    proc = subprocess.run([toolchain.host_cc(), *builder.cflags(variant), f"-I{folder}", str(folder / "driver.c"),
                           *map(str, objs), str(task_obj), "-lm", "-o", str(exe)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = subprocess.run([str(exe)], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and not out.stderr, out.stderr[-3000:]
    return [line.split() for line in out.stdout.splitlines()]


@pytest.mark.parametrize("precision", ["double", "float"])
def test_move_to_reaches_random_poses_within_the_limits(setup, precision):
    _, ftask, robot, targets, _ = setup
    rows = _run(setup, precision)
    assert len(rows) == N_POSES + 1
    for row, target in zip(rows[:N_POSES], targets[:N_POSES]):
        fault, speed, acc, outside, step = row[1], float(row[3]), float(row[4]), float(row[5]), float(row[6])
        assert outside == 0 and speed <= 1 + LIMIT_RTOL[precision] and acc <= ACC_ABS[precision], row[:7]
        assert step <= STEP_ABS[precision], row[:7]
        assert fault == "NONE", row[:7]  # every pose is reachable
        q = np.array([float(v) for v in row[7:]])
        pose = robot.fk(q)
        assert np.linalg.norm(pose[:3, 3] - target[:3, 3]) <= REACHED_TOL[precision]
        rot = Rotation.from_matrix(pose[:3, :3]).inv() * Rotation.from_matrix(target[:3, :3])
        assert rot.magnitude() <= REACHED_TOL[precision]
    # the unreachable pose: the fault, and the arm holds where it was
    fault, ticks = rows[N_POSES][1], int(rows[N_POSES][2])
    q_held = np.array([float(v) for v in rows[N_POSES][7:]])
    assert fault == "UNREACHABLE" and ticks == 0
    q0 = robot.configuration("q0")
    assert np.max(np.abs(q_held - q0)) <= (0 if precision == "double" else 1e-6)
