#!/usr/bin/env python3
"""On-board program evaluator benchmark (issue 26): measurements, not tests.

    python benchmarks/bench_program_table.py [--out benchmarks/results/program_table.json]

For the issue's bar program (tests/test_programs.py ``bar_task("cartesian")`` on Baxter: 4 lines,
2 arcs, 8 mm blends, the tool turning) and the bundled poses example
(examples/panda_polish_contour_program.toml: a line, a 182-row contour, a line), each table from
``program_table_c``:

1. Flash: bytes of the table (.rodata of an object holding it, arm-none-eabi-gcc, double and
   float) and of fw_program.o's code (float, -O3), against the time-law cells before merging.
2. Cortex-M4F executed instructions per ``fw_program_desired`` call (float, -O3; sinf/cosf from
   firmware_stub/arm/fw_fastmath.c as the verify build links them, and newlib's), at each tick of
   the plan, under qemu-system-arm -M mps2-an386 -icount shift=0 (SysTick, 40 instructions per
   count, calibrated in the run; benchmarks/c/bench_program_arm.c): mean and max over the ticks,
   per piece kind, net of the timing harness (a stub call timed the same way); and the largest
   difference of the M4's outputs (read back bit-exactly) from the planner's ProgramMotion at
   the same float tick times.

A missing tool skips its rows and the run exits 4; any error is a traceback (exit 1). About ten
seconds; ``--quick`` (a smoke run): the bar program only, with the fast sinf/cosf only.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
for path in (REPO, REPO / "tests"):  # a checkout without `pip install -e .`; the bar task
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

from armgen.codegen.toolchain import ARM_CPU_FLAGS, STRICT_FLAGS  # noqa: E402
from armgen.firmware.program_table import program_table_c  # noqa: E402
from armgen.planning.toolpath.geometry import Trimmed  # noqa: E402
from armgen.planning.tasks import configure_task, load_task  # noqa: E402
from test_programs import EXAMPLES, bar_task  # noqa: E402

STUB = REPO / "armgen" / "data" / "firmware_stub"
ARM = STUB / "arm"
ROBOT_INCLUDE = REPO / "generated" / "modular8"  # ctrl_robot.h's default binding: ctrl_real, precision
DRIVER = HERE / "c" / "bench_program_arm.c"
QEMU = ("qemu-system-arm", "-M", "mps2-an386", "-nographic", "-semihosting-config", "enable=on,target=native",
        "-icount", "shift=0")
OPT = "-O3"  # the controller's optimisation in the verify build
EXIT_TOOL_MISSING = 4  # the project's exit status for a missing tool (0 when every row was measured)


def run(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw)


def arm_flags(use_float: bool, work: Path) -> list[str]:
    return [*STRICT_FLAGS, OPT, *ARM_CPU_FLAGS, "-ffunction-sections", "-fdata-sections", "-I", str(STUB), "-I",
            str(ARM), "-I", str(ROBOT_INCLUDE), "-I", str(work), f"-DMODULAR8_USE_FLOAT={int(use_float)}"]


def rodata_bytes(work: Path, use_float: bool) -> int:
    """Bytes of the table: an object that keeps it (a non-static pointer to it)."""
    src = work / "keep.c"
    src.write_text('#include "fw_program.h"\n#include "table.h"\n'
                   'const fw_program *fw_bench_keep = &fw_program_table;\n')
    obj = work / f"keep_{int(use_float)}.o"
    run(["arm-none-eabi-gcc", *arm_flags(use_float, work), "-c", str(src), "-o", str(obj)])
    sizes = run(["arm-none-eabi-size", "-A", str(obj)]).stdout
    return sum(int(m.group(1)) for m in re.finditer(r"^\.(?:rodata|data\.rel\.ro)\S*\s+(\d+)", sizes, re.M))


def text_bytes(work: Path) -> int:
    obj = work / "fw_program.o"
    run(["arm-none-eabi-gcc", *arm_flags(True, work), "-c", str(STUB / "fw_program.c"), "-o", str(obj)])
    sizes = run(["arm-none-eabi-size", "-A", str(obj)]).stdout
    return sum(int(m.group(1)) for m in re.finditer(r"^\.text\S*\s+(\d+)", sizes, re.M))


def run_m4(work: Path, ticks: int, dt: float, fast_trig: bool) -> tuple[np.ndarray, np.ndarray]:
    """(executed instructions per call net of the harness, the outputs [p, R, xdot] per tick)
    at ticks 0 .. ticks-1 on the Cortex-M4F under QEMU."""
    elf = work / f"bench_{int(fast_trig)}.elf"
    sources = [DRIVER, STUB / "fw_program.c", ARM / "startup.c", ARM / "semihost.c"]
    wrap = []
    if fast_trig:
        sources.append(ARM / "fw_fastmath.c")
        wrap = ["-Wl,--wrap=sinf", "-Wl,--wrap=cosf"]
    run(["arm-none-eabi-gcc", *arm_flags(True, work), f"-DBENCH_TICKS={ticks}u", f"-DBENCH_DT=CTRL_LIT({dt!r})",
         "-nostartfiles", "--specs=nano.specs", "-T", str(ARM / "mps2_an386.ld"), *wrap, "-Wl,--gc-sections",
         *map(str, sources), "-lm", "-o", str(elf)])
    proc = subprocess.run([*QEMU, "-kernel", str(elf)], capture_output=True, text=True, timeout=600)
    text = proc.stdout + proc.stderr  # QEMU's semihosting console is stderr
    kv = dict(re.findall(r"^(\w+) (\d+)$", text, re.M))
    if kv.get("check") != "1":
        raise SystemExit(f"fw_program_check refused the table on the M4:\n{text[-2000:]}")
    per_count = int(kv["calib_insns"]) / int(kv["calib_ticks"])
    timed = sorted((int(k), int(c)) for k, c in re.findall(r"^call (\d+) (\d+)$", text, re.M))
    calls = np.array([c for _, c in timed])
    words = sorted((int(m.group(1)), m.group(2).split()) for m in re.finditer(r"^out (\d+) (.*)$", text, re.M))
    outputs = np.array([[int(w) for w in row] for _, row in words], dtype=np.uint32).view(np.float32)
    stub = int(kv["stub_sum"]) / ticks
    return (calls - stub) * per_count, outputs.astype(float)


def programs() -> dict:
    """The measured programs: the issue's bar program and the bundled poses example (a sampled
    polishing contour on the panda), each as the planner parses it."""
    polish = EXAMPLES / "panda_polish_contour_program.toml"
    task, _ = load_task(polish)
    return {"bar": configure_task(tomllib.loads(bar_task("cartesian")), "bar.toml").config,
            "polish (poses)": configure_task(task, str(polish)).config}


def measure(label: str, task, work: Path, quick: bool = False) -> dict:
    """Flash and instructions per call of one program (``task``: the planner's parsed task);
    what a missing tool kept from being measured is listed under ``not_measured``."""
    motion = task.motion
    table = program_table_c(motion)
    ticks = int(round(task.duration / task.step)) + 1
    s = motion.profile(np.arange(ticks) * task.step)[0]
    pieces = motion.program.pieces
    kind = [type(p.piece if isinstance(p, Trimmed) else p).__name__ for p in pieces]
    tick_kind = np.array([kind[k] for k in motion.program.piece_index(s)])
    macros = {k: int(v) for k, v in re.findall(r"^#define FW_PROGRAM_(\w+) (\d+)", table, re.M)}
    figures: dict = {"pieces": len(pieces), "cells": len(motion.profile.s) - 1, "sizes": macros, "ticks": ticks,
                     "duration_s": motion.duration}
    print(f"{label}: {len(pieces)} pieces, {figures['cells']} time-law cells -> {macros['SEGMENTS']} segments, "
          f"{macros['MAPS']} map rows, {macros['KNOTS']} spline intervals, {ticks} ticks")
    work.mkdir()
    (work / "table.h").write_text(table)
    try:
        flash = {"table_double_bytes": rodata_bytes(work, False), "table_float_bytes": rodata_bytes(work, True),
                 "fw_program_text_bytes": text_bytes(work)}
    except FileNotFoundError:
        print("  NOT MEASURED: arm-none-eabi-gcc not installed, flash and instruction rows skipped")
        figures["not_measured"] = "arm-none-eabi-gcc"
        return figures
    figures["flash"] = flash
    for key, value in flash.items():
        print(f"  flash {key:24s} {value:8d} B")
    # the M4's tick times, k * dt in float, and the planner's motion there
    t32 = (np.arange(ticks, dtype=np.float32) * np.float32(task.step)).astype(float)
    p, rot, xdot = motion(t32)
    reference = np.hstack([p, np.swapaxes(rot, -1, -2).reshape(-1, 9), xdot])
    for fast in (True,) if quick else (True, False):
        trig = "fast sinf/cosf" if fast else "newlib sinf/cosf"
        try:
            insns, outputs = run_m4(work, ticks, task.step, fast)
        except FileNotFoundError:
            print("  NOT MEASURED: qemu-system-arm not installed, instruction rows skipped")
            figures["not_measured"] = "qemu-system-arm"
            break
        rows = {"all": insns} | {k: insns[tick_kind == k] for k in sorted(set(tick_kind))}
        err = np.abs(outputs - reference)
        errors = {g: float(err[:, sl].max()) for g, sl in
                  (("position_m", slice(0, 3)), ("rotation", slice(3, 12)), ("velocity_m_s", slice(12, 15)),
                   ("angular_velocity_rad_s", slice(15, 18)))}
        figures[trig] = {k: {"mean": float(v.mean()), "max": float(v.max()), "calls": int(v.size)}
                         for k, v in rows.items()} | {"max_error_vs_planner": errors}
        print(f"  M4F instructions per fw_program_desired call ({trig}, {OPT}, ±40 per call):")
        for k, v in rows.items():
            print(f"    {k:10s} mean {v.mean():7.0f}  max {v.max():7.0f}  ({v.size} ticks)")
        print("    max |M4 float - planner| at the ticks: " + ", ".join(f"{k} {v:.2e}" for k, v in errors.items()))
    return figures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write the figures as JSON")
    parser.add_argument("--quick", action="store_true", help="the bar program, fast trig only (a smoke run)")
    args = parser.parse_args()
    measured = programs()
    if args.quick:
        measured = {"bar": measured["bar"]}
    with tempfile.TemporaryDirectory() as tmp:
        figures = {label: measure(label, task, Path(tmp) / f"p{k}", args.quick)
                   for k, (label, task) in enumerate(measured.items())}
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(figures, indent=2))
    return EXIT_TOOL_MISSING if any("not_measured" in f for f in figures.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
