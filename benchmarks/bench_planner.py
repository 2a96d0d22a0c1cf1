"""Plan wall time of the spec-20 combined plan (12 500 Euler steps) with each backend,
in one run, as ratios against the symbolic (CasADi interpreter) backend and against the
paper's 0.12 s (MATLAB, 3.3 GHz dual core).

    python benchmarks/bench_planner.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from armgen.planning.tasks import load_task, run_task

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "modular8_circle_combined.toml"
PAPER_SECONDS = 0.12


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    task, sha = load_task(EXAMPLE)
    rows = []
    for backend in ("symbolic", "c"):
        times = []
        for _ in range(args.repeat):
            started = time.perf_counter()
            result = run_task(dict(task), EXAMPLE.name, sha, backend)
            times.append(time.perf_counter() - started)
        steps = result.data.shape[0] - 1
        rows.append((backend, min(times), steps, result.metadata["summary"]["max_final_deviation_deg"]))
    base = rows[0][1]
    print(f"{'backend':10s} {'wall [s]':>9s} {'µs/step':>8s} {'vs symbolic':>11s} {'vs paper':>9s} {'final dev [deg]':>16s}")
    for backend, seconds, steps, dev in rows:
        print(f"{backend:10s} {seconds:9.3f} {seconds / steps * 1e6:8.1f} {seconds / base:11.2f} "
              f"{seconds / PAPER_SECONDS:9.1f} {dev:16.4g}")
    print("(wall time includes backend set-up: C generation and compilation for 'c'; "
          "the native C loop is the firmware stub's host build)")


if __name__ == "__main__":
    main()
