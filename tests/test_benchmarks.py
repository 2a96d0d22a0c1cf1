"""The benchmarks of benchmarks/ run: each in its ``--quick`` mode (a smoke run of every
measurement, seconds rather than minutes) exits 0 and prints its figures; one that cannot
measure exits non-zero (benchmarks/README.md: 1 a measurement failed, 4 a tool or peer is
missing), so a benchmark that stopped working is never green.

Robotics Toolbox (the ``bench`` extra, a peer of bench_ik.py) is not installed in CI: the
quick run names it as missing and still exits 0; the other peer, Pinocchio, comes with the
``test`` extra and must give figures.
"""

from __future__ import annotations

import importlib.util
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import require_tool

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
QUICK_TIMEOUT_S = 900  # the slowest quick run takes ~1 min on 2 idle cores; CI's are shared with the tests
ARM_TOOLS = ("arm-none-eabi-gcc", "arm-none-eabi-nm", "qemu-system-arm")
NUMBER = r"[0-9][0-9.e+-]*"
# Per script: the external tools its quick run needs, and lines that carry its figures.
QUICK_RUNS = {
    "bench_api.py": ((), [rf"robot\.fk \+ robot\.jacobian, 2000 configurations\s+{NUMBER} s",
                          rf"speed-up of the batch over per-call CasADi: {NUMBER}x"]),
    "bench_criteria.py": (("gcc", "valgrind", *ARM_TOOLS), [
        rf"^\s+ik\s+-\s+\d+\s+nan\s+-\s+\d+\s+\d+",  # the M4 row of the function whose driver did not link
        rf"^\s+fk_jacobian\s+-\s+\d+\s+nan\s+-\s+\d+\s+\d+\s+nan\s+bar <= 1000",
        rf"x86 -O2 float CasADi C of the same fk_jacobian\s+{NUMBER} instr/call",
        rf"snake12 generation, all functions\s+{NUMBER} s",
        rf"^\s+step_wgpm(\s+\d+){{3}}\s+{NUMBER}$"]),
    "bench_collision.py": (("gcc", *ARM_TOOLS), [
        r"^\s+collision_criterion\s+\d+\s+\d+\s+\d+\s+\d+\s+bar <= 10000: (meets|ABOVE)$",
        rf"coal\.distance from Python, the same \d+ pairs: {NUMBER} ns per configuration \({NUMBER} ns per query\); "
        rf"coal / C double distances {NUMBER}x"]),
    "bench_dynamics.py": (("gcc", *ARM_TOOLS), [
        rf"foreign URDFs with inertials\s+1\d\s+bar >= 10: meets",
        rf"double vs Pinocchio, max relative error\s+{NUMBER}",
        rf"^\s+gravity\s+\d+\s+\d+\s+\d+\s+\d+\s+bar <= 2500",
        rf"^\s+rnea\s+{NUMBER}\s+{NUMBER}\s+{NUMBER}\s+{NUMBER}x\s+-?{NUMBER}\s+-?{NUMBER}x\s+{NUMBER}$"]),
    "bench_firmware.py": (("gcc", *ARM_TOOLS), [
        r"M4F executed instructions per tick, mean\s+\d+ instr/tick",
        rf"controller\.o flash \(text \+ rodata\)\s+\d+ bytes",
        rf"host firmware -O2 double, \d+-tick plan\s+{NUMBER} ms",
        rf"Cortex-M4F float \(QEMU\): max \|Δq\|\s+{NUMBER} rad\s+bound {NUMBER}; pass"]),
    "bench_ik.py": (("gcc", *ARM_TOOLS), [
        rf"\| armgen C host -O2 double \| 30 \| {NUMBER} % \| {NUMBER} µs",
        rf"\| armgen C Cortex-M4F float -O2, bounded trig \(QEMU\), max_iterations \d+ \| 30 \| {NUMBER} % "
        r"\| \d+ instr",
        r"\| Robotics Toolbox ikine_LM \| "
        r"(30 \| [0-9.]+ %|— \| — \| — \| — \| MISSING: roboticstoolbox-python)",
        rf"\| Pinocchio CLIK \(Python loop\) \| 30 \| {NUMBER} %"]),
    "bench_ik_collision.py": (("gcc",), [
        rf"\| plain \(collision_free=False\) \| 40 \| {NUMBER} % \| {NUMBER} % \(\d+\) \| \d+ \|",
        rf"\| with the sphere, clearance 20 mm \| 40 \| {NUMBER} % \| {NUMBER} % \(\d+\) \| \d+ \| {NUMBER} ms \| "
        rf"{NUMBER} ms \|"]),
    "bench_kernel.py": (("gcc",), [
        rf"robot\.fk_jacobian\(q\), one call, compiled kernel\s+{NUMBER} us",
        rf"Pinocchio forwardKinematics \+ computeJointJacobians \+ getFrameJacobian\s+{NUMBER} us",
        rf"robot\.ik\(pose\) compiled mean {NUMBER} us, success {NUMBER} %; reference \(before\) {NUMBER} us",
        r"\| Robotics Toolbox ikine_LM \| (10 \| [0-9.]+ %|— \| — \| — \| — \| MISSING: roboticstoolbox-python)",
        rf"C called from C \(same code and flags\)\s+wall\s+{NUMBER} ns/sample\s+cpu\s+{NUMBER} ns/sample",
        rf"armgen ik panda \(one pose\)\s+compiled wall\s+{NUMBER} s cpu\s+{NUMBER} s \| reference \(before\) wall",
        rf"armgen plan panda_polish_contour_program\.toml\s+compiled wall\s+{NUMBER} s"]),
    "bench_kinematics.py": (("gcc", "valgrind", *ARM_TOOLS), [
        rf"x86 -O2 double fk_jacobian instructions\s+{NUMBER} instr/call",
        rf"CasADi C double \(jacobian\(\)\) instructions\s+{NUMBER} instr/call",
        rf"M4F -Os float fk_jacobian executed instr\s+{NUMBER} instr/call",
        rf"cross-check: -singlestep -d exec trace\s+{NUMBER} instr/call"]),
    "bench_link.py": (("gcc", *ARM_TOOLS), [rf"per received frame: {NUMBER} instructions \({NUMBER} with ACK replies\); per servo tick: {NUMBER}",
                                 rf"fuzz: \d+ chunks in {NUMBER} s: crashes 0, violations 0",
                                 rf"\| 50 \| 151 \| {NUMBER} \|", rf"\| \d+ \| 501 \| {NUMBER} \|"]),
    "bench_planner.py": (("gcc",), [
        rf"host firmware \(gcc -O2, double\): {NUMBER} us/tick",
        rf"c\s+planner\s+{NUMBER} s",
        rf"modular8_wgpm_demo\s+c\s+{NUMBER} s",
        rf"--workers 2\s+{NUMBER} s\s+speedup {NUMBER}x"]),
    "bench_program_table.py": (("arm-none-eabi-gcc", "qemu-system-arm"), [
        r"flash table_float_bytes\s+\d+ B",
        r"all\s+mean\s+\d+\s+max\s+\d+\s+\(\d+ ticks\)"]),
    "bench_programs.py": ((), [rf"poses: \s*{NUMBER} ms for \d+ samples", rf"poses / line per sample: {NUMBER}x"]),
    "bench_snake.py": ((), [rf"planar\s+exact\s+{NUMBER}\s+{NUMBER}", rf"planar\s+BDF\s+1\s+{NUMBER}"]),
    "bench_targets.py": (("gcc", *ARM_TOOLS, "riscv64-unknown-elf-gcc", "qemu-system-riscv32"), [
        r"^\| cortex-m7 \| double \| \d+ / \d+ / \d+ \| \d+ / \d+ / \d+ \| \d+% \| \d+ / \d+ \| \d+ / \d+ / \d+ \| \d+ \| \d+ \| \d+ \|$",
        r"^\| rv32imf \| float \| \d+ / \d+ / \d+ \| \d+ / \d+ / \d+ \| \d+% \| \d+ / \d+ \| \d+ / \d+ / \d+ \| \d+ \| \d+ \| \d+ \|$",
        r"^\| `ik` \| \d+ \| \d+ \| \d+ \| \d+ \| \d+ \|$",
        r"Cortex-M0\+ float \(soft float\) resolved-rate tick: max \d+ instructions against 133000 cycles"]),
    "bench_verify.py": (("gcc",), [rf"armgen verify \(fresh, compile, callbacks\)\s+wall\s+{NUMBER} s",
                                   rf"armgen verify planar3, cold store\s+wall\s+{NUMBER} s\s+cpu\s+{NUMBER} s\s+stages reused 0",
                                   rf"armgen verify planar3, repeated\s+wall\s+{NUMBER} s\s+cpu\s+{NUMBER} s\s+stages reused 3",
                                   rf"ratio batched / per sample: {NUMBER}"]),
    "fuzz.py": ((), [r"\| robot files \| \d+ \|", r"\| task files \| \d+ \|",
                     r"\| URDF files \| \d+ \|", r"\| sweep options \| \d+ \|"]),
}


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def test_every_benchmark_has_a_quick_run():
    assert sorted(p.name for p in BENCHMARKS.glob("*.py")) == sorted(QUICK_RUNS)


@pytest.mark.slow
@pytest.mark.parametrize("script", sorted(QUICK_RUNS))
def test_quick_run_exits_0_with_its_figures(script):
    tools, figures = QUICK_RUNS[script]
    for tool in tools:
        require_tool(tool)
    env = dict(os.environ, PYTHONPATH=str(ROOT), ARMGEN_NO_PROGRESS="1", MPLBACKEND="Agg")
    started, cpu = time.perf_counter(), _children_cpu_s()
    run = subprocess.run([sys.executable, str(BENCHMARKS / script), "--quick"], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=QUICK_TIMEOUT_S)
    print(f"{script} --quick: {time.perf_counter() - started:.1f} s wall, {_children_cpu_s() - cpu:.1f} s CPU")
    report = f"{script} --quick: exit {run.returncode}\n{run.stdout[-6000:]}\n{run.stderr[-4000:]}"
    assert run.returncode == 0, report
    missing = [figure for figure in figures if not re.search(figure, run.stdout, re.M)]
    assert not missing, f"lines not printed: {missing}\n{report}"


def _bench_module(name: str):
    sys.path.insert(0, str(BENCHMARKS))
    try:
        spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCHMARKS))
    return module


@pytest.mark.parametrize("section, status",
                         [(None, "measured"), ("fails", "failed"), ("misses a tool", "tool missing")])
def test_report_exit_status_says_whether_every_figure_was_measured(section, status, tmp_path):
    """A benchmark built on Report (kinematics, criteria, firmware) exits 0 only when every
    section measured; before, a section that failed to link was printed FAILED and the run
    still exited 0."""
    bench = _bench_module("bench_kinematics")

    def measured():
        pass

    def fails():
        raise RuntimeError("linking the criteria firmware failed (exit 1)")

    def misses_a_tool():
        bench.tool("no-such-tool-armgen-test")

    rep = bench.Report()
    rep.data["meta"] = {}
    rep.section("a", "1. measured:", measured)
    sections = {"fails": fails, "misses a tool": misses_a_tool}
    if section:
        rep.section("b", f"2. {section}:", sections[section])
    work = tmp_path / "build"
    work.mkdir()
    args = type("Args", (), {"out": None, "keep": False})()
    assert bench.finish(rep, args, work, time.perf_counter()) == bench.EXIT_CODES[status]
    assert bench.EXIT_CODES["measured"] == 0 and bench.EXIT_CODES["failed"] != 0 \
        and bench.EXIT_CODES["tool missing"] == 4  # the project's "missing tool" status


def test_criteria_driver_declares_each_function_as_the_header_does():
    """bench_criteria.py's M4 timing driver calls every generated function through a pointer of
    its exact type: ``ik`` returns a status (the driver declared it ``void`` and did not link)."""
    criteria = _bench_module("bench_criteria")
    header = (ROOT / "generated" / "modular8" / "modular8.h").read_text()
    returns = criteria.return_types(header, "modular8", ["fk_jacobian", "ik", "step_gpm", "manipulability"])
    assert returns == {"fk_jacobian": "void", "ik": "modular8_status", "step_gpm": "modular8_status",
                       "manipulability": "void"}
