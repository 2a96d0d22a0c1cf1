"""The cores beside the Cortex-M4F (armgen.firmware.TARGETS, docs/targets.md): the firmware
built for each, run under QEMU on its MPS2 model, must follow the plan within the bounds of the
precision it computes natively (armgen.verification.firmware_compare; the plan is the
independent reference, computed by the Python planner) and match the host run of that
precision."""

from __future__ import annotations

import copy
import os
from pathlib import Path

import pytest

from armgen import api
from armgen import firmware as fw
from armgen.planning.result import write_plan
from armgen.planning.tasks import apply_overrides, load_task, run_task
from armgen.robot import load_robot
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


def test_the_command_line_offers_every_target():
    assert api.VERIFY_TARGETS == tuple(fw.TARGETS)


@pytest.mark.parametrize("name", [t for t in fw.TARGETS if t != "cortex-m4"])  # the M4: tests/test_firmware.py
def test_target_stage_passes_under_qemu(name, tmp_path, short_plan_path, builder):
    require_tool("arm-none-eabi-gcc")
    require_tool("qemu-system-arm")
    target = fw.TARGETS[name]
    stage = stage_target(VerifyConfig(load_robot("modular8"), short_plan_path, target=name), tmp_path, builder)
    assert stage.passed, stage.render()
    rows = {(r[0], r[1]): r for r in stage.rows}
    assert (f"{name} vs host firmware, {target.precision}", "max |Δq| [rad]") in rows
    assert any(r[1].startswith("instructions per tick") for r in stage.rows)
