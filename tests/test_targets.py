"""The cores beside the Cortex-M4F (armgen.firmware.TARGETS, docs/targets.md): the firmware
built for each, run under QEMU on its MPS2 model, must follow the plan within the bounds of the
precision it computes natively (armgen.verification.firmware_compare; the plan is the
independent reference, computed by the Python planner) and match the host run of that
precision."""

from __future__ import annotations

import copy
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from armgen import api
from armgen import firmware as fw
from armgen.planning.result import write_plan
from armgen.planning.tasks import apply_overrides, load_task, run_task
from armgen.robot import load_robot, load_robot_any
from armgen.verification.pipeline import VerifyConfig, stage_target

from conftest import require_tool

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

# The short line of tests/test_firmware.py (a 5 s line of the circle example's robot).
SHORT = ["path.type=line", "path.end=[-450, 400, 900]", "timing.duration=5"]


@pytest.fixture(scope="module")
def short_plan_path(tmp_path_factory):
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    task, _ = load_task(EXAMPLES / "modular8_circle_combined.toml")
    result = run_task(apply_overrides(copy.deepcopy(task), SHORT), "targets")
    path = tmp_path_factory.mktemp("plan") / "plan.csv"
    write_plan(result, path)
    return path


@pytest.fixture(scope="module")
def builder(tmp_path_factory):
    return fw.FirmwareBuilder("modular8", tmp_path_factory.mktemp("firmware"))


@pytest.fixture(scope="module")
def baxter():
    return load_robot_any(str(Path(__file__).resolve().parent / "data" / "baxter_arm.toml"))


def test_the_command_line_offers_every_target():
    assert api.VERIFY_TARGETS == tuple(fw.TARGETS)


def require_target(name: str) -> fw.Target:
    target = fw.TARGETS[name]
    for tool in target.tools:
        require_tool(tool)
    return target


@pytest.mark.parametrize("name", [t for t in fw.TARGETS if t != "cortex-m4"])  # the M4: tests/test_firmware.py
def test_target_stage_passes_under_qemu(name, tmp_path, short_plan_path, builder):
    target = require_target(name)
    stage = stage_target(VerifyConfig(load_robot("modular8"), short_plan_path, target=name), tmp_path, builder)
    assert stage.passed, stage.render()
    rows = {(r[0], r[1]): r for r in stage.rows}
    assert (f"{name} vs host firmware, {target.precision}", "max |Δq| [rad]") in rows
    assert any(r[1].startswith("instructions per tick") for r in stage.rows)


def test_a_foreign_seven_dof_arm_passes_on_every_target(tmp_path, baxter):
    """Baxter's left arm (tests/data/baxter_arm.toml, not a bundled robot), the demo line of
    `armgen firmware` (no --plan), on every core."""
    targets = [name for name in fw.TARGETS if all(shutil.which(tool) for tool in fw.TARGETS[name].tools)]
    if len(targets) < len(fw.TARGETS):
        for name in fw.TARGETS:
            require_target(name)  # skips naming the missing tool
    builder = fw.FirmwareBuilder(baxter, tmp_path / "firmware")
    for name in targets:
        stage = stage_target(VerifyConfig(baxter, None, target=name), tmp_path / name, builder)
        assert stage.passed, stage.render()


# The 32-bit Thumb instructions Armv6-M has (all else is 16-bit): what the Cortex-M0+ image may
# hold, so that its run on the AN385's Cortex-M3 executes an M0+'s instructions and no more.
ARMV6M_32BIT = {"bl", "mrs", "msr", "dsb", "dmb", "isb", "udf"}


def test_the_cortex_m0plus_image_holds_armv6m_instructions_only(tmp_path, short_plan_path, builder):
    require_target("cortex-m0plus")
    objdump = require_tool("arm-none-eabi-objdump")
    from armgen.planning.result import read_plan
    task = fw.task_from_plan(read_plan(short_plan_path), "thumb1")
    elf = builder.executable(fw.target_variant("cortex-m0plus"), task, "thumb1")
    listing = subprocess.run([objdump, "-d", str(elf)], capture_output=True, text=True, check=True).stdout
    wide = {m.group(1) for m in re.finditer(r"^\s+[0-9a-f]+:\t[0-9a-f]{4} [0-9a-f]{4}\s+\t?(\w+)", listing, re.M)}
    narrow = re.findall(r"^\s+[0-9a-f]+:\t[0-9a-f]{4}\s+\t", listing, re.M)
    assert len(narrow) > 1000  # the listing was parsed: the image's 16-bit instructions
    assert wide <= ARMV6M_32BIT, wide - ARMV6M_32BIT
    assert not re.search(r"\bv(add|mul|ldr|str|mov)\.f32\b", listing)  # no FPU instruction: soft float


TOOLCHAIN_DIR = Path(fw.FIRMWARE_DIR) / "project" / "cmake"


def toolchain_file(name: str) -> Path:
    t = fw.TARGETS[name]
    return TOOLCHAIN_DIR / f"{t.compiler.removesuffix('-gcc')}-{name}.cmake"


def cmake_sets(path: Path) -> dict[str, str]:
    return {m.group(1): m.group(2).strip('"') for m in re.finditer(r"^set\((\w+) (.*?)\)", path.read_text(), re.M)}


@pytest.mark.parametrize("name", list(fw.TARGETS))
def test_each_toolchain_file_builds_what_armgen_builds(name):
    t = fw.TARGETS[name]
    sets = cmake_sets(toolchain_file(name))
    assert sets["CMAKE_C_COMPILER"] == t.compiler
    assert sets["CMAKE_C_FLAGS_INIT"].split() == [*t.cpu_flags, *t.compile_specs]
    assert sets["ARMGEN_LINK_SPECS"].split() == list(t.link_specs)
    assert (sets["ARMGEN_STARTUP"], sets["ARMGEN_LINKER_SCRIPT"]) == (t.startup, t.linker_script)
    assert sets["ARMGEN_QEMU"] == t.qemu and sets["ARMGEN_QEMU_MACHINE"].split(";") == ["-M", t.qemu_machine,
                                                                                       *t.qemu_extra]
    assert int(sets["ARMGEN_CPU_HZ"]) == t.cpu_hz
    assert sets["ARMGEN_FLOAT"] == ("OFF" if t.precision == "double" else "ON")


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    from click.testing import CliRunner
    from armgen.cli.main import cli
    folder = tmp_path_factory.mktemp("project") / "fw"
    out = CliRunner().invoke(cli, ["firmware", "modular8", "--out", str(folder)])
    assert out.exit_code == 0, out.output
    return folder


@pytest.mark.parametrize("name", [t for t in fw.TARGETS if t != "cortex-m4"])  # the M4: tests/test_install.py
def test_the_firmware_project_builds_and_runs_each_core(name, project, monkeypatch):
    """The project's toolchain file of the core: configure, build, its `qemu` target; the run
    follows the project's plan in the bounds of the core's precision."""
    from armgen.planning.result import read_plan
    from armgen.verification import firmware_compare as fwcmp
    target = require_target(name)
    require_tool("cmake")
    build = project / f"build-{name}"
    for cmd in (["cmake", "-S", str(project), "-B", str(build), f"-DCMAKE_TOOLCHAIN_FILE={toolchain_file(name)}"],
                ["cmake", "--build", str(build)], ["cmake", "--build", str(build), "--target", "qemu"]):
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    suffix = cmake_sets(toolchain_file(name))["ARMGEN_TARGET"]
    run = fw.parse_output((build / f"run-{suffix}.csv").read_text())
    assert run.summary["real_bytes"] == ("8" if target.precision == "double" else "4")
    monkeypatch.chdir(project)  # the plan's task names the project's robot.toml
    plan = read_plan(project / "demo" / "plan.csv")
    cmp = fwcmp.compare_with_plan(plan, run, fw.task_from_plan(plan, "demo"), target.precision, name)
    assert cmp.passed, cmp.rows


def test_the_float_cores_command_the_same_bits(short_plan_path, builder):
    """IEEE 754 binary32 arithmetic is correctly rounded in an FPU and in libgcc's soft float
    alike, -std=c99 contracts no a*b+c into a fused multiply-add (-ffp-contract=off), and every
    core links the same sin/cos (arm/fw_fastmath.c, the generated bounded trig): so the float
    runs of the Cortex-M4F, -M33, -M0+ and RV32IMF print the same bits, row for row. A core
    whose build fused operations or took another library's math would differ here."""
    from armgen.planning.result import read_plan
    floats = [name for name, t in fw.TARGETS.items() if t.precision == "float"]
    for name in floats:
        require_target(name)
    task = fw.task_from_plan(read_plan(short_plan_path), "bits")
    runs = {name: fw.run_qemu(builder.executable(fw.target_variant(name), task, f"bits_{name}"), target=name)
            for name in floats}
    reference = runs["cortex-m4"].data
    for name, run in runs.items():
        assert run.data.shape == reference.shape and (run.data == reference).all(), name
