#!/usr/bin/env python3
"""Kinematics benchmarks of armgen's generated C (issue 2): measurements, not tests.

    python benchmarks/bench_kinematics.py [--robot modular8] [--out benchmarks/results/kinematics.json]

In one run, for ``<robot>_fk_jacobian`` (tool pose T and geometric Jacobian J):

1. x86-64 host, gcc -O2 with the strict flags, double and float: ns/call (clock_gettime,
   best of 5 x 1e6 calls, q cycling through 256 configurations) and instructions/call from
   valgrind callgrind (``--toggle-collect=<fn>``, inclusive of the libm sin/cos/sincos it
   calls; the difference of two runs of 12288 and 2048 calls divided by 10240, which cancels
   one-time costs such as lazy PLT binding and gives whole cycles of the q table).
2. The CasADi C baseline in the same run: CasADi's own CodeGenerator on
   Function('fkj', [q], [T, J_ad]) with T from the same SymbolicModel FK and J_ad by AD,
   linear part ca.jacobian(p, q), angular part from ca.jacobian(vec(R), q) as w^ = dR/dq_i R^T.
3. The symbolic ``fk_jacobian`` casadi.Function called from Python (interpreter), ns/call.
4. Cortex-M4F: arm-none-eabi-gcc -Os, float; text bytes per generated function, undefined
   symbols (__aeabi_d* = soft double), and executed instructions per call under
   ``qemu-system-arm -M mps2-an386 -icount shift=0`` (SysTick on the CPU clock, calibrated in
   the same run), cross-checked by an instruction trace (``-singlestep -d exec,nochain``).
5. Generation time of ``generate_robot`` for the robot and for a synthetic 25-DOF chain.

Bars (reported, not asserted) are in BARS. A missing tool skips its rows
("skipped: <tool> not installed") and the run exits 4; a measurement that fails is reported
FAILED and the run exits 1 (EXIT_CODES). Run time is well under a minute on 2 cores; ``--quick``
runs every measurement with small counts in seconds (a smoke run: its figures are not the ones
to quote).
"""

from __future__ import annotations

import argparse
import bisect
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
if str(REPO) not in sys.path:  # run from a checkout without `pip install -e .`
    sys.path.insert(0, str(REPO))

from armgen.codegen.generate import generate_robot  # noqa: E402
from armgen.codegen.toolchain import ARM_CPU_FLAGS, STRICT_FLAGS  # noqa: E402
from armgen.robot import load_robot  # noqa: E402
from armgen.symbolic.model import SymbolicModel  # noqa: E402

DRIVER = HERE / "c" / "bench_fk_jacobian.c"
ARM_DRIVER = HERE / "c" / "bench_fk_jacobian_arm.c"
FIRMWARE = REPO / "firmware_stub" / "arm"

# Targets of issue 2 (for modular8); reported against, never asserted.
BARS = {
    "x86_float_instr": 900,     # FK+J x86 -O2 float, instructions/call
    "x86_double_instr": 1400,   # FK+J x86 -O2 double, instructions/call
    "casadi_double_instr_ref": 1850,  # the estimate for CasADi C double with jacobian()
    "m4_instr": 1500,           # Cortex-M4F -Os executed instructions/call
    "m4_text_bytes": 3072,      # Cortex-M4F -Os text of fk_jacobian
    "gen_seconds": 10.0,        # generate_robot, all functions
}

HOST_OPT = "-O2"
TIME_CALLS = 1_000_000
TIME_REPEATS = 5
CG_CALLS = (2048, 12288)  # multiples of the driver's 256-entry q table
ARM_OPT = "-Os"
ARM_NCALLS = 4096  # multiple of the firmware's 64-entry q table
ARM_TRACE_NCALLS = 64
QEMU_BASE = ("-M", "mps2-an386", "-nographic", "-semihosting-config", "enable=on,target=native",
             "-icount", "shift=0")
CHAIN25_FUNCTIONS = ("fk", "jacobian", "fk_jacobian")
# --quick: every measurement runs, with counts a few hundred times smaller (seconds, not minutes)
QUICK_COUNTS = {"TIME_CALLS": 10_000, "TIME_REPEATS": 1, "CG_CALLS": (256, 512), "ARM_NCALLS": 256}
# The exit status of every benchmark script built on Report (benchmarks/README.md).
EXIT_CODES = {"measured": 0, "failed": 1, "tool missing": 4}


class Skip(Exception):
    """A row that cannot be measured here (missing tool); the message is printed as is."""


def use_quick_counts() -> None:
    """--quick: the timing loops of this module (also used by bench_criteria.py) run QUICK_COUNTS."""
    globals().update(QUICK_COUNTS)


def tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise Skip(f"skipped: {name} not installed")
    return path


def run(cmd, what: str, timeout: float = 300, cwd=None, stderr_too: bool = False) -> str:
    try:
        proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout, cwd=cwd)
    except subprocess.TimeoutExpired:
        raise RuntimeError(f"{what}: timed out after {timeout:.0f} s") from None
    if proc.returncode != 0:
        raise RuntimeError(f"{what} failed (exit {proc.returncode}):\n$ {' '.join(map(str, cmd))}\n"
                           f"{proc.stdout[-4000:]}{proc.stderr[-4000:]}")
    return proc.stdout + proc.stderr if stderr_too else proc.stdout  # QEMU's semihosting console is stderr


def version_of(cmd: list[str]) -> str | None:
    if shutil.which(cmd[0]) is None:
        return None
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    text = (out.stdout or out.stderr).strip().splitlines()
    return text[0] if text else None


def q_table(n: int) -> np.ndarray:
    """The host driver's 256 configurations (same LCG), for the Python timings."""
    state, out = 12345, np.empty((256, n))
    for i in range(256):
        for k in range(n):
            state = (state * 1103515245 + 12345) & 0x7FFFFFFF
            out[i, k] = 4.0 * (state / 2147483648.0) - 2.0
    return out


# ---------------------------------------------------------------------------------------------
# host (x86) measurements
# ---------------------------------------------------------------------------------------------

def build_host_driver(work: Path, name: str, sources: list[Path], header: str, fn: str, real: str, ndof: str,
                      defines: list[str], include: Path, relaxed: list[Path] = ()) -> Path:
    """Driver and generated code as separate translation units (no LTO): the call is real."""
    cc = tool("gcc")
    objs = []
    common = ["-I", include, *[f"-D{d}" for d in defines]]
    for src in sources:
        obj = work / f"{name}_{src.stem}.o"
        run([cc, *STRICT_FLAGS, HOST_OPT, *common, "-c", src, "-o", obj], f"compiling {src.name}")
        objs.append(obj)
    for src in relaxed:  # third-party generated code (CasADi): its own style, no -Werror
        obj = work / f"{name}_{src.stem}.o"
        run([cc, "-std=c99", HOST_OPT, *common, "-c", src, "-o", obj], f"compiling {src.name}")
        objs.append(obj)
    drv = work / f"{name}_driver.o"
    run([cc, *STRICT_FLAGS, HOST_OPT, *common, f"-DBENCH_HEADER=\"{header}\"", f"-DBENCH_FN={fn}",
         f"-DBENCH_REAL={real}", f"-DBENCH_NDOF={ndof}", "-c", DRIVER, "-o", drv], "compiling the driver")
    exe = work / name
    run([cc, drv, *objs, "-o", exe, "-lm"], f"linking {name}")
    return exe


def time_ns(exe: Path) -> float:
    out = run([exe, "time", TIME_CALLS, TIME_REPEATS], f"timing {exe.name}", timeout=120)
    return float(re.search(r"ns_per_call ([0-9.eE+-]+)", out).group(1))


def callgrind_instr(exe: Path, fn: str, work: Path) -> dict:
    vg = tool("valgrind")
    totals = []
    top: dict[str, int] = {}
    for n in CG_CALLS:
        out_file = work / f"callgrind.{exe.name}.{n}"
        run([vg, "--tool=callgrind", f"--callgrind-out-file={out_file}", "--collect-atstart=no",
             f"--toggle-collect={fn}", exe, "count", n], f"callgrind {exe.name}", timeout=300)
        text = out_file.read_text()
        totals.append(int(re.search(r"^totals:\s+(\d+)", text, re.M).group(1)))
        if n == CG_CALLS[-1] and shutil.which("callgrind_annotate"):
            top = self_cost_by_function(out_file)
    per_call = (totals[1] - totals[0]) / (CG_CALLS[1] - CG_CALLS[0])
    # self cost (exclusive) per call of each function inside the toggled region
    split = {k: round(v / CG_CALLS[-1], 1) for k, v in top.items()}
    return {"instr_per_call": per_call, "method": f"callgrind --toggle-collect={fn} (inclusive), "
            f"(Ir[{CG_CALLS[1]} calls] - Ir[{CG_CALLS[0]} calls]) / {CG_CALLS[1] - CG_CALLS[0]}",
            "self_instr_per_call_by_function": split}


def self_cost_by_function(out_file: Path) -> dict[str, int]:
    out = run(["callgrind_annotate", "--inclusive=no", "--threshold=100", out_file], "callgrind_annotate")
    costs: dict[str, int] = {}
    for line in out.splitlines():
        m = re.match(r"\s*([\d,]+)\s+\([^)]*\)\s+(\S.*)$", line)
        if not m or "PROGRAM TOTALS" in line:
            continue
        func = m.group(2).split(":")[-1].split(" [")[0].strip()
        costs[func] = costs.get(func, 0) + int(m.group(1).replace(",", ""))
    return costs


def check_outputs(exe: Path, ref: ca.Function, q: np.ndarray) -> float:
    """Max abs difference of the C function's T and J against the symbolic function."""
    out = run([exe, "check", *[repr(float(x)) for x in q]], f"checking {exe.name}")
    got = np.array([float(v) for v in out.split()])
    T, J = ref(q)
    want = np.concatenate([np.array(T).ravel(order="F"), np.array(J).ravel(order="F")])
    return float(np.max(np.abs(got - want)))


def casadi_baseline_function(model: SymbolicModel) -> ca.Function:
    """T from the armgen FK; J by CasADi AD: Jv = dp/dq, w_i from (dR/dq_i) R^T (skew part)."""
    q, T = model.q, model.tool
    p, R = T[:3, 3], T[:3, :3]
    jv = ca.jacobian(p, q)
    dR = ca.jacobian(ca.vec(R), q)
    cols = []
    for i in range(model.n):
        W = ca.mtimes(ca.reshape(dR[:, i], 3, 3), R.T)
        cols.append(ca.vertcat(W[2, 1], W[0, 2], W[1, 0]))
    J = ca.vertcat(jv, ca.horzcat(*cols))
    return ca.Function("fkj", [q], [ca.densify(T), ca.densify(J)], ["q"], ["T", "J"])


def build_casadi_baseline(work: Path, model: SymbolicModel) -> tuple[Path, ca.Function]:
    f = casadi_baseline_function(model)
    cg_dir = work / "casadi"
    cg_dir.mkdir()
    gen = ca.CodeGenerator("fkj_casadi.c", {"with_header": True})
    gen.add(f)
    gen.generate(str(cg_dir) + os.sep)
    (cg_dir / "fkj_adapter.h").write_text(
        "#ifndef FKJ_ADAPTER_H\n#define FKJ_ADAPTER_H\n"
        "void casadi_fkj_call(const double *q, double *T, double *J);\n#endif\n")
    (cg_dir / "fkj_adapter.c").write_text(f"""#include "fkj_adapter.h"
#include "fkj_casadi.h"
/* Calls CasADi's generated fkj(arg, res, iw, w, mem) with static work arrays. */
void casadi_fkj_call(const double *q, double *T, double *J) {{
  static casadi_real w[{max(f.sz_w(), 1)}];
  static casadi_int iw[{max(f.sz_iw(), 1)}];
  const casadi_real *arg[{max(f.sz_arg(), 1)}];
  casadi_real *res[{max(f.sz_res(), 2)}];
  arg[0] = q;
  res[0] = T;
  res[1] = J;
  (void)fkj(arg, res, iw, w, 0);
}}
""")
    exe = build_host_driver(work, "bench_casadi", [cg_dir / "fkj_adapter.c"], "fkj_adapter.h", "casadi_fkj_call",
                            "double", str(model.n), [], cg_dir, relaxed=[cg_dir / "fkj_casadi.c"])
    return exe, f


def python_call_ns(f: ca.Function, qs: np.ndarray, min_seconds: float = 0.5) -> float:
    for i in range(20):  # warm-up
        f(qs[i % len(qs)])
    calls, t0 = 0, time.perf_counter()
    while True:
        for i in range(256):
            f(qs[i])
        calls += 256
        elapsed = time.perf_counter() - t0
        if elapsed >= min_seconds:
            return elapsed / calls * 1e9


def sx_op_counts(f: ca.Function) -> dict[str, int]:
    names = {getattr(ca, k): k[3:].lower() for k in dir(ca) if k.startswith("OP_")}
    counts: dict[str, int] = {}
    for k in range(f.n_instructions()):
        op = names.get(f.instruction_id(k), str(f.instruction_id(k)))
        counts[op] = counts.get(op, 0) + 1
    return dict(sorted(counts.items()))


# ---------------------------------------------------------------------------------------------
# Cortex-M4F
# ---------------------------------------------------------------------------------------------

def arm_flags(prefix: str) -> list[str]:
    return [*STRICT_FLAGS, ARM_OPT, *ARM_CPU_FLAGS, "-ffunction-sections", "-fdata-sections",
            f"-D{prefix.upper()}_USE_FLOAT=1"]


def arm_object(work: Path, gen_dir: Path, prefix: str) -> dict:
    gcc, size, nm = tool("arm-none-eabi-gcc"), tool("arm-none-eabi-size"), tool("arm-none-eabi-nm")
    obj = work / f"{prefix}_m4.o"
    run([gcc, *arm_flags(prefix), "-c", gen_dir / f"{prefix}.c", "-o", obj], "arm-none-eabi-gcc")
    sizes: dict[str, int] = {}
    other: dict[str, int] = {}
    for line in run([size, "-A", obj], "arm-none-eabi-size").splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[1].isdigit() and parts[0].startswith("."):
            sec, nbytes = parts[0], int(parts[1])
            if sec.startswith(f".text.{prefix}_"):
                sizes[sec[len(f".text.{prefix}_"):]] = nbytes
            elif nbytes and not sec.startswith((".comment", ".ARM.attributes", ".debug")):
                other[sec] = nbytes
    undefined = sorted({ln.split()[-1] for ln in run([nm, "-u", obj], "arm-none-eabi-nm").splitlines() if ln.strip()})
    return {"object": obj, "text_bytes": sizes, "text_total": sum(sizes.values()), "other_sections": other,
            "undefined": undefined, "aeabi_double": [s for s in undefined if s.startswith("__aeabi_d")]}


def arm_link(work: Path, gen_dir: Path, prefix: str, obj: Path, ncalls: int) -> Path:
    gcc = tool("arm-none-eabi-gcc")
    elf = work / f"bench_m4_{ncalls}.elf"
    run([gcc, *arm_flags(prefix), "-I", gen_dir, "-I", FIRMWARE,
         f"-DBENCH_HEADER=\"{prefix}.h\"", f"-DBENCH_FN={prefix}_fk_jacobian", f"-DBENCH_REAL={prefix}_real",
         f"-DBENCH_NDOF={prefix.upper()}_NDOF", f"-DBENCH_NCALLS={ncalls}",
         "-nostartfiles", "--specs=nano.specs", "-T", FIRMWARE / "mps2_an386.ld",
         "-Wl,--gc-sections", f"-Wl,-Map={elf.with_suffix('.map')}",
         FIRMWARE / "startup.c", FIRMWARE / "semihost.c", ARM_DRIVER, obj, "-lm", "-o", elf], "linking the M4 firmware")
    return elf


def elf_symbols(elf: Path) -> list[tuple[int, int, str]]:
    nm = tool("arm-none-eabi-nm")
    syms = []
    for line in run([nm, "-S", elf], "arm-none-eabi-nm").splitlines():
        p = line.split()
        if len(p) == 4 and p[2] in "tTwW":
            syms.append((int(p[0], 16) & ~1, int(p[1], 16), p[3]))
    return sorted(syms)


def libm_sections(map_file: Path) -> dict[str, dict[str, int]]:
    """Bytes of .text and .rodata the linker kept from libm (sin/cos and what they pull in),
    by the first symbol of each archive member, from the memory-map part of the map file."""
    text = map_file.read_text()
    text = text[text.find("Linker script and memory map"):]
    # a long section name stands alone and its address/size follow on the next line: join them
    text = re.sub(r"^( \.\S+)\n {10,}(0x)", r"\1 \2", text, flags=re.M)
    out: dict[str, dict[str, int]] = {"text": {}, "rodata": {}}
    lines = text.splitlines()
    for i, line in enumerate(lines):
        m = re.match(r"^ \.(text|rodata)\S*\s+0x[0-9a-f]+\s+0x([0-9a-f]+)\s+\S*libm[^/(]*\.a\((\S+)\)", line)
        if not m:
            continue
        sym = re.match(r"^\s+0x[0-9a-f]+\s+(\S+)\s*$", lines[i + 1]) if i + 1 < len(lines) else None
        name = sym.group(1) if sym and m.group(1) == "text" else m.group(3)
        out[m.group(1)][name] = out[m.group(1)].get(name, 0) + int(m.group(2), 16)
    return out


def qemu_counts(elf: Path) -> dict:
    qemu = tool("qemu-system-arm")
    out = run([qemu, *QEMU_BASE, "-kernel", elf], "qemu-system-arm", timeout=120, stderr_too=True)
    kv = {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\w+) (\d+)\s*$", out, re.M)}
    if "done" not in out:
        raise RuntimeError(f"firmware did not finish:\n{out}")
    ipt = kv["calib_insns"] / kv["calib_ticks"]
    n = kv["ncalls"]
    return {
        "insns_per_systick": ipt,
        "ncalls": n,
        "instr_per_call": (kv["ticks_fn"] - kv["ticks_stub"]) * ipt / n + 1,  # + the stub's `bx lr`
        "loop_instr_per_iteration": (kv["ticks_fn"] - kv["ticks_empty"]) * ipt / n,
        "resolution": ipt / n,
        "raw": kv,
    }


def qemu_trace_counts(elf: Path, work: Path, fn: str) -> dict:
    """Count every executed instruction from entering fn until control is back in its caller."""
    qemu = tool("qemu-system-arm")
    log = work / "qemu_exec.log"
    run([qemu, *QEMU_BASE, "-singlestep", "-d", "exec,nochain", "-D", log, "-kernel", elf],
        "qemu-system-arm trace", timeout=120)
    syms = elf_symbols(elf)
    starts = [s[0] for s in syms]

    def name_at(pc: int) -> str:
        i = bisect.bisect_right(starts, pc) - 1
        return syms[i][2] if i >= 0 and pc < syms[i][0] + syms[i][1] else "?"

    fn_start = next(s[0] for s in syms if s[2] == fn)
    lines = log.read_text().splitlines()
    per_call, by_fn = [], {}
    inside, count = False, 0
    for i, line in enumerate(lines):
        m = re.match(r"Trace \d+: \S+ \[[0-9a-f]+/([0-9a-f]+)/", line)
        if not m or (i + 1 < len(lines) and lines[i + 1].startswith("cpu_io_recompile")):
            continue  # a TB QEMU rewound for exact I/O is executed again on the next line
        pc = int(m.group(1), 16)
        if not inside:
            if pc == fn_start:
                inside, count = True, 0
            else:
                continue
        where = name_at(pc)
        if where == "timed_loop":  # back in the caller
            per_call.append(count)
            inside = False
            continue
        count += 1
        by_fn[where] = by_fn.get(where, 0) + 1
    log.unlink()
    if not per_call:
        raise RuntimeError("no calls found in the QEMU trace")
    n = len(per_call)
    return {"calls": n, "instr_per_call": sum(per_call) / n, "min": min(per_call), "max": max(per_call),
            "by_function_per_call": {k: round(v / n, 1) for k, v in sorted(by_fn.items(), key=lambda kv: -kv[1])}}


# ---------------------------------------------------------------------------------------------
# generation
# ---------------------------------------------------------------------------------------------

def chain25_toml() -> str:
    lines = ['name = "chain25"',
             'description = "synthetic 25-DOF chain: prismatic base + 24 revolute joints, alpha +-90 deg, a = 0.104 m"',
             'convention = "standard"', "", "[units]", 'length = "m"', 'angle = "deg"', "",
             "[[joints]]", 'name = "base"', 'type = "prismatic"', "a = 0.0", "d = 0.0", "alpha = 0.0",
             "qlim = [0.0, 1.0]"]
    for i in range(24):
        lines += ["", "[[joints]]", f'name = "r{i + 1}"', 'type = "revolute"', "a = 0.104", "d = 0.0",
                  f"alpha = {90 if i % 2 == 0 else -90}", "qlim = [-170, 170]"]
    return "\n".join(lines) + "\n"


def time_generation(robot, out_dir: Path, functions=None) -> dict:
    t0 = time.perf_counter()
    code, _ = generate_robot(robot, out_dir, functions=functions)
    wall = time.perf_counter() - t0
    return {"seconds": wall, "generate_seconds": code.generation_seconds, "functions": [e.name for e in code.emitted],
            "ops": {e.name: {"flops": e.flops, "op_counts": dict(sorted(e.op_counts.items())),
                             "work_reals": e.work_reals} for e in code.emitted}}


# ---------------------------------------------------------------------------------------------
# the run
# ---------------------------------------------------------------------------------------------

class Report:
    """Rows printed as they come and kept for the JSON; ``only`` names the sections to run.
    What could not be measured is kept too (``missing``: a tool is not installed; ``failed``: a
    build or run failed), so the run's exit status says whether every figure was measured."""

    def __init__(self, only: set[str] | None = None):
        self.rows: list[tuple[str, str, str, str]] = []
        self.data: dict = {}
        self.only = only
        self.missing: list[str] = []
        self.failed: list[str] = []

    def not_measured(self, what: str, exc: Skip) -> None:
        """A row inside a section that a missing tool skipped (the section goes on)."""
        self.row(what, str(exc))
        self.missing.append(f"{what}: {exc}")

    def row(self, what: str, value, unit: str = "", note: str = "") -> None:
        value = f"{value:.4g}" if isinstance(value, float) else str(value)
        self.rows.append((what, value, unit, note))
        print(f"  {what:<46} {value:>12} {unit:<11} {note}", flush=True)

    def section(self, key: str, title: str, func) -> None:
        if self.only is not None and key not in self.only:
            return
        print(f"\n{title}", flush=True)
        label = re.sub(r"^\d+\.\s*", "", title).split(",")[0].split(":")[0]
        started = time.perf_counter()
        try:
            func()
        except Skip as exc:
            self.row(label, str(exc))
            self.data.setdefault(key, {})["skipped"] = str(exc)
            self.missing.append(f"{label}: {exc}")
        except Exception as exc:  # a benchmark reports, it does not stop at the first failure
            self.row(label, "FAILED", "", str(exc).splitlines()[0][:120])
            self.data.setdefault(key, {})["error"] = str(exc)
            self.failed.append(f"{label}: {exc}")
        print(f"  ({time.perf_counter() - started:.1f} s)", flush=True)


def bar_note(value: float, bar: float, le: bool = True) -> str:
    ok = value <= bar if le else value < bar
    return f"bar {'<=' if le else '<'} {bar:g}: {'meets' if ok else 'ABOVE'}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="modular8", help="bundled robot name or robot file (default modular8)")
    ap.add_argument("--out", default=None, help="JSON results file (default benchmarks/results/kinematics.json; "
                    "none with --quick)")
    ap.add_argument("--keep", action="store_true", help="keep the build directory and print its path")
    ap.add_argument("--quick", action="store_true", help="every measurement with small counts, in seconds (a smoke run)")
    args = ap.parse_args(argv)
    if args.quick:
        use_quick_counts()
    elif args.out is None:
        args.out = str(HERE / "results" / "kinematics.json")

    started = time.perf_counter()
    rep = Report()
    work = Path(tempfile.mkdtemp(prefix="armgen_bench_"))
    robot = load_robot(args.robot)
    model = SymbolicModel(robot)
    sym_fkj = model.function("fk_jacobian")
    gen_dir = work / "gen"
    state: dict = {}
    rep.data["meta"] = {
        "robot": robot.name, "dof": robot.n, "python": platform.python_version(), "casadi": ca.__version__,
        "machine": platform.machine(), "cpu": _cpu_model(), "libc": " ".join(platform.libc_ver()),
        "gcc": version_of(["gcc", "--version"]), "valgrind": version_of(["valgrind", "--version"]),
        "arm-none-eabi-gcc": version_of(["arm-none-eabi-gcc", "--version"]),
        "qemu-system-arm": version_of(["qemu-system-arm", "--version"]),
        "host_flags": [*STRICT_FLAGS, HOST_OPT], "arm_flags": arm_flags(re.sub(r"[^0-9a-zA-Z_]", "_", robot.name).lower()),
        "bars": BARS,
    }
    print(f"armgen kinematics benchmark: robot {robot.name} ({robot.n} DOF), build dir {work}")

    # 5a. generation (also produces the code measured below)
    def gen_robot():
        first = time_generation(robot, gen_dir)
        again = [time_generation(robot, work / f"gen_again{i}")["seconds"] for i in range(2)]
        state["prefix"] = re.sub(r"[^0-9a-zA-Z_]", "_", robot.name).lower()
        rep.data["generation"] = {"robot": first, "repeat_seconds": again}
        rep.row(f"generate_robot {robot.name} ({len(first['functions'])} functions)", f"{first['seconds']:.3f}", "s",
                bar_note(first["seconds"], BARS["gen_seconds"], le=False) + f" (repeats {', '.join(f'{s:.3f}' for s in again)} s)")
        fkj = first["ops"].get("fk_jacobian")
        if fkj:
            rep.row("  fk_jacobian flops (generated)", str(fkj["flops"]), "ops", _ops_text(fkj["op_counts"]))

    rep.section("generation", "Generation:", gen_robot)
    if "prefix" not in state:
        print("code generation failed; nothing else to measure")
        return finish(rep, args, work, started)
    prefix = state["prefix"]
    P = prefix.upper()
    q_check = q_table(robot.n)[3]

    # 1. x86 native
    host = rep.data.setdefault("x86", {})

    def x86():
        tool("gcc")
        for precision, flag in (("double", "0"), ("float", "1")):
            exe = build_host_driver(work, f"bench_{precision}", [gen_dir / f"{prefix}.c"], f"{prefix}.h",
                                    f"{prefix}_fk_jacobian", f"{prefix}_real", f"{P}_NDOF",
                                    [f"{P}_USE_FLOAT={flag}"], gen_dir)
            err = check_outputs(exe, sym_fkj, q_check)
            entry = host.setdefault(precision, {})
            entry["max_abs_err_vs_symbolic"] = err
            entry["ns_per_call"] = time_ns(exe)
            rep.row(f"x86 {HOST_OPT} {precision} fk_jacobian time", f"{entry['ns_per_call']:.1f}", "ns/call",
                    f"max |err| vs symbolic {err:.1e}")
            state[f"exe_{precision}"] = exe
        for precision in ("double", "float"):
            try:
                cg = callgrind_instr(state[f"exe_{precision}"], f"{prefix}_fk_jacobian", work)
            except Skip as exc:
                rep.not_measured(f"x86 {HOST_OPT} {precision} fk_jacobian instructions", exc)
                host[precision]["instr_skipped"] = str(exc)
                continue
            host[precision].update(cg)
            rep.row(f"x86 {HOST_OPT} {precision} fk_jacobian instructions", f"{cg['instr_per_call']:.1f}", "instr/call",
                    bar_note(cg["instr_per_call"], BARS[f"x86_{precision}_instr"]))
            rep.row("  split (self instr/call)", "", "", _split_text(cg["self_instr_per_call_by_function"]))

    rep.section("x86", f"1. x86-64 native, gcc {HOST_OPT} strict flags:", x86)

    # 2. CasADi C baseline
    base = rep.data.setdefault("casadi_c_baseline", {})

    def baseline():
        tool("gcc")
        exe, f = build_casadi_baseline(work, model)
        base["description"] = ("CasADi CodeGenerator, Function('fkj',[q],[T, [jacobian(p,q); w from "
                               "jacobian(vec(R),q) R^T]]), casadi_real=double, gcc -std=c99 " + HOST_OPT)
        base["sx_ops"] = sx_op_counts(f)
        base["max_abs_err_vs_symbolic"] = check_outputs(exe, sym_fkj, q_check)
        base["ns_per_call"] = time_ns(exe)
        flops = sum(v for k, v in base["sx_ops"].items() if k not in ("input", "output", "const", "assign"))
        rep.row("CasADi C double (jacobian()) time", f"{base['ns_per_call']:.1f}", "ns/call",
                f"{flops} SX ops; max |err| vs symbolic {base['max_abs_err_vs_symbolic']:.1e}")
        try:
            cg = callgrind_instr(exe, "fkj", work)
        except Skip as exc:
            cg = {}
            base["instr_skipped"] = str(exc)
            rep.not_measured("CasADi C double (jacobian()) instructions", exc)
        else:
            base.update(cg)
            rep.row("CasADi C double (jacobian()) instructions", f"{cg['instr_per_call']:.1f}", "instr/call",
                    f"issue's estimate ~{BARS['casadi_double_instr_ref']}")
            rep.row("  split (self instr/call)", "", "", _split_text(cg["self_instr_per_call_by_function"]))
        for precision in ("double", "float"):
            ours = host.get(precision, {})
            ratios = {}
            if "instr_per_call" in ours and cg:
                ratios["instr"] = ours["instr_per_call"] / cg["instr_per_call"]
            if "ns_per_call" in ours:
                ratios["time"] = ours["ns_per_call"] / base["ns_per_call"]
            base.setdefault("ratios_ours_over_casadi", {})[precision] = ratios
            if ratios:
                rep.row(f"  ours {precision} / CasADi C double", " ".join(f"{v:.2f}x" for v in ratios.values()),
                        " / ".join(ratios), "lower is better")

    rep.section("casadi_c_baseline", "2. Baseline: CasADi C code generator, double, AD jacobian():", baseline)

    # 3. CasADi Python call
    def python_call():
        ns = python_call_ns(sym_fkj, q_table(robot.n))
        entry = rep.data["casadi_python"] = {"ns_per_call": ns, "call": "model.function('fk_jacobian')(numpy q)"}
        note = ""
        if "ns_per_call" in host.get("double", {}):
            entry["ratio_over_ours_double"] = ns / host["double"]["ns_per_call"]
            note = f"{entry['ratio_over_ours_double']:.0f}x our C double"
        rep.row("CasADi Python call of symbolic fk_jacobian", f"{ns:.0f}", "ns/call", note)

    rep.section("casadi_python", "3. CasADi Function called from Python:", python_call)

    # 4. Cortex-M4F
    m4 = rep.data.setdefault("cortex_m4f", {})

    def cortex_m4():
        info = arm_object(work, gen_dir, prefix)
        obj = info.pop("object")
        m4.update(info)
        text = info["text_bytes"]
        rep.row(f"M4F {ARM_OPT} float text fk_jacobian", str(text.get("fk_jacobian")), "bytes",
                bar_note(text.get("fk_jacobian", 0), BARS["m4_text_bytes"]))
        for name, nbytes in text.items():
            if name != "fk_jacobian":
                rep.row(f"  text {name}", str(nbytes), "bytes")
        rep.row("  text all generated functions", str(info["text_total"]), "bytes")
        rep.row("  undefined symbols of the object", str(len(info["undefined"])), "", " ".join(info["undefined"]))
        rep.row("  __aeabi_d* (soft double) in the object", str(len(info["aeabi_double"])), "",
                " ".join(info["aeabi_double"]) or "none")
        elf = arm_link(work, gen_dir, prefix, obj, ARM_NCALLS)
        image_syms = {s[2] for s in elf_symbols(elf)}
        image_d = sorted(s for s in image_syms if s.startswith("__aeabi_d"))
        m4["aeabi_double_in_image"] = image_d
        lm = libm_sections(elf.with_suffix(".map"))
        m4["libm_linked_bytes"] = lm
        rep.row("  libm text linked (sinf/cosf + deps)", str(sum(lm["text"].values())), "bytes",
                " ".join(f"{k}:{v}" for k, v in lm["text"].items()))
        rep.row("  libm rodata linked", str(sum(lm["rodata"].values())), "bytes",
                " ".join(f"{k}:{v}" for k, v in lm["rodata"].items()))
        rep.row("  __aeabi_d* in the linked image", str(len(image_d)), "", " ".join(image_d) or "none")
        try:
            counts = qemu_counts(elf)
        except Skip as exc:
            rep.not_measured("M4F executed instructions (QEMU)", exc)
            m4["qemu_skipped"] = str(exc)
            return
        m4["qemu_icount_systick"] = counts
        rep.row(f"M4F {ARM_OPT} float fk_jacobian executed instr", f"{counts['instr_per_call']:.1f}", "instr/call",
                bar_note(counts["instr_per_call"], BARS["m4_instr"]) +
                f" (QEMU -icount shift=0, SysTick; +-{counts['resolution']:.2f})")
        rep.row("  loop iteration incl. call and q indexing", f"{counts['loop_instr_per_iteration']:.1f}", "instr/iter")
        trace = qemu_trace_counts(arm_link(work, gen_dir, prefix, obj, ARM_TRACE_NCALLS), work, f"{prefix}_fk_jacobian")
        m4["qemu_exec_trace"] = trace
        rep.row("  cross-check: -singlestep -d exec trace", f"{trace['instr_per_call']:.2f}", "instr/call",
                f"{trace['calls']} calls, min {trace['min']} max {trace['max']}")
        rep.row("  split (instr/call)", "", "", _split_text(trace["by_function_per_call"]))

    rep.section("cortex_m4f", f"4. Cortex-M4F, arm-none-eabi-gcc {ARM_OPT} float:", cortex_m4)

    # 5b. 25-DOF chain
    def chain25():
        path = work / "chain25.toml"
        path.write_text(chain25_toml())
        r25 = load_robot(path)
        avail = SymbolicModel(r25).available()
        res = time_generation(path, work / "gen_chain25", functions=CHAIN25_FUNCTIONS)
        res["available"] = list(avail)
        rep.data["generation"]["chain25"] = res
        rep.row(f"generate_robot chain25 ({', '.join(CHAIN25_FUNCTIONS)})", f"{res['seconds']:.3f}", "s",
                f"available(): {', '.join(avail)}")
        for name, ops in res["ops"].items():
            rep.row(f"  chain25 {name} flops", str(ops["flops"]), "ops", _ops_text(ops["op_counts"]))

    rep.section("generation", "5. Generation of a synthetic 25-DOF chain:", chain25)
    return finish(rep, args, work, started)


def _ops_text(counts: dict) -> str:
    return ", ".join(f"{v} {k}" for k, v in counts.items() if k not in ("input", "output", "const"))


def _split_text(split: dict) -> str:
    items = sorted(((k, v) for k, v in split.items() if v >= 0.5), key=lambda kv: -kv[1])
    return ", ".join(f"{k} {v:g}" for k, v in items[:9])


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def finish(rep: Report, args, work: Path, started: float) -> int:
    """Write the JSON report, print where and what could not be measured, remove the build
    folder (unless --keep); the exit status of EXIT_CODES."""
    rep.data["meta"]["run_seconds"] = time.perf_counter() - started
    rep.data["table"] = [{"what": w, "value": v, "unit": u, "note": n} for w, v, u, n in rep.rows]
    rep.data["not_measured"] = {"failed": rep.failed, "tool missing": rep.missing}
    if args.out:  # a --quick run writes no results file unless asked to: its figures are a smoke run's
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(rep.data, indent=2, default=str) + "\n")
        print(f"\nwrote {out} (run {rep.data['meta']['run_seconds']:.1f} s)")
    else:
        print(f"\nrun {rep.data['meta']['run_seconds']:.1f} s")
    if args.keep:
        print(f"build directory kept: {work}")
    else:
        shutil.rmtree(work, ignore_errors=True)
    for kind, whats in (("FAILED", rep.failed), ("NOT MEASURED (tool missing)", rep.missing)):
        for what in whats:
            print(f"{kind}: {what.splitlines()[0][:200]}")
    if rep.failed:
        return EXIT_CODES["failed"]
    return EXIT_CODES["tool missing"] if rep.missing else EXIT_CODES["measured"]


if __name__ == "__main__":
    sys.exit(main())
