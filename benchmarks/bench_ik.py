#!/usr/bin/env python3
"""Inverse-kinematics benchmark (issue 25): measurements, not tests.

    python benchmarks/bench_ik.py [--quick] [--poses N] [--out benchmarks/results/ik.json] [--no-qemu]

Per robot (iiwa14, panda, modular8 and the Kinova Gen3 of benchmarks/data/kinova_gen3.toml,
a 7-DOF arm that is not bundled), N poses (default 10 000; --quick: 30), each the FK of a
seeded random configuration inside the limits, solved from one fixed seed configuration (the
middle of the limits) by:

- armgen's Python API (``Robot.ik`` on the whole batch; and one pose per call on a subset);
- the generated C, host gcc -O2 (a C driver times every call with clock_gettime), double
  (tolerances 1e-6 m / 1e-6 rad) and float (1e-4 m / 1e-4 rad);
- the float C on a Cortex-M4F under QEMU (-icount shift=0, SysTick on the processor clock,
  calibrated in the run as in benchmarks/bench_kinematics.py): executed instructions per
  solve, mean and max (on the first --m4-poses poses, default all), -O2 with the bounded-range
  sin/cos (<P>_BOUNDED_TRIG=1), with the full cap and with max_iterations capped at the steps
  that fit the 1 ms budget (M4_BUDGET over the full run's instructions per step);
- Robotics Toolbox's ``ikine_LM`` (C++ solver; its defaults: 30 iterations × up to 100
  random searches, joint limits on; tol 1e-13 on ½‖e‖², i.e. ‖e‖ ≤ 4.5e-7);
- a Pinocchio CLIK loop (the damped Gauss–Newton loop of Pinocchio's documentation, full step,
  damping 1e-12, joints clamped to the limits, at most 1000 iterations), on a model built
  from the same DH table (its FK is checked against armgen's).

Success of every solver is judged here, the same way: the double FK of its answer within
1e-6 m and 1e-6 rad of the target (1e-4 for the float C; orientation as SciPy's rotation
vector of R_target Rᵀ), inside the joint limits. Times are wall-clock per solve on a shared
machine (noisy); the peers' include their Python call overhead (Robotics Toolbox's and
Pinocchio's are Python APIs). Bars (reported, not asserted): ≥ 99.5 % success; host C ≥ 10×
faster than the best peer at an equal or higher success rate; M4 worst case ≤ 170 000
instructions.

A run that cannot measure a row fails: exit 4 when a tool (arm-none-eabi-gcc, qemu-system-arm;
``--no-qemu`` leaves the M4 out) or a peer (the ``bench`` extra: ``pip install '.[bench]'``;
``--no-peers`` leaves them out) is missing, and any error is a traceback (exit 1). ``--quick``
(30 poses per robot, a smoke run) names a missing peer in its table and still exits 0: CI
installs the ``test`` extra, which has Pinocchio but not Robotics Toolbox (benchmarks/README.md).
"""

from __future__ import annotations

import argparse
import json
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from armgen.codegen.generate import CodegenConfig, generate, write  # noqa: E402
from armgen.codegen.toolchain import ARM_CPU_FLAGS  # noqa: E402
from armgen.robot import load_robot  # noqa: E402
from armgen.symbolic import ik  # noqa: E402

ROBOTS = ["iiwa14", "panda", "modular8", str(REPO / "benchmarks" / "data" / "kinova_gen3.toml")]
SUCCESS_TOL = 1e-6
FLOAT_SUCCESS_TOL = ik.FLOAT_TOL
SEED = 2025
FIRMWARE = REPO / "armgen" / "data" / "firmware_stub" / "arm"
RTB_TOL = 1e-13  # on ½‖e‖²
# The M4 budget: 170 000 instructions (1 ms at 168 MHz). The second M4 run caps max_iterations
# at the steps that fit, from the instructions per step of the full run's slowest solve (one
# fewer while the call's own overhead still takes the worst case over the budget).
M4_BUDGET = 170_000
PIN_ITERATIONS = 1000
PIN_DAMPING = 1e-12
PIN_EPS = 1e-7  # on ‖log6‖, below the 1e-6 bar
PEER_INSTALL = "pip install '.[bench]'"
EXIT_TOOL_MISSING = 4  # the project's exit status for a missing tool (0 when every row was measured)
QUICK_POSES = 30  # --quick: a smoke run of every row (the figures are not the ones to quote)


def poses_for(robot, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = robot.qmin + (robot.qmax - robot.qmin) * rng.random((count, robot.n))
    return q, robot.fk(q)


def judged(robot, q: np.ndarray, poses: np.ndarray, tol: float, limit_slack: np.ndarray | float = 0.0) -> np.ndarray:
    """Success by the double FK: position and orientation within tol, inside the limits (give
    or take limit_slack: the float build clamps to the float-rounded limits, ≤ ½ ulp away)."""
    reached = robot.fk(q)
    rows = np.array(robot.task_rows)
    error = np.concatenate([poses[:, :3, 3] - reached[:, :3, 3],
                            Rotation.from_matrix(poses[:, :3, :3] @ np.swapaxes(reached[:, :3, :3], 1, 2)).as_rotvec()],
                           axis=1)[:, rows]
    pos = np.linalg.norm(error[:, rows < 3], axis=1)
    ori = np.linalg.norm(error[:, rows >= 3], axis=1)
    inside = np.all((q >= robot.qmin - limit_slack) & (q <= robot.qmax + limit_slack), axis=1)
    return (pos <= tol) & (ori <= tol) & inside & np.all(np.isfinite(q), axis=1)


def row(name: str, ok: np.ndarray, seconds: np.ndarray | None, extra: str = "") -> dict:
    entry = {"solver": name, "success": float(np.mean(ok)), "poses": int(ok.size)}
    if seconds is not None:
        entry |= {"mean_us": float(np.mean(seconds) * 1e6), "max_us": float(np.max(seconds) * 1e6)}
    entry["note"] = extra
    return entry


# -- armgen: Python -------------------------------------------------------------------------------

# The solver alone, as the peers (none of them checks collisions): Robot.ik checks a robot with
# capsules (the bundled iiwa14 and panda) against itself unless told not to, which
# benchmarks/bench_ik_collision.py measures.
PLAIN = {"collision_free": False}


def python_api(robot, poses: np.ndarray, singles: int) -> list[dict]:
    started = time.perf_counter()
    result = robot.ik(poses, seed=robot.qmid, **PLAIN)
    total = time.perf_counter() - started
    ok = judged(robot, result.q, poses, SUCCESS_TOL)
    entry = row("armgen Python, batch", ok, np.array([total / len(poses)]),
                f"whole batch {total:.2f} s; iterations mean {result.iterations.mean():.1f}, max {result.iterations.max()}")
    entry["max_us"] = None  # a batch has no per-solve time
    times = []
    for pose in poses[:singles]:
        t0 = time.perf_counter()
        robot.ik(pose, seed=robot.qmid, **PLAIN)
        times.append(time.perf_counter() - t0)
    return [entry, row(f"armgen Python, one pose per call ({singles} poses)", ok[:singles], np.array(times))]


# -- armgen: generated C on the host -----------------------------------------------------------------

HOST_DRIVER = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "{p}.h"

/* argv: poses.bin count seed.bin tol out.bin; out: per pose q[NDOF], pos, ori, iterations, status, ns */
int main(int argc, char **argv) {{
  long n, i;
  int k;
  double *poses, *out, seed_d[{P}_NDOF], tol;
  FILE *f;
  if (argc != 6) return 2;
  n = atol(argv[2]);
  tol = atof(argv[4]);
  poses = malloc(sizeof(double) * 16 * (size_t)n);
  out = malloc(sizeof(double) * ({P}_NDOF + 5) * (size_t)n);
  f = fopen(argv[1], "rb");
  if (!f || fread(poses, sizeof(double), 16 * (size_t)n, f) != 16 * (size_t)n) return 3;
  fclose(f);
  f = fopen(argv[3], "rb");
  if (!f || fread(seed_d, sizeof(double), {P}_NDOF, f) != {P}_NDOF) return 3;
  fclose(f);
  for (i = 0; i < n; ++i) {{
    {p}_real T[16], seed[{P}_NDOF], q[{P}_NDOF], pos, ori, iterations, success;
    struct timespec t0, t1;
    {p}_status status;
    for (k = 0; k < 16; ++k) T[k] = ({p}_real)poses[16 * i + k];
    for (k = 0; k < {P}_NDOF; ++k) seed[k] = ({p}_real)seed_d[k];
    clock_gettime(CLOCK_MONOTONIC, &t0);
    status = {p}_ik(T, seed, seed, ({p}_real)0, ({p}_real)tol, ({p}_real)tol, ({p}_real){cap}, q, &pos, &ori, &iterations,
                    &success);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    for (k = 0; k < {P}_NDOF; ++k) out[({P}_NDOF + 5) * i + k] = (double)q[k];
    out[({P}_NDOF + 5) * i + {P}_NDOF] = (double)pos;
    out[({P}_NDOF + 5) * i + {P}_NDOF + 1] = (double)ori;
    out[({P}_NDOF + 5) * i + {P}_NDOF + 2] = (double)iterations;
    out[({P}_NDOF + 5) * i + {P}_NDOF + 3] = (double)status;
    out[({P}_NDOF + 5) * i + {P}_NDOF + 4] = (double)(t1.tv_sec - t0.tv_sec) * 1e9 + (double)(t1.tv_nsec - t0.tv_nsec);
  }}
  f = fopen(argv[5], "wb");
  if (!f || fwrite(out, sizeof(double), ({P}_NDOF + 5) * (size_t)n, f) != ({P}_NDOF + 5) * (size_t)n) return 4;
  fclose(f);
  return 0;
}}
"""


def generated_ik(robot, work: Path) -> tuple[Path, str]:
    prefix = robot.name.lower()
    out = work / prefix
    write(generate(CodegenConfig(robot, functions=("ik",))), out)
    return out, prefix


def host_c(robot, poses: np.ndarray, work: Path, precision: str) -> tuple[dict, np.ndarray]:
    gen_dir, p = generated_ik(robot, work)
    driver = work / f"driver_{p}.c"
    driver.write_text(HOST_DRIVER.format(p=p, P=p.upper(), cap=ik.MAX_ITERATIONS))
    exe = work / f"ik_{p}_{precision}"
    subprocess.run(["gcc", "-std=c99", "-O2", f"-D{p.upper()}_USE_FLOAT={int(precision == 'float')}", "-I", str(gen_dir),
                    str(driver), str(gen_dir / f"{p}.c"), "-lm", "-o", str(exe)], check=True)
    (work / "poses.bin").write_bytes(np.ascontiguousarray(poses.transpose(0, 2, 1)).tobytes())  # column-major
    (work / "seed.bin").write_bytes(np.ascontiguousarray(robot.qmid).tobytes())
    tol = SUCCESS_TOL if precision == "double" else FLOAT_SUCCESS_TOL
    subprocess.run([str(exe), str(work / "poses.bin"), str(len(poses)), str(work / "seed.bin"), repr(tol),
                    str(work / "out.bin")], check=True)
    out = np.fromfile(work / "out.bin").reshape(len(poses), robot.n + 5)
    q, status, ns = out[:, :robot.n], out[:, robot.n + 3], out[:, robot.n + 4]
    slack = np.spacing(np.abs(np.concatenate([robot.qmin, robot.qmax])).astype(np.float32)).max()
    ok = judged(robot, q, poses, tol, slack if precision == "float" else 0.0)
    agree = np.mean((status == 0) == ok)
    return row(f"armgen C host -O2 {precision}", ok, ns * 1e-9,
               f"iterations mean {out[:, robot.n + 2].mean():.1f}, max {out[:, robot.n + 2].max():.0f}; "
               f"status OK agrees with the double-FK judgement on {agree:.2%}"), q


# -- armgen: float C on the Cortex-M4F under QEMU ---------------------------------------------------------

M4_DRIVER = r"""
#include <stdint.h>
#include "{p}.h"
#include "semihost.h"
#include "poses.h"

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_MASK 0xFFFFFFu

typedef {p}_status (*ik_fn)(const {p}_real *, const {p}_real *, const {p}_real *, {p}_real, {p}_real, {p}_real,
                            {p}_real, {p}_real *, {p}_real *, {p}_real *, {p}_real *, {p}_real *);
static ik_fn volatile selected = {p}_ik;

__attribute__((noinline)) static uint32_t timed_calib(uint32_t iterations) {{
  uint32_t t0, t1;
  t0 = SYST_CVR;
  __asm__ volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(iterations)::"cc");
  t1 = SYST_CVR;
  return (t0 - t1) & SYST_MASK;
}}

int main(void) {{
  uint32_t i, t0, t1, ticks, ticks_max = 0u, ticks_sum_hi = 0u, ticks_sum_lo = 0u, ok = 0u, calib_small, calib_large;
  uint32_t steps_at_max = 0u;
  {p}_real q[{P}_NDOF], pos, ori, iterations, success;
  SYST_RVR = SYST_MASK;
  SYST_CVR = 0u;
  SYST_CSR = 5u;
  calib_small = timed_calib(1000u);
  calib_large = timed_calib(101000u);
  sh_put_kv("calib_insns", 2u * 100000u);
  sh_put_kv("calib_ticks", calib_large - calib_small);
  for (i = 0; i < POSES; ++i) {{
    ik_fn fn = selected;
    t0 = SYST_CVR;
    if (fn(pose[i], seed, seed, {P}_LIT(0.0), {P}_LIT(1e-4), {P}_LIT(1e-4), ({p}_real){cap}, q, &pos, &ori, &iterations,
           &success) == {P}_OK) {{
      ++ok;
    }}
    t1 = SYST_CVR;
    ticks = (t0 - t1) & SYST_MASK;
    if (ticks > ticks_max) {{
      ticks_max = ticks;
      steps_at_max = (uint32_t)iterations;
    }}
    ticks_sum_lo += ticks;
    if (ticks_sum_lo >= 1000000u) {{ ticks_sum_hi += 1u; ticks_sum_lo -= 1000000u; }}
  }}
  sh_put_kv("poses", POSES);
  sh_put_kv("ok", ok);
  sh_put_kv("ticks_max", ticks_max);
  sh_put_kv("steps_at_max", steps_at_max);
  sh_put_kv("ticks_sum_millions", ticks_sum_hi);
  sh_put_kv("ticks_sum_rest", ticks_sum_lo);
  sh_puts("done\n");
  return 0;
}}
"""


def m4(robot, poses: np.ndarray, work: Path, cap: int = ik.MAX_ITERATIONS) -> dict:
    gcc, qemu = shutil.which("arm-none-eabi-gcc"), shutil.which("qemu-system-arm")
    if not gcc or not qemu:
        return {"solver": "armgen C Cortex-M4F float (QEMU)", "missing": "arm-none-eabi-gcc/qemu-system-arm",
                "note": "MISSING: arm-none-eabi-gcc/qemu-system-arm (apt-get install -y gcc-arm-none-eabi "
                        "libnewlib-arm-none-eabi qemu-system-arm)"}
    gen_dir, p = generated_ik(robot, work)
    m4_dir = work / "m4"
    m4_dir.mkdir(exist_ok=True)
    table = ",\n".join("{" + ", ".join(f"{float(v)!r}f" for v in pose.T.reshape(16)) + "}" for pose in poses)
    (m4_dir / "poses.h").write_text(f"#define POSES {len(poses)}u\nstatic const {p}_real pose[POSES][16] = {{\n{table}\n}};\n"
                                    f"static const {p}_real seed[{p.upper()}_NDOF] = "
                                    f"{{{', '.join(f'{float(v)!r}f' for v in robot.qmid)}}};\n")
    (m4_dir / "main.c").write_text(M4_DRIVER.format(p=p, P=p.upper(), cap=cap))
    elf = m4_dir / "ik.elf"
    flags = ["-std=c99", "-O2", *ARM_CPU_FLAGS, "-ffunction-sections", "-fdata-sections", f"-D{p.upper()}_USE_FLOAT=1",
             f"-D{p.upper()}_BOUNDED_TRIG=1"]
    subprocess.run([gcc, *flags, "-I", str(gen_dir), "-I", str(FIRMWARE), "-I", str(m4_dir), "-nostartfiles",
                    "--specs=nano.specs", "-T", str(FIRMWARE / "mps2_an386.ld"), "-Wl,--gc-sections",
                    str(FIRMWARE / "startup.c"), str(FIRMWARE / "semihost.c"), str(m4_dir / "main.c"),
                    str(gen_dir / f"{p}.c"), "-lm", "-o", str(elf)], check=True)
    run = subprocess.run([qemu, "-M", "mps2-an386", "-nographic", "-semihosting-config", "enable=on,target=native",
                          "-icount", "shift=0", "-kernel", str(elf)], capture_output=True, text=True, timeout=3000)
    values = {}
    for line in (run.stdout + run.stderr).splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[1].isdigit():
            values[parts[0]] = int(parts[1])
    per_tick = values["calib_insns"] / values["calib_ticks"]
    total_ticks = values["ticks_sum_millions"] * 1_000_000 + values["ticks_sum_rest"]
    mean = total_ticks * per_tick / values["poses"]
    worst = values["ticks_max"] * per_tick
    return {"solver": f"armgen C Cortex-M4F float -O2, bounded trig (QEMU), max_iterations {cap}", "poses": values["poses"],
            "success": values["ok"] / values["poses"], "mean_instructions": mean, "max_instructions": worst,
            "mean_us_at_168MHz": mean / 168.0, "max_us_at_168MHz": worst / 168.0,
            "instructions_per_step": worst / max(values["steps_at_max"], 1),
            "note": f"success = status OK (the float C's own errors <= 1e-4); ±{per_tick:.0f} instructions"}


# -- peers ------------------------------------------------------------------------------------------------

def rtb_robot(robot):
    import roboticstoolbox as rtb
    from spatialmath import SE3

    links = []
    for j in robot.joints:
        cls = rtb.RevoluteDH if robot.convention == "standard" else rtb.RevoluteMDH
        links.append(cls(d=j.d, a=j.a, alpha=j.alpha, offset=j.offset, qlim=list(j.qlim)))
    return rtb.DHRobot(links, base=SE3(robot.base, check=False), tool=SE3(robot.tool, check=False), name=robot.name)


def rtb_peer(robot, poses: np.ndarray) -> dict:
    try:
        model = rtb_robot(robot)
    except ImportError:
        return missing_peer("Robotics Toolbox ikine_LM", "roboticstoolbox-python")
    ets = model.ets()
    q_check = robot.qmid + 0.1
    fk_gap = float(np.abs(ets.eval(q_check) - robot.fk(q_check)).max())
    qs, times = [], []
    for pose in poses:
        t0 = time.perf_counter()
        sol = ets.ikine_LM(pose, q0=robot.qmid, tol=RTB_TOL, joint_limits=True, seed=SEED)
        times.append(time.perf_counter() - t0)
        qs.append(sol.q)
    ok = judged(robot, np.array(qs), poses, SUCCESS_TOL)
    return row("Robotics Toolbox ikine_LM", ok, np.array(times), f"FK agrees with armgen to {fk_gap:.1e}")


def pinocchio_model(robot):
    import pinocchio as pin

    def se3(matrix):
        return pin.SE3(matrix[:3, :3].copy(), matrix[:3, 3].copy())

    def rot_z(angle):
        m = np.eye(4)
        m[:2, :2] = [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]
        return m

    def tz(d):
        m = np.eye(4)
        m[2, 3] = d
        return m

    def tx_rx(a, alpha):
        m = np.eye(4)
        m[0, 3] = a
        m[1:3, 1:3] = [[np.cos(alpha), -np.sin(alpha)], [np.sin(alpha), np.cos(alpha)]]
        return m

    model = pin.Model()
    parent, before = 0, robot.base.copy()
    for j in robot.joints:
        if robot.convention == "standard":  # Rz(q + off) Tz(d) Tx(a) Rx(alpha): Tz(d) Tx Rx after the joint
            placement, after = before @ rot_z(j.offset), tz(j.d) @ tx_rx(j.a, j.alpha)
        else:  # Rx(alpha) Tx(a) Rz(q + off) Tz(d): Tz(d) commutes with Rz, after the joint
            placement, after = before @ tx_rx(j.a, j.alpha) @ rot_z(j.offset), tz(j.d)
        parent = model.addJoint(parent, pin.JointModelRZ(), se3(placement), j.name)
        model.lowerPositionLimit[parent - 1] = j.qlim[0]
        model.upperPositionLimit[parent - 1] = j.qlim[1]
        before = after
    frame = model.addFrame(pin.Frame("tool", parent, se3(before @ robot.tool), pin.FrameType.OP_FRAME))
    return model, frame


def missing_peer(solver: str, package: str) -> dict:
    return {"solver": solver, "missing": package, "note": f"MISSING: {package} not installed ({PEER_INSTALL})"}


def pin_peer(robot, poses: np.ndarray) -> dict:
    try:
        import pinocchio as pin
    except ImportError:
        return missing_peer("Pinocchio CLIK (Python loop)", "pin")

    model, frame = pinocchio_model(robot)
    data = model.createData()
    q_check = robot.qmid + 0.1
    pin.framesForwardKinematics(model, data, q_check)
    fk_gap = float(np.abs(data.oMf[frame].homogeneous - robot.fk(q_check)).max())
    qs, times = [], []
    for pose in poses:
        target = pin.SE3(pose[:3, :3].copy(), pose[:3, 3].copy())
        t0 = time.perf_counter()
        q = robot.qmid.copy()
        for _ in range(PIN_ITERATIONS):
            pin.framesForwardKinematics(model, data, q)
            current = data.oMf[frame]
            # world-aligned error at the tool: position difference and rotation vector
            err = np.concatenate([target.translation - current.translation,
                                  pin.log3(target.rotation @ current.rotation.T)])
            if np.linalg.norm(err) < PIN_EPS:
                break
            jac = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)
            dq = jac.T @ np.linalg.solve(jac @ jac.T + PIN_DAMPING * np.eye(6), err)
            q = np.clip(q + dq, robot.qmin, robot.qmax)
        times.append(time.perf_counter() - t0)
        qs.append(q)
    ok = judged(robot, np.array(qs), poses, SUCCESS_TOL)
    return row("Pinocchio CLIK (Python loop)", ok, np.array(times), f"FK agrees with armgen to {fk_gap:.1e}")


# -- report --------------------------------------------------------------------------------------------------

def table(rows: list[dict]) -> str:
    lines = ["| solver | poses | success | mean time | worst time | note |", "|---|---|---|---|---|---|"]
    for r in rows:
        if "mean_instructions" in r:
            timing = (f"{r['mean_instructions']:.0f} instr ({r['mean_us_at_168MHz']:.0f} µs @168 MHz)",
                      f"{r['max_instructions']:.0f} instr ({r['max_us_at_168MHz']:.0f} µs)")
        elif "mean_us" in r:
            timing = (f"{r['mean_us']:.1f} µs", "—" if r.get("max_us") is None else f"{r['max_us']:.1f} µs")
        else:
            timing = ("—", "—")
        success = f"{100 * r['success']:.2f} %" if "success" in r else "—"
        lines.append(f"| {r['solver']} | {r.get('poses', '—')} | {success} | {timing[0]} | {timing[1]} | {r['note']} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=10_000)
    parser.add_argument("--quick", action="store_true",
                        help=f"{QUICK_POSES} poses per robot (a smoke run; a missing peer is named, not an error)")
    parser.add_argument("--m4-poses", type=int, default=None, help="poses run on the M4 (default: all)")
    parser.add_argument("--singles", type=int, default=300, help="poses solved one per call in Python")
    parser.add_argument("--no-qemu", action="store_true")
    parser.add_argument("--no-peers", action="store_true")
    parser.add_argument("--robots", nargs="*", default=ROBOTS)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    count = QUICK_POSES if args.quick else args.poses
    not_measured = []
    report = {"poses": count, "platform": platform.platform(), "processor": platform.processor(),
              "python": platform.python_version(), "robots": {}}
    for index, name in enumerate(args.robots):
        robot = load_robot(name)
        _, poses = poses_for(robot, count, SEED + index)
        rows = []
        with tempfile.TemporaryDirectory(prefix="bench-ik-") as tmp:
            work = Path(tmp)
            rows += python_api(robot, poses, min(args.singles, count))
            rows.append(host_c(robot, poses, work, "double")[0])
            rows.append(host_c(robot, poses, work, "float")[0])
            if not args.no_qemu:
                full = m4(robot, poses[:args.m4_poses or count], work)
                rows.append(full)
                if "instructions_per_step" in full:
                    cap = max(1, min(ik.MAX_ITERATIONS, int(M4_BUDGET // full["instructions_per_step"])))
                    capped = m4(robot, poses[:args.m4_poses or count], work, cap)
                    while capped["max_instructions"] > M4_BUDGET and cap > 1:  # the call's own overhead
                        cap -= 1
                        capped = m4(robot, poses[:args.m4_poses or count], work, cap)
                    rows.append(capped)
        if not args.no_peers:
            rows.append(rtb_peer(robot, poses))
            rows.append(pin_peer(robot, poses))
        not_measured += [f"{robot.name}: {r['solver']} ({r['missing']})" for r in rows
                         if "missing" in r and not (args.quick and r["solver"].startswith(("Robotics", "Pinocchio")))]
        peers = [r for r in rows if r["solver"].startswith(("Robotics", "Pinocchio")) and "mean_us" in r]
        c_double = next(r for r in rows if r["solver"] == "armgen C host -O2 double")
        summary = {}
        if peers:
            best = min(peers, key=lambda r: r["mean_us"])
            summary = {"best_peer": best["solver"], "best_peer_mean_us": best["mean_us"],
                       "speedup_host_c_double_vs_best_peer": best["mean_us"] / c_double["mean_us"],
                       "success_host_c_double_minus_best_peer": c_double["success"] - best["success"]}
        report["robots"][robot.name] = {"rows": rows, "summary": summary}
        print(f"\n## {robot.name} ({robot.n} DOF, {count} poses, seed configuration: middle of the limits)\n")
        print(table(rows))
        if summary:
            print(f"\nhost C double vs the fastest peer ({summary['best_peer']}): "
                  f"{summary['speedup_host_c_double_vs_best_peer']:.1f}x faster, success "
                  f"{100 * c_double['success']:.2f} % vs {100 * best['success']:.2f} %")
        sys.stdout.flush()
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(report, indent=2) + "\n")
    for what in not_measured:
        print(f"NOT MEASURED (missing): {what}")
    return EXIT_TOOL_MISSING if not_measured else 0


if __name__ == "__main__":
    sys.exit(main())
