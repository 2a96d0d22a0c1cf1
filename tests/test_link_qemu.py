"""The link on the Cortex-M4F under QEMU (mps2-an386): the firmware's float build with fw_link on
the CMSDK UART0, which QEMU connects to a pseudo-terminal (``-serial pty``); the same client as
for the host firmware. Then the firmware project's own UART runner (arm/fw_link_uart.c, built by
the project's CMake) on the Cortex-M4F (mps2-an386), the Cortex-M7 (mps2-an500) and the
Cortex-M0+ (mps2-an385, soft float). QEMU runs without -icount here, so the board's SysTick time is the wall
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
from armgen.api import firmware_project, read_plan
from armgen.link import LinkClient, plan_pose_waypoints, plan_waypoints
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


# -- the firmware project's own UART runner (arm/fw_link_uart.c): receive interrupt, SysTick ------

PROJECT_CORES = {"m4": ("arm-none-eabi-cortex-m4.cmake", "mps2-an386"),
                 "m7": ("arm-none-eabi-cortex-m7.cmake", "mps2-an500"),
                 "m0plus": ("arm-none-eabi-cortex-m0plus.cmake", "mps2-an385")}
# The demo's resolved-rate plan streamed as poses: the float build's resolved-rate step and FK
# (single precision: 1e-7 m at 1 m) behind the closed loop; 1e-4 m as for the host's pose stream.
POSE_STREAM_TOL_M = 1e-4


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    for tool in ("arm-none-eabi-gcc", "qemu-system-arm", "cmake"):
        require_tool(tool)
    out = tmp_path_factory.mktemp("fw_link_project") / "fw"
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    firmware_project("modular8", out)
    return out


def _project_board(project, core: str):
    toolchain, machine = PROJECT_CORES[core]
    build = project / f"build-{core}"
    for args in (["-S", str(project), "-B", str(build), f"-DCMAKE_TOOLCHAIN_FILE={project / 'cmake' / toolchain}"],
                 ["--build", str(build), "--target", f"modular8_{core}_link"]):
        done = subprocess.run(["cmake", *args], capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return subprocess.Popen(["qemu-system-arm", "-M", machine, "-nographic", "-monitor", "none", "-serial", "pty",
                             "-kernel", str(build / f"modular8_{core}_link.elf")],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _port(proc) -> str:
    line = proc.stdout.readline()
    found = re.search(r"(/dev/pts/\d+)", line)
    assert found, line
    return found.group(1)


def _round_trips(link, name: str, values: dict | None = None) -> list[float]:
    latency = []
    for _ in range(LATENCY_SAMPLES):
        started = time.perf_counter()
        link.request(name, values)
        latency.append(time.perf_counter() - started)
    return latency


@pytest.mark.parametrize("core", sorted(PROJECT_CORES))
def test_the_projects_uart_runner_streams_the_demo_plan(project, core):
    """The project's <prefix>_<core>_link image under QEMU: joints, then tool poses, of the demo's
    plan streamed at 50 Hz over UART0 (received by its interrupt); TELEMETRY and ACK round trips."""
    plan_read = read_plan(project / "demo" / "plan.csv")
    columns, data = list(plan_read.columns), plan_read.data
    t, q, qd = plan_waypoints(columns, data, NDOF, 50.0)
    t_pose, poses, twists = plan_pose_waypoints(columns, data, 50.0)
    q_plan = data[:, [columns.index(f"q{i}_rad") for i in range(1, NDOF + 1)]]
    p_plan = data[:, [columns.index(c) for c in ("x_m", "y_m", "z_m")]]
    proc = _project_board(project, core)
    try:
        port = _port(proc)
        with LinkClient(port, timeout=QEMU_BOOT_TIMEOUT_S) as link:
            replies = link.stream(t, q, qd, lead_s=LEAD_S)
            end = link.wait_idle()
            assert (end.state_name, end.fault_name) == ("DONE", "NONE") and end["underruns"] == 0
            telemetry = _round_trips(link, "LOCK", {"locked": 0})
            link.move_to_joints(q[0])
            link.wait_idle()
            pose_replies = link.stream_poses(t_pose, poses, twists, lead_s=LEAD_S)
            pose_end = link.wait_idle()
        with LinkClient(port, timeout=QEMU_BOOT_TIMEOUT_S, replies="ACK") as link:
            ack = _round_trips(link, "LOCK", {"locked": 0})
            counts = link.status()
    finally:
        proc.terminate()
        proc.communicate(timeout=30)
    last = len(q_plan) - 1
    running = [r for r in replies if r.state_name == "RUNNING"]
    deviation = max(float(np.abs(r.q - q_plan[min(r["motion_tick"], last)]).max()) for r in running)
    pose_running = [r for r in pose_replies if r.state_name == "RUNNING"]
    # stream tick k commands the pose at (k + 1) dt (test_link_pty.py)
    pose_error = max(float(np.linalg.norm(np.array(r["tool"][:3]) - p_plan[min(r["motion_tick"] + 1, last)]))
                     for r in pose_running)
    print(f"{core} project runner: {len(t)} waypoints at 50 Hz, max joint deviation {deviation:.3g} rad; "
          f"{len(t_pose)} poses, tool within {pose_error * 1e3:.3g} mm of the plan; round trip median "
          f"TELEMETRY {np.median(telemetry) * 1e3:.2f} ms (min {min(telemetry) * 1e3:.2f}), ACK "
          f"{np.median(ack) * 1e3:.2f} ms (min {min(ack) * 1e3:.2f})")
    assert len(running) > len(t) // 2 and deviation <= FLOAT_STREAM_TOL
    assert (pose_end.state_name, pose_end.fault_name) == ("DONE", "NONE") and pose_end["underruns"] == 0
    assert len(pose_running) > len(t_pose) // 2 and pose_error <= POSE_STREAM_TOL_M
    assert counts["rx_overflow"] == 0 and counts["malformed"] == 0 and counts["bad_crc"] == 0
