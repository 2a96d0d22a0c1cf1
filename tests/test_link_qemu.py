"""The link on the Cortex-M4F under QEMU (mps2-an386): the firmware's float build with fw_link on
the CMSDK UART0, which QEMU connects to a pseudo-terminal (``-serial pty``); the same client as
for the host firmware. QEMU runs without -icount here, so the board's SysTick time is the wall
clock's and the client's 50 Hz is the board's 50 Hz."""

from __future__ import annotations

import dataclasses
import os
import re
import subprocess
import time

import numpy as np
import pytest

from armgen import firmware as fw
from armgen.link import LinkClient
from armgen.planning.tasks import load_task, run_task

from conftest import require_tool
from link_builds import TASK, builder, task

NDOF = 8
DT = 0.001
WAYPOINT_EVERY = 20  # 50 Hz
LEAD_S = 0.3
# The float build computes the Hermite and the follower in single precision (|q| < 2 rad: an ulp
# is 2.4e-7) and reports q in single precision; 1e-5 rad is ~40 ulps.
FLOAT_STREAM_TOL = 1e-5
QEMU_BOOT_TIMEOUT_S = 10.0
LATENCY_SAMPLES = 50


@pytest.fixture(scope="module")
def board():
    for tool in ("arm-none-eabi-gcc", "qemu-system-arm"):
        require_tool(tool)
    elf = builder().executable(dataclasses.replace(fw.ARM_VARIANT, runner="link_uart"), task(), name="uart")
    proc = subprocess.Popen(["qemu-system-arm", "-M", "mps2-an386", "-nographic", "-monitor", "none",
                             "-semihosting-config", "enable=on,target=native", "-serial", "pty", "-kernel", str(elf)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        line = proc.stdout.readline()
        found = re.search(r"(/dev/pts/\d+)", line)
        assert found, line
        yield found.group(1)
    finally:
        proc.terminate()
        proc.communicate(timeout=30)


def test_stream_a_plan_over_the_emulated_uart(board):
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    document, _ = load_task(TASK)
    result = run_task(document, str(TASK))
    cols = list(result.columns)
    t = result.data[:, 0]
    q = result.data[:, [cols.index(f"theta_j{i}_rad") for i in range(1, NDOF + 1)]]
    qd = result.data[:, [cols.index(f"omega_j{i}_rad_s") for i in range(1, NDOF + 1)]]
    pick = np.arange(0, len(t), WAYPOINT_EVERY)
    with LinkClient(board, timeout=QEMU_BOOT_TIMEOUT_S) as link:
        replies = link.stream(t[pick], q[pick], qd[pick], lead_s=LEAD_S)
        end = link.wait_idle()
        latency = []
        for _ in range(LATENCY_SAMPLES):
            started = time.perf_counter()
            link.status()
            latency.append(time.perf_counter() - started)
    assert (end.state_name, end.fault_name) == ("DONE", "NONE") and end["underruns"] == 0
    running = [r for r in replies if r.state_name == "RUNNING"]
    assert len(running) > len(pick) // 2
    deviation = max(float(np.abs(r.q - q[r["motion_tick"]]).max()) for r in running)
    print(f"QEMU UART: {len(pick)} waypoints at 50 Hz, max joint deviation at the {len(running)} replies' ticks "
          f"{deviation:.3g} rad; STATUS round trip min {min(latency) * 1e3:.2f} ms, "
          f"median {np.median(latency) * 1e3:.2f} ms, max {max(latency) * 1e3:.2f} ms")
    assert deviation <= FLOAT_STREAM_TOL
    assert np.abs(end.q - q[-1]).max() <= FLOAT_STREAM_TOL
