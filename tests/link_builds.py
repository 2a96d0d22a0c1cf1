"""The host builds of the link the tests share (built once per test process): the pty runner
(host/link_main.c) and the fuzz/codec driver (host/link_fuzz.c), ASan/UBSan, double, on
modular8 with the configuration of examples/modular8_ptp_two_segments.toml (1 ms ticks, its
start, the robot's limits)."""

from __future__ import annotations

import functools
import os
import tempfile
from pathlib import Path

from armgen import firmware as fw
from armgen.planning.tasks import load_task

REPO = Path(__file__).resolve().parent.parent
TASK = REPO / "examples" / "modular8_ptp_two_segments.toml"


@functools.lru_cache(maxsize=None)
def builder() -> fw.FirmwareBuilder:
    return fw.FirmwareBuilder("modular8", tempfile.mkdtemp(prefix="armgen_link_"))


@functools.lru_cache(maxsize=None)
def task() -> fw.FirmwareTask:
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    document, _ = load_task(TASK)
    return fw.task_from_dict(document, "ptp_two_segments")


@functools.lru_cache(maxsize=None)
def link_executable(runner: str) -> Path:
    """``runner``: "link" (the pty server) or "link_fuzz"."""
    variant = fw.Variant("host", "double", sanitize=True, opt="-O1", runner=runner)
    return builder().executable(variant, task(), name="ptp")


COLLISION_TASK = REPO / "examples" / "iiwa14_pick_table.toml"


@functools.lru_cache(maxsize=None)
def collision_link_executable() -> Path:
    """The pty runner on iiwa14 (capsules: -DCTRL_HAS_COLLISION=1) with the pick-from-the-table
    task's [collision] (the table a half-space under the arm), integrated by explicit Euler as the
    controller does; double, without the sanitizers (a second robot's build: keep it short)."""
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    document, _ = load_task(COLLISION_TASK)
    document["integrator"] = {"method": "euler", "step": 0.01}
    task = fw.task_from_dict(document, "pick_table")
    builder = fw.FirmwareBuilder("iiwa14", tempfile.mkdtemp(prefix="armgen_link_collision_"))
    return builder.executable(fw.Variant("host", "double", opt="-O1", runner="link"), task, name="pick")
