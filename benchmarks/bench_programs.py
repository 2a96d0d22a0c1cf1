#!/usr/bin/env python3
"""Programs benchmark (issue 24): measurements, not tests.

    python benchmarks/bench_programs.py [--rows 2000] [--planner wgpm] [--out benchmarks/results/programs.json]

In one run, on iiwa14 from the same start pose, at the same tool speed and acceleration:

1. a ``poses`` program of ``--rows`` CSV rows (a planar wave, 0.2 mm between rows), and
2. a ``line`` program of the same length (the reference),

each planned end to end by ``run_task`` (parse, CSV, spline and arc-length table, time law,
the planner's steps, the limits check), best of 3 after a warm-up that builds the kernels.
Both have the same duration, hence the same number of samples: the figure is planning time
per sample and the ratio poses/line. The bar (reported, never asserted): within 2×. The time
to build the program alone (CSV → geometry → time law) is printed beside it. Any error is a
traceback (exit 1). ``--quick`` (a smoke run, seconds): QUICK_ROWS rows, one repeat.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
if str(REPO) not in sys.path:  # run from a checkout without `pip install -e .`
    sys.path.insert(0, str(REPO))

from armgen.planning.tasks import run_task  # noqa: E402
from armgen.planning.toolpath.schema import ProgramPath  # noqa: E402
from armgen.planning.toolpath.task import build_program, program_spec  # noqa: E402
from armgen.planning.toolpath.timelaw import program_profile  # noqa: E402
from armgen.robot import load_robot, rpy_matrix  # noqa: E402

BAR_RATIO = 2.0
REPEATS = 3
QUICK_ROWS = 1500  # --quick (a smoke run): a program (~280 mm) that outlasts twice the wgpm ramp (2 s)
QUICK_REPEATS = 1
START = ([550.0, -190.0, 400.0], [180.0, 0.0, 180.0])  # mm, deg

TASK = """
planner = "{planner}"
robot = "iiwa14"
start = {{ pose = {{ xyz = {xyz}, rpy = {rpy} }}, seed = "qz" }}
[units]
length = "mm"
angle = "deg"
[path]
type = "program"
speed = 50
acceleration = 250
[[path.moves]]
{move}
[integrator]
step = 0.01
"""


def wave(rows: int) -> np.ndarray:
    """A planar wave along +y from the start: ~0.2 mm between rows, 10 mm amplitude (mm)."""
    y = START[0][1] + 0.2 * np.arange(1, rows + 1) / math.sqrt(1.2)
    x = START[0][0] + 10.0 * np.sin((y - START[0][1]) / 25.0)
    return np.column_stack([x, y, np.full(rows, START[0][2])])


def best_of(func, repeats: int) -> float:
    func()  # warm-up: kernels, imports
    best = math.inf
    for _ in range(repeats):
        started = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - started)
    return best


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=2000)
    parser.add_argument("--planner", default="wgpm", choices=("cartesian", "fault_tolerant", "wgpm"))
    parser.add_argument("--out", default=None, help="also write the figures as JSON")
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_ROWS} rows, one repeat (a smoke run)")
    args = parser.parse_args()
    repeats = QUICK_REPEATS if args.quick else REPEATS
    if args.quick:
        args.rows = QUICK_ROWS
    xyz, rpy = START
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch)
        points = wave(args.rows)
        (folder / "wave.csv").write_text("x,y,z,roll,pitch,yaw\n" + "".join(
            f"{x:.6f},{y:.6f},{z:.6f},{rpy[0]},{rpy[1]},{rpy[2]}\n" for x, y, z in points))
        poses_text = TASK.format(planner=args.planner, xyz=xyz, rpy=rpy, move='kind = "poses"\nfile = "wave.csv"')
        poses_path = folder / "poses.toml"
        poses_path.write_text(poses_text)
        poses_task = tomllib.loads(poses_text)
        # the line of the same length: the program's length, measured once
        spec = program_spec(ProgramPath.model_validate(poses_task["path"]), str(poses_path), 1e-3, math.pi / 180)
        pose = np.eye(4)
        pose[:3, 3] = np.array(xyz) * 1e-3
        pose[:3, :3] = rpy_matrix(*np.radians(rpy))
        program = build_program(spec, pose, str(poses_path))
        end = np.array(xyz) + [0.0, program.length * 1e3, 0.0]
        line_text = TASK.format(planner=args.planner, xyz=xyz, rpy=rpy,
                                move=f'kind = "line"\nto = {{ xyz = {end.round(6).tolist()} }}')
        line_path = folder / "line.toml"
        line_path.write_text(line_text)
        line_task = tomllib.loads(line_text)

        results = {}
        for name, task, path in (("line", line_task, line_path), ("poses", poses_task, poses_path)):
            samples = len(run_task(task, str(path)).data)
            seconds = best_of(lambda: run_task(task, str(path)), repeats)
            results[name] = {"seconds": seconds, "samples": samples, "ms_per_sample": seconds / samples * 1e3}
        poses_model = ProgramPath.model_validate(poses_task["path"])
        build = best_of(lambda: program_profile(build_program(program_spec(poses_model, str(poses_path), 1e-3,
                                                                           math.pi / 180), pose, "bench"), None),
                        repeats)
    ratio = results["poses"]["ms_per_sample"] / results["line"]["ms_per_sample"]
    robot = load_robot("iiwa14")
    print(f"iiwa14, {args.planner}, {args.rows} rows, path {program.length * 1e3:.1f} mm "
          f"({robot.n} joints), best of {repeats}:")
    for name, r in results.items():
        print(f"  {name:5s}: {r['seconds'] * 1e3:8.1f} ms for {r['samples']} samples = {r['ms_per_sample']:.3f} ms/sample")
    print(f"  poses / line per sample: {ratio:.2f}x (bar: within {BAR_RATIO:g}x: {'met' if ratio <= BAR_RATIO else 'NOT met'})")
    print(f"  building the poses program alone (CSV, spline, arc length, time law): {build * 1e3:.1f} ms")
    if args.out:
        Path(args.out).write_text(json.dumps({"rows": args.rows, "planner": args.planner, "results": results,
                                              "ratio": ratio, "build_seconds": build}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
