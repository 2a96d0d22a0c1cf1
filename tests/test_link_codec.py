"""The link's codec: one message table makes both sides, and they agree bit for bit.

The Python side is the ``cobs`` package and :func:`zlib.crc32` (independent, maintained
implementations); the board's C (fw_link.c's COBS and CRC-32, the generated fw_link_msgs.c) is
run under ASan/UBSan by host/link_fuzz.c: frames Python encodes come back from the C byte for
byte, COBS of random buffers (long runs without a zero included) equals the package's, and the
parser fuzz acts on every intact frame and on nothing else.
"""

from __future__ import annotations

import random
import re
import struct
import subprocess
import zlib
from pathlib import Path

import pytest
from cobs import cobs
from hypothesis import given, settings, strategies as st

from armgen import firmware as fw
from armgen.link import c_codec
from armgen.link.codec import FrameDecoder, LinkProtocolError, encode
from armgen.link.protocol import CRC, HEADER, MESSAGES, NDOF, VERSION, max_body_size

from conftest import require_tool
from link_builds import REPO, link_executable, task as link_task

NDOF_MODULAR8 = 8
SEED = 40
ECHO_MESSAGES = 400  # random messages through the C and back: every type ~40 times
QUICK_FUZZ_CHUNKS = 20_000  # the test's share of the fuzz; benchmarks/bench_link.py runs >= 10^6


def run_c(*args: str, data: bytes = b"") -> bytes:
    proc = subprocess.run([str(link_executable("link_fuzz")), *args], input=data, capture_output=True, timeout=300)
    assert proc.returncode == 0 and not proc.stderr, proc.stderr.decode()[-3000:]
    return proc.stdout


def random_values(message, rng: random.Random) -> dict:
    """Every field filled; floats include NaN with a payload, ±inf, -0 and subnormals as bit patterns."""
    def f32() -> float:
        bits = rng.getrandbits(32) if rng.random() < 0.5 else struct.unpack("<I", struct.pack("<f", rng.uniform(-5, 5)))[0]
        return struct.unpack("<f", struct.pack("<I", bits))[0]
    out = {}
    for f in message.fields:
        one = (lambda: f32()) if f.kind == "f32" else (lambda: rng.getrandbits({"u8": 8, "u16": 16, "u32": 32}[f.kind]))
        out[f.name] = [one() for _ in range(f.length(NDOF_MODULAR8))] if f.is_array else one()
    return out


def test_generated_c_is_the_table():
    """fw_link_msgs.{h,c} in the stub are what the table and the templates make today."""
    for name, text in c_codec.render().items():
        assert (c_codec.stub_dir() / name).read_text(encoding="utf-8") == text, \
            f"{name} is stale: python -m armgen.link.c_codec"


def test_python_frames_come_back_from_c_bit_for_bit():
    rng = random.Random(SEED)
    frames = []
    for k in range(ECHO_MESSAGES):
        message = MESSAGES[k % len(MESSAGES)]
        frames.append(encode(message.name, rng.getrandbits(16), NDOF_MODULAR8, random_values(message, rng)))
    back = run_c("echo", data=b"".join(frames))
    assert back == b"".join(frames)
    # and what the C wrote decodes in Python to the same bits
    decoded = FrameDecoder(NDOF_MODULAR8).feed(back)
    assert len(decoded) == len(frames)


def test_a_frame_the_c_cannot_decode_is_refused_by_python_too():
    good = encode("STATUS", 7, NDOF_MODULAR8)
    bad_crc = bytearray(cobs.decode(good[:-1]))
    bad_crc[-1] ^= 0x40
    frames = [cobs.encode(bytes(bad_crc)) + b"\x00", b"\x05\x01\x02\x03\x00"]
    assert run_c("echo", data=b"".join(frames)) == b"\x00\x00"
    decoder = FrameDecoder(NDOF_MODULAR8)
    assert decoder.feed(b"".join(frames)) == []
    assert decoder.counts["bad_crc"] == 1 and decoder.counts["malformed"] == 1


@pytest.mark.parametrize("length", [0, 1, 253, 254, 255, 508, 1000])
def test_cobs_of_the_c_equals_the_package(length):
    rng = random.Random(length)
    for zeros in (0.0, 0.05, 0.5):  # no zero at all: the 254-byte blocks
        data = bytes(0 if rng.random() < zeros else rng.randrange(1, 256) for _ in range(length))
        encoded = run_c("cobs", data=data)
        assert encoded == cobs.encode(data)
        if length:
            assert run_c("uncobs", data=encoded) == data


@settings(max_examples=200, deadline=None)
@given(st.sampled_from([m for m in MESSAGES]), st.integers(0, 0xFFFF), st.randoms(use_true_random=False))
def test_python_round_trip(message, seq, rng):
    values = random_values(message, rng)
    (frame,) = FrameDecoder(NDOF_MODULAR8).feed(encode(message.name, seq, NDOF_MODULAR8, values))
    assert frame.seq == seq and frame.message is message
    for name, v in values.items():
        got = frame.values[name]
        want = v if isinstance(v, list) else [v]
        got = list(got) if isinstance(got, tuple) else [got]
        pack = struct.Struct("<f") if isinstance(want[0], float) else None
        if pack:
            assert [pack.pack(x) for x in got] == [pack.pack(x) for x in want]  # bits, NaN payloads included
        else:
            assert got == want


def test_frame_layout_is_the_documented_one():
    """version | type | seq (LE) | body | CRC-32 of all that (LE), COBS, 0x00 — by hand."""
    frame = encode("LOCK", 0x1234, NDOF_MODULAR8, {"locked": 0x05})
    raw = bytes([VERSION, 0x07, 0x34, 0x12, 0x05, 0, 0, 0])
    assert frame == cobs.encode(raw + struct.pack("<I", zlib.crc32(raw))) + b"\x00"
    assert HEADER.size + CRC.size == 8


def test_bad_messages_name_the_field():
    with pytest.raises(LinkProtocolError, match="MOVE_TO_JOINTS.q needs 8 values"):
        encode("MOVE_TO_JOINTS", 1, NDOF_MODULAR8, {"q": [0.0] * 7})
    with pytest.raises(LinkProtocolError, match="unknown message"):
        encode("JUMP", 1, NDOF_MODULAR8)
    with pytest.raises(LinkProtocolError, match="has no field 'speed'"):
        encode("STATUS", 1, NDOF_MODULAR8, {"speed": 1})


def test_python_decoder_drops_other_versions_and_oversized_frames():
    decoder = FrameDecoder(NDOF_MODULAR8)
    other = encode("STATUS", 1, NDOF_MODULAR8, version=VERSION + 1)
    oversized = bytes([1 + k % 255 for k in range(2 * max_body_size(NDOF_MODULAR8))]) + b"\x00"
    assert decoder.feed(other + oversized + encode("STATUS", 2, NDOF_MODULAR8)) != []
    assert decoder.counts["wrong_version"] == 1 and decoder.counts["oversized"] == 1
    # HELLO_REPLY keeps its layout in every version: the handshake reads a board of another one
    old_board = {"accepted": 0, "version": VERSION - 1, "ndof": 8, "dt_us": 1000, "watchdog_ticks": 100,
                 "waypoint_capacity": 32}
    [reply] = FrameDecoder(0).feed(encode("HELLO_REPLY", 0, 0, old_board, version=VERSION - 1))
    assert reply.values == old_board and reply.version == VERSION - 1


# A pose file's twists are central differences of its samples: for x = a sin(2 pi f t) and a yaw
# at a constant rate, the difference errs by h^2 |d3x/dt3| / 6 = (0.01 s)^2 (2 pi)^3 0.1 / 6 = 4e-4
# m/s (a = 0.1 m, f = 1 Hz) and not at all on the constant rate.
POSE_FILE_STEP_S = 0.01
POSE_FILE_TWIST_TOL = 5e-4


@settings(max_examples=25, deadline=None)
@given(roll=st.floats(-3, 3), pitch=st.floats(-1.5, 1.5), yaw0=st.floats(-3, 3), rate=st.floats(-2, 2))
def test_pose_file_waypoints_against_the_closed_form(roll, pitch, yaw0, rate):
    import numpy as np

    from armgen.description import rpy_matrix
    from armgen.link import plan_pose_waypoints

    t = np.arange(0, 1.0 + 1e-9, POSE_FILE_STEP_S)
    x = 0.1 * np.sin(2 * np.pi * t)
    yaw = yaw0 + rate * t
    columns = ["t_s", "x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad"]
    data = np.column_stack([t, x, 0.2 + 0 * t, 0.3 + 0 * t, roll + 0 * t, pitch + 0 * t, yaw])
    times, poses, twists = plan_pose_waypoints(columns, data, 50.0)
    assert np.allclose(times, np.arange(51) * 0.02)
    k = np.rint(times / POSE_FILE_STEP_S).astype(int)
    assert np.allclose(poses[:, :3, 3], data[k, 1:4])
    assert np.allclose(poses[:, :3, :3], [rpy_matrix(roll, pitch, y) for y in yaw[k]])
    # R = Rz(yaw) Ry Rx: yaw turns about the base's z, so omega = (0, 0, rate) in the base frame
    inner = slice(1, -1)
    assert np.allclose(twists[inner, 0], 0.2 * np.pi * np.cos(2 * np.pi * times[inner]), atol=POSE_FILE_TWIST_TOL)
    assert np.allclose(twists[inner, 1:3], 0.0)
    assert np.allclose(twists[inner, 3:], [0.0, 0.0, rate], atol=1e-9)
    assert np.all(twists[[0, -1]] == 0)  # rest to rest


def test_parser_fuzz_quick():
    """Intact, mutated, random, over-long, other-version, replayed, board-type and wrong-length
    frames, under ASan/UBSan: every intact frame is acted on, nothing else is."""
    out = run_c("fuzz", str(QUICK_FUZZ_CHUNKS), str(SEED)).decode()
    summary = dict(line[2:].split() for line in out.splitlines() if line.startswith("# "))
    assert int(summary["chunks"]) == QUICK_FUZZ_CHUNKS
    assert int(summary["violations"]) == 0
    # each kind of bad frame was sent and counted by its own rule
    for key in ("bad_crc", "malformed", "oversized", "wrong_version", "out_of_order"):
        assert int(summary[key]) > 0, key
    assert int(summary["commands"]) > 0 and int(summary["setpoints"]) > 0  # valid frames were acted on


def test_ndof_arrays_size_every_message():
    for message in MESSAGES:
        per_joint = sum(4 for f in message.fields if f.count == NDOF)
        assert message.body_size(9) - message.body_size(8) == per_joint


LINK_SOURCES = ("fw_link.c", "fw_link_msgs.c")  # the board's side; the host runners are test harnesses
LINK_FILES = {"fw_link.c", "fw_link.h", "fw_link_msgs.c", "fw_link_msgs.h"}


def link_misra_deviations() -> list[tuple[set[str], set[str]]]:
    """(rules, files) per row of docs/link.md's deviation table."""
    text = (REPO / "docs" / "link.md").read_text(encoding="utf-8")
    section = text.split("## MISRA C:2012 deviations", 1)[1]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and re.fullmatch(r"[\d.]+(, [\d.]+)*", cells[0]):
            rows.append(({r.strip() for r in cells[0].split(",")}, {f.strip() for f in cells[1].split(",")}))
    return rows


def test_link_misra_findings_are_documented_deviations(tmp_path):
    """cppcheck's MISRA C:2012 addon over the link's board sources, for modular8 and for iiwa14
    with its dynamics: every finding in the link's files is a row of docs/link.md's table, and
    every row is still needed."""
    cppcheck = require_tool("cppcheck")
    rows = link_misra_deviations()
    assert rows, "the deviation table is missing from docs/link.md"
    builds = {"modular8": (link_task(), []),
              "iiwa14": (fw.task_from_file(REPO / "examples" / "iiwa14_fault_circle_wln.toml"), ["-DCTRL_HAS_DYNAMICS=1"])}
    stub = fw.FIRMWARE_DIR
    findings = set()
    for name, (task, defines) in builds.items():
        gen_dir = REPO / "generated" / name
        fw.write_task_files(task, tmp_path / name, gen_dir)
        proc = subprocess.run([cppcheck, "--addon=misra", "--std=c99", "-q", "--template={file}:{line}:{id}",
                               f"-DCTRL_ROBOT={name}", f"-DCTRL_ROBOT_UC={name.upper()}",
                               f'-DCTRL_ROBOT_HEADER="{name}.h"', f"-D{name.upper()}_USE_FLOAT=1", "-DFW_USE_FLOAT=1",
                               *defines, f"-I{stub}", f"-I{gen_dir}", f"-I{tmp_path / name}",
                               *(str(stub / s) for s in LINK_SOURCES)], capture_output=True, text=True, timeout=900)
        found = {(Path(f).name, rule) for f, _, rule in
                 re.findall(r"^(.+?):(\d+):misra-c2012-([\d.]+)$", proc.stdout + proc.stderr, re.M)}
        assert found, f"cppcheck's MISRA addon reported nothing for {name}: is the addon installed?"
        findings |= {(f, rule) for f, rule in found if f in LINK_FILES}
    undocumented = sorted(f"{f} rule {rule}" for f, rule in findings
                          if not any(rule in rules and f in files for rules, files in rows))
    assert not undocumented, "MISRA findings outside docs/link.md's deviation list:\n" + "\n".join(undocumented)
    stale = [sorted(rules) for rules, files in rows if not any(rule in rules and f in files for f, rule in findings)]
    assert not stale, f"deviation rows that no finding needs any more: {stale}"


@settings(max_examples=300, deadline=None)
@given(st.lists(st.one_of(st.binary(max_size=300), st.sampled_from([b"\x00", b"\x00\x00"])), max_size=20),
       st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=5))
def test_python_decoder_takes_any_bytes(chunks, seqs):
    """Garbage between valid frames: the decoder never raises, returns only valid frames, and
    every valid frame sent after a delimiter comes out."""
    decoder = FrameDecoder(NDOF_MODULAR8)
    frames = []
    for chunk in chunks:
        frames += decoder.feed(chunk)
    sent = [encode("STATUS", s, NDOF_MODULAR8) for s in seqs]
    got = decoder.feed(b"\x00" + b"".join(sent))
    assert [f.seq for f in got[-len(seqs):]] == seqs and all(f.name == "STATUS" for f in got[-len(seqs):])
    for f in frames:  # a frame found in garbage (a CRC-32 collision, ~never) is still a whole message
        (again,) = FrameDecoder(NDOF_MODULAR8).feed(encode(f.name, f.seq, NDOF_MODULAR8, dict(f.values)))
        assert (again.name, again.seq) == (f.name, f.seq)


def _compile_fw_link(tmp_path, *defines: str) -> str:
    """fw_link.c under the strict flags with these -D; the symbols its object needs (nm -u)."""
    require_tool("gcc")
    stub = REPO / "armgen" / "data" / "firmware_stub"
    obj = tmp_path / "fw_link.o"
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-Wdouble-promotion",
                    "-Wfloat-conversion", "-Wshadow", *defines, f"-I{stub}", f"-I{REPO / 'generated' / 'modular8'}",
                    "-c", str(stub / "fw_link.c"), "-o", str(obj)], check=True, capture_output=True, text=True)
    return subprocess.run(["nm", "-u", str(obj)], check=True, capture_output=True, text=True).stdout


@pytest.mark.parametrize("precision", ["0", "1"])
def test_fw_link_builds_for_a_robot_without_step_fault(precision, tmp_path):
    """A robot whose generated code lacks step_fault and ft_index is built with
    -DCTRL_HAS_FAULT_TOLERANT=0: the link falls back to step_gpm (no sigma_min) under the strict
    flags, and its object calls neither."""
    undefined = _compile_fw_link(tmp_path, "-DCTRL_HAS_FAULT_TOLERANT=0", f"-DMODULAR8_USE_FLOAT={precision}")
    assert "modular8_step_gpm_from_jacobian" in undefined
    assert "step_fault" not in undefined and "ft_index" not in undefined


@pytest.mark.parametrize("precision", ["0", "1"])
def test_fw_link_builds_with_a_collision_model(precision, tmp_path):
    """-DCTRL_HAS_COLLISION=1 (a robot with capsules): TELEMETRY.clearance reads
    ctrl_output.clearance, under the strict flags in both precisions (its value:
    tests/test_link_pty.py on iiwa14)."""
    undefined = _compile_fw_link(tmp_path, "-DCTRL_HAS_COLLISION=1", f"-DMODULAR8_USE_FLOAT={precision}")
    assert "modular8_step_fault_from_jacobian" in undefined
