#!/usr/bin/env python3
"""Every core of armgen.firmware.TARGETS (issue 42): measurements, not tests.

    python benchmarks/bench_targets.py [--robot modular8] [--out benchmarks/results/targets.json] [--quick]

Per core, in the precision it computes natively (float; double on the Cortex-M7), under QEMU
with -icount shift=0 (executed instructions; the timer calibrated in each run: SysTick on the
Arm cores, mcycle on RISC-V; docs/targets.md):

1. ``fk_jacobian`` and ``ik`` of the robot's checked-in generated C (-Os, bounded trig, as the
   firmware links them), each call timed on its own (benchmarks/c/bench_target_fn.c):
   instructions per call, mean and max, net of the harness (a stub timed the same way); ik
   from the robot's mid-range seed to the poses of seeded random configurations, its success
   rate (status OK, the C's own tolerance check).
2. The firmware (armgen's verify build of the core, fw.target_variant) on the RESOLVED_RATE and
   WEIGHTED_GPM tasks of bench_firmware.py: instructions per tick, mean and max; flash
   (text + data) and static RAM (data + bss) of the RESOLVED_RATE image, its peak stack.
3. The Cortex-M0+ (no FPU): the resolved-rate tick against a 1 kHz budget at 133 MHz (RP2040),
   counting one cycle per instruction (a lower bound: loads, stores and taken branches take 2
   on the M0+).

A missing tool leaves its core out and the run exits 4; an error is a traceback (exit 1).
4. The static worst-case bound (armgen.firmware.bound) of every generated function and of each
   tick, beside the measured maximum; ik also to unreachable poses (every call runs all its
   steps: the adversarial case the bound covers); the tick's cycle bound on the Cortex-M4F at
   0 and 5 flash wait states (STM32F4 at 168 MHz) and on the Cortex-M0+ from SRAM (RP2040).

``--quick``: fewer configurations and poses, the resolved-rate task only.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
for path in (REPO, HERE):  # a checkout without `pip install -e .`; bench_firmware's tasks
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

from armgen import firmware as fw  # noqa: E402
from armgen.firmware import bound  # noqa: E402
from armgen.codegen.toolchain import STRICT_FLAGS  # noqa: E402
from armgen.robot import load_robot  # noqa: E402
from armgen.symbolic import ik  # noqa: E402
from bench_firmware import mode_task  # noqa: E402

STUB = Path(fw.FIRMWARE_DIR)
DRIVER = HERE / "c" / "bench_target_fn.c"
SEED = 42
CONFIGURATIONS, POSES = 256, 64
QUICK_CONFIGURATIONS, QUICK_POSES = 32, 8
UNREACHABLE_SHARE = 8  # one unreachable pose per 8 reachable ones (each call runs all its steps)
UNREACHABLE_FACTOR = 3.0  # an arm's reach is its links' length: three times a reached pose's distance is beyond it
IK_TOL = {"float": 1e-4, "double": 1e-6}  # position [m] and orientation [rad]; float resolves ~1e-5 at 1 m
MODES = ("RESOLVED_RATE", "WEIGHTED_GPM")
M0PLUS_HZ, TICK_HZ = 133_000_000, 1000
# The cores with a cycle model: (label, model) each, and the clock the figures are given at.
# Cortex-M4F: code in zero-wait memory (SRAM, or every fetch an ART hit), and STM32F4's flash
# at 168 MHz (5 wait states); Cortex-M0+: the RP2040's SRAM at 133 MHz.
CYCLE_MODELS = {"cortex-m4": (("0 wait states", bound.CortexM4Cycles(0)), ("5 wait states", bound.CortexM4Cycles(5))),
                "cortex-m0plus": (("SRAM", bound.CortexM0PlusCycles()),)}
CYCLE_CLOCK_HZ = {"cortex-m4": 168_000_000, "cortex-m0plus": M0PLUS_HZ}  # RP2040's clock, a 1 kHz control loop
EXIT_TOOL_MISSING = 4


def run(cmd: list[str], what: str) -> str:
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        raise RuntimeError(f"{what} failed (exit {proc.returncode}):\n$ {' '.join(map(str, cmd))}\n{proc.stderr[-3000:]}")
    return proc.stdout


def literal(value: float, precision: str) -> str:
    return f"{float(np.float32(value))!r}f" if precision == "float" else repr(float(value))


def reachable_poses(robot, n_poses: int, rng) -> list[np.ndarray]:
    """Poses of configurations within the middle 80 % of each joint's range."""
    lo, hi = robot.qmin, robot.qmax
    return [robot.fk(q) for q in rng.uniform(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), size=(n_poses, robot.n))]


def unreachable_poses(robot, n_poses: int, rng) -> list[np.ndarray]:
    """The IK's worst case: reachable poses moved UNREACHABLE_FACTOR times as far from the base,
    beyond any configuration's reach, so every call runs its max_iterations steps (restarting
    as often as its attempts stall)."""
    poses = reachable_poses(robot, n_poses, rng)
    for T in poses:
        T[:3, 3] *= UNREACHABLE_FACTOR
    return poses


def poses_header(robot, precision: str, n_qs: int, n_poses: int, targets: list[np.ndarray] | None = None,
                 max_iterations: int = ik.MAX_ITERATIONS) -> str:
    """bench_poses.h: seeded configurations for fk_jacobian; ik's targets (default: reachable
    poses) and its max_iterations."""
    rng = np.random.default_rng(SEED)
    qs = rng.uniform(robot.qmin, robot.qmax, size=(n_qs, robot.n))
    targets = reachable_poses(robot, n_poses, rng) if targets is None else targets
    n_poses = len(targets)
    p = robot.name.lower()

    def row(values) -> str:
        return "{" + ", ".join(literal(v, precision) for v in values) + "}"

    return (f"#define BENCH_QS {n_qs}u\n#define BENCH_POSES {n_poses}u\n"
            f"#define BENCH_TOL (({p}_real){literal(IK_TOL[precision], precision)})\n"
            f"#define BENCH_MAX_ITERATIONS {max_iterations}\n"
            f"static const {p}_real qtab[BENCH_QS][{robot.n}] = {{\n" + ",\n".join(row(q) for q in qs) + "\n};\n"
            f"static const {p}_real pose[BENCH_POSES][16] = {{\n"
            + ",\n".join(row(T.T.reshape(16)) for T in targets) + "\n};\n"
            f"static const {p}_real seed[{robot.n}] = {row(robot.qmid)};\n")


def run_image(target: fw.Target, elf: Path) -> dict[str, int]:
    cmd = [target.qemu, "-M", target.qemu_machine, *target.qemu_extra, *fw.QEMU_MACHINE[2:], *fw.QEMU_ICOUNT,
           "-kernel", str(elf)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    text = proc.stdout + proc.stderr
    if proc.returncode != 0 or "done" not in text:
        raise RuntimeError(f"{elf.name} under {target.qemu} failed (exit {proc.returncode}):\n{text[-2000:]}")
    return {k: int(v) for k, v in (line.split() for line in text.splitlines() if len(line.split()) == 2)
            if v.isdigit()}


def calls_image(target: fw.Target, robot, work: Path, header: str, gen: Path | None = None) -> tuple[Path, list[str]]:
    """The image of benchmarks/c/bench_target_fn.c with the robot's generated C (``gen``, default
    the checked-in generated/<robot>) and bench_poses.h = ``header``: its path and the compile
    flags. -g: the DWARF lines the static bound reads (it changes no instruction); every
    function the generated header declares kept in the image (-u), for its bound."""
    p, precision = robot.name.lower(), target.precision
    gen = gen or REPO / "generated" / robot.name
    work.mkdir(parents=True, exist_ok=True)
    (work / "bench_poses.h").write_text(header)
    cc = target.compiler
    flags = [*STRICT_FLAGS, *target.cpu_flags, *target.compile_specs, "-g", "-ffunction-sections", "-fdata-sections",
             f"-D{p.upper()}_USE_FLOAT={int(precision == 'float')}", f"-D{p.upper()}_BOUNDED_TRIG=1",
             f"-DBENCH_PREFIX={p}", f'-DBENCH_HEADER="{p}.h"', f"-DBENCH_NDOF={robot.n}",
             "-I", str(gen), "-I", str(work), "-I", str(STUB / "arm"), "-I", str(HERE / "c")]
    objs = []
    for src, opt in ((gen / f"{p}.c", "-Os"), (DRIVER, "-O2"), (STUB / target.startup, "-Os"),
                     (STUB / "arm" / "semihost.c", "-Os")):
        obj = work / (src.stem + ".o")
        run([cc, *flags, opt, "-c", src, "-o", obj], f"compiling {src.name} for {target.name}")
        objs.append(obj)
    elf = work / "functions.elf"
    keep = [f"-Wl,-u,{name}" for name in re.findall(rf"^(?!static)\w[\w ]*?\b({p}_\w+)\(",
                                                    (gen / f"{p}.h").read_text(), re.M)]
    run([cc, *flags, "-nostartfiles", *target.link_specs, "-T", STUB / target.linker_script, "-Wl,--gc-sections",
         *keep, *objs, "-lm", "-o", elf], f"linking the {target.name} benchmark")
    return elf, [*flags, "-Os"]


def measure_calls(target: fw.Target, elf: Path) -> dict:
    """Instructions per call of fk_jacobian and ik (mean, max), net of the harness."""
    v = run_image(target, elf)
    per = v["calib_insns"] / v["calib_ticks"]
    fk_stub, ik_stub = v["fk_stub_sum"] / v["fk_calls"], v["ik_stub_sum"] / v["ik_calls"]
    return {"instructions_per_count": per,
            "fk_jacobian": {"mean": (v["fk_sum"] / v["fk_calls"] - fk_stub) * per, "max": (v["fk_max"] - fk_stub) * per,
                            "calls": v["fk_calls"]},
            "ik": {"mean": (v["ik_sum"] / v["ik_calls"] - ik_stub) * per, "max": (v["ik_max"] - ik_stub) * per,
                   "calls": v["ik_calls"], "success": v["ik_ok"] / v["ik_calls"], "steps_at_max": v["ik_steps_at_max"]}}


def static_bounds(target: fw.Target, robot, elf: Path, flags: list[str], max_iterations: int, gen: Path) -> dict:
    """The static worst-case bound (armgen.firmware.bound) of each generated function in the image."""
    p = robot.name.lower()
    analyzer = bound.analyzer(target, elf, flags, p, max_iterations)
    return {name.removeprefix(p + "_"): analyzer.bound(name).instructions
            for name in bound.generated_functions(analyzer, p, gen / f"{p}.h")}


def functions(target: fw.Target, robot, work: Path, n_qs: int, n_poses: int) -> dict:
    """fk_jacobian and ik per call on the core (section 1): ik to reachable poses and to
    unreachable ones (every call runs ik.MAX_ITERATIONS steps); every generated function's bound."""
    precision = target.precision
    elf, flags = calls_image(target, robot, work / "reachable", poses_header(robot, precision, n_qs, n_poses))
    out = {"precision": precision, **measure_calls(target, elf)}
    out["ik"]["tolerance"] = IK_TOL[precision]
    far = unreachable_poses(robot, max(1, n_poses // UNREACHABLE_SHARE), np.random.default_rng(SEED + 1))
    elf_far, _ = calls_image(target, robot, work / "unreachable", poses_header(robot, precision, n_qs, n_poses, far))
    worst = measure_calls(target, elf_far)["ik"]
    out["ik_unreachable"] = {k: worst[k] for k in ("mean", "max", "calls", "success", "steps_at_max")}
    out["bound"] = static_bounds(target, robot, elf, flags, ik.MAX_ITERATIONS, REPO / "generated" / robot.name)
    return out


def size(target: fw.Target, elf: Path) -> dict[str, int]:
    out = run([target.tools[1], "-A", elf], f"sizing {elf.name}")
    sections = {parts[0]: int(parts[1]) for parts in (line.split() for line in out.splitlines())
                if len(parts) >= 3 and parts[0].startswith(".") and parts[1].isdigit()}
    flash = sum(v for k, v in sections.items() if k not in (".bss", ".heap", ".comment") and not k.startswith(".debug")
                and k not in (".ARM.attributes", ".riscv.attributes", ".stack"))
    ram = sections.get(".data", 0) + sections.get(".sdata", 0) + sections.get(".bss", 0)
    return {"flash_bytes": flash, "static_ram_bytes": ram}


def firmware(target: fw.Target, builder: fw.FirmwareBuilder, work: Path, modes) -> dict:
    """Instructions per tick of each mode, flash and RAM (section 2)."""
    import dataclasses
    quiet = dataclasses.replace(fw.target_variant(target.name), print_rows=False)
    out = {}
    for mode in modes:
        task = mode_task(mode, work)
        elf = builder.executable(quiet, task, f"{target.name}_{mode}")
        run = fw.run_qemu(elf, target=target.name)
        ipt = fw.instructions_per_tick(run)
        flags = builder.cflags(quiet)
        static = bound.tick_bound(target, elf, flags, builder.prefix, task.mode, task.header).instructions
        out[mode] = {"mean": ipt["mean"], "max": ipt["max"], "bound": static, "ticks": int(ipt["ticks"]),
                     "end": f"{run.state}/{run.fault}", "stack_peak_bytes": int(run.summary["stack_peak_bytes"])}
        models = CYCLE_MODELS.get(target.name, ())  # cycles (docs/targets.md, "Static bound")
        out[mode]["cycle_bound"] = {
            label: bound.analyzer(target, elf, flags, block_cost=model).bound(
                "ctrl_tick", bound.tick_avoid(builder.prefix, mode, "CTRL_PATH_PROGRAM" in task.header)).instructions
            for label, model in models}
        if mode == "RESOLVED_RATE":
            out["image"] = size(target, elf)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="modular8", help="a bundled robot with checked-in generated C (default modular8)")
    ap.add_argument("--out", default=None, help="JSON results (default benchmarks/results/targets.json; "
                                                "--quick writes none unless given)")
    ap.add_argument("--quick", action="store_true", help="a smoke run: fewer calls, the resolved-rate task only")
    args = ap.parse_args(argv)
    robot = load_robot(args.robot)
    n_qs, n_poses = (QUICK_CONFIGURATIONS, QUICK_POSES) if args.quick else (CONFIGURATIONS, POSES)
    modes = MODES[:1] if args.quick else MODES
    results: dict = {"robot": robot.name, "seed": SEED, "configurations": n_qs, "poses": n_poses, "targets": {}}
    missing = []
    with tempfile.TemporaryDirectory(prefix="armgen-bench-targets-") as tmp:
        work = Path(tmp)
        builder = fw.FirmwareBuilder(robot, work / "firmware")
        for name, target in fw.TARGETS.items():
            absent = [t for t in target.tools if shutil.which(t) is None]
            if absent:
                missing.append(f"{name}: {', '.join(absent)} (apt-get install -y {' '.join(target.apt_packages)})")
                print(f"{name}: MISSING {', '.join(absent)}", flush=True)
                continue
            r = functions(target, robot, work / name, n_qs, n_poses)
            r["firmware"] = firmware(target, builder, work, modes)
            results["targets"][name] = r
            print(f"{name} ({target.qemu_machine}, {r['precision']}): fk_jacobian {r['fk_jacobian']['mean']:.0f} / "
                  f"{r['fk_jacobian']['max']:.0f}, ik {r['ik']['mean']:.0f} / {r['ik']['max']:.0f} instr/call", flush=True)
    print(f"\n{robot.name}: executed instructions per call or tick (mean / max / static bound), QEMU -icount; "
          f"ik unreachable: {ik.MAX_ITERATIONS} steps a call\n")
    head = ["target", "precision", "fk_jacobian", "ik", "ik success", "ik unreachable (max / bound)"] + [
        f"tick {m}" for m in modes] + ["flash [B]", "static RAM [B]", "peak stack [B]"]
    print("| " + " | ".join(head) + " |\n|" + "---|" * len(head))
    for name, r in results["targets"].items():
        f, b = r["firmware"], r["bound"]
        cells = [name, r["precision"], f"{r['fk_jacobian']['mean']:.0f} / {r['fk_jacobian']['max']:.0f} / {b['fk_jacobian']}",
                 f"{r['ik']['mean']:.0f} / {r['ik']['max']:.0f} / {b['ik']}", f"{r['ik']['success']:.0%}",
                 f"{r['ik_unreachable']['max']:.0f} / {b['ik']}"]
        cells += [f"{f[m]['mean']:.0f} / {f[m]['max']:.0f} / {f[m]['bound']}" for m in modes]
        cells += [str(f["image"]["flash_bytes"]), str(f["image"]["static_ram_bytes"]),
                  str(max(f[m]["stack_peak_bytes"] for m in modes))]
        print("| " + " | ".join(cells) + " |")
    print(f"\nStatic bound of each generated function [instructions per call; ik: {ik.MAX_ITERATIONS} steps]\n")
    names = sorted({n for r in results["targets"].values() for n in r["bound"]})
    print("| function | " + " | ".join(results["targets"]) + " |\n|---|" + "---|" * len(results["targets"]))
    for n in names:
        print(f"| `{n}` | " + " | ".join(str(r["bound"].get(n, "-")) for r in results["targets"].values()) + " |")
    for name, hz in CYCLE_CLOCK_HZ.items():
        if name in results["targets"]:
            print(f"\n{name} cycle bound per tick (docs/targets.md): at {hz // 1_000_000} MHz")
            for m in modes:
                for label, cycles in results["targets"][name]["firmware"][m]["cycle_bound"].items():
                    print(f"  {m}: {label}: {cycles} cycles, {cycles / hz * 1e6:.0f} µs")
    m0 = results["targets"].get("cortex-m0plus")
    if m0 is not None:
        budget = M0PLUS_HZ // TICK_HZ
        rr = m0["firmware"]["RESOLVED_RATE"]
        results["m0plus_budget"] = {"cycles_per_tick": budget, "rr_max_instructions": rr["max"],
                                    "share": rr["max"] / budget}
        print(f"\nCortex-M0+ float (soft float) resolved-rate tick: max {rr['max']:.0f} instructions against "
              f"{budget} cycles per 1 kHz tick at 133 MHz: {rr['max'] / budget:.0%} of the budget "
              f"(at least; {'fits' if rr['max'] <= budget else 'does NOT fit'})")
        worst = rr["cycle_bound"]["SRAM"]
        results["m0plus_budget"].update(cycle_bound=worst, guaranteed_rate_hz=M0PLUS_HZ // worst)
        print(f"Its static cycle bound from SRAM: {worst} cycles, {worst / M0PLUS_HZ * 1e3:.2f} ms: a tick rate of "
              f"{M0PLUS_HZ // worst} Hz is guaranteed")
    out = args.out or (None if args.quick else str(HERE / "results" / "targets.json"))
    if out:
        Path(out).write_text(json.dumps(results, indent=2) + "\n")
        print(f"wrote {out}")
    for line in missing:
        print(f"MISSING {line}")
    return EXIT_TOOL_MISSING if missing else 0


if __name__ == "__main__":
    sys.exit(main())
