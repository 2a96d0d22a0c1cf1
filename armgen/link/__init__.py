"""The host link (issue 40, docs/link.md): a versioned binary protocol between a host and the
controller on the board, over any byte stream —

- :mod:`.protocol`: the messages, defined once (this table makes both sides);
- :mod:`.codec`: the host's framing (COBS, CRC-32), messages to frames and back;
- :mod:`.c_codec`: the board's packers and parsers, ``fw_link_msgs.{h,c}`` of the firmware stub;
- :mod:`.client`: a session with a board on pyserial (serial port, pseudo-terminal, TCP);
- :mod:`.waypoints`: a plan's joint samples or tool poses as a stream's timed waypoints.

The board's side is ``armgen/data/firmware_stub/fw_link.{h,c}``.
"""

from .client import CommandRefused, LinkClient, LinkError, Telemetry
from .codec import Frame, FrameDecoder, LinkProtocolError, encode
from .protocol import FAULT_NAMES, MESSAGES, STATE_NAMES, VERSION
from .waypoints import plan_pose_waypoints, plan_waypoints

__all__ = ["CommandRefused", "FAULT_NAMES", "MESSAGES", "STATE_NAMES", "VERSION", "Frame", "FrameDecoder", "LinkClient", "LinkError",
           "LinkProtocolError", "Telemetry", "encode", "plan_pose_waypoints", "plan_waypoints"]
