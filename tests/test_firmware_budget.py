"""The Cortex-M4F budgets (issue 37, item 18): flash of the generated kinematics and of the
firmware image, and executed instructions per tick in every controller mode, each with a 5 %
margin under its bar. The sizes are measured as benchmarks/bench_criteria.py (the generated
file) and benchmarks/bench_firmware.py (the image, the modes) measure them; docs/firmware.md
gives the figures of a run."""

from __future__ import annotations

import copy
import dataclasses
import os
import subprocess
from pathlib import Path

import pytest

from armgen import firmware as fw
from armgen.codegen.toolchain import ARM_CPU_FLAGS, STRICT_FLAGS
from armgen.planning.tasks import apply_overrides, load_task, run_task

from conftest import require_tool

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "examples"
ROBOT = "modular8"  # the benchmarks' robot: 8 joints, every controller mode

KB = 1024
# The generated file's text (every .text.<prefix>_* section, -Os float, bounded trig: the
# firmware's build; benchmarks/bench_criteria.py measures the same): issue 37's 96 KB, under
# the project's 100 KB bar.
GENERATED_TEXT_BAR_BYTES = 96 * KB
# The whole firmware image's text (all modes, runner, CSV printer, startup, newlib's libm).
IMAGE_TEXT_BAR_BYTES = 100 * KB
# Each tick's bar (instructions, QEMU -icount): FAULT_TOLERANT and WEIGHTED_GPM are capped on
# their worst tick (issue 12's 12 000 and 14 000), every mode by the firmware's 5 000 per tick
# (issue 7), and the resolved-rate mean by the lean criteria's 3 500 (issue 12).
TICK_BAR_MAX = {"RESOLVED_RATE": 5000, "PLAYBACK": 5000, "FAULT_TOLERANT": 12000, "WEIGHTED_GPM": 14000}
RESOLVED_RATE_MEAN_BAR = 3500
# Every figure stays this far under its bar: room for the next feature, and for a compiler
# or QEMU update (a tick moves by ±40, the SysTick resolution).
BUDGET_SHARE = 0.95

# One plan per mode, as benchmarks/bench_firmware.py's section 5 (MODE_PLANS).
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


def section_sizes(obj: Path) -> dict[str, int]:
    out = {}
    for line in subprocess.run([require_tool("arm-none-eabi-size"), "-A", str(obj)], capture_output=True,
                               text=True, check=True).stdout.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0].startswith(".") and parts[1].isdigit():
            out[parts[0]] = int(parts[1])
    return out


@pytest.mark.arm
@pytest.mark.parametrize("bounded_trig", [1, 0])
def test_generated_kinematics_fit_their_flash_budget(tmp_path, bounded_trig):
    """The checked-in generated/modular8 C, every function, as bench_criteria.py measures it
    (before this release's emitter: 105 750 B with bounded trig, 101 442 B plain; before the
    shared out-of-line trig and the looped probes of the IK and the q-twins: 99 254 / 96 066 B)."""
    gcc = require_tool("arm-none-eabi-gcc")
    P = ROBOT.upper()
    obj = tmp_path / f"{ROBOT}.o"
    subprocess.run([gcc, *STRICT_FLAGS, "-Os", *ARM_CPU_FLAGS, "-ffunction-sections", "-fdata-sections",
                    f"-D{P}_USE_FLOAT=1", f"-D{P}_BOUNDED_TRIG={bounded_trig}", "-c",
                    str(REPO / "generated" / ROBOT / f"{ROBOT}.c"), "-o", str(obj)], check=True)
    text = sum(n for name, n in section_sizes(obj).items() if name.startswith(f".text.{ROBOT}_"))
    assert text <= GENERATED_TEXT_BAR_BYTES, f"{text} B of text > {GENERATED_TEXT_BAR_BYTES} B"


@pytest.fixture(scope="module")
def builder(tmp_path_factory):
    return fw.FirmwareBuilder(ROBOT, tmp_path_factory.mktemp("firmware_budget"))


@pytest.mark.arm
def test_firmware_image_fits_its_flash_budget_and_the_combined_plan_its_tick_budget(builder):
    """bench_firmware.py's image: the combined plan's M4 build without row printing (before:
    117 456 B of text); its 12 500 ticks under QEMU, the resolved-rate mean of sections 1-2
    (before: 3 299)."""
    require_tool("arm-none-eabi-gcc")
    require_tool("qemu-system-arm")
    task, sha = load_task(EXAMPLES / "modular8_circle_combined.toml")
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    plan = run_task(copy.deepcopy(task), "modular8_circle_combined.toml", sha, "c")
    elf = builder.executable(dataclasses.replace(fw.ARM_VARIANT, print_rows=False),
                             fw.task_from_plan(plan, "combined"), "image")
    lines = subprocess.run([require_tool("arm-none-eabi-size"), str(elf)], capture_output=True, text=True,
                           check=True).stdout.splitlines()
    text = int(lines[1].split()[0])
    assert text <= IMAGE_TEXT_BAR_BYTES, f"image text {text} B > {IMAGE_TEXT_BAR_BYTES} B"
    run = fw.run_qemu(elf)
    assert (run.state, run.fault) == ("DONE", "NONE")
    ipt = fw.instructions_per_tick(run)
    assert ipt["mean"] <= BUDGET_SHARE * RESOLVED_RATE_MEAN_BAR, ipt
    assert ipt["max"] <= BUDGET_SHARE * TICK_BAR_MAX["RESOLVED_RATE"], ipt


@pytest.mark.arm
@pytest.mark.parametrize("label", list(MODE_PLANS))
def test_every_mode_tick_is_five_percent_under_its_bar(builder, label):
    """Instructions per tick under QEMU, the mode's plan of bench_firmware.py (before:
    FAULT_TOLERANT wln smooth 11 992 at worst against 12 000)."""
    require_tool("arm-none-eabi-gcc")
    require_tool("qemu-system-arm")
    name, overrides = MODE_PLANS[label]
    path = EXAMPLES / f"{name}.toml"
    task, sha = load_task(path)
    apply_overrides(task, overrides)
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    ftask = fw.task_from_plan(run_task(task, name, sha), name) if task["planner"] == "ptp" else fw.task_from_dict(task, name)
    run = fw.run_qemu(builder.executable(dataclasses.replace(fw.ARM_VARIANT, print_rows=False), ftask,
                                         "mode_" + "".join(c for c in label if c.isalnum())))
    assert (run.state, run.fault) == ("DONE", "NONE")
    ipt = fw.instructions_per_tick(run)
    mode = label.split()[0]
    assert ipt["max"] <= BUDGET_SHARE * TICK_BAR_MAX[mode], ipt
    if mode == "RESOLVED_RATE":
        assert ipt["mean"] <= BUDGET_SHARE * RESOLVED_RATE_MEAN_BAR, ipt
