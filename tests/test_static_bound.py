"""The static worst-case instruction bound (armgen.firmware.bound, issue 42) against QEMU's
count of executed instructions (-icount; the independent reference): the bound of each
generated function and of the weighted-GPM tick must be at least every measured count, on
random and adversarial inputs (an IK that runs all its max_iterations steps), and within a
stated factor of the measured maximum (docs/targets.md, "Static bound")."""

from __future__ import annotations

import dataclasses
import importlib.util
import subprocess
from pathlib import Path

import numpy as np
import pytest

from armgen import firmware as fw
from armgen.firmware import bound
from armgen.firmware.project import demo_task
from armgen.planning.tasks import load_task, run_task
from armgen.robot import load_robot, load_robot_any

from conftest import require_tool
from test_programs import bar_task

REPO = Path(__file__).resolve().parents[1]
BAXTER = REPO / "tests" / "data" / "baxter_arm.toml"  # a 7-DOF arm that is not a bundled robot
SEED = 7

# Bound / measured maximum: the goal of issue 42 (1.5) where the FPU computes the precision
# the build runs; the double build's libm sin/cos (Cortex-M7) and the Cortex-M0+'s soft float
# have long worst paths (large arguments, subnormal operands) that the control tasks never
# take, so their bounds stand further above what runs.
TIGHTNESS = {"cortex-m4": 1.5, "cortex-m33": 1.5, "rv32imf": 1.5, "cortex-m7": 1.8, "cortex-m0plus": 2.2}
# The IK's adversarial run: unreachable poses, each call runs its max_iterations steps.
IK_ITERATIONS = 30  # enough steps for two restarts per call (ITERATIONS = 15 per attempt), a short QEMU run
IK_POSES = 4
FK_CONFIGURATIONS = 64


def require_target(name: str) -> fw.Target:
    target = fw.TARGETS[name]
    for tool in (*target.tools, target.compiler.replace("-gcc", "-objdump"), target.compiler.replace("-gcc", "-addr2line")):
        require_tool(tool)
    return target


def bench_targets():
    """benchmarks/bench_targets.py: the driver that times each call of fk_jacobian and ik."""
    spec = importlib.util.spec_from_file_location("bench_targets", REPO / "benchmarks" / "bench_targets.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def weighted_gpm_task(robot_ref: str | Path):
    """The weighted-GPM demo of examples/modular8_wgpm_demo.toml: modular8's own, or the same
    method on another robot along its `armgen firmware` demo line (SI units)."""
    task, _ = load_task(REPO / "examples" / "modular8_wgpm_demo.toml")
    if robot_ref != "modular8":
        robot = load_robot_any(str(robot_ref))
        line = demo_task(robot, str(robot_ref))
        task.update(units={"length": "m", "angle": "rad"}, robot=str(robot_ref), start=line["start"],
                    path=line["path"], timing=dict(task["timing"], duration=5))
    return fw.task_from_dict(task, "wgpm")


@pytest.mark.parametrize("name", list(fw.TARGETS))
def test_the_weighted_gpm_tick_bound_holds_on_each_core(name, tmp_path):
    target = require_target(name)
    check_tick("modular8", target, tmp_path)


@pytest.mark.parametrize("name", ["cortex-m4", "rv32imf"])
def test_the_weighted_gpm_tick_bound_holds_for_a_foreign_arm(name, tmp_path):
    target = require_target(name)
    check_tick(BAXTER, target, tmp_path)


def check_tick(robot_ref, target: fw.Target, work: Path) -> None:
    robot = load_robot_any(str(robot_ref)) if robot_ref != "modular8" else load_robot("modular8")
    builder = fw.FirmwareBuilder(robot, work / "firmware")
    variant = dataclasses.replace(fw.target_variant(target.name), print_rows=False)
    task = weighted_gpm_task(robot_ref)
    elf = builder.executable(variant, task, "wgpm")
    static = bound.tick_bound(target, elf, builder.cflags(variant), builder.prefix, task.mode, task.header)
    run = fw.run_qemu(elf, target=target.name)
    assert (run.state, run.fault) == ("DONE", "NONE")
    measured = fw.instructions_per_tick(run)
    # a tick's count is read off a timer of `resolution` instructions a count (SysTick), so the
    # measured maximum may stand one count above the instructions executed
    assert static.instructions + measured["resolution"] >= measured["max"], (static.instructions, measured)
    assert static.instructions <= TIGHTNESS[target.name] * measured["max"], (static.instructions, measured)
    models = {"cortex-m4": [bound.CortexM4Cycles(0), bound.CortexM4Cycles(5)], "cortex-m0plus": [bound.CortexM0PlusCycles()]}
    cycles = [bound.analyzer(target, elf, builder.cflags(variant), block_cost=model).bound(
        "ctrl_tick", bound.tick_avoid(builder.prefix, "WEIGHTED_GPM")).instructions for model in models.get(target.name, [])]
    # every instruction takes a cycle at least, and wait states only add
    assert all(c >= static.instructions for c in cycles) and cycles == sorted(cycles), (static.instructions, cycles)


def test_the_playback_tick_bound_holds(tmp_path):
    """PLAYBACK: the PTP evaluator's bisection over at most CTRL_MAX_SEGMENTS segments."""
    target = require_target("cortex-m4")
    task, sha = load_task(REPO / "examples" / "modular8_ptp_two_segments.toml")
    firmware_task = fw.task_from_plan(run_task(task, "ptp", sha), "ptp")
    builder = fw.FirmwareBuilder("modular8", tmp_path / "firmware")
    variant = dataclasses.replace(fw.target_variant(target.name), print_rows=False)
    elf = builder.executable(variant, firmware_task, "ptp")
    static = bound.tick_bound(target, elf, builder.cflags(variant), builder.prefix, firmware_task.mode,
                              firmware_task.header).instructions
    measured = fw.instructions_per_tick(fw.run_qemu(elf, target=target.name))
    assert static + measured["resolution"] >= measured["max"], (static, measured)
    assert static <= TIGHTNESS[target.name] * measured["max"], (static, measured)


def halvings(n: int) -> int:
    """The turns fw_program.c's search takes over n entries, by running its loop."""
    turns = 0
    while n > 1:
        n -= n // 2
        turns += 1
    return turns


def test_the_program_tick_bound_holds(tmp_path):
    """A program task's tick (issue 26's seam program, weighted GPM, on Baxter: lines, an arc,
    rounded corners): the evaluator's searches counted over the task's table sizes, each as
    many turns as the search's own loop takes on that many entries."""
    target = require_target("cortex-m4")
    source = tmp_path / "seam.toml"
    source.write_text(bar_task("wgpm", BAXTER), encoding="utf-8")
    task, sha = load_task(source)
    firmware_task = fw.task_from_plan(run_task(task, str(source), sha), str(source), load_robot_any(str(BAXTER)))
    assert "CTRL_PATH_PROGRAM" in firmware_task.header
    builder = fw.FirmwareBuilder(firmware_task.robot, tmp_path / "firmware")
    variant = dataclasses.replace(fw.target_variant(target.name), print_rows=False)
    elf = builder.executable(variant, firmware_task, "program")
    static = bound.tick_bound(target, elf, builder.cflags(variant), builder.prefix, firmware_task.mode,
                              firmware_task.header)
    ranges = bound.program_search_ranges(firmware_task.header)
    assert ranges["search_map"] > 1 and ranges["search_segment"] > 1  # corners and a time law to search
    for search, entries in ranges.items():
        counted = [line for line in static.loops if f"({search} of at most {entries} entries" in line]
        assert counted and all(line.endswith(f": {halvings(entries)}") for line in counted), (search, static.loops)
    run = fw.run_qemu(elf, target=target.name)
    assert (run.state, run.fault) == ("DONE", "NONE")
    measured = fw.instructions_per_tick(run)
    assert static.instructions + measured["resolution"] >= measured["max"], (static.instructions, measured)
    assert static.instructions <= TIGHTNESS[target.name] * measured["max"], (static.instructions, measured)


@pytest.mark.parametrize("name", list(fw.TARGETS))
def test_fk_jacobian_and_ik_bounds_hold_on_random_and_unreachable_poses(name, tmp_path):
    """fk_jacobian on seeded random configurations; ik to reachable poses (random) and to
    unreachable ones (adversarial: every call runs IK_ITERATIONS steps)."""
    target = require_target(name)
    bt = bench_targets()
    robot = load_robot("modular8")
    p = robot.name.lower()
    rng = np.random.default_rng(SEED)
    poses = bt.reachable_poses(robot, IK_POSES, rng) + bt.unreachable_poses(robot, IK_POSES, rng)
    header = bt.poses_header(robot, target.precision, FK_CONFIGURATIONS, len(poses), poses, IK_ITERATIONS)
    elf, flags = bt.calls_image(target, robot, tmp_path, header)
    measured = bt.measure_calls(target, elf)
    assert measured["ik"]["steps_at_max"] == IK_ITERATIONS  # the slowest call ran every step
    analyzer = bound.analyzer(target, elf, flags, p, IK_ITERATIONS)
    resolution = measured["instructions_per_count"]
    for function in ("fk_jacobian", "ik"):
        static = analyzer.bound(f"{p}_{function}").instructions
        worst = measured[function]["max"]
        assert static + resolution >= worst, (function, static, worst)
        assert static <= TIGHTNESS[target.name] * worst, (function, static, worst)


def test_every_generated_function_has_a_bound(tmp_path):
    """Each function the generated header declares (kinematics, criteria, steps, ik) is
    bounded on the Cortex-M4F: no loop in them lacks a count."""
    target = require_target("cortex-m4")
    bt = bench_targets()
    robot = load_robot("modular8")
    elf, flags = bt.calls_image(target, robot, tmp_path, bt.poses_header(robot, "float", 1, 1))
    analyzer = bound.analyzer(target, elf, flags, "modular8", 1)
    names = bound.generated_functions(analyzer, "modular8", REPO / "generated" / "modular8" / "modular8.h")
    assert {"modular8_fk_jacobian", "modular8_ik", "modular8_step_wgpm_from_jacobian", "modular8_zghal"} <= set(names)
    bounds = {name: analyzer.bound(name).instructions for name in names}
    assert all(b > 0 for b in bounds.values()), bounds
    # the IK's bound grows by one step's bound per step allowed
    more = bound.analyzer(target, elf, flags, "modular8", 2).bound("modular8_ik").instructions
    assert more > bounds["modular8_ik"]


def test_a_loop_without_a_count_is_refused(tmp_path):
    """A data-dependent loop (no `for` with a constant bound, no down-counter) is a BoundError
    naming the function and the line, not a guess."""
    target = require_target("cortex-m4")
    src = tmp_path / "halving.c"
    src.write_text("unsigned halvings(unsigned x) {\n  unsigned n = 0u;\n  while (x > 1u) {\n"
                   "    x /= 2u;\n    ++n;\n  }\n  return n;\n}\n", encoding="utf-8")
    obj = tmp_path / "halving.o"
    flags = [*target.cpu_flags, "-O2", "-g"]
    subprocess.run([target.compiler, *flags, "-c", str(src), "-o", str(obj)], check=True)
    with pytest.raises(bound.BoundError, match=r"halvings: the loop at 0x[0-9a-f]+ .*halving\.c:\d"):
        bound.analyzer(target, obj, flags).bound("halvings")


def test_a_loop_s_line_is_its_own_beside_a_dropped_function(tmp_path):
    """A function --gc-sections drops keeps its line table in the image, at addresses from 0,
    where the code that is linked lies: the loop's count must come from its own `for` line (the
    object file's), not from the dropped function's line at the same address."""
    target = require_target("cortex-m4")
    body = "\n".join(f"  a[{k % 50}] = a[{k * 7 % 50}] * {k} + a[{k * 3 % 50}];" for k in range(400))
    src = tmp_path / "dropped.c"
    src.write_text(f"void dropped(int *a) {{\n{body}\n}}\n\nint used(const int *a) {{\n  int s = 0, i;\n"
                   "  for (i = 0; i < 5; ++i) {\n    s += a[i] * a[i + 1];\n  }\n  return s;\n}\n", encoding="utf-8")
    for_line = src.read_text(encoding="utf-8").splitlines().index("  for (i = 0; i < 5; ++i) {") + 1
    flags = [*target.cpu_flags, "-O2", "-g", "-ffunction-sections"]
    obj, elf = tmp_path / "dropped.o", tmp_path / "dropped.elf"
    subprocess.run([target.compiler, *flags, "-c", str(src), "-o", str(obj)], check=True)
    subprocess.run([target.compiler, *flags, "-nostdlib", "-Wl,--gc-sections", "-Wl,-e,used", "-Wl,-Ttext=0",
                    f"-Wl,-Map={elf.with_suffix('.map')}", str(obj), "-o", str(elf)], check=True)
    loops = bound.analyzer(target, elf, flags).bound("used").loops
    assert len(loops) == 1 and f"dropped.c:{for_line} (5): 5" in loops[0], loops


def search_image(target: fw.Target, work: Path, macro: str) -> tuple[Path, list[str]]:
    """An object file whose function `find` runs fw_program.c's search macro ``macro``."""
    src = work / "search.c"
    src.write_text(f"typedef float ctrl_real;\ntypedef struct {{ ctrl_real t; }} row;\n{macro}\n"
                   "DEFINE_SEARCH(search_segment, row, t)\n"
                   "int find(const row *a, int n, ctrl_real x) { return search_segment(a, n, x); }\n", encoding="utf-8")
    flags = [*target.cpu_flags, "-Os", "-g"]
    subprocess.run([target.compiler, *flags, "-c", str(src), "-o", str(work / "search.o")], check=True)
    return work / "search.o", flags


def test_the_program_search_counts_its_halvings_and_nothing_else(tmp_path):
    """fw_program.c's DEFINE_SEARCH over N entries counts as many turns as its loop takes; the
    same macro searching one entry less a turn (linear) is refused, not counted as halving."""
    target = require_target("cortex-m4")
    text = (REPO / "armgen" / "data" / "firmware_stub" / "fw_program.c").read_text(encoding="utf-8")
    macro = text[text.index("#define DEFINE_SEARCH"):text.index("DEFINE_SEARCH(search_segment")]
    entries = 100
    obj, flags = search_image(target, tmp_path, macro)
    analyzer = bound.analyzer(target, obj, flags)
    analyzer.halving_ranges["search_segment"] = entries
    (loop,) = analyzer.bound("find").loops
    assert loop.endswith(f"(search_segment of at most {entries} entries, halved each turn): {halvings(entries)}"), loop
    linear = tmp_path / "linear"
    linear.mkdir()
    obj, flags = search_image(target, linear, macro.replace("n -= half;", "n -= 1;  "))
    analyzer = bound.analyzer(target, obj, flags)
    analyzer.halving_ranges["search_segment"] = entries
    with pytest.raises(bound.BoundError, match="not the halving search"):
        analyzer.bound("find")


def test_a_mode_without_a_tick_is_refused():
    with pytest.raises(bound.BoundError, match="SAMPLED"):
        bound.tick_avoid("modular8", "SAMPLED")
