"""The host firmware serving the link over a pseudo-terminal, driven by armgen.link's client in
real time: a plan streamed at 50 Hz, the watchdog when the stream is cut, the session's rules.

The run's own CSV (one row per 1 ms tick: the commands, the link's flags, the count of valid
frames) is the record the checks read; the reference is the plan the PTP planner made
(examples/modular8_ptp_two_segments.toml: 3-4 splines through a via point, 1 ms samples).
"""

from __future__ import annotations

import math
import os
import random
import subprocess
import time
from contextlib import contextmanager

import numpy as np
import pandas as pd
import pytest

from armgen.link import VERSION, LinkClient, LinkError, encode
from armgen.planning.tasks import load_task, run_task

from link_builds import TASK, collision_link_executable, link_executable

DT = 0.001  # the task's step: the controller's period
WAYPOINT_EVERY = 20  # plan samples per waypoint: 50 Hz
NDOF = 8
QDOT_MAX = math.radians(90)  # robots/modular8.toml: qdlim 90 deg/s, every joint
QDDOT_MAX = math.radians(360)  # qddlim 360 deg/s^2
WATCHDOG_MS = 500  # long enough that a loaded CI host's pauses between frames do not fire it
WATCHDOG_TICKS = WATCHDOG_MS  # at 1 ms
LEAD_S = 0.3  # waypoints sent this far ahead of their time: a loaded CI host stays ahead
# The streamed commands against the plan: the wire carries IEEE single (|q| < 2 rad: half an
# ulp is 2^-24 * 2 = 1.2e-7 rad) and the cubic Hermite between 20-ms waypoints of a quintic-free
# 3-4 spline errs by h^4 |q''''| / 384 < 1e-9 rad; 1e-6 leaves a margin for the two.
STREAM_DEVIATION_TOL = 1e-6
# The follower limits each change of velocity to qddot_max * dt exactly; the CSV's %.17g and
# the division by dt add a few ulps.
LIMIT_RTOL = 1e-9
SEED = 40


@pytest.fixture(scope="module")
def plan():
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    document, _ = load_task(TASK)
    result = run_task(document, str(TASK))
    cols = list(result.columns)
    t = result.data[:, 0]
    q = result.data[:, [cols.index(f"theta_j{i}_rad") for i in range(1, NDOF + 1)]]
    qd = result.data[:, [cols.index(f"omega_j{i}_rad_s") for i in range(1, NDOF + 1)]]
    return t, q, qd


@contextmanager
def board(tmp_path):
    """The host firmware on a fresh pty; yields (port, the CSV path)."""
    csv = tmp_path / "run.csv"
    proc = subprocess.Popen([str(link_executable("link")), "--csv", str(csv), "--watchdog-ms", str(WATCHDOG_MS)],
                            stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line.startswith("# port "), line + proc.stderr.read()
        yield line.split()[-1], csv
    finally:
        time.sleep(0.05)
        proc.terminate()
        _, err = proc.communicate(timeout=30)
        assert "Sanitizer" not in err and "runtime error" not in err, err[-3000:]


def read_run(csv) -> pd.DataFrame:
    run = pd.read_csv(csv)
    return run.iloc[:-1] if run.iloc[-1].isna().any() else run  # a row cut by the runner's end


def commands(run):
    return run[[f"q{i}" for i in range(1, NDOF + 1)]].to_numpy(), run[[f"qd{i}" for i in range(1, NDOF + 1)]].to_numpy()


def assert_within_speed_and_acceleration(qd):
    assert np.abs(qd).max() <= QDOT_MAX * (1 + LIMIT_RTOL)
    assert np.abs(np.diff(qd, axis=0)).max() / DT <= QDDOT_MAX * (1 + LIMIT_RTOL)


def test_stream_a_plan_at_50_hz(plan, tmp_path):
    t, q, qd = plan
    pick = np.arange(0, len(t), WAYPOINT_EVERY)
    assert pick[-1] == len(t) - 1  # the plan's last sample is a waypoint
    with board(tmp_path) as (port, csv):
        with LinkClient(port) as link:
            replies = link.stream(t[pick], q[pick], qd[pick], lead_s=LEAD_S)
            end = link.wait_idle()
    assert len(replies) == len(pick) and all(r.result_name == "OK" for r in replies)
    assert (end.state_name, end.fault_name) == ("DONE", "NONE")
    assert end["underruns"] == 0 and end["rejected"] == 0
    run = read_run(csv)
    streamed = run[run.state == 1]  # RUNNING: tick k of the stream commands the plan at k * dt
    k = np.rint(streamed.t_s.to_numpy() / DT).astype(int)
    assert k[0] == 0 and k[-1] == len(t) - 1 and np.all(np.diff(k) == 1)
    q_cmd, qd_cmd = commands(streamed)
    deviation = np.abs(q_cmd - q[k]).max()
    print(f"stream at 50 Hz: {len(pick)} waypoints, {len(k)} ticks, max joint deviation {deviation:.3g} rad")
    assert deviation <= STREAM_DEVIATION_TOL
    assert_within_speed_and_acceleration(commands(run)[1])
    # ends exactly on the last waypoint as the wire carried it (IEEE single)
    assert np.array_equal(commands(run[run.state == 2])[0][-1], q[-1].astype(np.float32).astype(float))


def test_watchdog_stops_a_cut_stream_within_the_acceleration_limits(plan, tmp_path):
    t, q, qd = plan
    pick = np.arange(0, len(t), WAYPOINT_EVERY)
    cut = random.Random(SEED).randrange(15, 120)  # while the arm moves
    with board(tmp_path) as (port, csv):
        with LinkClient(port) as link:
            link.stream(t[pick], q[pick], qd[pick], lead_s=LEAD_S, stop_after=cut)
            time.sleep(LEAD_S + (WATCHDOG_TICKS + 200) * DT)  # silence: the watchdog fires, the arm stops
            after = link.status()
            refused = link.request("MOVE_TO_JOINTS", {"q": q[0]}, check=False)
    assert (after.state_name, after.fault_name) == ("FAULT", "STALE") and "STALE" in after.flags
    assert refused.result_name == "STALE"
    run = read_run(csv)
    rx = run.rx_frames.to_numpy()
    last_frame = int(run.tick[np.nonzero(rx == rx[np.nonzero(run.link_flags.to_numpy() & 4)[0][0]])[0][0]])
    decision = int(run.tick[np.nonzero(run.link_flags.to_numpy() & 4)[0][0]])
    print(f"watchdog: stream cut after waypoint {cut}; ticks from the last frame to the stop decision "
          f"{decision - last_frame} (timeout {WATCHDOG_TICKS}); reported {after['stale_ticks']}")
    assert decision - last_frame == WATCHDOG_TICKS + 1 == after["stale_ticks"]
    q_cmd, qd_cmd = commands(run)
    assert np.abs(qd_cmd[decision - 1]).max() > 0.01  # it was moving when the stream stopped
    assert_within_speed_and_acceleration(qd_cmd)
    held = run[run.state == 3]
    assert len(held) > 0 and np.all(commands(held)[1] == 0)
    assert np.all(commands(held)[0] == commands(held)[0][0])  # at rest, holding


def test_session_rules(plan, tmp_path):
    t, q, qd = plan
    with board(tmp_path) as (port, _):
        with LinkClient(port) as link:
            start = link.status()
            assert (start.state_name, start.flags) == ("IDLE", ("SESSION",))
            assert math.isnan(start["clearance"]) and math.isnan(start["sigma_min"])  # modular8: no capsules; no step yet
            assert np.allclose(start.q, q[0], atol=1e-6)
            off = q[0].copy()
            off[2] += 0.01
            bad = link.request("WAYPOINT", {"t_us": 0, "last": 0, "q": off, "qd": np.zeros(NDOF)}, check=False)
            assert bad.result_name == "STREAM_START"
            outside = q[0].copy()
            outside[0] = 100.0
            assert link.request("MOVE_TO_JOINTS", {"q": outside}, check=False).result_name == "BAD_VALUE"
            target = q[0] + 0.05
            moving = link.move_to_joints(target)
            assert moving.result_name == "OK"
            assert link.request("MOVE_TO_JOINTS", {"q": target}, check=False).result_name == "REFUSED_STATE"
            done = link.wait_idle()
            assert (done.state_name, done.fault_name) == ("DONE", "NONE")
            assert np.abs(done.q - target).max() <= 2 ** -23 * 2  # the wire's float32 of the target
            assert link.request("START", check=False).result_name == "REFUSED_STATE"  # not after a move
            # a frame with an old sequence number is not acted on (and not answered)
            link.serial.write(encode("STOP", link.seq, NDOF))
            after = link.status()
            assert after["out_of_order"] == 1 and after["state"] == done["state"]
        with pytest.raises(LinkError, match=f"board speaks protocol version {VERSION}"):
            import armgen.link.client as client
            original = client.encode
            client.encode = lambda *a, **k: original(*a, **{**k, "version": VERSION + 1})
            try:
                LinkClient(port)
            finally:
                client.encode = original


SERVO_PERIOD_S = 0.02  # twists at 50 Hz
SERVO_TWISTS = 150  # 3 s
SERVO_RAMP_S = 0.3  # the trace starts from rest: a twist that jumps from 0 is not reachable within qddot_max
# "The tool within 1 mm of the integrated twist" (issue 40's bar), where the twist is reachable
SERVO_TOOL_TOL_M = 1e-3
SERVO_TOOL_ORIENTATION_TOL_RAD = 1e-3  # its orientation counterpart: 1 mm at a 1 m lever


def _rotation(phi: np.ndarray) -> np.ndarray:
    """exp of the rotation vector phi (Rodrigues)."""
    angle = float(np.linalg.norm(phi))
    if angle == 0.0:
        return np.eye(3)
    k = phi / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def twist_trace(amplitude: float, seed: int = SEED) -> np.ndarray:
    """Sines of random phase and frequency per axis ([v; w]; w at twice the amplitude, in rad/s),
    ramped in from rest, sampled every SERVO_PERIOD_S (the host's zero-order hold)."""
    rng = np.random.default_rng(seed)
    t = np.arange(SERVO_TWISTS) * SERVO_PERIOD_S
    phase, freq = rng.uniform(0, 2 * np.pi, 6), rng.uniform(0.2, 0.6, 6)
    scale = np.array([1, 1, 1, 2, 2, 2]) * amplitude
    return scale * np.sin(2 * np.pi * freq * t[:, None] + phase) * np.minimum(1.0, t / SERVO_RAMP_S)[:, None]


def servo_run(tmp_path, twists):
    with board(tmp_path) as (port, csv):
        with LinkClient(port) as link:
            replies = link.servo(twists, SERVO_PERIOD_S)
            end = link.status()
    return replies, end, read_run(csv)


def servo_tool_error(replies, twists, run) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The tool's distance (m) and angle (rad) from the integrated twist at every tick of one
    servo run in the board's CSV, and the run's first and last row."""
    from armgen.robot import load_robot

    q_cmd, _ = commands(run)
    # the twist each tick followed: the one whose reply names the latest tick at or before it
    ticks = run.tick.to_numpy()
    start = [r["tick"] for r in replies]
    assert start == sorted(start)
    active = np.searchsorted(start, ticks, side="right") - 1
    first = int(np.nonzero(active >= 0)[0][0])
    rx = run.rx_frames.to_numpy()
    at_last = int(np.nonzero(ticks == start[-1])[0][0])
    last = int(np.nonzero(rx > rx[at_last])[0][0])  # the trace's last twist held until the next frame (a zero twist)
    v = twists[active[first:last], :3]
    pose = load_robot("modular8").fk(q_cmd)
    integrated = pose[first - 1, :3, 3] + np.cumsum(v * DT, axis=0)  # from the held command's tool position
    error = np.linalg.norm(pose[first:last, :3, 3] - integrated, axis=1)
    rotation = pose[first - 1, :3, :3]
    angle = np.zeros(last - first)
    for j, w in enumerate(twists[active[first:last], 3:]):  # R <- Rot(w dt) R, base frame
        rotation = _rotation(w * DT) @ rotation
        relative = pose[first + j, :3, :3] @ rotation.T
        angle[j] = np.arccos(np.clip((np.trace(relative) - 1) / 2, -1, 1))
    return error, angle, first, last


def test_servo_follows_a_recorded_twist_within_the_limits(tmp_path):
    twists = twist_trace(0.05)  # 5 cm/s, 0.1 rad/s: reachable from the task's start
    replies, end, run = servo_run(tmp_path, twists)
    assert (end.state_name, end.fault_name) == ("DONE", "NONE")
    assert_within_speed_and_acceleration(commands(run)[1])
    error, angle, first, last = servo_tool_error(replies, twists, run)
    print(f"servo: {len(twists)} twists at 50 Hz, {last - first} ticks; tool from the integrated twist: "
          f"max {error.max() * 1e3:.3g} mm, {angle.max() * 1e3:.3g} mrad")
    assert error.max() <= SERVO_TOOL_TOL_M
    assert angle.max() <= SERVO_TOOL_ORIENTATION_TOL_RAD


def test_servo_scales_an_impossible_twist_down_instead_of_breaking_the_limits(tmp_path):
    from armgen.robot import load_robot

    twists = twist_trace(2.0)  # 2 m/s, 4 rad/s: far beyond the joints' 90 deg/s, and into their limits
    _, end, run = servo_run(tmp_path, twists)
    assert (end.state_name, end.fault_name) == ("DONE", "NONE")  # no fault: scaled, never refused by the controller
    q_cmd, qd_cmd = commands(run)
    assert_within_speed_and_acceleration(qd_cmd)
    robot = load_robot("modular8")
    lo, hi = np.array([j.qlim[0] for j in robot.joints]), np.array([j.qlim[1] for j in robot.joints])
    assert np.all(q_cmd >= lo) and np.all(q_cmd <= hi)
    assert np.abs(qd_cmd).max() >= 0.9 * QDOT_MAX  # it did go as fast as the joints may


def test_watchdog_stops_a_servo_whose_host_went_silent(tmp_path):
    twists = twist_trace(0.05)[:50]  # 1 s of the trace, then nothing: the host hangs mid-motion
    with board(tmp_path) as (port, csv):
        with LinkClient(port) as link:
            for k, xdot in enumerate(twists):
                link.send("TWIST", {"xdot": xdot})
                link.poll()
                time.sleep(SERVO_PERIOD_S)
            time.sleep((WATCHDOG_TICKS + 300) * DT)
            after = link.status()
    assert (after.state_name, after.fault_name) == ("FAULT", "STALE")
    assert after["stale_ticks"] == WATCHDOG_TICKS + 1
    run = read_run(csv)
    decision = int(np.nonzero(run.link_flags.to_numpy() & 4)[0][0])
    q_cmd, qd_cmd = commands(run)
    assert np.abs(qd_cmd[decision - 1]).max() > 0.01  # it was moving
    assert_within_speed_and_acceleration(qd_cmd)
    held = run[run.state == 3]
    assert len(held) > 0 and np.all(commands(held)[1] == 0)


def test_stop_mid_stream_brings_the_arm_to_rest_within_the_acceleration_limits(plan, tmp_path):
    t, q, qd = plan
    pick = np.arange(0, len(t), WAYPOINT_EVERY)
    with board(tmp_path) as (port, csv):
        with LinkClient(port) as link:
            link.stream(t[pick], q[pick], qd[pick], lead_s=0.0, stop_after=60)  # 1.2 s in, moving
            stopped = link.stop()
            refused = link.request("MOVE_TO_JOINTS", {"q": q[0]}, check=False)  # while it stops
            end = link.wait_idle()
    assert stopped.result_name == "OK"
    assert (end.state_name, end.fault_name) == ("DONE", "NONE")
    run = read_run(csv)
    q_cmd, qd_cmd = commands(run)
    assert_within_speed_and_acceleration(qd_cmd)
    assert refused.result_name == "REFUSED_STATE"  # the ramp from ~0.3 rad/s at 6.3 rad/s^2 takes ~50 ticks
    done = run[run.state == 2]
    assert np.all(commands(done)[1] == 0) and np.all(commands(done)[0] == commands(done)[0][0])


# -- pose streams, the servo's criteria and damping, ACK replies (protocol version 2) ------------

# A pose stream against the plan's tool poses: the Hermite between 20-ms poses with the exact
# twists errs by h^4 |p''''| / 384 (< 1e-9 m on this plan), the wire's IEEE single by 1e-7 m;
# what is left is the closed loop's lag (20/s) behind the rotation vector's approximate rate and
# the acceleration limit on the self-motion's ramp: measured 2.3e-5 m. 1e-4 m is the issue's
# 1 mm servo bar ten times tighter.
POSE_STREAM_TOL_M = 1e-4
POSE_STREAM_TOL_RAD = 1e-4  # its orientation counterpart (1e-4 m at a 1 m lever)
POSE_ARRIVE_M = 1e-5 * math.sqrt(3)  # fw_link.h FW_LINK_POSE_ARRIVE_M, per axis
SERVO_EPSILON, SERVO_LAMBDA_MAX = 0.02, 0.02  # fw_link.h FW_LINK_SERVO_EPSILON, FW_LINK_SERVO_LAMBDA_MAX
# The reported sigma_min and damping travel as IEEE single (relative 6e-8); the generated
# step_fault finds sigma_min by bisection of J J^T's tridiagonal form to ~1e-12 (double build).
SIGMA_RTOL = 1e-6
# The clearance against armgen.robot's at the reported q: both travel as IEEE single (the
# clearance 6e-8 relative; q to 1.2e-7 rad, which moves a point at a lever under 1.5 m by 2e-7 m)
CLEARANCE_TOL_M = 1e-6
# Reversed at the reach, 1 s at 0.1 m/s: the tool comes back at once (the reference waited at
# most FW_LINK_SERVO_MAX_LAG_M = 10 mm ahead) but leaves the singular pose slowly while sigma_min
# is small; half the 100 mm (a reference left 285 mm beyond the reach would bring none).
REVERSED_TWISTS = 50
REVERSED_MIN_M = 0.05


def _angle(R: np.ndarray) -> np.ndarray:
    return np.arccos(np.clip((np.trace(R, axis1=-2, axis2=-1) - 1) / 2, -1, 1))


def test_stream_tool_poses_at_50_hz(plan, tmp_path):
    from armgen.robot import load_robot

    t, q, qd = plan
    robot = load_robot("modular8")
    poses = robot.fk(q)
    twists = np.einsum("kij,kj->ki", robot.jacobian(q), qd)  # the plan's tool twist, J q'
    pick = np.arange(0, len(t), WAYPOINT_EVERY)
    with board(tmp_path) as (port, csv):
        with LinkClient(port) as link:
            replies = link.stream_poses(t[pick], poses[pick], twists[pick], lead_s=LEAD_S)
            end = link.wait_idle()
    assert len(replies) == len(pick) and all(r.result_name == "OK" for r in replies)
    assert all("POSES" in r.flags for r in replies[1:-1])
    assert (end.state_name, end.fault_name) == ("DONE", "NONE") and end["underruns"] == 0
    run = read_run(csv)
    q_cmd, qd_cmd = commands(run)
    assert_within_speed_and_acceleration(qd_cmd)
    running = np.nonzero(run.state.to_numpy() == 1)[0]
    # stream tick k steps toward the pose at k dt with its twist: its command is the plan's at (k + 1) dt
    k = np.minimum(np.arange(len(running)) + 1, len(t) - 1)
    tool = robot.fk(q_cmd[running])
    position = np.linalg.norm(tool[:, :3, 3] - poses[k, :3, 3], axis=1)
    orientation = _angle(tool[:, :3, :3] @ poses[k, :3, :3].transpose(0, 2, 1))
    print(f"pose stream at 50 Hz: {len(pick)} poses, {len(running)} ticks ({len(t)} in the plan); tool from the "
          f"plan's pose: max {position.max() * 1e3:.3g} mm, {orientation.max() * 1e3:.3g} mrad; joints from the "
          f"plan's (another redundancy resolution): max {np.abs(q_cmd[running] - q[k]).max():.3g} rad")
    assert position.max() <= POSE_STREAM_TOL_M and orientation.max() <= POSE_STREAM_TOL_RAD
    last = robot.fk(q_cmd[-1])
    assert np.linalg.norm(last[:3, 3] - poses[-1, :3, 3].astype(np.float32)) <= POSE_ARRIVE_M + 1e-7
    assert np.all(qd_cmd[-1] == 0)


def test_servo_criteria_move_the_arm_in_its_null_space_only(tmp_path):
    """The same twist trace from the same start under each criterion: the tool follows the
    integrated twist in every run (the self-motion stays in the null space), and the criterion's
    own measure ends better than minimum norm's (NONE)."""
    from armgen.robot import load_robot

    robot = load_robot("modular8")
    twists = twist_trace(0.05)
    end_q, runs_replies = {}, {}
    with board(tmp_path) as (port, csv):
        with LinkClient(port) as link:
            q0 = link.status().q
            _, _, vt = np.linalg.svd(robot.jacobian(q0))
            away = q0 + 0.3 * vt[-1]  # a start displaced in J's null space: the tool where it was
            assert robot.within_limits(away)
            runs = [("NONE", q0), ("JOINT_LIMITS", q0), ("MANIPULABILITY", q0), ("JOINT_MANIPULABILITY", q0),
                    ("NONE", away), ("REST", away)]
            for criterion, start in runs:
                if np.abs(link.status().q - start).max() > 0:
                    link.move_to_joints(start)
                    link.wait_idle()
                assert link.servo_setup(criterion).result_name == "OK"
                replies = link.servo(twists, SERVO_PERIOD_S)
                end = link.status()
                assert (end.state_name, end.fault_name) == ("DONE", "NONE")
                key = (criterion, tuple(start))
                end_q[key], runs_replies[key] = end.q, replies
            assert link.request("SERVO_SETUP", {"criterion": 6, "gain": 0.0}, check=False).result_name == "BAD_VALUE"
            assert link.request("SERVO_SETUP", {"criterion": 1, "gain": -1.0}, check=False).result_name == "BAD_VALUE"
    run = read_run(csv)
    assert_within_speed_and_acceleration(commands(run)[1])
    for key, replies in runs_replies.items():
        error, angle, _, _ = servo_tool_error(replies, twists, run)
        print(f"servo criterion {key[0]}: tool from the integrated twist max {error.max() * 1e3:.3g} mm, "
              f"{angle.max() * 1e3:.3g} mrad")
        assert error.max() <= SERVO_TOOL_TOL_M and angle.max() <= SERVO_TOOL_ORIENTATION_TOL_RAD, key[0]
    h_l = {c: float(robot.joint_limit_criterion(end_q[(c, tuple(q0))])) for c in ("NONE", "JOINT_LIMITS")}
    w = {c: float(robot.manipulability(end_q[(c, tuple(q0))])) for c in ("NONE", "MANIPULABILITY")}
    h_m = {c: float(robot.joint_manipulability(end_q[(c, tuple(q0))])["H_M"]) for c in ("NONE", "JOINT_MANIPULABILITY")}
    rest = {c: float(np.linalg.norm(end_q[(c, tuple(away))] - q0)) for c in ("NONE", "REST")}
    print(f"servo criteria after the trace: H_L {h_l}, w {w}, H_M {h_m}, |q - q_start| {rest}")
    assert h_l["JOINT_LIMITS"] < h_l["NONE"]
    assert w["MANIPULABILITY"] > w["NONE"]
    assert h_m["JOINT_MANIPULABILITY"] > h_m["NONE"]
    assert rest["REST"] < 0.5 * rest["NONE"]  # gain 1/s over the 3 s trace: exp(-3) of the offset in the null space


def test_servo_into_a_singular_pose_damps_by_sigma_min_and_keeps_the_limits(tmp_path):
    """A twist that stretches the arm out of its workspace: sigma_min falls to ~0, the damping
    rises as lambda^2 = (1 - (sigma/eps)^2) lambda_max^2, the step is scaled into the limits; the
    reversed twist brings the tool back at once (the reference waited at the reach)."""
    from armgen.robot import load_robot

    robot = load_robot("modular8")
    with board(tmp_path) as (port, csv):
        with LinkClient(port) as link:
            tool = np.array(link.status()["tool"][:3])
            n = 200  # 4 s at 50 Hz, 0.1 m/s: 0.4 m outward, beyond the reach; then 1 s back
            ramp = np.minimum(1.0, np.arange(n + REVERSED_TWISTS) * SERVO_PERIOD_S / SERVO_RAMP_S)[:, None]
            twists = np.zeros((n + REVERSED_TWISTS, 6))
            outward = tool / np.linalg.norm(tool)
            twists[:, :3] = 0.1 * outward * ramp
            twists[n:, :3] *= -1
            replies = link.servo(twists, SERVO_PERIOD_S)
            end = link.status()
    assert (end.state_name, end.fault_name) == ("DONE", "NONE")
    run = read_run(csv)
    q_cmd, qd_cmd = commands(run)
    assert_within_speed_and_acceleration(qd_cmd)
    lo, hi = np.array([j.qlim[0] for j in robot.joints]), np.array([j.qlim[1] for j in robot.joints])
    assert np.all(q_cmd >= lo) and np.all(q_cmd <= hi)
    sigma = np.array([r["sigma_min"] for r in replies])
    damping = np.array([r["damping"] for r in replies])
    scale = np.array([r["servo_scale"] for r in replies])
    # each reply's step ran at the command of the tick before the reply's
    rows = np.searchsorted(run.tick.to_numpy(), [r["tick"] - 1 for r in replies])
    svd = np.array([np.linalg.svd(robot.jacobian(q_cmd[i]), compute_uv=False).min() for i in rows])
    expected = SERVO_LAMBDA_MAX * np.sqrt(np.clip(1 - (sigma / SERVO_EPSILON) ** 2, 0, None))
    print(f"servo into the reach: sigma_min from {sigma.max():.3g} to {sigma.min():.3g}, damping up to "
          f"{damping.max():.3g}, twist scaled down to {scale.min():.3g}; sigma_min vs the SVD's: max relative "
          f"difference {np.max(np.abs(sigma - svd) / svd):.2g}")
    assert sigma.min() < 0.1 * SERVO_EPSILON and sigma.max() > SERVO_EPSILON  # from a regular pose into a singular one
    assert np.allclose(sigma, svd, rtol=SIGMA_RTOL)
    assert np.allclose(damping, expected, rtol=SIGMA_RTOL, atol=SIGMA_RTOL * SERVO_LAMBDA_MAX)
    assert np.all(damping[sigma > SERVO_EPSILON] == 0)  # the exact step away from singular poses
    along = np.array([np.dot(np.array(r["tool"][:3]) - tool, outward) for r in replies])
    back = along[n - 1] - along[-1]
    print(f"servo reversed at the reach ({along[n - 1] * 1e3:.0f} mm out of the 400 mm asked): "
          f"{back * 1e3:.0f} mm back in {REVERSED_TWISTS * SERVO_PERIOD_S:g} s at 100 mm/s")
    assert back >= REVERSED_MIN_M


def test_ack_replies_for_a_100_hz_stream(plan, tmp_path):
    from armgen.link import MESSAGES

    t, q, qd = plan
    pick = np.arange(0, len(t), WAYPOINT_EVERY // 2)  # 100 Hz
    with board(tmp_path) as (port, csv):
        with LinkClient(port, replies="ACK") as link:
            replies = link.stream(t[pick], q[pick], qd[pick], lead_s=LEAD_S)
            end = link.wait_idle()
            frames = link.poll()
    assert all(set(r.values) == {f.name for f in next(m for m in MESSAGES if m.name == "ACK").fields} for r in replies)
    assert all(r.result_name == "OK" for r in replies) and len(replies) == len(pick)
    assert "q" in end.values and (end.state_name, end.fault_name) == ("DONE", "NONE")  # STATUS: TELEMETRY
    assert not [f for f in frames if f.name == "TELEMETRY"]  # nothing unsolicited
    run = read_run(csv)
    streamed = run[run.state == 1]
    k = np.rint(streamed.t_s.to_numpy() / DT).astype(int)
    deviation = np.abs(commands(streamed)[0] - q[k]).max()
    ack = next(m for m in MESSAGES if m.name == "ACK").body_size(NDOF)
    telemetry = next(m for m in MESSAGES if m.name == "TELEMETRY").body_size(NDOF)
    print(f"stream at 100 Hz with ACK replies: {len(pick)} waypoints, max joint deviation {deviation:.3g} rad; "
          f"reply bodies {ack} B instead of {telemetry} B")
    assert deviation <= STREAM_DEVIATION_TOL


def test_telemetry_reports_the_controllers_clearance():
    """On a robot with capsules and a task with [collision] (iiwa14 over its table),
    TELEMETRY.clearance is the controller's least distance: the least of the robot's checked
    distances (its self pairs and the table) at the command, as armgen.robot computes them."""
    from armgen.description.collision import PlaneObstacle
    from armgen.robot import load_robot

    proc = subprocess.Popen([str(collision_link_executable())], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        with LinkClient(proc.stdout.readline().split()[-1]) as link:
            status = link.status()
    finally:
        proc.terminate()
        proc.communicate(timeout=30)
    table = PlaneObstacle(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0))  # the task's [[obstacles]], SI
    least = float(load_robot("iiwa14").collision_distances(status.q, [table]).min())
    print(f"clearance: TELEMETRY {status['clearance']:.9g} m, armgen.robot {least:.9g} m")
    assert status["clearance"] == pytest.approx(least, abs=CLEARANCE_TOL_M)


def test_watchdog_stops_a_cut_pose_stream_within_the_acceleration_limits(plan, tmp_path):
    from armgen.robot import load_robot

    t, q, qd = plan
    robot = load_robot("modular8")
    pick = np.arange(0, len(t), WAYPOINT_EVERY)
    cut = random.Random(SEED + 1).randrange(15, 120)  # while the arm moves
    with board(tmp_path) as (port, csv):
        with LinkClient(port) as link:
            link.stream_poses(t[pick], robot.fk(q[pick]), np.einsum("kij,kj->ki", robot.jacobian(q[pick]), qd[pick]),
                              lead_s=LEAD_S, stop_after=cut)
            time.sleep(LEAD_S + (WATCHDOG_TICKS + 200) * DT)
            after = link.status()
    assert (after.state_name, after.fault_name) == ("FAULT", "STALE") and after["stale_ticks"] == WATCHDOG_TICKS + 1
    run = read_run(csv)
    decision = int(np.nonzero(run.link_flags.to_numpy() & 4)[0][0])
    q_cmd, qd_cmd = commands(run)
    assert np.abs(qd_cmd[decision - 1]).max() > 0.01  # it was moving
    assert_within_speed_and_acceleration(qd_cmd)
    held = run[run.state == 3]
    assert len(held) > 0 and np.all(commands(held)[1] == 0)
