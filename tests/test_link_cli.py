"""``armgen link PORT …`` against the host firmware on a pseudo-terminal: status, a joint move,
a streamed plan file, watch; and the exit codes of a port without a board (4) and a refused
command (3)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from armgen.api import plan

from link_builds import TASK, link_executable

NDOF = 8
PRINT_RTOL = 5e-6  # status prints %.6g: half a unit of the sixth significant digit
FLOAT32_ATOL = 2.4e-7  # the wire's IEEE single of a joint value below 2 rad (one ulp), for values printed near 0
# a pose stream ends within fw_link.h's FW_LINK_POSE_ARRIVE_M (1e-5 m per axis) of its last pose;
# status prints %.6g of ~0.5 m: 5e-7 m more
POSE_ARRIVE_M = 1e-5 + 1e-6


def armgen(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "armgen.cli.main", *args], capture_output=True, text=True,
                          timeout=120, env=dict(os.environ, ARMGEN_NO_PROGRESS="1"))


@pytest.fixture()
def port():
    proc = subprocess.Popen([str(link_executable("link"))], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        yield proc.stdout.readline().split()[-1]
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=30)
        assert "Sanitizer" not in err and "runtime error" not in err, err[-3000:]


def test_status_move_to_stream_watch(port, tmp_path):
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    status = armgen("link", port, "status")
    assert status.returncode == 0, status.stderr
    assert "state IDLE" in status.stdout and "fault NONE" in status.stdout
    ptp = plan(TASK)
    ptp.save(tmp_path / "ptp.csv")
    # the plan starts at the firmware's start: stream it at 50 Hz
    streamed = armgen("link", port, "stream", str(tmp_path / "ptp.csv"), "--rate", "50")
    assert streamed.returncode == 0, streamed.stderr
    assert "streamed 151 waypoints" in streamed.stdout and "state DONE" in streamed.stdout
    deviation = float(streamed.stdout.split("ticks ")[1].split()[0])
    assert deviation < 1e-5  # the replies' float32 commands against the plan interpolated at their ticks
    q_end = ptp.data[-1, [ptp.columns.index(f"theta_j{i}_rad") for i in range(1, NDOF + 1)]]
    target = ",".join(f"{v:.9f}" for v in q_end - 0.02)
    moved = armgen("link", port, "move-to", "--joints", target)
    assert moved.returncode == 0, moved.stderr
    assert "state DONE" in moved.stdout
    got = np.array([float(v) for v in moved.stdout.split("q [rad|m]")[1].split("\n")[0].split()])
    assert np.allclose(got, q_end - 0.02, rtol=PRINT_RTOL, atol=FLOAT32_ATOL)
    trace = tmp_path / "twists.csv"
    t = np.arange(50) * 0.02
    ramp = np.minimum(1.0, t / 0.3)  # from rest
    columns = {"vx_m_s": 0.02 * ramp, "vy_m_s": 0.0 * t, "vz_m_s": -0.01 * ramp, "wx_rad_s": 0.0 * t,
               "wy_rad_s": 0.0 * t, "wz_rad_s": 0.05 * ramp}
    trace.write_text(",".join(columns) + "\n" + "\n".join(",".join(f"{columns[c][k]:.6g}" for c in columns)
                                                          for k in range(len(t))) + "\n")
    served = armgen("link", port, "servo", str(trace))
    assert served.returncode == 0, served.stderr
    assert "sent 50 twists" in served.stdout and "state DONE" in served.stdout
    watched = armgen("link", port, "watch", "--count", "3", "--period", "0.01")
    assert watched.returncode == 0 and watched.stdout.count("state DONE") == 3
    criterion = armgen("link", port, "servo", str(trace), "--criterion", "manipulability")
    assert criterion.returncode == 0 and "state DONE" in criterion.stdout, criterion.stderr
    # a pose file from where the tool rests: 3 cm along x and back, 10 poses a second, rest to rest
    from armgen.description import matrix_rpy
    from armgen.link import LinkClient

    with LinkClient(port) as link:
        tool = np.array(link.status()["tool"])
    rpy = matrix_rpy(tool[3:].reshape(3, 3, order="F"))
    t = np.arange(11) * 0.1
    x = tool[0] + 0.03 * (1 - np.cos(np.pi * t)) / 2
    rows = [(tk, xk, tool[1], tool[2], *rpy) for tk, xk in zip(t, x)]
    header = "t_s,x_m,y_m,z_m,roll_rad,pitch_rad,yaw_rad\n"
    (tmp_path / "there.csv").write_text(header + "\n".join(",".join(f"{v:.9g}" for v in r) for r in rows) + "\n")
    (tmp_path / "back.csv").write_text(header + "\n".join(",".join(f"{v:.9g}" for v in (r[0], *b[1:]))
                                                           for r, b in zip(rows, rows[::-1])) + "\n")
    there = armgen("link", port, "stream", str(tmp_path / "there.csv"), "--rate", "10")
    assert there.returncode == 0, there.stderr
    assert "streamed 11 tool poses" in there.stdout and "state DONE" in there.stdout
    tool_there = [float(v) for v in there.stdout.split("tool [m]")[1].split("\n")[0].split()]
    assert np.allclose(tool_there, [x[-1], tool[1], tool[2]], atol=POSE_ARRIVE_M)
    back = armgen("link", port, "stream", str(tmp_path / "back.csv"), "--rate", "10", "--ack")
    assert back.returncode == 0 and "state DONE" in back.stdout, back.stderr
    assert "ticks nan" in back.stdout  # ACK replies carry no pose: nothing measured


def test_refused_and_missing(port, tmp_path):
    outside = ",".join(["10"] * NDOF)
    refused = armgen("link", port, "move-to", "--joints", outside)
    assert refused.returncode == 3 and "BAD_VALUE" in refused.stderr
    wrong_count = armgen("link", port, "move-to", "--joints", "0,0")
    assert wrong_count.returncode != 0 and "MOVE_TO_JOINTS.q needs 8 values" in wrong_count.stderr
    (tmp_path / "speeds.csv").write_text("vx,vy\n1,2\n")
    bad_trace = armgen("link", port, "servo", str(tmp_path / "speeds.csv"))
    assert bad_trace.returncode == 2 and "no column vx_m_s" in bad_trace.stderr
    (tmp_path / "times.csv").write_text("t_s,x_m\n0,0.1\n0.02,0.1\n")
    no_pose = armgen("link", port, "stream", str(tmp_path / "times.csv"))
    assert no_pose.returncode == 2 and "times.csv: the file has no column y_m" in no_pose.stderr, no_pose.stderr
    missing = armgen("link", "/nonexistent/tty", "status")
    assert missing.returncode == 4 and "cannot open /nonexistent/tty" in missing.stderr


def test_the_host_firmware_over_tcp():
    """--tcp: the same link on a TCP socket (pyserial's socket:// URL), a client after another."""
    proc = subprocess.Popen([str(link_executable("link")), "--tcp", "0"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        url = proc.stdout.readline().split()[-1]
        assert url.startswith("socket://127.0.0.1:")
        first = armgen("link", url, "status")
        moved = armgen("link", url, "move-to", "--joints", "-0.9,-0.8,1.2,-0.8,0.6,1.3,0.6,-0.5")
        assert first.returncode == 0 and "state IDLE" in first.stdout, first.stderr
        assert moved.returncode == 0 and "state DONE" in moved.stdout, moved.stderr
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=30)
        assert "Sanitizer" not in err and "runtime error" not in err, err[-3000:]
