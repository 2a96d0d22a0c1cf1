"""The link's messages, defined once: this table makes both the Python codec (:mod:`.codec`) and
the C packers and parsers of the firmware (``fw_link_msgs.{h,c}``, :mod:`.c_codec`).

A frame on the byte stream (UART, USB CDC, TCP, a pseudo-terminal) is

    COBS( version u8 | type u8 | seq u16 | body | CRC-32 u32 ) 0x00

little-endian; the CRC-32 (IEEE 802.3, zlib's) covers version, type, seq and body; COBS removes
every zero byte from the frame, so the 0x00 delimiter resynchronises a receiver after any error
(docs/link.md: why COBS and a CRC-32). A body is the message's fields in the order listed,
each a fixed size: ``ndof`` arrays have the robot's joint count (the board says it in
HELLO_REPLY), so every message of a robot has one length and a frame of another length is
malformed.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from importlib import resources

VERSION = 2  # the protocol's version: the first byte of every frame, checked by both ends (2: ACK, pose waypoints,
# SERVO_SETUP, TELEMETRY's sigma_min, damping and clearance)
HEADER = struct.Struct("<BBH")  # version, type, seq
CRC = struct.Struct("<I")
NDOF = "ndof"  # an array of one value per joint

KINDS = {"u8": "B", "u16": "H", "u32": "I", "f32": "f"}  # struct codes, little-endian
C_TYPES = {"u8": "uint8_t", "u16": "uint16_t", "u32": "uint32_t", "f32": "float"}


@dataclass(frozen=True)
class Field:
    name: str
    kind: str  # u8 | u16 | u32 | f32
    count: int | str = 1  # 1: a scalar; n: an array of n; NDOF: one per joint
    doc: str = ""

    def length(self, ndof: int) -> int:
        return ndof if self.count == NDOF else int(self.count)

    @property
    def is_array(self) -> bool:
        return self.count != 1


@dataclass(frozen=True)
class Message:
    name: str
    code: int
    sender: str  # "host" | "board"
    fields: tuple[Field, ...]
    doc: str

    def body_size(self, ndof: int) -> int:
        return sum(struct.calcsize("<" + KINDS[f.kind]) * f.length(ndof) for f in self.fields)


# Results of a host frame, in TELEMETRY.result of the reply (the reply's ack_seq names the frame).
RESULTS = (
    ("OK", "acted on"),
    ("REFUSED_STATE", "not accepted in the controller's state (e.g. START after MOVE_TO, MOVE_TO while moving)"),
    ("BAD_VALUE", "a value is non-finite, outside the joint limits or above a speed limit"),
    ("STREAM_START", "a stream's first waypoint is not at t = 0 or not at the held command"),
    ("STREAM_ORDER", "a waypoint not later than the one before it"),
    ("STREAM_FULL", "the board's waypoint buffer is full: send later"),
    ("STALE", "the watchdog has latched STALE: nothing is acted on until the controller is re-initialised"),
)
# TELEMETRY.link_flags bits
FLAGS = (
    ("SESSION", "a host has said HELLO in this protocol version"),
    ("STREAMING", "a waypoint stream is being followed"),
    ("STALE", "the watchdog fired: stopping, then the controller's STALE fault"),
    ("SERVOING", "a TWIST is being followed"),
    ("POSES", "the stream being followed is of tool poses (POSE_WAYPOINT)"),
)
# HELLO.replies: what answers a host frame other than HELLO and STATUS (STATUS: always TELEMETRY)
REPLIES = (
    ("TELEMETRY", "the full TELEMETRY"),
    ("ACK", "an ACK (seq, result, state, fault, flags, free waypoints, ticks): 16 bytes instead of ~190"),
)
# SERVO_SETUP.criterion: the self-motion of SERVO and of a pose stream (a redundant arm's null space)
CRITERIA = (
    ("TASK", "the compiled-in task's own choice (its null-space method and gain; joint limits for a joint-space task)"),
    ("NONE", "minimum norm: no self-motion"),
    ("JOINT_LIMITS", "descent of the Zghal joint-limit criterion H_L: away from the joint limits"),
    ("MANIPULABILITY", "ascent of the manipulability w = sqrt(det(J J^T)): away from singular poses"),
    ("JOINT_MANIPULABILITY", "ascent of the joint manipulability H_M = sum omega_i: fault tolerance to a locked joint"),
    ("REST", "descent of H_R = |q - q_start|^2 / 2: back toward the start configuration"),
)

MESSAGES: tuple[Message, ...] = (
    Message("HELLO", 0x01, "host", (
        Field("telemetry_period", "u16", doc="ticks between unsolicited TELEMETRY frames; 0: only replies"),
        Field("replies", "u8", doc="the reply to a command frame: 0 TELEMETRY, 1 ACK (REPLIES; STATUS: TELEMETRY)"),
    ), "opens a session (the version handshake); its seq is the base of the host's sequence"),
    Message("START", 0x02, "host", (), "runs the task compiled into the firmware (CTRL_CMD_START)"),
    Message("STOP", 0x03, "host", (), "ends the motion: a moving arm ramps to rest within qddot_max, then the "
            "controller holds (CTRL_CMD_STOP); ends a stream or a servo"),
    Message("MOVE_TO_POSE", 0x04, "host", (
        Field("pose", "f32", 16, "the tool pose, 4x4 homogeneous, column-major, m"),
    ), "to a tool pose: the on-board IK, then a joint-space move within the limits (CTRL_CMD_MOVE_TO)"),
    Message("MOVE_TO_JOINTS", 0x05, "host", (
        Field("q", "f32", NDOF, "the joint target, rad (m for a prismatic joint)"),
    ), "to a joint target: the same joint-space move within the limits (CTRL_CMD_MOVE_TO_JOINTS)"),
    Message("WAYPOINT", 0x06, "host", (
        Field("t_us", "u32", doc="time from the stream's start, microseconds (the first waypoint: 0)"),
        Field("last", "u8", doc="1: the stream ends here (the arm stops at this waypoint)"),
        Field("q", "f32", NDOF, "joint positions, rad (m)"),
        Field("qd", "f32", NDOF, "joint velocities, rad/s (m/s)"),
    ), "one timed waypoint of a stream, interpolated on board at every tick (cubic Hermite) within the limits"),
    Message("LOCK", 0x07, "host", (
        Field("locked", "u32", doc="bit i: joint i's drive reports a lock (permanent: ctrl_input.locked)"),
    ), "a lock report, handed to the controller on every tick from now on"),
    Message("STATUS", 0x08, "host", (), "asks for TELEMETRY; also the heartbeat that keeps the watchdog fed"),
    Message("TWIST", 0x09, "host", (
        Field("xdot", "f32", 6, "the tool's twist [v; w] in the base frame, m/s and rad/s (the robot's task rows)"),
    ), "servo: the tool moves at this twist (resolved rate with damping, scaled down to the joint limits) until the next"),
    Message("POSE_WAYPOINT", 0x0A, "host", (
        Field("t_us", "u32", doc="time from the stream's start, microseconds (the first waypoint: 0)"),
        Field("last", "u8", doc="1: the stream ends here (the arm stops at this pose)"),
        Field("tool", "f32", 12, "the tool pose: position (m), then the rotation, column-major (TELEMETRY.tool's layout)"),
        Field("twist", "f32", 6, "the tool's twist [v; w] at t, base frame, m/s and rad/s"),
    ), "one timed tool pose of a stream: interpolated in task space at every tick and followed by the resolved-rate step "
       "within the limits (its clock slowed where they scale the step down)"),
    Message("SERVO_SETUP", 0x0B, "host", (
        Field("criterion", "u8", doc="the self-motion (CRITERIA): 0 the task's own choice"),
        Field("gain", "f32", doc="its gain (alpha = +-gain grad H); 0: the criterion's default"),
    ), "the null-space criterion of SERVO and of pose streams, from the next one on"),
    Message("HELLO_REPLY", 0x81, "board", (
        Field("accepted", "u8", doc="1: the session is open; 0: the host's version differs (see version)"),
        Field("version", "u8", doc="the board's protocol version"),
        Field("ndof", "u8", doc="joints of the robot"),
        Field("dt_us", "u32", doc="the control period, microseconds"),
        Field("watchdog_ticks", "u32", doc="ticks without a valid frame after which a moving arm is stopped (STALE)"),
        Field("waypoint_capacity", "u16", doc="waypoints the board buffers"),
    ), "the answer to HELLO"),
    Message("TELEMETRY", 0x82, "board", (
        Field("tick", "u32", doc="the link's tick count since the board started"),
        Field("motion_tick", "u32", doc="the controller's tick index within the motion"),
        Field("state", "u8", doc="ctrl_state"),
        Field("fault", "u8", doc="ctrl_fault (STALE from the watchdog's decision on)"),
        Field("link_flags", "u8", doc="bits: " + ", ".join(f"{i} {n}" for i, (n, _) in enumerate(FLAGS))),
        Field("result", "u8", doc="the result of the frame ack_seq names (RESULTS)"),
        Field("ack_seq", "u16", doc="seq of the last host frame acted on or refused"),
        Field("waypoints_free", "u16", doc="free slots of the waypoint buffer"),
        Field("q", "f32", NDOF, "the joint command, rad (m)"),
        Field("qd", "f32", NDOF, "the joint velocity command, rad/s (m/s)"),
        Field("tool", "f32", 12, "the tool pose of the command: position (m), then the rotation, column-major"),
        Field("pos_err", "f32", doc="|p_d - p|, m (resolved-rate modes)"),
        Field("ori_err", "f32", doc="orientation error, rad (resolved-rate modes)"),
        Field("locked", "u32", doc="bit i: joint i frozen as locked"),
        Field("rx_frames", "u32", doc="valid frames received"),
        Field("bad_crc", "u32", doc="frames whose CRC-32 did not match"),
        Field("malformed", "u32", doc="frames that are no COBS, too short, of an unknown type or a wrong length"),
        Field("oversized", "u32", doc="frames longer than the largest message"),
        Field("out_of_order", "u32", doc="frames whose seq is not newer than the last one (repeats, replays)"),
        Field("wrong_version", "u32", doc="frames of another protocol version"),
        Field("no_session", "u32", doc="valid frames before a HELLO"),
        Field("rejected", "u32", doc="valid frames refused (result other than OK)"),
        Field("rx_overflow", "u32", doc="bytes dropped because the receive ring was full"),
        Field("seq_gaps", "u32", doc="host frames missing between two received (lost on the wire)"),
        Field("underruns", "u32", doc="ticks a stream reached its last waypoint before the stream's end"),
        Field("stale_ticks", "u32", doc="ticks from the last valid frame to the watchdog's stop decision (0: none)"),
        Field("sigma_min", "f32", doc="sigma_min of J at the last resolved-rate step of SERVO or a pose stream (NaN: none)"),
        Field("damping", "f32", doc="the damping lambda of that step (0 away from singular poses)"),
        Field("servo_scale", "f32", doc="the scale of that step's twist, (0, 1]: below 1 where the limits slowed it"),
        Field("clearance", "f32", doc="the controller's least clearance to the obstacles, m (NaN: not computed)"),
    ), "the board's state: the reply to STATUS (and, in TELEMETRY replies, to every valid host frame), and every "
       "telemetry_period ticks"),
    Message("ACK", 0x83, "board", (
        Field("tick", "u32", doc="the link's tick count since the board started"),
        Field("motion_tick", "u32", doc="the controller's tick index within the motion"),
        Field("ack_seq", "u16", doc="seq of the host frame this answers"),
        Field("result", "u8", doc="its result (RESULTS)"),
        Field("state", "u8", doc="ctrl_state"),
        Field("fault", "u8", doc="ctrl_fault (STALE from the watchdog's decision on)"),
        Field("link_flags", "u8", doc="TELEMETRY's link_flags"),
        Field("waypoints_free", "u16", doc="free slots of the waypoint buffer"),
    ), "the light reply to a command frame in a session opened with replies = 1"),
)

BY_NAME = {m.name: m for m in MESSAGES}
BY_CODE = {m.code: m for m in MESSAGES}


def max_body_size(ndof: int) -> int:
    return max(m.body_size(ndof) for m in MESSAGES)


def _controller_enum(prefix: str) -> tuple[str, ...]:
    """The names of a controller enum (``CTRL_FAULT_``, ``CTRL_STATE_``) by value, read from the
    firmware's controller.h: the one place they are defined."""
    text = resources.files("armgen.data").joinpath("firmware_stub/controller.h").read_text(encoding="utf-8")
    pairs = {int(v): n for n, v in re.findall(rf"\b{prefix}(\w+)\s*=\s*(\d+)", text)}
    return tuple(pairs.get(i, "?") for i in range(max(pairs) + 1))


FAULT_NAMES = _controller_enum("CTRL_FAULT_")
STATE_NAMES = _controller_enum("CTRL_STATE_")
