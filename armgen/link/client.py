"""The host side of the link: a client on pyserial, for a serial port (``/dev/ttyUSB0``,
``COM3``), a pseudo-terminal (the host firmware's ``/dev/pts/N``) or TCP (``socket://host:port``,
pyserial's URL handlers).

    with LinkClient("/dev/ttyUSB0") as link:
        print(link.status().state_name)
        link.move_to_joints(q)
        link.wait_idle()            # sends STATUS as the watchdog's heartbeat meanwhile
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import serial

from ..errors import ArmgenError
from .codec import Frame, FrameDecoder, encode
from .protocol import CRITERIA, FAULT_NAMES, FLAGS, REPLIES, RESULTS, STATE_NAMES, VERSION

REPLY_MESSAGES = ("TELEMETRY", "ACK")  # the board's answers to a host frame (ack_seq names it)
HANDSHAKE_NDOF = 0  # HELLO and HELLO_REPLY have no per-joint field: decodable before the board says ndof
TELEMETRY_KEPT = 1000  # the latest TELEMETRY frames a session keeps (self.telemetry)
HEARTBEATS_PER_TIMEOUT = 4  # frames per watchdog timeout while a stream's waypoints are sparser
DEFAULT_TIMEOUT_S = 2.0
# A servo at rest: the closed loop's last corrections on a zero twist decay as exp(-20 t) and
# never reach exactly 0; below this (rad/s, m/s) STOP's jump to velocity 0 is nothing.
SERVO_REST_SPEED = 1e-6  # a reply takes one tick plus the wire; 2 s covers a loaded host running the board


class LinkError(ArmgenError):
    """No answer, a refused handshake or a port that cannot be opened (exit 4, as a failed tool)."""

    exit_code = 4


class CommandRefused(LinkError):
    """The board refused a command (its result names why: the state, a value, the stream, STALE): exit 3."""

    exit_code = 3


@dataclass(frozen=True)
class Telemetry:
    """One TELEMETRY frame, or an ACK (its subset: tick, motion_tick, ack_seq, result, state, fault,
    link_flags, waypoints_free): ``values`` by the protocol's field names, and their readings."""

    seq: int
    values: dict[str, Any]

    def __getitem__(self, name: str) -> Any:
        return self.values[name]

    @property
    def state_name(self) -> str:
        s = self.values["state"]
        return STATE_NAMES[s] if s < len(STATE_NAMES) else str(s)

    @property
    def fault_name(self) -> str:
        f = self.values["fault"]
        return FAULT_NAMES[f] if f < len(FAULT_NAMES) else str(f)

    @property
    def result_name(self) -> str:
        r = self.values["result"]
        return RESULTS[r][0] if r < len(RESULTS) else str(r)

    @property
    def flags(self) -> tuple[str, ...]:
        return tuple(name for bit, (name, _) in enumerate(FLAGS) if self.values["link_flags"] >> bit & 1)

    @property
    def q(self) -> np.ndarray:
        return np.array(self.values["q"])


class LinkClient:
    """A session with a board: the handshake on opening, then commands and telemetry."""

    def __init__(self, port: str, *, baudrate: int = 115200, timeout: float = DEFAULT_TIMEOUT_S,
                 telemetry_period: int = 0, replies: str = "TELEMETRY"):
        try:
            self.serial = serial.serial_for_url(port, baudrate=baudrate, timeout=0.005)
        except (serial.SerialException, ValueError) as exc:
            raise LinkError(f"cannot open {port}: {exc}") from None
        self.port = port
        self.timeout = timeout
        self.seq = 0
        self.telemetry: deque[Telemetry] = deque(maxlen=TELEMETRY_KEPT)
        self._decoder = FrameDecoder(HANDSHAKE_NDOF)
        reply_names = [name for name, _ in REPLIES]
        if replies not in reply_names:
            raise LinkError(f"replies={replies!r}: choose one of {', '.join(reply_names)}")
        self.replies = replies
        self.hello = self._handshake(telemetry_period, reply_names.index(replies))
        self.ndof = self.hello["ndof"]
        self._decoder = FrameDecoder(self.ndof)

    # -- plumbing
    def close(self) -> None:
        self.serial.close()

    def __enter__(self) -> LinkClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def send(self, name: str, values: dict[str, Any] | None = None) -> int:
        """Send one message; returns its sequence number."""
        self.seq = (self.seq + 1) & 0xFFFF
        self.serial.write(encode(name, self.seq, self.ndof, values))
        return self.seq

    def poll(self) -> list[Frame]:
        """The frames received so far (telemetry also appended to ``self.telemetry``)."""
        data = self.serial.read(self.serial.in_waiting or 1)
        frames = self._decoder.feed(data)
        self.telemetry.extend(Telemetry(f.seq, f.values) for f in frames if f.name in REPLY_MESSAGES)
        return frames

    def _await(self, accept, what: str) -> Frame:
        deadline = time.monotonic() + self.timeout
        while time.monotonic() < deadline:
            for frame in self.poll():
                if accept(frame):
                    return frame
        counts = {k: v for k, v in self._decoder.counts.items() if v and k != "frames"}
        raise LinkError(f"no {what} from {self.port} within {self.timeout:g} s"
                        + (f" (dropped frames: {counts})" if counts else ""))

    def _handshake(self, telemetry_period: int, replies: int) -> dict[str, Any]:
        self.ndof = HANDSHAKE_NDOF
        self.serial.reset_input_buffer()
        self.serial.write(b"\x00")  # ends any partial frame on the wire: the board resynchronises
        self.seq = 0
        self.serial.write(encode("HELLO", self.seq, HANDSHAKE_NDOF, {"telemetry_period": telemetry_period,
                                                                   "replies": replies}))
        try:
            reply = self._await(lambda f: f.name == "HELLO_REPLY", "HELLO_REPLY")
        except LinkError as exc:
            raise LinkError(f"{exc}: is it an armgen board speaking protocol version {VERSION}?") from None
        if not reply.values["accepted"]:
            raise LinkError(f"the board speaks protocol version {reply.values['version']}, this armgen {VERSION}")
        return dict(reply.values)

    # -- requests
    def request(self, name: str, values: dict[str, Any] | None = None, *, check: bool = True) -> Telemetry:
        """Send a message and wait for the reply that answers it (TELEMETRY, or an ACK in a session
        opened with ``replies="ACK"``; STATUS: always TELEMETRY); ``check``: a result other than OK
        raises LinkError naming it."""
        seq = self.send(name, values)
        frame = self._await(lambda f: f.name in REPLY_MESSAGES and f.values["ack_seq"] == seq, f"reply to {name}")
        reply = Telemetry(frame.seq, frame.values)
        if check and reply.result_name != "OK":
            raise CommandRefused(f"{name} refused: {reply.result_name} ({dict(RESULTS)[reply.result_name]}); "
                            f"state {reply.state_name}, fault {reply.fault_name}")
        return reply

    def status(self) -> Telemetry:
        return self.request("STATUS")

    def start(self) -> Telemetry:
        return self.request("START")

    def stop(self) -> Telemetry:
        return self.request("STOP")

    def move_to_pose(self, pose: Sequence[Sequence[float]] | np.ndarray) -> Telemetry:
        """To a tool pose (4x4 homogeneous, m): the board's IK, then a move within the limits."""
        T = np.asarray(pose, dtype=float)
        if T.shape != (4, 4):
            raise LinkError(f"a pose is 4x4, got shape {T.shape}")
        return self.request("MOVE_TO_POSE", {"pose": T.flatten(order="F")})

    def move_to_joints(self, q: Sequence[float]) -> Telemetry:
        return self.request("MOVE_TO_JOINTS", {"q": list(q)})

    def wait_idle(self, heartbeat_s: float = 0.02, limit_s: float = 600.0) -> Telemetry:
        """STATUS every heartbeat_s (it feeds the watchdog) until the arm no longer moves."""
        end = time.monotonic() + limit_s
        while True:
            reply = self.status()
            if reply.state_name not in ("RUNNING", "DEGRADED") or time.monotonic() > end:
                return reply
            time.sleep(heartbeat_s)

    def stream(self, t: Sequence[float], q: np.ndarray, qd: np.ndarray, *, lead_s: float = 0.1,
               stop_after: int | None = None) -> list[Telemetry]:
        """Stream timed joint waypoints in real time, each sent lead_s before its time (the board
        interpolates between them), the last marked as the stream's end; then wait until the arm
        is at rest. ``stop_after``: send only that many waypoints, then nothing (the watchdog's
        test: the stream cut). Returns the replies to the waypoints."""
        t = np.asarray(t, dtype=float)
        q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
        if q.shape != (len(t), self.ndof) or qd.shape != q.shape:
            raise LinkError(f"waypoints need {self.ndof} joint values each: q {q.shape}, qd {qd.shape}, t {t.shape}")
        return self._stream("WAYPOINT", t, [{"q": q[k], "qd": qd[k]} for k in range(len(t))], lead_s, stop_after)

    def stream_poses(self, t: Sequence[float], poses: np.ndarray, twists: np.ndarray, *, lead_s: float = 0.1,
                     stop_after: int | None = None) -> list[Telemetry]:
        """Stream timed tool poses (``poses``: n 4x4 homogeneous, m; ``twists``: n rows
        [v; w], base frame, m/s and rad/s) as :meth:`stream` does joint waypoints: the board
        interpolates them in task space and follows them by its resolved-rate step within the
        limits. Returns the replies to the poses."""
        t = np.asarray(t, dtype=float)
        poses, twists = np.asarray(poses, dtype=float), np.asarray(twists, dtype=float)
        if poses.shape != (len(t), 4, 4) or twists.shape != (len(t), 6):
            raise LinkError(f"pose waypoints need a 4x4 pose and a 6-value twist each: poses {poses.shape}, "
                            f"twists {twists.shape}, t {t.shape}")
        tool = np.concatenate([poses[:, :3, 3], poses[:, :3, :3].transpose(0, 2, 1).reshape(len(t), 9)], axis=1)
        return self._stream("POSE_WAYPOINT", t, [{"tool": tool[k], "twist": twists[k]} for k in range(len(t))],
                            lead_s, stop_after)

    def _stream(self, message: str, t: np.ndarray, points: list[dict[str, Any]], lead_s: float,
                stop_after: int | None) -> list[Telemetry]:
        if len(t) == 0 or t[0] != 0.0 or np.any(np.diff(t) <= 0):
            raise LinkError("waypoint times must start at 0 and increase")
        count = len(t) if stop_after is None else min(stop_after, len(t))
        replies: list[Telemetry] = []
        sent: dict[int, int] = {}
        heartbeat_s = self.hello["watchdog_ticks"] * self.hello["dt_us"] * 1e-6 / HEARTBEATS_PER_TIMEOUT
        capacity = self.hello["waypoint_capacity"]

        marks: dict[int, int] = {}  # seq of each frame sent -> waypoints sent up to and with it

        def board_full() -> bool:
            """Flow control (a board slower than the wall clock is not overrun): the waypoints the
            latest reply (to a waypoint or a heartbeat) says are buffered, plus those sent after
            the frame it answers; a lost reply makes the estimate late, never stuck."""
            latest = next((r for r in reversed(self.telemetry) if r["ack_seq"] in marks), None)
            if latest is None:
                return len(sent) >= capacity - 1
            in_flight = len(sent) - marks[latest["ack_seq"]]
            return capacity - latest["waypoints_free"] + in_flight >= capacity - 1

        start = last_sent = time.monotonic()
        for k in range(count):
            due = start + t[k] - lead_s
            deadline = time.monotonic() + self.timeout
            while time.monotonic() < due or board_full():
                if time.monotonic() > deadline and board_full():
                    raise LinkError(f"the board took no waypoint for {self.timeout:g} s (its buffer stays full)")
                if time.monotonic() - last_sent > heartbeat_s:  # sparse waypoints: keep the watchdog fed
                    marks[self.send("STATUS")] = len(sent)
                    last_sent = time.monotonic()
                self._collect(sent, replies)
                time.sleep(0.001)
            values = {"t_us": int(round(t[k] * 1e6)), "last": int(k == len(t) - 1), **points[k]}
            seq = self.send(message, values)
            sent[seq] = k
            marks[seq] = len(sent)
            last_sent = time.monotonic()
            self._collect(sent, replies)
        deadline = time.monotonic() + self.timeout
        while len(replies) < count and time.monotonic() < deadline:
            self._collect(sent, replies)
        refused = [r for r in replies if r.result_name != "OK"]
        if refused:
            r = refused[0]
            raise CommandRefused(f"waypoint {sent[r['ack_seq']]} refused: {r.result_name} "
                            f"({dict(RESULTS)[r.result_name]})")
        return replies

    def servo(self, twists: np.ndarray, period_s: float) -> list[Telemetry]:
        """Send one tool twist ([v; w], base frame, m/s, rad/s) every period_s (servo: the board
        follows each within its limits until the next), then a zero twist until the arm is at
        rest, then STOP. Returns the replies to the twists, in order (``tick``: the tick from
        which the board followed each)."""
        twists = np.asarray(twists, dtype=float)
        if twists.ndim != 2 or twists.shape[1] != 6:
            raise LinkError(f"twists are rows of 6 values [vx vy vz wx wy wz], got shape {twists.shape}")
        replies: list[Telemetry] = []
        sent: dict[int, int] = {}
        start = time.monotonic()
        for k, xdot in enumerate(twists):
            while time.monotonic() < start + k * period_s:
                self._collect(sent, replies)
                time.sleep(0.001)
            sent[self.send("TWIST", {"xdot": xdot})] = k
        deadline = time.monotonic() + self.timeout
        while len(replies) < len(twists) and time.monotonic() < deadline:
            self._collect(sent, replies)
        refused = [r for r in replies if r.result_name != "OK"]
        if refused:
            raise CommandRefused(f"twist {sent[refused[0]['ack_seq']]} refused: {refused[0].result_name}")
        self.request("TWIST", {"xdot": np.zeros(6)})
        deadline = time.monotonic() + self.timeout
        while max(abs(v) for v in self.status()["qd"]) > SERVO_REST_SPEED and time.monotonic() < deadline:
            time.sleep(0.005)
        self.stop()
        return sorted(replies, key=lambda r: sent[r["ack_seq"]])

    def _collect(self, sent: dict[int, int], replies: list[Telemetry]) -> None:
        """The replies to the frames ``sent``: the first frame naming each (an unsolicited
        TELEMETRY of ``telemetry_period`` names the last frame too, after its reply)."""
        answered = {r["ack_seq"] for r in replies}
        for frame in self.poll():
            seq = frame.values.get("ack_seq")
            if frame.name in REPLY_MESSAGES and seq in sent and seq not in answered:
                replies.append(Telemetry(frame.seq, frame.values))
                answered.add(seq)

    def servo_setup(self, criterion: str = "TASK", gain: float = 0.0) -> Telemetry:
        """The self-motion of SERVO and pose streams from now on: a criterion of
        :data:`armgen.link.protocol.CRITERIA` by name, its gain (0: the criterion's default)."""
        names = [name for name, _ in CRITERIA]
        if criterion not in names:
            raise LinkError(f"criterion {criterion!r}: choose one of {', '.join(names)}")
        return self.request("SERVO_SETUP", {"criterion": names.index(criterion), "gain": gain})

    def watch(self, period_s: float = 0.1) -> Iterator[Telemetry]:
        """Telemetry every period_s (STATUS requests: they also feed the watchdog)."""
        while True:
            yield self.status()
            time.sleep(period_s)
