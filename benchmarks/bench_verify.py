#!/usr/bin/env python3
"""``armgen verify`` benchmark (issue 29): measurements, not tests.

    python benchmarks/bench_verify.py [--robot modular8] [--samples 10000]

In one run, on the checked-in ``generated/<robot>/``, each figure as wall and CPU time (CPU
includes the compilers; a shared machine inflates wall time, not CPU time):

1. The whole ``armgen verify <robot>`` pipeline (fresh, compile, callbacks).
2. The compile stage's four builds (strict -O2 library and ASan/UBSan driver, double and float)
   one after another, and in parallel as the pipeline runs them.
3. The callbacks stage's C evaluations: every sample through the library's batched entry (what
   the pipeline does) against one ctypes call per sample (what it did), same inputs.
4. The callbacks stage's inputs: drawn for all samples at once (``batch_inputs``) against one
   sample at a time (``function_inputs``, what it did), and the interpreter's ``Function.map``
   on them.

The bar (reported, never asserted): the whole pipeline on modular8 in ≤ 15 s on an idle
2-core machine (it took 57 s before issue 29). A pipeline stage that does not pass, or any
error, fails the run (exit 1). ``--quick`` (a smoke run, seconds): planar3 (unless --robot is
given) and QUICK_SAMPLES samples.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
if str(REPO) not in sys.path:  # run from a checkout without `pip install -e .`
    sys.path.insert(0, str(REPO))
os.environ.setdefault("ARMGEN_NO_PROGRESS", "1")

from armgen.codegen.compiled import CompiledModel  # noqa: E402
from armgen.robot import load_robot  # noqa: E402
from armgen.symbolic.model import SymbolicModel  # noqa: E402
from armgen.verification import pipeline  # noqa: E402
from armgen.verification.compare import _batched_reference, _per_sample, reference_samples  # noqa: E402
from armgen.verification.samples import batch_inputs, function_inputs, joint_samples  # noqa: E402

BAR_SECONDS = 15.0
PER_SAMPLE_SUBSET = 2000  # samples timed one at a time, scaled to --samples
QUICK_ROBOT = "planar3"  # --quick: the smallest generated code
QUICK_SAMPLES = 200


def cpu_seconds() -> float:
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def timed(label: str, call, scale: float = 1.0):
    wall, cpu = time.perf_counter(), cpu_seconds()
    out = call()
    wall, cpu = (time.perf_counter() - wall) * scale, (cpu_seconds() - cpu) * scale
    print(f"  {label:58s} wall {wall:7.2f} s   cpu {cpu:7.2f} s" + (f"   (×{scale:g} of a subset)" if scale != 1 else ""))
    return out, wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", default=None, help="a bundled robot (default modular8; planar3 with --quick)")
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--quick", action="store_true", help=f"planar3, {QUICK_SAMPLES} samples (a smoke run)")
    args = parser.parse_args()
    if args.quick:
        args.samples = QUICK_SAMPLES
    args.robot = args.robot or (QUICK_ROBOT if args.quick else "modular8")
    robot = load_robot(args.robot)
    gen_dir = REPO / "generated" / robot.name
    config = pipeline.VerifyConfig(robot, samples=args.samples, generated=gen_dir, robot_ref=args.robot)
    found = pipeline.read_manifest(config)
    functions = SymbolicModel(robot).functions()
    print(f"{args.robot}: {len(functions)} functions × 2 precisions × {args.samples} samples, {os.cpu_count()} CPUs, "
          f"load {os.getloadavg()[0]:.1f}")

    print("1. the pipeline")
    stages, total = timed("armgen verify (fresh, compile, callbacks)",
                          lambda: pipeline.run_pipeline(config, echo=lambda text: None))
    failed = [stage.render() for stage in stages if not stage.passed]
    if failed:
        raise SystemExit("armgen verify did not pass, nothing to measure:\n" + "\n".join(failed))
    print(f"  bar: ≤ {BAR_SECONDS:g} s on an idle machine -> {'met' if total <= BAR_SECONDS else 'not met'} here")

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        print("2. the compile stage's four builds")
        builds = pipeline.compile_builds(config, work / "serial", functions, found)
        (work / "serial").mkdir()
        _, serial = timed("one after another", lambda: [action() for _, _, action in builds])
        builds = pipeline.compile_builds(config, work, functions, found)
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
            _, parallel = timed("in parallel", lambda: [f.result() for f in [pool.submit(a) for _, _, a in builds]])
        print(f"  ratio parallel / serial: {parallel / serial:.2f}")

        print("3. the callbacks stage's C evaluations (double)")
        library = next(f for f in work.glob("lib*_double.so"))
        compiled = CompiledModel(library, found.prefix, functions, "double")
        prepared = reference_samples(functions, robot, args.samples, config.seed, "double")
        subset = min(PER_SAMPLE_SUBSET, args.samples)

        def batched():
            for name, func in functions.items():
                inputs = prepared[name].inputs
                compiled.raw[name].batch([_per_sample(a, func.sparsity_in(k).shape) for k, a in enumerate(inputs)])

        def per_sample():
            for name in functions:
                inputs = prepared[name].inputs
                for s in range(subset):
                    compiled.raw[name](*[a[s] for a in inputs])

        _, fast = timed("batched entry, one call per function", batched)
        _, slow = timed("one ctypes call per sample", per_sample, args.samples / subset)
        print(f"  ratio batched / per sample: {fast / slow:.3f}")

        print("4. the callbacks stage's inputs and reference (double)")
        q, _ = joint_samples(robot, args.samples, config.seed)

        def all_at_once():
            return {name: batch_inputs(func, robot, q, np.random.default_rng(k))
                    for k, (name, func) in enumerate(functions.items())}

        def one_at_a_time():
            for k, func in enumerate(functions.values()):
                rng = np.random.default_rng(k)
                for s in range(subset):
                    function_inputs(func, robot, q[s], rng)

        inputs, fast = timed("inputs drawn for all samples at once", all_at_once)
        _, slow = timed("inputs drawn one sample at a time", one_at_a_time, args.samples / subset)
        print(f"  ratio at once / one at a time: {fast / slow:.3f}")
        timed("interpreter outputs (Function.map)",
              lambda: [_batched_reference(func, inputs[name]) for name, func in functions.items()])


if __name__ == "__main__":
    sys.exit(main())
