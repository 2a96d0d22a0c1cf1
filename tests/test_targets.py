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
