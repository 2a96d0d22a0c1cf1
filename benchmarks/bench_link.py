"""The host link (issue 40's bar, docs/link.md), on modular8's host firmware (double, ASan/UBSan)
with the configuration of examples/modular8_ptp_two_segments.toml (1 ms ticks):

1. parser fuzz: >= 10^6 chunks fed a byte at a time to fw_link on a running controller — intact
   frames, mutated copies, random bytes, over-long frames, and frames with a valid CRC-32 but
   another version, a replayed sequence number, a board's type or a wrong length. Crashes (the
   sanitizers abort) and violations (a chunk that changed the count of frames acted on by
   anything but 1 for an intact frame and 0 otherwise) must both be 0;
2. streaming over a pseudo-terminal in real time: the PTP plan's samples as waypoints at 10, 25,
   50 and 100 Hz, the max joint deviation of the 1 kHz commands from the plan's 1 ms samples;
3. the watchdog: the stream cut after a seeded random waypoint, five times: ticks from the last
   valid frame to the stop decision (timeout 500 ticks) and the peak deceleration of the stop
   over qddot_max;
4. the Cortex-M4F (float, the firmware's own build, QEMU -icount): executed instructions per
   received TWIST frame (the bytes into the ring, the decode and dispatch, the TELEMETRY reply, or
   the ACK reply of a session opened with replies = ACK) and per servo tick (fw_link's step and the controller's SETPOINT tick), bench/link_bench.c.

    python benchmarks/bench_link.py [--chunks 1000000] [--seed 40] [--quick]

``--quick``: 20 000 chunks, 50 Hz only, one cut (a smoke run, seconds).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from link_builds import TASK, builder, link_executable, task  # noqa: E402

from armgen import firmware as fw  # noqa: E402
from armgen.link import LinkClient  # noqa: E402
from armgen.planning.tasks import load_task, run_task  # noqa: E402

DT = 0.001
NDOF = 8
QDDOT_MAX = math.radians(360)  # robots/modular8.toml qddlim
WATCHDOG_MS = 500  # a loaded host's pauses between frames must not fire it before the cut
WATCHDOG_TICKS = WATCHDOG_MS  # at 1 ms
LEAD_S = 0.3


def fuzz(chunks: int, seed: int) -> dict[str, str]:
    started = time.perf_counter()
    proc = subprocess.run([str(link_executable("link_fuzz")), "fuzz", str(chunks), str(seed)], capture_output=True,
                          text=True, timeout=3600)
    summary = dict(line[2:].split() for line in proc.stdout.splitlines() if line.startswith("# "))
    summary["crashes"] = "0" if proc.returncode == 0 and not proc.stderr else f"exit {proc.returncode}: {proc.stderr[-300:]}"
    summary["seconds"] = f"{time.perf_counter() - started:.1f}"
    return summary


def the_plan():
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    document, _ = load_task(TASK)
    result = run_task(document, str(TASK))
    cols = list(result.columns)
    return (result.data[:, 0], result.data[:, [cols.index(f"theta_j{i}_rad") for i in range(1, NDOF + 1)]],
            result.data[:, [cols.index(f"omega_j{i}_rad_s") for i in range(1, NDOF + 1)]])


def run_board(action) -> pd.DataFrame:
    with tempfile.TemporaryDirectory() as folder:
        csv = Path(folder) / "run.csv"
        proc = subprocess.Popen([str(link_executable("link")), "--csv", str(csv), "--watchdog-ms", str(WATCHDOG_MS)],
                                stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        try:
            port = proc.stdout.readline().split()[-1]
            with LinkClient(port) as link:
                action(link)
        finally:
            time.sleep(0.05)
            proc.terminate()
            proc.communicate(timeout=30)
        run = pd.read_csv(csv)
    return run.iloc[:-1] if run.iloc[-1].isna().any() else run


def stream(plan, rate_hz: float) -> tuple[float, int]:
    t, q, qd = plan
    every = int(round(1 / (rate_hz * DT)))
    pick = np.arange(0, len(t), every)
    if pick[-1] != len(t) - 1:
        pick = np.append(pick, len(t) - 1)
    run = run_board(lambda link: (link.stream(t[pick], q[pick], qd[pick], lead_s=LEAD_S), link.wait_idle()))
    streamed = run[run.state == 1]
    k = np.rint(streamed.t_s.to_numpy() / DT).astype(int)
    q_cmd = streamed[[f"q{i}" for i in range(1, NDOF + 1)]].to_numpy()
    return float(np.abs(q_cmd - q[k]).max()), len(pick)


def cut(plan, after: int) -> tuple[int, float]:
    t, q, qd = plan
    pick = np.arange(0, len(t), 20)

    def action(link):
        link.stream(t[pick], q[pick], qd[pick], lead_s=LEAD_S, stop_after=after)
        time.sleep(LEAD_S + (WATCHDOG_TICKS + 200) * DT)

    run = run_board(action)
    flags, rx = run.link_flags.to_numpy(), run.rx_frames.to_numpy()
    decision = int(np.nonzero(flags & 4)[0][0])
    last_frame = int(np.nonzero(rx == rx[decision])[0][0])
    qd_cmd = run[[f"qd{i}" for i in range(1, NDOF + 1)]].to_numpy()[decision - 1:]
    return int(run.tick[decision] - run.tick[last_frame]), float(np.abs(np.diff(qd_cmd, axis=0)).max() / DT / QDDOT_MAX)


def m4_costs() -> dict[str, float]:
    """Instructions per part (mean, and max where it matters) from bench/link_bench.c under QEMU."""
    elf = builder().executable(dataclasses.replace(fw.ARM_VARIANT, runner="link_bench"), task(), name="link_bench")
    proc = subprocess.run(["qemu-system-arm", *fw.QEMU_MACHINE, *fw.QEMU_ICOUNT, "-kernel", str(elf)],
                          capture_output=True, text=True, timeout=600)
    text = proc.stdout + proc.stderr
    if proc.returncode != 0 or "# end" not in text:
        raise SystemExit(f"bench/link_bench.c failed under QEMU (exit {proc.returncode}):\n{text[-2000:]}")
    kv = dict(line[2:].split() for line in text.splitlines() if line.startswith("# ") and len(line.split()) == 3)
    per_count = int(kv["calib_insns"]) / int(kv["calib_ticks"])
    out = {"frame_bytes": float(kv["frame_bytes"]), "sizeof_link": float(kv["sizeof_link"])}
    if kv["pose_rejected"] != "0" or kv["state"] != "DONE":
        raise SystemExit(f"bench/link_bench.c: the pose stream was refused or did not end: {text[-2000:]}")
    for part in ("rx", "input_frame", "input_servo", "ctrl", "output_reply", "output_quiet", "output_ack", "input_pose"):
        out[part] = int(kv[f"{part}_sum"]) / int(kv[f"{part}_count"]) * per_count
        out[part + "_max"] = int(kv[f"{part}_max"]) * per_count
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--chunks", type=int, default=1_000_000)
    parser.add_argument("--seed", type=int, default=40)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    chunks = 20_000 if args.quick else args.chunks
    rates = (50.0,) if args.quick else (10.0, 25.0, 50.0, 100.0)
    cuts = 1 if args.quick else 5

    print("== 1. parser fuzz (ASan/UBSan)")
    f = fuzz(chunks, args.seed)
    print(f"| chunks | intact | mutated | random | over-long | other version | replayed | board type | wrong length |")
    print(f"| {f['chunks']} | {f['intact']} | {f['mutated']} | {f['random']} | {f['oversized_sent']} | "
          f"{f['other_version']} | {f['replayed']} | {f['board_type']} | {f['wrong_length']} |")
    print(f"counted by the board: bad CRC {f['bad_crc']}, malformed {f['malformed']}, oversized {f['oversized']}, "
          f"other version {f['wrong_version']}, out of order {f['out_of_order']}")
    print(f"fuzz: {f['chunks']} chunks in {f['seconds']} s: crashes {f['crashes']}, violations {f['violations']} "
          f"(commands {f['commands']}, setpoints {f['setpoints']} of which {f['pose_setpoints']} of pose streams, "
          f"mutated but intact {f['mutated_but_intact']})")

    plan = the_plan()
    print("\n== 2. a plan streamed over a pseudo-terminal (modular8 PTP, 3 s, commands at 1 kHz)")
    print("| waypoints per s | waypoints | max joint deviation from the plan [rad] |")
    for rate in rates:
        deviation, count = stream(plan, rate)
        print(f"| {rate:g} | {count} | {deviation:.3g} |")

    print(f"\n== 3. the watchdog (timeout {WATCHDOG_TICKS} ticks): the stream cut")
    print("| cut after waypoint | ticks from the last frame to the stop decision | peak deceleration / qddot_max |")
    rng = random.Random(args.seed)
    for _ in range(cuts):
        after = rng.randrange(15, 120)
        ticks, decel = cut(plan, after)
        print(f"| {after} | {ticks} | {decel:.4f} |")

    print("\n== 4. Cortex-M4F instructions (float, QEMU -icount; a SysTick count is 40 instructions)")
    m = m4_costs()
    decode = m["input_frame"] - m["input_servo"]
    print(f"| part | mean | max |")
    print(f"| a TWIST frame's {m['frame_bytes']:.0f} bytes into the ring (fw_link_receive) | {m['rx']:.0f} | {m['rx_max']:.0f} |")
    print(f"| decode, checks and dispatch of the frame (input on its tick - a servo step) | {decode:.0f} | |")
    print(f"| the TELEMETRY reply (tool pose, packing, CRC-32, COBS) | {m['output_reply']:.0f} | {m['output_reply_max']:.0f} |")
    print(f"| the ACK reply instead (HELLO.replies = ACK) | {m['output_ack']:.0f} | {m['output_ack_max']:.0f} |")
    print(f"| a servo step (fw_link_input without a frame) | {m['input_servo']:.0f} | {m['input_servo_max']:.0f} |")
    print(f"| a pose-stream step (fw_link_input without a frame: Hermite, rotation, the servo's step) | "
          f"{m['input_pose']:.0f} | {m['input_pose_max']:.0f} |")
    print(f"| the controller's SETPOINT tick | {m['ctrl']:.0f} | {m['ctrl_max']:.0f} |")
    print(f"| fw_link_output with nothing to send | {m['output_quiet']:.0f} | {m['output_quiet_max']:.0f} |")
    print(f"per received frame: {m['rx'] + decode + m['output_reply']:.0f} instructions "
          f"({m['rx'] + decode + m['output_ack']:.0f} with ACK replies); per servo tick: "
          f"{m['input_servo'] + m['ctrl'] + m['output_quiet']:.0f} instructions; sizeof(fw_link) {m['sizeof_link']:.0f} B")


if __name__ == "__main__":
    main()
