#!/usr/bin/env python3
"""Planner benchmarks (issue 15): measurements, not tests.

    python benchmarks/bench_planner.py [--repeat 3] [--survey 100] [--skip-survey]

1. `armgen plan examples/modular8_circle_combined.toml` (12 500 Euler steps): the planner's
   run time (``run_time_s`` of the summary, warm kernel cache) and the whole CLI call (a new
   process: imports, kernel build, planning, CSV + JSON), for each backend; per-step time
   against the native host firmware (gcc -O2, double) running the same plan, built and
   timed in this run.
2. The fault-tolerant and weighted-GPM examples: planner run time per backend, against the
   figures of the interpreted planners at commit 85a2322 (PREVIOUS, measured on this
   2-core machine with the same command before the rewrite).
3. The weighted-GPM survey (SURVEY_ARGS, 100 random tasks): serial, `--workers 2` and a
   2-worker Dask LocalCluster (processes); speedups against serial and whether the three
   tables are identical.

Bars (reported, not asserted): BARS.
"""

from __future__ import annotations

import argparse
import copy
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
if str(REPO) not in sys.path:  # run from a checkout without `pip install -e .`
    sys.path.insert(0, str(REPO))

from armgen.planning.sweep import SweepSpec, parse_grid, parse_range, sweep  # noqa: E402
from armgen.planning.tasks import apply_overrides, load_task, run_task  # noqa: E402

EXAMPLES = REPO / "examples"
COMBINED = EXAMPLES / "modular8_circle_combined.toml"
BARS = {"combined_plan_s": 0.25, "combined_cli_s": 0.8, "example_speedup": 10.0, "survey_speedup": 1.7}
# Planner run time (s, symbolic backend; c in brackets) of the interpreted planners at 85a2322,
# one run each on this machine (other jobs running), from the same run_task call.
PREVIOUS = {"modular8_circle_combined": 4.10, "iiwa14_fault_circle_gpm": 0.93, "iiwa14_fault_circle_wln": 1.28,
            "modular8_fault_circle_gpm": 0.71, "modular8_fault_circle_wln": 0.63, "modular8_wgpm_demo": 1.58}
PREVIOUS_C = {"modular8_circle_combined": 11.37, "iiwa14_fault_circle_wln": 4.52, "modular8_wgpm_demo": 8.10}
# The survey of docs/wgpm.md: a random start in the free band and a random circle through it.
SURVEY_SET = ["timing.duration=20", "path.relative=true"]
SURVEY_GRID = "method.name=['pinv', 'wgpm']"
SURVEY_RANGES = ["start=[-98,-98,-98,-98,-98,-98,-98,-98]:[98,98,98,98,98,98,98,98]",
                 "path.via=[-250,-250,-250]:[250,250,250]", "path.end=[-250,-250,-250]:[250,250,250]"]


def plan_time(example: str, backend: str, repeat: int, overrides=()) -> float:
    task, sha = load_task(EXAMPLES / f"{example}.toml")
    apply_overrides(task, list(overrides))
    run_task(copy.deepcopy(task), example, sha, backend)  # builds (and for c compiles) the kernel once
    return min(run_task(copy.deepcopy(task), example, sha, backend).metadata["summary"]["run_time_s"]
               for _ in range(repeat))


def cli_time(backend: str, out: Path) -> float:
    env = dict(os.environ, PYTHONPATH=str(REPO), ARMGEN_NO_PROGRESS="1")
    started = time.perf_counter()
    subprocess.run([sys.executable, "-m", "armgen.cli.main", "plan", str(COMBINED), "-o", str(out), "--backend",
                    backend], check=True, capture_output=True, env=env)
    return time.perf_counter() - started


def firmware_ns_per_tick(work: Path) -> float | None:
    from armgen.verify import firmware as fw

    try:
        task, sha = load_task(COMBINED)
        plan = run_task(task, COMBINED.name, sha)
        exe = fw.FirmwareBuilder("modular8", work / "fw").executable(fw.Variant("host", "double"),
                                                                      fw.task_from_plan(plan, COMBINED.name), "time")
        out = subprocess.run([str(exe), "--quiet", "--time", "20"], capture_output=True, text=True, check=True).stdout
    except Exception as exc:  # noqa: BLE001 -- a missing compiler skips the row
        print(f"  host firmware: skipped ({exc})")
        return None
    return float(fw.parse_output(out).summary["wall_ns_per_tick"])


def survey(count: int, work: Path) -> None:
    import pandas as pd

    task, sha = load_task(EXAMPLES / "modular8_wgpm_demo.toml")
    apply_overrides(task, SURVEY_SET)
    spec = SweepSpec([parse_grid(SURVEY_GRID)], [parse_range(r) for r in SURVEY_RANGES], count, seed=1)
    # warm the on-disk kernel cache so no column pays for compilation
    sweep(task, "demo", sha, SweepSpec(spec.grid, spec.ranges, 1, seed=1), work / "warm.csv", "c", workers=1)
    times, tables = {}, {}
    for label, kwargs in (("serial", {"workers": 1}), ("--workers 2", {"workers": 2}), ("dask 2 workers", None)):
        out = work / f"survey_{len(times)}.csv"
        if kwargs is None:
            from distributed import LocalCluster

            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
                started = time.perf_counter()
                sweep(task, "demo", sha, spec, out, "c", scheduler=cluster.scheduler_address)
        else:
            started = time.perf_counter()
            sweep(task, "demo", sha, spec, out, "c", **kwargs)
        times[label] = time.perf_counter() - started
        tables[label] = out.read_text()
    frame = pd.read_csv(work / "survey_0.csv")
    print(f"  {count} tasks x 2 methods = {len(frame)} runs ({(frame['status'] == 'ok').sum()} ok), c backend")
    for label, seconds in times.items():
        print(f"  {label:16s} {seconds:7.2f} s   speedup {times['serial'] / seconds:4.2f}x   "
              f"table identical to serial: {tables[label] == tables['serial']}")
    print(f"  (bar: speedup >= {BARS['survey_speedup']} with 2 workers)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--survey", type=int, default=100)
    parser.add_argument("--skip-survey", action="store_true")
    args = parser.parse_args()
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    work = Path(tempfile.mkdtemp(prefix="armgen-bench-planner-"))

    print("1. armgen plan examples/modular8_circle_combined.toml (12 500 steps)")
    fw_ns = firmware_ns_per_tick(work)
    for backend in ("symbolic", "c"):
        seconds = plan_time("modular8_circle_combined", backend, args.repeat)
        cli = min(cli_time(backend, work / "combined.csv") for _ in range(args.repeat))
        per_step = seconds / 12500 * 1e9
        vs_fw = f", {per_step / fw_ns:.0f}x the host firmware's {fw_ns:.0f} ns/tick" if fw_ns else ""
        print(f"  {backend:8s} planner {seconds:6.3f} s (bar {BARS['combined_plan_s']} s; was "
              f"{PREVIOUS['modular8_circle_combined'] if backend == 'symbolic' else PREVIOUS_C['modular8_circle_combined']} s)"
              f"   CLI {cli:5.2f} s (bar {BARS['combined_cli_s']} s)   {per_step / 1e3:.1f} us/step{vs_fw}")

    print("2. examples: planner run time, best of --repeat (was: interpreted planners at 85a2322)")
    for example in PREVIOUS:
        for backend in ("symbolic", "c"):
            seconds = plan_time(example, backend, args.repeat)
            before = PREVIOUS if backend == "symbolic" else PREVIOUS_C
            was = f"was {before[example]:5.2f} s, {before[example] / seconds:5.1f}x faster" if example in before else ""
            print(f"  {example:28s} {backend:8s} {seconds:6.3f} s   {was}")
    print(f"  (bar: >= {BARS['example_speedup']}x faster than before)")

    if not args.skip_survey:
        print(f"3. weighted-GPM survey: {args.survey} random tasks")
        survey(args.survey, work)


if __name__ == "__main__":
    main()
