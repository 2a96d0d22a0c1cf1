"""Mutation fuzzing of the loaders at scale (issues 11, 27, 37): 10 000 robot files, 10 000 task
files, 10 000 URDF files, 2 000 sets of sweep options, 10 000 poses CSV files, 10 000 Robot.ik
calls and 2 000 `armgen ik` command lines by default, seeded, with the suite's mutators
(tests/fuzzing.py). Prints one row per
file kind: cases, clean errors, accepted, tracebacks, hangs, accepted nonsense (a certainly
invalid file that was accepted) and failed plans that left files behind; then the first
example of each bad outcome. Not a test: nothing here asserts.

    python benchmarks/fuzz.py [--robots 10000] [--tasks 10000] [--urdfs 10000] [--sweeps 2000] [--poses 10000]
                              [--iks 10000] [--ik-commands 2000] [--seed 0] [--full-plan-share 0.03] [--quick]

``--quick``: QUICK_CASES cases of each kind (a smoke run of the table, seconds).
"""

from __future__ import annotations

import argparse
import os
import random
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from fuzzing import (FULL_PLAN_BASES, ik_case, ik_cli_case, mutate_ik, mutate_ik_cli, mutate_poses,  # noqa: E402
                     mutate_robot, mutate_sweep, mutate_task, mutate_urdf, poses_case, robot_case, sweep_case,
                     task_case, urdf_case)

from armgen.progress import progress  # noqa: E402

QUICK_CASES = 20
COLUMNS = ("cases", "clean errors", "accepted", "tracebacks", "hangs", "accepted nonsense", "wrote on failure")


def _tally(counts: Counter, examples: dict, outcome, invalid: bool, label: str) -> None:
    counts["cases"] += 1
    kind = {"clean": "clean errors", "accepted": "accepted", "traceback": "tracebacks", "hang": "hangs"}[outcome.kind]
    counts[kind] += 1
    if invalid and outcome.kind == "accepted":
        counts["accepted nonsense"] += 1
        examples.setdefault("accepted nonsense", label)
    if outcome.wrote:
        counts["wrote on failure"] += 1
        examples.setdefault("wrote on failure", label)
    if outcome.kind in ("traceback", "hang"):
        examples.setdefault(kind, f"{label}: {outcome.detail[:200]}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", type=int, default=10_000)
    parser.add_argument("--tasks", type=int, default=10_000)
    parser.add_argument("--urdfs", type=int, default=10_000)
    parser.add_argument("--sweeps", type=int, default=2_000)
    parser.add_argument("--poses", type=int, default=10_000)
    parser.add_argument("--iks", type=int, default=10_000)
    parser.add_argument("--ik-commands", type=int, default=2_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--full-plan-share", type=float, default=0.03,
                        help="share of task cases planned and written in full (the rest: schema validation)")
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_CASES} cases of each kind (a smoke run)")
    args = parser.parse_args()
    if args.quick:
        args.robots = args.tasks = args.urdfs = args.sweeps = args.poses = args.iks = args.ik_commands = QUICK_CASES
    os.environ.setdefault("ARMGEN_NO_PROGRESS", "")
    rows, examples, seconds = {}, {}, {}

    started = time.perf_counter()
    counts: Counter = Counter()
    with progress(args.robots, "robot files") as bar:
        for k in range(args.robots):
            rng = random.Random(f"robot-{args.seed}-{k}")
            text, invalid = mutate_robot(rng)
            _tally(counts, examples, robot_case(text), invalid, f"robot case {k}")
            bar.update(1)
    rows["robot files"], seconds["robot files"] = counts, time.perf_counter() - started

    started = time.perf_counter()
    counts = Counter()
    with progress(args.tasks, "task files") as bar:
        for k in range(args.tasks):
            rng = random.Random(f"task-{args.seed}-{k}")
            full = rng.random() < args.full_plan_share
            name, task, invalid = mutate_task(rng, FULL_PLAN_BASES if full else None)
            counts["full plans"] += full
            _tally(counts, examples, task_case(task, full), invalid, f"task case {k} ({name})")
            bar.update(1)
    rows["task files"], seconds["task files"] = counts, time.perf_counter() - started

    for kind, count, mutate, case in (("URDF files", args.urdfs, mutate_urdf, urdf_case),
                                      ("sweep options", args.sweeps, mutate_sweep, sweep_case),
                                      ("poses CSV files", args.poses, mutate_poses, poses_case),
                                      ("Robot.ik calls", args.iks, mutate_ik, ik_case),
                                      ("armgen ik command lines", args.ik_commands, mutate_ik_cli, ik_cli_case)):
        started = time.perf_counter()
        counts = Counter()
        with progress(count, kind) as bar:
            for k in range(count):
                rng = random.Random(f"{kind}-{args.seed}-{k}")
                case_input, invalid = mutate(rng)
                _tally(counts, examples, case(case_input), invalid, f"{kind} case {k}")
                bar.update(1)
        rows[kind], seconds[kind] = counts, time.perf_counter() - started

    print("| file kind | " + " | ".join(COLUMNS) + " | full plans | wall s |")
    print("|---" * (len(COLUMNS) + 3) + "|")
    for kind, c in rows.items():
        print(f"| {kind} | " + " | ".join(str(c[col]) for col in COLUMNS) + f" | {c['full plans']} | "
              f"{seconds[kind]:.1f} |")
    for kind, example in examples.items():
        print(f"first {kind}: {example}")


if __name__ == "__main__":
    main()
