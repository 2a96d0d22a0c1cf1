#!/usr/bin/env python3
"""Firmware benchmarks (issue 7): measurements, not tests.

    python benchmarks/bench_firmware.py [--out benchmarks/results/firmware.json] [--keep]

For the joint controller of firmware_stub/ running spec 20's combined plan on modular8
(12 500 Euler ticks, h = 0.02 s, from examples/modular8_circle_combined.toml):

1. Cortex-M4F (arm-none-eabi-gcc, float, the build armgen verify --target uses: optimisation
   per source as fw.ARM_VARIANT, generated kinematics -Os): flash and RAM of the
   controller and of each generated function it links (arm-none-eabi-size -A, nm -S), the
   image, sizeof(ctrl); stack use: -fstack-usage per function, the worst call chain from
   ctrl_tick (-fcallgraph-info=su), and the measured peak (the firmware paints its stack).
2. Executed instructions per tick under qemu-system-arm -M mps2-an386 -icount shift=0
   (SysTick on the processor clock, 40 instructions per count, calibrated in the run; the
   method of benchmarks/README.md), mean / max / min over the 12 501 ticks, for that build
   and for variants (newlib trig, -O2, -Os); a per-function split from an instruction trace
   of a short plan with every operator active.
3. The same 12 500-tick plan run natively by the host firmware (gcc -O2, double and float),
   best wall time of 20 runs, against the Python planner (symbolic backend, timed in this
   run) and the paper's 0.12 s.
4. Replay errors of those runs against the plan (host double, host float, QEMU float).
5. Every controller mode (issue 13): per mode, on modular8, float, the Cortex-M4F build —
   executed instructions per tick (mean, max, max/mean), µs per tick at 168 MHz, flash
   (controller.o + the generated functions the mode calls), RAM (sizeof(ctrl)), stack
   (-fstack-usage worst static chain of the mode's tick, and the peak measured under QEMU);
   ratios against RESOLVED_RATE measured in the same run. ``--modes-only`` runs just this.
6. MOVE_TO (``--move-to-only``).
7. A program on board (issue 26, ``--program-only``): the seam program of
   tests/test_programs.py (4 lines, 2 arcs, 8 mm blends, the torch turning) on Baxter's arm
   (tests/data, not bundled), cartesian with CLIK: instructions per tick (mean, max) against a
   line task on the same robot from the same start with the same method and gain (today's
   resolved-rate tick) in the same build, flash of the program table and of fw_program.o, RAM
   (sizeof(ctrl)), and the replay error of the QEMU run against the plan.
8. The feed-forward torque (issue 39, ``--feedforward-only``): on the bundled iiwa14 (inertials,
   taumax), instructions per tick (mean, max) of a resolved-rate line and of a ptp swing played
   back with feedforward none / gravity / inverse_dynamics, against the same arm's robot file
   without its inertials (no dynamics compiled in); the image's text and sizeof(ctrl) of each,
   and the host's ns per tick (gcc -O2 double, best of 20).
9. The collision check and criterion on board (issue 38, ``--collision-only``): the bar task of
   benchmarks/data/collision/ (Baxter's arm, not bundled, beside a column above a table) run
   without [collision], with the clearance check alone, and with the check and the criterion,
   per obstacle-slot layout of the robot (its defaults, 4 slots with a box, 4 without):
   instructions per tick (mean, max), the image's text, and the criterion run's replay error
   against its plan (QEMU float, host double).

Bars (reported, not asserted): BARS. A missing tool skips its rows and the run exits 4; a
measurement that fails is reported FAILED and the run exits 1 (bench_kinematics.py's
EXIT_CODES). About a minute on 2 cores. ``--quick`` (seconds, a smoke run whose figures are not
the ones to quote): sections 0–4 on the 5-s plan of the split (QUICK_OVERRIDES) instead of the
12 500-tick one, without the variants and the trace, host time best of 2; no section 5.
"""

from __future__ import annotations

import argparse
import collections
import copy
import dataclasses
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
if str(REPO) not in sys.path:  # run from a checkout without `pip install -e .`
    sys.path.insert(0, str(REPO))

from bench_kinematics import Report, Skip, bar_note, finish  # noqa: E402

from armgen.planning.result import write_plan  # noqa: E402
from armgen.planning.tasks import apply_overrides, load_task, run_task  # noqa: E402
from armgen import firmware as fw  # noqa: E402
from armgen.verification import firmware_compare as fwcmp  # noqa: E402

EXAMPLE = REPO / "examples" / "modular8_circle_combined.toml"
PAPER_SECONDS = 0.12
BARS = {"m4_instr_per_tick": 5000, "host_plan_ms": 20.0, "ft_instr_per_tick_max": 12000,
        "wgpm_instr_per_tick_max": 14000, "max_over_mean": 1.1, "lean_m4_instr_per_tick": 3500}
# The previous figures (docs/firmware.md, the run before the lean criteria: Cauchy–Binet
# criteria, newlib isfinite/fmax/sinf/cosf calls), printed beside this run's with the ratio.
PREVIOUS = {"m4_instr_per_tick": 4823, "RESOLVED_RATE": 4707, "PLAYBACK": 1440, "FAULT_TOLERANT gpm": 34537,
            "FAULT_TOLERANT wln smooth": 50296, "FAULT_TOLERANT wln plain": 35263, "WEIGHTED_GPM": 30221}
# Section 5: one plan per controller mode (modular8). Generated functions per mode.
MODE_PLANS = {
    "RESOLVED_RATE": ("modular8_circle_combined", ["path.type=line", "path.end=[-450, 400, 900]",
                                                   "timing.duration=5", "method.theta_s=75", "method.T_smo_L=0.5",
                                                   "method.T_sum_L=1", "method.rho_L=0.01"]),
    "PLAYBACK": ("modular8_ptp_two_segments", []),
    "FAULT_TOLERANT gpm": ("modular8_fault_circle_gpm", []),
    "FAULT_TOLERANT wln smooth": ("modular8_fault_circle_wln", []),
    "FAULT_TOLERANT wln plain": ("modular8_fault_circle_wln", ["method.weight_rule=plain"]),
    "WEIGHTED_GPM": ("modular8_wgpm_demo", []),
}
# The generated functions each mode links (the firmware's: the steps' *_from_jacobian twins),
# plus the fixed loops (symbolic.loops) those call, matched by name in the image.
MODE_FUNCTIONS = {"RESOLVED_RATE": fw.FIRMWARE_FUNCTIONS, "PLAYBACK": (),
                  "FAULT_TOLERANT": ("fk_jacobian", *fw.OPTIONAL_FUNCTIONS["FAULT_TOLERANT"]),
                  "WEIGHTED_GPM": ("fk_jacobian", *fw.OPTIONAL_FUNCTIONS["WEIGHTED_GPM"])}
MODE_LOOPS = {"FAULT_TOLERANT", "WEIGHTED_GPM"}
MODE_TICK = {"RESOLVED_RATE": "tick_resolved_rate", "PLAYBACK": "tick_playback",
             "FAULT_TOLERANT": "tick_fault_tolerant", "WEIGHTED_GPM": "tick_weighted_gpm"}
HOST_REPEATS = 20
QUICK_HOST_REPEATS = 2
# A short plan with every operator active (windows open and close, alpha_R and gamma_R ramp):
# the instruction trace of its 251 ticks gives the per-function split.
SPLIT_OVERRIDES = ["path.type=line", "path.end=[-450, 400, 900]", "timing.duration=5", "method.theta_s=75",
                   "method.T_smo_L=0.5", "method.T_sum_L=1", "method.rho_L=0.01", "method.gamma_R_ramp=1",
                   "method.T_smo_R=1"]
QUICK_OVERRIDES = SPLIT_OVERRIDES  # --quick: 251 ticks instead of 12 501


def tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise Skip(f"skipped: {name} not installed (apt-get install -y {fw.APT_PACKAGES})")
    return path


def run(cmd, timeout=600) -> str:
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"{cmd[0]} failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return proc.stdout + proc.stderr


# ------------------------------------------------------------------------------------------
# sizes and stack
# ------------------------------------------------------------------------------------------

def section_sizes(obj: Path) -> dict[str, int]:
    out = {}
    for line in run([tool("arm-none-eabi-size"), "-A", obj]).splitlines():
        p = line.split()
        if len(p) >= 2 and p[0].startswith(".") and p[1].isdigit() and int(p[1]) > 0:
            out[p[0]] = int(p[1])
    return out


def flash_ram(obj: Path) -> dict[str, int]:
    s = section_sizes(obj)
    text = sum(v for k, v in s.items() if k.startswith(".text"))
    rodata = sum(v for k, v in s.items() if k.startswith(".rodata"))
    ram = sum(v for k, v in s.items() if k.startswith((".data", ".bss")))
    return {"text": text, "rodata": rodata, "data_bss": ram, "flash": text + rodata + sum(
        v for k, v in s.items() if k.startswith(".data"))}


def linked_symbols(elf: Path) -> dict[str, int]:
    out = {}
    for line in run([tool("arm-none-eabi-nm"), "-S", elf]).splitlines():
        p = line.split()
        if len(p) == 4:
            out[p[3]] = int(p[1], 16)
    return out


def image_size(elf: Path) -> dict[str, int]:
    lines = run([tool("arm-none-eabi-size"), elf]).splitlines()
    text, data, bss = (int(x) for x in lines[1].split()[:3])
    return {"text": text, "data": data, "bss": bss}


def stack_usage(obj_dir: Path) -> dict[str, int]:
    out = {}
    for su in obj_dir.glob("*.su"):
        for line in su.read_text().splitlines():
            where, nbytes, _kind = line.split("\t")
            out[where.rsplit(":", 1)[-1]] = int(nbytes)
    return out


def worst_chain(obj_dir: Path, root: str = "ctrl_tick", avoid: tuple[str, ...] = ()) -> tuple[int, list[str], list[str]]:
    """Deepest stack from root over the -fcallgraph-info=su graphs; functions without a
    frame size (libm) are listed as unknown and count 0."""
    size: dict[str, int] = {}
    edges: dict[str, set[str]] = collections.defaultdict(set)
    for ci in obj_dir.glob("*.ci"):
        text = ci.read_text()
        for m in re.finditer(r'node: \{ title: "([^"]+)" label: "([^"\\]+)(?:\\n[^"]*?\\n(\d+) bytes)?', text):
            name = m.group(1).rsplit(":", 1)[-1]
            if m.group(3) is not None:
                size[name] = int(m.group(3))
        for m in re.finditer(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"', text):
            edges[m.group(1).rsplit(":", 1)[-1]].add(m.group(2).rsplit(":", 1)[-1])
    wrapped = {"sinf": "__wrap_sinf", "cosf": "__wrap_cosf"}  # the M4 build links -Wl,--wrap
    unknown: set[str] = set()

    def depth(f: str, seen: tuple[str, ...]) -> tuple[int, list[str]]:
        f = wrapped.get(f, f)
        if f in seen:
            return 0, []
        if f not in size:
            unknown.add(f)
            return 0, [f]
        best, path = 0, []
        for g in edges.get(f, ()):
            if g in avoid:  # another mode's tick: not on this mode's chain
                continue
            d, p = depth(g, seen + (f,))
            if d > best:
                best, path = d, p
        return size[f] + best, [f, *path]

    total, path = depth(root, ())
    return total, path, sorted(unknown)


# ------------------------------------------------------------------------------------------
# QEMU trace split
# ------------------------------------------------------------------------------------------

def trace_split(elf: Path, work: Path) -> dict:
    qemu = tool("qemu-system-arm")
    log = work / "exec.log"
    subprocess.run([qemu, *fw.QEMU_MACHINE, *fw.QEMU_ICOUNT, "-singlestep", "-d", "exec,nochain", "-D", str(log),
                    "-kernel", str(elf)], capture_output=True, timeout=600, check=True)
    syms = []
    for line in run([tool("arm-none-eabi-nm"), "-S", elf]).splitlines():
        p = line.split()
        if len(p) == 4 and p[2] in "tTwW":
            syms.append((int(p[0], 16) & ~1, int(p[1], 16), p[3]))
    syms.sort()
    starts = [s[0] for s in syms]
    import bisect

    def name_at(pc: int) -> str:
        i = bisect.bisect_right(starts, pc) - 1
        return syms[i][2] if i >= 0 and pc < syms[i][0] + syms[i][1] else "?"

    entry = next(s[0] for s in syms if s[2] == "ctrl_tick")
    by: collections.Counter = collections.Counter()
    inside, ticks = False, 0
    with open(log) as handle:
        lines = handle.read().splitlines()
    for i, line in enumerate(lines):
        m = re.match(r"Trace \d+: \S+ \[[0-9a-f]+/([0-9a-f]+)/", line)
        if not m or (i + 1 < len(lines) and lines[i + 1].startswith("cpu_io_recompile")):
            continue
        pc = int(m.group(1), 16)
        if not inside:
            if pc != entry:
                continue
            inside, ticks = True, ticks + 1
        where = name_at(pc)
        if where.startswith("timed_tick"):
            inside = False
            continue
        by[where] += 1
    log.unlink()
    total = sum(by.values())
    return {"ticks": ticks, "instr_per_tick": total / ticks,
            "by_function_per_tick": {k: round(v / ticks, 1) for k, v in by.most_common()}}


# ------------------------------------------------------------------------------------------
# the run
# ------------------------------------------------------------------------------------------

def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=None, help="JSON results file (default benchmarks/results/firmware.json; "
                    "none with --quick)")
    ap.add_argument("--keep", action="store_true", help="keep the build directory")
    ap.add_argument("--modes-only", action="store_true", help="only section 5 (every controller mode)")
    ap.add_argument("--move-to-only", action="store_true", help="only section 6 (MOVE_TO under QEMU)")
    ap.add_argument("--program-only", action="store_true", help="only section 7 (a program on board)")
    ap.add_argument("--feedforward-only", action="store_true",
                    help="only section 8 (the feed-forward torque, iiwa14)")
    ap.add_argument("--collision-only", action="store_true",
                    help="only section 9 (the collision check and criterion on board, Baxter's arm)")
    ap.add_argument("--quick", action="store_true", help="sections 0-4 on a 5-s plan, in seconds (a smoke run)")
    args = ap.parse_args(argv)
    if args.out is None and not args.quick:
        args.out = str(HERE / "results" / "firmware.json")
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    started = time.perf_counter()
    work = Path(tempfile.mkdtemp(prefix="armgen_fwbench_"))
    rep = Report()
    rep.data["meta"] = {
        "python": platform.python_version(), "machine": platform.machine(),
        "gcc": run(["gcc", "--version"]).splitlines()[0] if shutil.which("gcc") else None,
        "arm-none-eabi-gcc": run(["arm-none-eabi-gcc", "--version"]).splitlines()[0]
        if shutil.which("arm-none-eabi-gcc") else None,
        "qemu-system-arm": run(["qemu-system-arm", "--version"]).splitlines()[0] if shutil.which("qemu-system-arm") else None,
        "bars": BARS, "arm_variant": fw.ARM_VARIANT.name,
    }
    print(f"armgen firmware benchmark, build dir {work}")

    state: dict = {}
    if args.feedforward_only:
        rep.section("feedforward", FEEDFORWARD_TITLE, lambda: feedforward_section(rep, work))
        return finish(rep, args, work, started)
    if args.collision_only:
        rep.section("collision", COLLISION_TITLE, lambda: collision_section(rep, work))
        return finish(rep, args, work, started)
    if args.program_only:
        rep.section("program", "7. A program on board, Baxter's arm, Cortex-M4F float (QEMU -icount):",
                    lambda: program_section(rep, work))
        return finish(rep, args, work, started)
    if args.move_to_only:
        rep.section("move_to", "6. MOVE_TO, modular8, Cortex-M4F float (QEMU -icount):",
                    lambda: move_to_table(rep, work, fw.FirmwareBuilder("modular8", work / "fw")))
        return finish(rep, args, work, started)
    if args.modes_only:
        rep.section("modes", "5. Every controller mode, modular8, Cortex-M4F float (QEMU -icount):",
                    lambda: modes_table(rep, work, fw.FirmwareBuilder("modular8", work / "fw")))
        return finish(rep, args, work, started)

    def planning():
        task, sha = load_task(EXAMPLE)
        if args.quick:
            apply_overrides(task, list(QUICK_OVERRIDES))
        t0 = time.perf_counter()
        result = run_task(copy.deepcopy(task), EXAMPLE.name, sha, "symbolic")
        state["python_s"] = time.perf_counter() - t0
        state["plan"] = result
        state["task"] = fw.task_from_plan(result, EXAMPLE.name)
        write_plan(result, work / "combined.csv")
        rep.data["plan"] = {"python_symbolic_s": state["python_s"], "ticks": state["task"].n_ticks}
        rep.row(f"Python planner, symbolic backend ({state['task'].n_ticks - 1} steps)", state["python_s"], "s")

    rep.section("plan", "0. The plan (examples/modular8_circle_combined.toml):", planning)
    if "task" not in state:
        return finish(rep, args, work, started)
    plan, task = state["plan"], state["task"]
    builder = fw.FirmwareBuilder("modular8", work / "fw")
    m4 = rep.data.setdefault("cortex_m4f", {})

    def sizes():
        tool("arm-none-eabi-gcc")
        variant = dataclasses.replace(fw.ARM_VARIANT, print_rows=False, extra=("-fcallgraph-info=su",))
        elf = builder.executable(variant, task, "sizes")
        state["elf"] = elf
        obj_dir = builder.object_dir(variant)
        objs = {p.stem: p for p in obj_dir.glob("*.o")}
        ctrl = flash_ram(objs["controller"])
        m4["controller"] = ctrl
        rep.row("controller.o flash (text + rodata)", ctrl["flash"], "bytes",
                f"text {ctrl['text']}, rodata {ctrl['rodata']}; RAM (data + bss) {ctrl['data_bss']}: no globals")
        syms = linked_symbols(elf)
        prefix = builder.prefix
        gen = {f: syms.get(f"{prefix}_{f}", 0) for f in fw.FIRMWARE_FUNCTIONS}
        m4["generated_text"] = gen
        rep.row("generated functions linked (text)", sum(gen.values()), "bytes",
                ", ".join(f"{k} {v}" for k, v in gen.items()))
        other = {k: syms.get(k, 0) for k in ("fw_ptp_eval", "__wrap_sinf", "__wrap_cosf", "fw_task")}
        m4["other"] = other
        rep.row("PTP evaluator fw_ptp_eval (text)", other["fw_ptp_eval"], "bytes")
        rep.row("fast sinf + cosf (text)", other["__wrap_sinf"] + other["__wrap_cosf"], "bytes")
        rep.row("task configuration fw_task (rodata, flash)", other["fw_task"], "bytes",
                f"incl. room for {fw.MAX_SEGMENTS} playback segments x 8 joints")
        img = image_size(elf)
        m4["image"] = img
        rep.row("whole image: text / data / bss", f"{img['text']} / {img['data']} / {img['bss']}", "bytes",
                "incl. runner, CSV printer, startup, newlib libm")
        # a size-optimised build for comparison
        small = fw.Variant("arm", "float", opt="-Os", print_rows=False)
        small_elf = builder.executable(small, task, "sizes_os")
        small_ctrl = flash_ram(builder.object_dir(small) / "controller.o")
        m4["controller_Os"] = small_ctrl
        m4["image_Os"] = image_size(small_elf)
        rep.row("  the same with everything -Os: controller.o flash", small_ctrl["flash"], "bytes",
                f"image text {m4['image_Os']['text']}")
        su = stack_usage(obj_dir)
        m4["stack_usage"] = {k: su[k] for k in sorted(su, key=lambda k: -su[k])}
        keys = ["ctrl_tick", "tick_resolved_rate", "ctrl_init", "init_resolved_rate",
                *(f"{prefix}_{f}" for f in fw.FIRMWARE_FUNCTIONS), "fw_ptp_eval", "__wrap_sinf"]
        rep.row("stack per function (-fstack-usage)", "", "bytes", ", ".join(f"{k} {su.get(k, 0)}" for k in keys))
        total, path, unknown = worst_chain(obj_dir)
        m4["stack_worst_chain"] = {"bytes": total, "path": path, "unknown": unknown}
        rep.row("stack, worst chain from ctrl_tick (static)", total, "bytes",
                " > ".join(path) + (f"; + libm frames ({', '.join(unknown)})" if unknown else ""))

    def qemu_counts():
        tool("qemu-system-arm")
        if "elf" not in state:
            raise Skip("skipped: no Cortex-M4F build")
        run_ = fw.run_qemu(state["elf"])
        state["summary"] = run_.summary
        ipt = fw.instructions_per_tick(run_)
        m4["instructions_per_tick"] = ipt
        m4["stack_peak_bytes"] = int(run_.summary["stack_peak_bytes"])
        m4["sizeof_ctrl"] = int(run_.summary["sizeof_ctrl"])
        rep.row("M4F executed instructions per tick, mean", ipt["mean"], "instr/tick",
                bar_note(ipt["mean"], BARS["m4_instr_per_tick"]) + f" ({int(ipt['ticks'])} ticks, ±{ipt['resolution']:.0f}); "
                f"previous {PREVIOUS['m4_instr_per_tick']} ({ipt['mean'] / PREVIOUS['m4_instr_per_tick']:.2f}x); "
                f"lean-criteria {bar_note(ipt['mean'], BARS['lean_m4_instr_per_tick'])}")
        rep.row("  max / min over the ticks", f"{ipt['max']:.0f} / {ipt['min']:.0f}", "instr/tick",
                bar_note(ipt["max"], BARS["m4_instr_per_tick"]))
        rep.row("  at 168 MHz (1 instr/cycle lower bound)", ipt["mean"] / 168.0, "µs/tick",
                f"{ipt['mean'] / 168e6 / 0.02 * 100:.2f} % of the 20 ms period")
        rep.row("stack peak measured under QEMU (whole firmware)", m4["stack_peak_bytes"], "bytes")
        rep.row("sizeof(ctrl) (the controller object, RAM)", m4["sizeof_ctrl"], "bytes",
                f"sizeof(ctrl_config) {run_.summary['sizeof_config']} (const, flash)")
        if args.quick:
            return
        variants = {
            "newlib sinf/cosf": dataclasses.replace(fw.ARM_VARIANT, print_rows=False, fast_trig=False),
            "all -O2": fw.Variant("arm", "float", opt="-O2", print_rows=False),
            "all -Os": fw.Variant("arm", "float", opt="-Os", print_rows=False),
        }
        m4["variants"] = {}
        for label, v in variants.items():
            r = fw.instructions_per_tick(fw.run_qemu(builder.executable(v, task, "v_" + re.sub(r"\W", "", label))))
            m4["variants"][label] = r
            rep.row(f"  variant: {label}", r["mean"], "instr/tick", f"max {r['max']:.0f}")
        # the split
        split_task = copy.deepcopy(load_task(EXAMPLE)[0])
        apply_overrides(split_task, SPLIT_OVERRIDES)
        split_elf = builder.executable(dataclasses.replace(fw.ARM_VARIANT, print_rows=False),
                                       fw.task_from_dict(split_task, "split"), "split")
        split = trace_split(split_elf, work)
        m4["split"] = split
        rep.row("split (trace of a 5-s plan, every operator on)", split["instr_per_tick"], "instr/tick",
                ", ".join(f"{k} {v:g}" for k, v in list(split["by_function_per_tick"].items())[:9]))

    rep.section("sizes", "1. Cortex-M4F sizes and stack (fw.ARM_VARIANT, float):", sizes)
    rep.section("qemu", "2. Cortex-M4F executed instructions per tick (QEMU -icount shift=0, SysTick):", qemu_counts)

    host = rep.data.setdefault("host", {})

    def host_time():
        tool("gcc")
        for precision in ("double", "float"):
            exe = builder.executable(fw.Variant("host", precision), task, f"time_{precision}")
            repeats = QUICK_HOST_REPEATS if args.quick else HOST_REPEATS
            out = subprocess.run([str(exe), "--quiet", "--time", str(repeats)], capture_output=True, text=True,
                                 check=True).stdout
            s = fw.parse_output(out).summary
            ms = float(s["wall_ns_best"]) / 1e6
            host[precision] = {"ms": ms, "ns_per_tick": float(s["wall_ns_per_tick"]), "ticks": int(s["timed_ticks"])}
            note = (f"{bar_note(ms, BARS['host_plan_ms'])}; Python planner {state['python_s'] / (ms / 1e3):.0f}x slower, "
                    f"paper {PAPER_SECONDS / (ms / 1e3):.0f}x slower")
            rep.row(f"host firmware -O2 {precision}, {task.n_ticks - 1}-tick plan", ms, "ms", note)
            rep.row("  per tick", host[precision]["ns_per_tick"], "ns")

    rep.section("host", "3. The whole plan natively on the host (gcc -O2, best of 20):", host_time)

    replay = rep.data.setdefault("replay", {})

    def replays():
        runs = [("host double, ASan/UBSan", fw.Variant("host", "double", sanitize=True, opt="-O1"), "double"),
                ("host float", fw.Variant("host", "float"), "float")]
        if shutil.which("arm-none-eabi-gcc") and shutil.which("qemu-system-arm"):
            runs.append(("Cortex-M4F float (QEMU)", fw.ARM_VARIANT, "float"))
        for label, v, precision in runs:
            exe = builder.executable(v, task, "replay_" + re.sub(r"\W", "", label))
            r = fw.run_qemu(exe) if v.target == "arm" else fw.run_host(exe)
            cmp = fwcmp.compare_with_plan(plan, r, task, precision, label)
            bq, bt = fwcmp.bounds_for(precision, task.mode)
            replay[label] = {"max_dq_rad": cmp.max_dq, "bound_rad": bq, "max_dtask_m": cmp.max_dtask, "bound_m": bt,
                             "passed": cmp.passed, "end": f"{r.state}/{r.fault}"}
            rep.row(f"{label}: max |Δq|", cmp.max_dq, "rad", f"bound {bq:g}; {'pass' if cmp.passed else 'FAIL'}")
            rep.row(f"{label}: max |Δ task error|", cmp.max_dtask, "m", f"bound {bt:g}; end {r.state}/{r.fault}")

    rep.section("replay", "4. Replay of the plan against the plan CSV:", replays)
    if args.quick:
        return finish(rep, args, work, started)
    rep.section("modes", "5. Every controller mode, modular8, Cortex-M4F float (QEMU -icount):",
                lambda: modes_table(rep, work, builder))
    rep.section("feedforward", FEEDFORWARD_TITLE, lambda: feedforward_section(rep, work))
    rep.section("collision", COLLISION_TITLE, lambda: collision_section(rep, work))
    return finish(rep, args, work, started)


def mode_task(label: str, work: Path):
    name, overrides = MODE_PLANS[label]
    path = REPO / "examples" / f"{name}.toml"
    task, sha = load_task(path)
    apply_overrides(task, list(overrides))
    if task["planner"] == "ptp":
        return fw.task_from_plan(run_task(task, name, sha), name)
    return fw.task_from_dict(task, name)


def modes_table(rep: Report, work: Path, builder) -> None:
    """Section 5: every controller mode on the same Cortex-M4F build."""
    tool("arm-none-eabi-gcc")
    tool("qemu-system-arm")
    modes = rep.data.setdefault("modes", {})
    variant = dataclasses.replace(fw.ARM_VARIANT, print_rows=False, extra=("-fcallgraph-info=su",))
    elf = None
    for label in MODE_PLANS:
        task = mode_task(label, work)
        elf = builder.executable(variant, task, "mode_" + re.sub(r"\W", "", label))
        r = fw.run_qemu(elf)
        ipt = fw.instructions_per_tick(r)
        mode = label.split()[0]
        modes[label] = {"mean": ipt["mean"], "max": ipt["max"], "ticks": ipt["ticks"], "end": f"{r.state}/{r.fault}",
                        "stack_peak_bytes": int(r.summary["stack_peak_bytes"]), "sizeof_ctrl": int(r.summary["sizeof_ctrl"]),
                        "mode": mode}
    obj_dir = builder.object_dir(variant)
    syms = linked_symbols(elf)
    ctrl = flash_ram(obj_dir / "controller.o")
    ptp = syms.get("fw_ptp_eval", 0)
    ref = modes["RESOLVED_RATE"]
    print(f"  {'mode':<28} {'instr/tick mean':>15} {'max':>8} {'max/mean':>8} {'µs@168MHz':>10} {'vs RR':>6} "
          f"{'flash B':>8} {'RAM B':>6} {'stack B static/peak':>20}")
    for label, m in modes.items():
        mode = m["mode"]
        gen = sum(syms.get(f"{builder.prefix}_{f}", 0) for f in MODE_FUNCTIONS[mode]) + (ptp if mode == "PLAYBACK" else 0)
        if mode in MODE_LOOPS:
            gen += sum(size for sym, size in syms.items() if sym.startswith(f"{builder.prefix}_") and sym.endswith("_loop"))
        others = tuple(t for k, t in MODE_TICK.items() if k != mode)
        static, path, _unknown = worst_chain(obj_dir, avoid=others)
        m.update({"flash_bytes": ctrl["flash"] + gen, "controller_flash": ctrl["flash"], "generated_flash": gen,
                  "stack_static_bytes": static, "stack_chain": path, "max_over_mean": m["max"] / m["mean"],
                  "us_per_tick_168MHz": m["max"] / 168.0, "vs_resolved_rate": m["mean"] / ref["mean"]})
        bar = BARS["ft_instr_per_tick_max"] if mode == "FAULT_TOLERANT" else (
            BARS["wgpm_instr_per_tick_max"] if mode == "WEIGHTED_GPM" else None)
        note = f"; bar max <= {bar}: {'meets' if m['max'] <= bar else 'ABOVE'}" if bar else ""
        if label in PREVIOUS:
            note += f"; previous mean {PREVIOUS[label]} ({m['mean'] / PREVIOUS[label]:.2f}x)"
        print(f"  {label:<28} {m['mean']:>15.0f} {m['max']:>8.0f} {m['max_over_mean']:>8.3f} "
              f"{m['us_per_tick_168MHz']:>10.1f} {m['vs_resolved_rate']:>6.2f} {m['flash_bytes']:>8} "
              f"{m['sizeof_ctrl']:>6} {static:>10}/{m['stack_peak_bytes']:<9} {m['end']}{note}", flush=True)
        rep.rows.append((f"mode {label}: instr/tick mean / max", f"{m['mean']:.0f} / {m['max']:.0f}", "instr/tick",
                         f"max/mean {m['max_over_mean']:.3f}; {m['us_per_tick_168MHz']:.1f} µs at 168 MHz{note}"))


MOVE_TO_POSES = 10  # QEMU runs (each ~ a second); tests/test_move_to.py sends 100 on the host
MOVE_TO_SEED = 26
MOVE_TO_SPREAD_RAD = 0.5  # targets: FK of random configurations within this of q0 (reachable)


def move_to_table(rep: Report, work: Path, builder) -> None:
    """Section 6: MOVE_TO's worst tick (the one that solves the IK) and its mean tick, against
    the resolved-rate tick of the same build."""
    import numpy as np

    tool("arm-none-eabi-gcc")
    tool("qemu-system-arm")
    robot = builder.robot
    quiet = dataclasses.replace(fw.ARM_VARIANT, print_rows=False)
    rr = fw.instructions_per_tick(fw.run_qemu(builder.executable(quiet, mode_task("RESOLVED_RATE", work), "mt_rr")))
    q0 = robot.configuration("q0")
    hold = {"planner": "ptp", "robot": robot.name, "method": "3-4", "step": 0.01,
            "waypoints": {"t": [0.0, 1.0], "omega": {j.name: [0.0, 0.0] for j in robot.joints},
                          "theta": {j.name: [float(q), float(q)] for j, q in zip(robot.joints, q0)}}}
    task = fw.task_from_plan(run_task(hold, "hold"), "hold", robot)
    rng = np.random.default_rng(MOVE_TO_SEED)
    qs = np.clip(q0 + rng.uniform(-MOVE_TO_SPREAD_RAD, MOVE_TO_SPREAD_RAD, (MOVE_TO_POSES, robot.n)), robot.qmin,
                 robot.qmax)
    variant = dataclasses.replace(quiet, extra=("-DFW_MOVE_TO=1",))
    worst, means, ends, errors = [], [], [], []
    for k, target in enumerate(robot.fk(qs)):
        values = ", ".join(f"CTRL_LIT({float(v)!r})" for v in target.T.ravel())
        posed = dataclasses.replace(task, header=task.header + f"const ctrl_real fw_move_to_target[16] = {{{values}}};\n")
        r = fw.run_qemu(builder.executable(variant, posed, f"move_to_{k}"))
        ipt = fw.instructions_per_tick(r)
        worst.append(ipt["max"])
        means.append(ipt["mean"])
        ends.append(f"{r.state}/{r.fault}")
    data = rep.data.setdefault("move_to", {})
    data.update({"poses": MOVE_TO_POSES, "worst_tick_max": max(worst), "worst_tick_median": float(np.median(worst)),
                 "mean_tick": float(np.mean(means)), "resolved_rate_mean": rr["mean"], "ends": ends})
    print(f"  {MOVE_TO_POSES} poses: ends {sorted(set(ends))}; worst tick (the IK) max {max(worst):.0f}, median "
          f"{np.median(worst):.0f} instructions ({max(worst) / 168.0:.0f} µs at 168 MHz); mean tick "
          f"{np.mean(means):.0f}; resolved-rate tick mean {rr['mean']:.0f} in the same build "
          f"(worst MOVE_TO tick / RR mean = {max(worst) / rr['mean']:.1f}x)", flush=True)
    rep.rows.append(("MOVE_TO worst tick (IK), max over poses", f"{max(worst):.0f}", "instr",
                     f"{MOVE_TO_POSES} poses; RR tick mean {rr['mean']:.0f}"))


# The reference tick for section 7: a line from the seam's start to its first corner, the same
# method (the cartesian default) and CLIK gain, at the seam's speed (40 mm in 0.5 s).
REFERENCE_LINE = """
planner = "cartesian"
robot = "{robot}"
start = {{ pose = {{ xyz = {xyz}, rpy = {rpy} }}, seed = "q0" }}
[units]
length = "mm"
angle = "deg"
[path]
type = "line"
end = {end}
orientation = "hold"
[timing]
duration = 0.5
law = "trapezoidal"
[integrator]
method = "euler"
step = 0.01
clik_gain = 20
"""


def program_section(rep: Report, work: Path) -> None:
    """Section 7: the seam program's tick against the resolved-rate line tick, same build."""
    import tomllib

    sys.path.insert(0, str(REPO / "tests"))
    from test_programs import BAR_MOVES, BAR_START, BAXTER, bar_task

    tool("arm-none-eabi-gcc")
    tool("qemu-system-arm")
    builder = fw.FirmwareBuilder(str(BAXTER), work / "baxter")
    quiet = dataclasses.replace(fw.ARM_VARIANT, print_rows=False)
    xyz, rpy = BAR_START
    tasks = {"program (seam)": bar_task("cartesian"),
             "line (reference)": REFERENCE_LINE.format(robot=BAXTER, xyz=xyz, rpy=rpy, end=BAR_MOVES[0][1])}
    data = rep.data.setdefault("program", {})
    for label, text in tasks.items():
        path = work / (re.sub(r"\W", "", label) + ".toml")
        path.write_text(text)
        plan = run_task(tomllib.loads(text), str(path))
        task = fw.task_from_plan(plan, str(path), builder.robot)
        name = re.sub(r"\W", "", label)
        ipt = fw.instructions_per_tick(fw.run_qemu(builder.executable(quiet, task, name)))
        run = fw.run_qemu(builder.executable(fw.ARM_VARIANT, task, name + "_rows"))
        cmp = fwcmp.compare_with_plan(plan, run, task, "float", label)
        host = fw.run_host(builder.executable(fw.Variant("host", "double"), task, name + "_host"))
        host_dq = fwcmp.compare_with_plan(plan, host, task, "double", label).max_dq
        data[label] = {"mean": ipt["mean"], "max": ipt["max"], "ticks": ipt["ticks"], "max_dq_rad": cmp.max_dq,
                       "host_double_max_dq_rad": host_dq,
                       "end": f"{run.state}/{run.fault}", "sizeof_ctrl": int(run.summary["sizeof_ctrl"])}
    prog, line = data["program (seam)"], data["line (reference)"]
    ratio_mean, ratio_max = prog["mean"] / line["mean"], prog["max"] / line["max"]
    syms = linked_symbols(builder.work / f"{quiet.name}_programseam" / "fw_m4.elf")
    table = sum(size for sym, size in syms.items() if sym.startswith("fw_program_table"))
    evaluator = flash_ram(builder.object_dir(quiet) / "fw_program.o")["flash"]
    data.update({"ratio_mean": ratio_mean, "ratio_max": ratio_max, "table_flash_bytes": table,
                 "fw_program_flash_bytes": evaluator})
    for label, m in data.items():
        if isinstance(m, dict):
            print(f"  {label:<18} instr/tick mean {m['mean']:>7.0f}  max {m['max']:>7.0f}  ({m['ticks']} ticks, "
                  f"{m['end']}); max |dq| vs plan: QEMU float {m['max_dq_rad']:.2e}, host double "
                  f"{m['host_double_max_dq_rad']:.2e} rad; sizeof(ctrl) {m['sizeof_ctrl']} B")
    print(f"  program / line: mean {ratio_mean:.3f}x, max {ratio_max:.3f}x (goal <= 1.2x); program table "
          f"{table} B flash, fw_program.o {evaluator} B", flush=True)
    rep.rows.append(("program tick / resolved-rate tick (mean, max)", f"{ratio_mean:.3f} / {ratio_max:.3f}", "x",
                     f"goal <= 1.2; table {table} B, evaluator {evaluator} B"))


FEEDFORWARD_TITLE = "8. The feed-forward torque, iiwa14, Cortex-M4F float (QEMU -icount) and host:"
FEEDFORWARD_CHOICES = ("none", "gravity", "inverse_dynamics")
# The robot file's inertial fields: without them the same arm has no dynamics (the baseline).
INERTIAL_FIELD = re.compile(r"^(mass|com|inertia|motor_inertia) *=.*\n", re.M)


def feedforward_tasks(robot, robot_ref: str) -> dict:
    """Section 8's tasks: a 5 cm line of the tool in 1 s (resolved rate), and a ptp swing of a1,
    a2, a4 by 1, 0.4, 0.5 rad in 1.5 s (playback), both from q0 at a 10 ms tick."""
    q0 = robot.configuration("q0")
    end = robot.fk(q0)[:3, 3] + [0.05, 0.0, 0.0]
    line = {"planner": "cartesian", "robot": robot_ref, "start": "q0",
            "path": {"type": "line", "end": end.tolist(), "orientation": "hold"},
            "timing": {"duration": 1.0, "law": "cubic"}, "integrator": {"method": "euler", "step": 0.01},
            "method": {"name": "pinv"}}
    swing = {"a1": 1.0, "a2": 0.4, "a4": 0.5}
    ptp = {"planner": "ptp", "robot": robot_ref, "method": "quintic", "step": 0.01,
           "waypoints": {"t": [0.0, 1.5], "omega": {j.name: [0.0, 0.0] for j in robot.joints},
                         "theta": {j.name: [float(q), float(q + swing.get(j.name, 0.0))]
                                   for j, q in zip(robot.joints, q0)}}}
    return {"resolved-rate line": line, "ptp swing (playback)": ptp}


def feedforward_section(rep: Report, work: Path) -> None:
    """Section 8: what the feed-forward torque adds to a tick, per choice, against the arm
    without dynamics."""
    from armgen.firmware.configuration import with_feedforward
    from armgen.robot import BUNDLED_DIR, load_robot

    tool("arm-none-eabi-gcc")
    tool("qemu-system-arm")
    quiet = dataclasses.replace(fw.ARM_VARIANT, print_rows=False)
    host = fw.Variant("host", "double", opt="-O2")
    plain_file = work / "iiwa14_without_inertials.toml"
    plain_file.write_text(INERTIAL_FIELD.sub("", (BUNDLED_DIR / "iiwa14.toml").read_text(encoding="utf-8"))
                          .replace('name = "iiwa14"', 'name = "iiwa14_plain"', 1), encoding="utf-8")
    arms = {"iiwa14": (load_robot("iiwa14"), "iiwa14"), "plain": (load_robot(plain_file), str(plain_file))}
    if not arms["iiwa14"][0].has_dynamics or arms["plain"][0].has_dynamics:
        raise RuntimeError("section 8 needs the bundled iiwa14 with inertials and its copy without")
    data = rep.data.setdefault("feedforward", {})
    for key, (robot, ref) in arms.items():
        builder = fw.FirmwareBuilder(robot, work / f"ff_{key}")
        for label, task_doc in feedforward_tasks(robot, ref).items():
            task = fw.task_from_plan(run_task(copy.deepcopy(task_doc), label), label, robot)
            for choice in (FEEDFORWARD_CHOICES if key == "iiwa14" else ("without dynamics",)):
                ftask = with_feedforward(task, choice) if key == "iiwa14" else task
                name = re.sub(r"\W", "", f"{label}_{choice}")
                elf = builder.executable(quiet, ftask, name)
                run = fw.run_qemu(elf)
                ipt = fw.instructions_per_tick(run)
                wall = fw.run_host(builder.executable(host, ftask, name + "_host"), ["--quiet", "--time", "20"])
                m = {"mean": ipt["mean"], "max": ipt["max"], "end": f"{run.state}/{run.fault}",
                     "image_text": image_size(elf)["text"], "sizeof_ctrl": int(run.summary["sizeof_ctrl"]),
                     "host_ns_per_tick": float(wall.summary["wall_ns_per_tick"])}
                data.setdefault(label, {})[choice] = m
    for label, by_choice in data.items():
        base = by_choice["without dynamics"]
        for choice, m in by_choice.items():
            print(f"  {label:<22} {choice:<17} instr/tick mean {m['mean']:>6.0f} (+{m['mean'] - base['mean']:>5.0f})  "
                  f"max {m['max']:>6.0f}  {m['end']:<10} image text {m['image_text']:>6} B  sizeof(ctrl) "
                  f"{m['sizeof_ctrl']} B  host {m['host_ns_per_tick']:.0f} ns/tick", flush=True)
        added = by_choice["inverse_dynamics"]["mean"] - base["mean"]
        rep.rows.append((f"feed-forward (inverse dynamics), {label}: added instr/tick", f"{added:.0f}", "instr",
                         f"gravity +{by_choice['gravity']['mean'] - base['mean']:.0f}, "
                         f"none +{by_choice['none']['mean'] - base['mean']:.0f}"))


COLLISION_TITLE = "9. The collision check and criterion on board (issue 38), Baxter's arm, Cortex-M4F float (QEMU -icount):"
COLLISION_TASK = REPO / "benchmarks" / "data" / "collision" / "baxter_pillar_seam.toml"
# The robot's obstacle slots per build ([collision_check] max_obstacles): the robot file's
# defaults (12 slots, two of them boxes), four slots of each kind, four slots without a box. The
# generated functions evaluate every slot, active or not, so their cost is the slots', not the
# task's (its column and table fit each).
COLLISION_SLOTS = {"default slots (4 sphere, 4 capsule, 2 box, 2 plane)": None,
                   "4 slots (1 sphere, 1 capsule, 1 box, 1 plane)": "{ sphere = 1, capsule = 1, box = 1, plane = 1 }",
                   "4 slots (2 sphere, 1 capsule, 1 plane)": "{ sphere = 2, capsule = 1, box = 0, plane = 1 }"}
# The check-only task moves the column this far (mm, +x) out of the seam's way: the minimum-norm
# plan then keeps the clearance and runs to its end (the check's cost does not depend on where
# the obstacles are).
COLUMN_AWAY_MM = 1000.0


def collision_tasks(robot_ref: str) -> dict:
    """Section 9's variants of the bar task: without [collision] (nothing checked on board), the
    check alone (gain 0, the column moved away), and the check with the criterion (gain 0.01)."""
    import tomllib

    doc = tomllib.loads(COLLISION_TASK.read_text(encoding="utf-8"))
    doc["robot"] = robot_ref
    plain = copy.deepcopy(doc)
    del plain["obstacles"], plain["collision"]
    check = copy.deepcopy(doc)
    check["collision"]["gain"] = 0.0
    for key in ("a", "b"):
        check["obstacles"][0][key][0] += COLUMN_AWAY_MM
    return {"no [collision]": plain, "check only (gain 0)": check, "check + criterion (gain 0.01)": doc}


def collision_section(rep: Report, work: Path) -> None:
    """Section 9: instructions per tick of the resolved-rate tick without, with the clearance
    check, and with the check and the criterion, per obstacle-slot layout; the image's text; the
    criterion run's replay error (QEMU float, host double) against its plan."""
    tool("arm-none-eabi-gcc")
    tool("qemu-system-arm")
    quiet = dataclasses.replace(fw.ARM_VARIANT, print_rows=False)
    text = (COLLISION_TASK.parent / "baxter_arm_capsules.toml").read_text(encoding="utf-8")
    data = rep.data.setdefault("collision", {})
    for k, (slots_label, slots) in enumerate(COLLISION_SLOTS.items()):
        robot_text = text if slots is None else text.replace(
            "[collision_check]\n", f"[collision_check]\nmax_obstacles = {slots}\n", 1).replace(
            'name = "baxter_arm_capsules"', f'name = "baxter_arm_capsules_s{k}"', 1)
        robot_file = work / f"baxter_slots{k}.toml"
        robot_file.write_text(robot_text, encoding="utf-8")
        builder = None
        for label, doc in collision_tasks(str(robot_file)).items():
            plan = run_task(copy.deepcopy(doc), str(COLLISION_TASK))
            task = fw.task_from_plan(plan, label)
            builder = builder or fw.FirmwareBuilder(task.robot, work / f"collision_{k}")
            name = re.sub(r"\W", "", label)
            elf = builder.executable(quiet, task, name)
            qrun = fw.run_qemu(elf)
            ipt = fw.instructions_per_tick(qrun)
            m = {"mean": ipt["mean"], "max": ipt["max"], "ticks": ipt["ticks"], "end": f"{qrun.state}/{qrun.fault}",
                 "image_text": image_size(elf)["text"], "sizeof_ctrl": int(qrun.summary["sizeof_ctrl"]),
                 "plan_min_clearance_m": plan.metadata["summary"]["collision"]["min_clearance_m"]}
            if task.collision is not None and task.collision.settings.gain > 0:
                run_rows = fw.run_qemu(builder.executable(fw.ARM_VARIANT, task, name + "_rows"))
                host = fw.run_host(builder.executable(fw.Variant("host", "double"), task, name + "_host"))
                m["max_dq_rad"] = fwcmp.compare_with_plan(plan, run_rows, task, "float", label).max_dq
                m["host_double_max_dq_rad"] = fwcmp.compare_with_plan(plan, host, task, "double", label).max_dq
                m["fw_min_clearance_m"] = float(run_rows.column("clearance_m").min())
            data.setdefault(slots_label, {})[label] = m
        by_task = data[slots_label]
        base = by_task["no [collision]"]
        print(f"  {slots_label}:")
        for label, m in by_task.items():
            replay = (f"; replay |dq| QEMU float {m['max_dq_rad']:.1e}, host double {m['host_double_max_dq_rad']:.1e} rad, "
                      f"least distance {m['fw_min_clearance_m'] * 1e3:.1f} mm" if "max_dq_rad" in m else "")
            print(f"    {label:<31} instr/tick mean {m['mean']:>7.0f} (+{m['mean'] - base['mean']:>6.0f})  max "
                  f"{m['max']:>7.0f}  {m['end']:<10} image text {m['image_text']:>6} B{replay}", flush=True)
        check, full = by_task["check only (gain 0)"], by_task["check + criterion (gain 0.01)"]
        rep.rows.append((f"collision on board, {slots_label}: instr/tick", f"{full['mean']:.0f}", "instr",
                         f"without {base['mean']:.0f}, check only {check['mean']:.0f}; criterion alone "
                         f"+{full['mean'] - check['mean']:.0f}"))


if __name__ == "__main__":
    sys.exit(main())
