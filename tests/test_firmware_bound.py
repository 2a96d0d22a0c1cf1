"""``armgen firmware --bound TARGET`` (issue 42): the static worst-case bounds written into the
project's manifest and README (and ``armgen firmware-task --bound``'s bounds.json) are those
armgen.firmware.bound computes directly from the project's own files built for the core, and
the tick's bound holds against QEMU's count of the instructions each tick of that build
executes (-icount: the independent reference). Without --bound the project is unchanged and
needs no cross toolchain; with a core whose toolchain is missing, nothing is written and the
error names the packages."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from armgen import firmware as fw
from armgen.cli.main import cli
from armgen.firmware import bound
from armgen.firmware.project import MANIFEST
from armgen.firmware.tasks import task_from_file
from armgen.robot import load_robot_any

from test_programs import bar_task
from test_static_bound import BAXTER, require_target

REPO = Path(__file__).resolve().parents[1]
PTP_TASK = REPO / "examples" / "modular8_ptp_two_segments.toml"  # a PLAYBACK tick (the PTP evaluator's bisection)


def firmware(*args: str):
    return CliRunner().invoke(cli, ["firmware", "modular8", *args])


def test_without_bound_the_manifest_and_readme_have_no_bounds(tmp_path):
    out = tmp_path / "p"
    result = firmware("--out", str(out))
    assert result.exit_code == 0, result.output
    manifest = json.loads((out / MANIFEST).read_text(encoding="utf-8"))
    assert set(manifest) == {"armgen", "robot", "files"}
    assert "armgen firmware --bound" not in (out / "README.md").read_text(encoding="utf-8")


def test_a_missing_cross_toolchain_writes_nothing_and_names_the_package(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path / "no-tools"))
    out = tmp_path / "p"
    result = firmware("--out", str(out), "--bound", "rv32imf")
    assert result.exit_code == 4, result.output
    assert "riscv64-unknown-elf-gcc" in result.output and "gcc-riscv64-unknown-elf" in result.output
    assert list(tmp_path.iterdir()) == [], list(tmp_path.iterdir())  # no project, no staging folder


def test_an_unknown_target_is_refused(tmp_path):
    result = firmware("--out", str(tmp_path / "p"), "--bound", "cortex-m4,pdp11")
    assert result.exit_code == 2, result.output
    assert "pdp11" in result.output and "cortex-m0plus" in result.output
    assert not (tmp_path / "p").exists()


def test_an_uncountable_image_writes_nothing(tmp_path, monkeypatch):
    """The bounds are computed in the staging folder's turn: a BoundError (exit 5) leaves no
    project behind (the toolchain check and the count stand in for a build that cannot be counted)."""
    from armgen.firmware import project

    def uncountable(target, *args):
        raise bound.BoundError(f"{target.name}: the loop at 0x100 has no count")

    monkeypatch.setattr(project, "require_bound_tools", lambda target: None)
    monkeypatch.setattr(project, "project_bounds", uncountable)
    result = firmware("--out", str(tmp_path / "p"), "--bound", "cortex-m4")
    assert result.exit_code == 5, result.output
    assert "has no count" in result.output
    assert list(tmp_path.iterdir()) == [], list(tmp_path.iterdir())


@pytest.mark.parametrize("task", [None, PTP_TASK], ids=["demo_resolved_rate", "ptp_playback"])
def test_the_project_bounds_are_bound_py_s_and_hold_under_qemu(task, tmp_path, monkeypatch):
    target = require_target("cortex-m4")
    out = tmp_path / "p"
    result = firmware("--out", str(out), "--bound", "cortex-m4", *(["--task", str(task)] if task else []))
    assert result.exit_code == 0, result.output
    (written,) = json.loads((out / MANIFEST).read_text(encoding="utf-8"))["bounds"]
    assert written["target"] == "cortex-m4"

    # the same build from the project's own files: its generated code and its demo plan
    monkeypatch.chdir(out)  # the plan's task names the project's robot.toml, as `armgen verify` runs there
    robot = load_robot_any("robot.toml")
    firmware_task = task_from_file(Path("demo") / "plan.csv", robot)
    builder = fw.FirmwareBuilder(robot, tmp_path / "build", out / "generated")
    variant = dataclasses.replace(fw.target_variant(target.name), print_rows=False)
    elf = builder.executable(variant, firmware_task, "direct")
    flags = builder.cflags(variant)
    tick = bound.tick_bound(target, elf, flags, builder.prefix, firmware_task.mode, firmware_task.header)
    assert written["mode"] == firmware_task.mode.upper()
    assert written["tick"]["instructions"] == tick.instructions
    analyzer = bound.analyzer(target, elf, flags)
    names = bound.generated_functions(analyzer, builder.prefix, out / "generated" / f"{builder.prefix}.h")
    assert f"{builder.prefix}_fk_jacobian" in names
    assert {n: r["instructions"] for n, r in written["functions"].items()} == {n: analyzer.bound(n).instructions
                                                                                for n in names}
    # every instruction takes a cycle at least, and wait states only add
    for row in [written["tick"], *written["functions"].values()]:
        cycles = [row["cycles"][m] for m in ("0 flash wait states", "5 flash wait states")]
        assert row["instructions"] <= cycles[0] <= cycles[1], row
    assert all(written["cycle_models"].values()) and written["library_assumptions"]

    run = fw.run_qemu(elf, target=target.name)
    assert (run.state, run.fault) == ("DONE", "NONE")
    measured = fw.instructions_per_tick(run)
    # a tick is read off a timer of `resolution` instructions a count (test_static_bound)
    assert written["tick"]["instructions"] + measured["resolution"] >= measured["max"], (written["tick"], measured)

    # `armgen firmware-task --bound` of the project's plan and generated code: the same bounds
    task_files = CliRunner().invoke(cli, ["firmware-task", "demo/plan.csv", "-o", str(tmp_path / "task"), "--robot",
                                          "robot.toml", "--gen-dir", "generated", "--bound", "cortex-m4"])
    assert task_files.exit_code == 0, task_files.output
    assert json.loads((tmp_path / "task" / "bounds.json").read_text(encoding="utf-8")) == [written]

    readme = (out / "README.md").read_text(encoding="utf-8")
    section = readme[readme.index("## Worst case per tick"):readme.index("## Other cores")]
    assert f"| `ctrl_tick` ({written['mode']} mode, running) | {tick.instructions} |" in section


def test_a_program_task_s_bound_counts_its_table(tmp_path, monkeypatch):
    """A program task (issue 26's seam program, weighted GPM, on Baxter): the project's tick
    bound is bound.tick_bound's of the same build (the evaluator's searches over the task's
    table) and holds under QEMU."""
    target = require_target("cortex-m4")
    source = tmp_path / "seam.toml"
    source.write_text(bar_task("wgpm", BAXTER), encoding="utf-8")
    out = tmp_path / "p"
    result = CliRunner().invoke(cli, ["firmware", str(BAXTER), "--task", str(source), "--out", str(out),
                                      "--bound", "cortex-m4"])
    assert result.exit_code == 0, result.output
    (written,) = json.loads((out / MANIFEST).read_text(encoding="utf-8"))["bounds"]
    monkeypatch.chdir(out)  # the plan's task names the project's robot.toml
    robot = load_robot_any("robot.toml")
    firmware_task = task_from_file(Path("demo") / "plan.csv", robot)
    assert "CTRL_PATH_PROGRAM" in firmware_task.header and written["mode"] == firmware_task.mode.upper()
    builder = fw.FirmwareBuilder(robot, tmp_path / "build", out / "generated")
    variant = dataclasses.replace(fw.target_variant(target.name), print_rows=False)
    elf = builder.executable(variant, firmware_task, "direct")
    tick = bound.tick_bound(target, elf, builder.cflags(variant), builder.prefix, firmware_task.mode,
                            firmware_task.header)
    assert written["tick"]["instructions"] == tick.instructions
    assert any("search_segment of at most" in line for line in tick.loops), tick.loops
    measured = fw.instructions_per_tick(fw.run_qemu(elf, target=target.name))
    assert tick.instructions + measured["resolution"] >= measured["max"], (tick.instructions, measured)
