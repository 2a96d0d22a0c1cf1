#!/usr/bin/env python3
"""The compiled kernel behind the Python API (issue 41): measurements, not tests.

    python benchmarks/bench_kernel.py [--quick] [--robot panda] [--poses 1000] [--batch 1000000] [--out k.json]

In one run, on the 7-DOF panda (``--robot``):

1. Single calls from Python, best of REPEATS runs of ``--calls`` calls, CPU µs per call (the
   process's CPU time: on a shared machine the wall clock counts other processes' turns too):
   ``robot.fk_jacobian(q)`` on the compiled kernel; the same on the CasADi reference (the path
   before issue 41, ``ARMGEN_KERNEL=reference``); Pinocchio's ``forwardKinematics`` +
   ``computeJointJacobians`` + ``getFrameJacobian`` (LOCAL_WORLD_ALIGNED: the geometric
   Jacobian, checked against armgen's) from Python, on a model built from the same DH table
   (benchmarks/bench_ik.py). Bar: ≤ 2 µs and ≤ Pinocchio.
2. IK on the bench poses of benchmarks/bench_ik.py (FK of seeded configurations inside the
   limits, solved from the middle of the limits), one pose per call: ``robot.ik(pose)`` compiled
   and on the CasADi reference (on the first ``--reference-poses``: ~10 ms each), and Robotics
   Toolbox's ``ikine_LM`` and the Pinocchio CLIK loop of bench_ik.py; success judged alike
   (bench_ik.judged: the FK of the answer within 1e-6 m / 1e-6 rad, inside the limits). The
   table's times are wall clock (as bench_ik.py's); armgen's rows add the mean CPU time, which
   the bar judges: ``robot.ik`` ≤ 50 µs mean at the reference's success rate.
3. A batch of ``--batch`` configurations (default 10⁶): ``robot.fk_jacobian(Q)`` wall and CPU
   time per sample (one core: the samples loop in C on the calling thread), against the same C
   called from C (benchmarks/c/bench_fk_jacobian_batch.c, the kernel's code and flags, fresh
   output arrays per repeat on both sides); the ratio and the throughput per core are CPU time.
4. The command line, each command in its own process (what a user waits for, the interpreter's
   start and armgen's import included), best of CLI_REPEATS after one warm-up run (the kernel
   built or the store's checked): ``armgen ik`` of one pose and ``armgen plan`` of the bundled
   panda polishing program (a start given as a pose, solved by the IK; then every waypoint's
   IK), on the compiled kernel and with ``ARMGEN_KERNEL=reference`` (before issue 41): wall
   and CPU time (the child's, from ``wait4``).

Wall-clock figures on a shared machine are noisy; CPU time is printed beside the batch.
``--quick`` (a smoke run: 20 000 single calls, 10 poses, 3 on the reference, 10⁴ batch) prints
every row; a missing Robotics Toolbox is named ``MISSING`` and the quick run still exits 0 (CI
does not install the ``bench`` extra). A full run that cannot measure a row exits 4 (a peer or
gcc missing); any error is a traceback (exit 1).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
for path in (REPO, HERE):
    if str(path) not in sys.path:  # run from a checkout without `pip install -e .`; bench_ik beside it
        sys.path.insert(0, str(path))

import bench_ik  # noqa: E402
from armgen.codegen import api_kernel  # noqa: E402
from armgen.codegen.generate import CodegenConfig, generate, write  # noqa: E402
from armgen.codegen.toolchain import STRICT_FLAGS, host_cc  # noqa: E402
from armgen.robot import load_robot  # noqa: E402

SINGLE_BAR_US = 2.0  # robot.fk_jacobian(q) from Python (issue 41)
IK_BAR_US = 50.0  # robot.ik(pose) mean on the bench poses (issue 41)
REPEATS = 5
CALLS = 200_000
POSES = 1000
REFERENCE_POSES = 100
BATCH = 1_000_000
QUICK = {"calls": 20_000, "poses": 10, "reference_poses": 3, "batch": 10_000}
SEED = 41
EXIT_TOOL_MISSING = 4
C_DRIVER = HERE / "c" / "bench_fk_jacobian_batch.c"


def per_call_us(func, calls: int, repeats: int = REPEATS) -> float:
    """Best of ``repeats`` runs of ``calls`` calls, CPU µs per call (this process's CPU time: on a
    shared machine the wall clock also counts the time other processes held the core)."""
    func()
    return min(timeit.repeat(func, number=calls, repeat=repeats, timer=time.process_time)) / calls * 1e6


def reference_robot(name: str):
    robot = load_robot(name)
    robot.__dict__["_kernel"] = None  # the CasADi path (what ARMGEN_KERNEL=reference selects)
    return robot


def single_calls(robot, reference, calls: int) -> dict:
    q = np.random.default_rng(SEED).uniform(robot.qmin, robot.qmax, robot.n)
    figures = {"compiled_us": per_call_us(lambda: robot.fk_jacobian(q), calls),
               "compiled_fk_us": per_call_us(lambda: robot.fk(q), calls),
               "reference_us": per_call_us(lambda: reference.fk_jacobian(q), max(calls // 100, 100), 3)}
    try:
        import pinocchio as pin
    except ImportError:
        return figures | {"pinocchio": "MISSING: pin not installed (pip install '.[test]')"}
    model, frame = bench_ik.pinocchio_model(robot)
    data = model.createData()
    world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

    def pinocchio():
        pin.forwardKinematics(model, data, q)
        pin.computeJointJacobians(model, data, q)
        return pin.getFrameJacobian(model, data, frame, world)

    figures["pinocchio_jacobian_gap"] = float(np.abs(pinocchio() - robot.jacobian(q)).max())
    figures["pinocchio_us"] = per_call_us(pinocchio, calls)
    return figures


def ik_rows(robot, reference, count: int, reference_count: int) -> list[dict]:
    _, poses = bench_ik.poses_for(robot, count, bench_ik.SEED)

    start = robot.qmid  # (a property computed on each access: once, outside the timing)

    # The bar and the peers are the plain solver (collision_free=False: neither Robotics Toolbox
    # nor the Pinocchio loop checks collisions); the default, with the arm's self-collision check
    # (issue 38), gets a row of its own.
    def one_per_call(solver, selected, collision_free=False):
        qs, times, cpu = [], [], []
        for pose in selected:
            started, started_cpu = time.perf_counter(), time.process_time()
            qs.append(solver.ik(pose, seed=start, collision_free=collision_free).q)
            times.append(time.perf_counter() - started)
            cpu.append(time.process_time() - started_cpu)
        return np.array(qs), np.array(times), float(np.mean(cpu) * 1e6)

    rows = []
    q, times, cpu = one_per_call(robot, poses)
    rows.append(bench_ik.row("robot.ik(pose), compiled kernel", bench_ik.judged(robot, q, poses, bench_ik.SUCCESS_TOL),
                             times, f"CPU mean {cpu:.1f} µs") | {"cpu_mean_us": cpu})
    q_ref, times_ref, cpu_ref = one_per_call(reference, poses[:reference_count])
    rows.append(bench_ik.row(f"robot.ik(pose), CasADi reference (before; first {reference_count} poses)",
                             bench_ik.judged(robot, q_ref, poses[:reference_count], bench_ik.SUCCESS_TOL), times_ref,
                             f"CPU mean {cpu_ref:.1f} µs; same answers as compiled on these poses: "
                             f"max |dq| {np.abs(q_ref - q[:reference_count]).max():.1e}") | {"cpu_mean_us": cpu_ref})
    if robot.has_collision:
        q_checked, times_checked, cpu_checked = one_per_call(robot, poses, collision_free=True)
        rows.append(bench_ik.row("robot.ik(pose), compiled kernel, self-collision checked (the default)",
                                 bench_ik.judged(robot, q_checked, poses, bench_ik.SUCCESS_TOL), times_checked,
                                 f"CPU mean {cpu_checked:.1f} µs") | {"cpu_mean_us": cpu_checked})
    started = time.perf_counter()
    batch = robot.ik(poses, seed=start, collision_free=False)
    per_pose = (time.perf_counter() - started) / count
    entry = bench_ik.row("robot.ik(poses), compiled kernel, one batched call",
                         bench_ik.judged(robot, batch.q, poses, bench_ik.SUCCESS_TOL), np.array([per_pose]))
    rows.append(entry | {"max_us": None})
    rows.append(bench_ik.rtb_peer(robot, poses))
    rows.append(bench_ik.pin_peer(robot, poses))
    return rows


def c_batch_ns(robot, q: np.ndarray, work: Path, repeats: int) -> tuple[float, float]:
    """(wall, CPU) ns per sample of the kernel's fk_jacobian called from C on ``q`` (count, n)."""
    code = generate(CodegenConfig(robot, "double", "", ("fk_jacobian",)))
    write(code, work)
    binary = work / "bench_batch"
    subprocess.run([host_cc(), *STRICT_FLAGS, api_kernel.OPTIMISATION, *api_kernel.FLOATING_POINT_FLAGS,
                    f"-D{code.prefix.upper()}_USE_FLOAT=0", f"-DBENCH_HEADER=\"{code.prefix}.h\"",
                    f"-DBENCH_FN={code.prefix}_fk_jacobian", f"-DBENCH_NDOF={robot.n}", f"-I{work}", str(C_DRIVER),
                    str(work / f"{code.prefix}.c"), "-o", str(binary), "-lm"], check=True)
    np.ascontiguousarray(q).tofile(work / "q.bin")
    out = subprocess.run([str(binary), str(work / "q.bin"), str(len(q)), str(repeats)], check=True,
                         capture_output=True, text=True).stdout
    figures = dict(line.split() for line in out.splitlines())
    return float(figures["ns_per_sample"]), float(figures["cpu_ns_per_sample"])


def batch_figures(robot, count: int, repeats: int) -> dict:
    q = np.random.default_rng(SEED + 1).uniform(robot.qmin, robot.qmax, (count, robot.n))
    robot.fk_jacobian(q[:2])
    best_wall, best_cpu = float("inf"), float("inf")
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        robot.fk_jacobian(q)
        best_wall = min(best_wall, time.perf_counter() - wall)
        best_cpu = min(best_cpu, time.process_time() - cpu)
    with tempfile.TemporaryDirectory(prefix="bench-kernel-") as tmp:
        c_wall, c_cpu = c_batch_ns(robot, q, Path(tmp), repeats)
    return {"count": count, "python_wall_ns": best_wall / count * 1e9, "python_cpu_ns": best_cpu / count * 1e9,
            "c_wall_ns": c_wall, "c_cpu_ns": c_cpu}


# The command-line rows: the panda polishing program starts at a pose (solved by the IK).
CLI_PROGRAM = REPO / "armgen" / "data" / "examples" / "panda_polish_contour_program.toml"
CLI_IK_POSE = ("--xyz", "0.55", "0", "0.35", "--rpy", "180", "0", "-45", "--units", "deg")  # the program's start
CLI_REPEATS = 3


def _armgen_command() -> list[str]:
    """The ``armgen`` script of this interpreter's environment."""
    script = Path(sys.executable).with_name("armgen")
    if not script.is_file():
        raise SystemExit(f"no armgen command beside {sys.executable}: pip install -e . first")
    return [str(script)]


def _run_timed(command: list[str], env: dict[str, str]) -> tuple[float, float]:
    """(wall, CPU) seconds of one run of ``command`` (its CPU time from wait4); a failure raises."""
    started = time.perf_counter()
    process = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - started
    process.returncode = os.waitstatus_to_exitcode(status)
    if process.returncode != 0:
        raise SystemExit(f"{' '.join(command)} exited {process.returncode}: {process.stderr.read().decode()[-2000:]}")
    process.stderr.close()
    return wall, usage.ru_utime + usage.ru_stime


def cli_rows(robot_name: str, repeats: int) -> list[dict]:
    """``armgen ik`` and ``armgen plan`` wall and CPU seconds, compiled kernel and CasADi reference."""
    armgen = _armgen_command()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        commands = {f"armgen ik {robot_name} (one pose)": [*armgen, "ik", robot_name, *CLI_IK_POSE],
                    f"armgen plan {CLI_PROGRAM.name}": [*armgen, "plan", str(CLI_PROGRAM), "-o", f"{tmp}/plan.csv"]}
        for label, command in commands.items():
            row = {"command": label}
            for evaluator in ("compiled", "reference"):
                env = {**os.environ, api_kernel.KERNEL_ENV: evaluator, "ARMGEN_NO_PROGRESS": "1"}
                _run_timed(command, env)  # warm-up: the kernel built or found
                best = min(_run_timed(command, env) for _ in range(repeats))
                row[f"{evaluator}_wall_s"], row[f"{evaluator}_cpu_s"] = best
            rows.append(row)
    return rows


def ik_table(rows: list[dict]) -> str:
    lines = ["| solver | poses | success | mean | max | note |", "|---|---:|---:|---:|---:|---|"]
    for r in rows:
        if "missing" in r:
            lines.append(f"| {r['solver']} | — | — | — | — | {r['note']} |")
            continue
        peak = "—" if r.get("max_us") is None else f"{r['max_us']:.1f} µs"
        lines.append(f"| {r['solver']} | {r['poses']} | {100 * r['success']:.2f} % | {r['mean_us']:.1f} µs | {peak} "
                     f"| {r['note']} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="panda")
    parser.add_argument("--calls", type=int, default=CALLS)
    parser.add_argument("--poses", type=int, default=POSES)
    parser.add_argument("--reference-poses", type=int, default=REFERENCE_POSES)
    parser.add_argument("--batch", type=int, default=BATCH)
    parser.add_argument("--quick", action="store_true", help="a smoke run of every row (figures not to quote)")
    parser.add_argument("--out", type=Path, default=None, help="also write the figures as JSON")
    args = parser.parse_args(argv)
    if args.quick:
        for key, value in QUICK.items():
            setattr(args, key, value)

    robot, reference = load_robot(args.robot), reference_robot(args.robot)
    started = time.perf_counter()
    if robot._kernel is None:
        print("FAILED: no compiled kernel (see the warning above)")
        return 1
    kernel_ready = time.perf_counter() - started
    print(f"robot {robot.name} ({robot.n} joints); compiled kernel ready in {kernel_ready:.2f} s "
          "(built now, or loaded from the store and self-tested)")

    single = single_calls(robot, reference, args.calls)
    print(f"\n## single call from Python, best of {REPEATS} x {args.calls} calls\n")
    print(f"  robot.fk_jacobian(q), one call, compiled kernel          {single['compiled_us']:8.3f} us")
    print(f"  robot.fk(q), one call, compiled kernel                   {single['compiled_fk_us']:8.3f} us")
    print(f"  robot.fk_jacobian(q), one call, CasADi reference (before) {single['reference_us']:8.3f} us")
    not_measured = []
    if "pinocchio_us" in single:
        ratio = single["compiled_us"] / single["pinocchio_us"]
        meets = single["compiled_us"] <= min(SINGLE_BAR_US, single["pinocchio_us"])
        print(f"  Pinocchio forwardKinematics + computeJointJacobians + getFrameJacobian "
              f"{single['pinocchio_us']:8.3f} us  (Jacobian agrees to {single['pinocchio_jacobian_gap']:.1e})")
        print(f"  compiled / Pinocchio {ratio:.2f}x; compiled / reference "
              f"{single['compiled_us'] / single['reference_us']:.4f}x; bar <= {SINGLE_BAR_US} us and <= Pinocchio: "
              f"{'meets' if meets else 'misses'}")
    else:
        print(f"  Pinocchio: {single['pinocchio']}")
        not_measured.append("pin")

    rows = ik_rows(robot, reference, args.poses, min(args.reference_poses, args.poses))
    print("\n## IK on the bench poses (bench_ik.py's, seed configuration: middle of the limits)\n")
    print(ik_table(rows))
    compiled_row, reference_row = rows[0], rows[1]
    print(f"\n  robot.ik(pose) compiled mean {compiled_row['cpu_mean_us']:.1f} us, "
          f"success {100 * compiled_row['success']:.2f} %;"
          f" reference (before) {reference_row['cpu_mean_us']:.1f} us, success {100 * reference_row['success']:.2f} %"
          f" (CPU time; wall {compiled_row['mean_us']:.1f} and {reference_row['mean_us']:.1f} us);"
          f" speed-up {reference_row['cpu_mean_us'] / compiled_row['cpu_mean_us']:.0f}x; bar <= {IK_BAR_US} us: "
          f"{'meets' if compiled_row['cpu_mean_us'] <= IK_BAR_US else 'misses'}")
    not_measured += [r["missing"] for r in rows if "missing" in r and not args.quick]

    batch = batch_figures(robot, args.batch, 3 if not args.quick else 2)
    print(f"\n## batch of {batch['count']} configurations, fk_jacobian, one core\n")
    print(f"  robot.fk_jacobian(Q), compiled kernel   wall {batch['python_wall_ns']:8.1f} ns/sample   "
          f"cpu {batch['python_cpu_ns']:8.1f} ns/sample")
    print(f"  C called from C (same code and flags)    wall {batch['c_wall_ns']:8.1f} ns/sample   "
          f"cpu {batch['c_cpu_ns']:8.1f} ns/sample")
    print(f"  Python batch / C from C (CPU): {batch['python_cpu_ns'] / batch['c_cpu_ns']:.2f}x; throughput per core "
          f"{1e3 / batch['python_cpu_ns']:.2f} M samples/s (C from C: {1e3 / batch['c_cpu_ns']:.2f})")

    cli = cli_rows(robot.name, CLI_REPEATS if not args.quick else 1)
    print(f"\n## the command line, one process per command, best of {CLI_REPEATS if not args.quick else 1} "
          "after a warm-up\n")
    for row in cli:
        print(f"  {row['command']:44s} compiled wall {row['compiled_wall_s']:6.2f} s cpu {row['compiled_cpu_s']:6.2f} s"
              f" | reference (before) wall {row['reference_wall_s']:6.2f} s cpu {row['reference_cpu_s']:6.2f} s"
              f" | wall ratio {row['compiled_wall_s'] / row['reference_wall_s']:.2f}x")

    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"robot": robot.name, "platform": platform.platform(),
                                        "python": platform.python_version(), "single": single, "ik": rows,
                                        "batch": batch, "cli": cli}, indent=2) + "\n")
    for what in not_measured:
        print(f"NOT MEASURED (missing): {what}")
    return EXIT_TOOL_MISSING if not_measured else 0


if __name__ == "__main__":
    sys.exit(main())
