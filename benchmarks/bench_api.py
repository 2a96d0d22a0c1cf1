#!/usr/bin/env python3
"""Python-API benchmark (issue 14): measurements, not tests.

    python benchmarks/bench_api.py [--robot modular8] [--batch 100000] [--out benchmarks/results/api.json]

In one run, on ``--batch`` seeded configurations inside the joint limits:

1. ``robot.fk(q) + robot.jacobian(q)`` on the whole batch (the vectorised replay of the SX
   functions, see ``armgen/symbolic/replay.py``): wall and CPU time, best of 5 after a warm-up
   (the first call builds the model; its time is printed separately).
2. ``robot.fk_jacobian(q)`` likewise (one pass for both).
3. The reference: the symbolic ``fk`` and ``jacobian`` ``casadi.Function`` called once per
   configuration from Python (the per-call CasADi interpreter), timed on 2 000 configurations
   and scaled to the batch.
4. The same per-call reference through the API's single-sample path (``robot.fk(q[k])``).

The bar (reported, never asserted): fk + jacobian on 100 000 configurations of modular8 in
≤ 0.2 s. Wall-clock figures are noisy on a shared machine; CPU time is printed beside them.
``--quick`` (a smoke run, about a second): QUICK_BATCH configurations, QUICK_PER_CALL_SAMPLES
per call, best of 2; the bar is not judged. Any error is a traceback (exit 1).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
if str(REPO) not in sys.path:  # run from a checkout without `pip install -e .`
    sys.path.insert(0, str(REPO))

import armgen  # noqa: E402

BAR_SECONDS = 0.2  # fk + jacobian, 100 000 configurations of modular8 (issue 14)
REPEATS = 5
PER_CALL_SAMPLES = 2000
QUICK_BATCH = 2000
QUICK_PER_CALL_SAMPLES = 200
QUICK_REPEATS = 2
SEED = 20261123


def best_of(func, repeats: int = REPEATS) -> tuple[float, float]:
    """(best wall time, CPU time of that run) in seconds."""
    best = (float("inf"), float("inf"))
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        func()
        best = min(best, (time.perf_counter() - wall, time.process_time() - cpu))
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="modular8")
    parser.add_argument("--batch", type=int, default=100_000)
    parser.add_argument("--out", type=Path, default=None, help="also write the figures as JSON")
    parser.add_argument("--quick", action="store_true",
                        help="a smoke run in about a second (small batch, bar not judged)")
    args = parser.parse_args()
    repeats, per_call_samples = (QUICK_REPEATS, QUICK_PER_CALL_SAMPLES) if args.quick else (REPEATS, PER_CALL_SAMPLES)
    if args.quick:
        args.batch = QUICK_BATCH

    robot = armgen.load_robot(args.robot)
    q = np.random.default_rng(SEED).uniform(robot.qmin, robot.qmax, (args.batch, robot.n))

    started = time.perf_counter()
    robot.fk(q[:2]), robot.jacobian(q[:2]), robot.fk_jacobian(q[:2])
    first_call = time.perf_counter() - started

    batch_wall, batch_cpu = best_of(lambda: (robot.fk(q), robot.jacobian(q)), repeats)
    fused_wall, fused_cpu = best_of(lambda: robot.fk_jacobian(q), repeats)

    symbolic = robot.symbolic  # the same casadi.Functions the API evaluates
    fk, jac = symbolic.function("fk"), symbolic.function("jacobian")
    sample = q[:per_call_samples]

    def per_call_casadi():
        for qk in sample:
            fk(qk), jac(qk)

    def per_call_api():
        for qk in sample:
            robot.fk(qk), robot.jacobian(qk)

    casadi_wall, _ = best_of(per_call_casadi, min(repeats, 3))
    api_single_wall, _ = best_of(per_call_api, min(repeats, 3))
    scale = args.batch / per_call_samples
    casadi_batch = casadi_wall * scale

    rows = [
        ("first call (model build + replay setup)", first_call, None),
        (f"robot.fk + robot.jacobian, {args.batch} configurations", batch_wall, batch_cpu),
        (f"robot.fk_jacobian, {args.batch} configurations", fused_wall, fused_cpu),
        (f"per-call CasADi fk + jacobian, scaled to {args.batch}", casadi_batch, None),
        (f"per-call robot.fk(q[k]) + robot.jacobian(q[k]), scaled to {args.batch}", api_single_wall * scale, None),
    ]
    print(f"robot {robot.name} ({robot.n} joints), batch {args.batch}, best of {repeats}")
    for label, wall, cpu in rows:
        cpu_text = f"   cpu {cpu:8.4f} s" if cpu is not None else ""
        print(f"  {label:70s} {wall:8.4f} s  ({wall / args.batch * 1e6:7.3f} us/config){cpu_text}")
    print(f"  speed-up of the batch over per-call CasADi: {casadi_batch / batch_wall:.1f}x (fk + jacobian), "
          f"{casadi_batch / fused_wall:.1f}x (fk_jacobian)")
    if args.quick:
        print(f"  bar: fk + jacobian <= {BAR_SECONDS} s on 100 000 configurations -> not judged (--quick)")
    else:
        verdict = "meets" if batch_wall <= BAR_SECONDS else "misses"
        print(f"  bar: fk + jacobian <= {BAR_SECONDS} s on 100 000 configurations -> {verdict} ({batch_wall:.3f} s)")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({
            "robot": robot.name, "batch": args.batch, "first_call_s": first_call,
            "fk_plus_jacobian_s": batch_wall, "fk_plus_jacobian_cpu_s": batch_cpu,
            "fk_jacobian_s": fused_wall, "fk_jacobian_cpu_s": fused_cpu,
            "per_call_casadi_scaled_s": casadi_batch, "per_call_api_scaled_s": api_single_wall * scale,
            "bar_s": BAR_SECONDS,
        }, indent=2) + "\n")


if __name__ == "__main__":
    main()
