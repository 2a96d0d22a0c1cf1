"""The host side of the link's framing: messages to frames and back (:mod:`.protocol`'s table).

COBS comes from the maintained ``cobs`` package, the CRC-32 from :func:`zlib.crc32`; the
firmware's C (``fw_link.c``) is tested bit-equal against both (tests/test_link_codec.py).
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field
from typing import Any

from cobs import cobs

from .protocol import BY_CODE, BY_NAME, CRC, HEADER, KINDS, VERSION, Message, max_body_size

DELIMITER = b"\x00"


class LinkProtocolError(ValueError):
    """A message that cannot be encoded (an unknown name, a missing or misshapen field)."""


@dataclass(frozen=True)
class Frame:
    """A decoded, valid frame."""

    version: int
    message: Message
    seq: int
    values: dict[str, Any]

    @property
    def name(self) -> str:
        return self.message.name


def _layout(message: Message, ndof: int) -> struct.Struct:
    return struct.Struct("<" + "".join(f"{f.length(ndof)}{KINDS[f.kind]}" for f in message.fields))


def encode_body(message: Message, ndof: int, values: dict[str, Any]) -> bytes:
    flat: list[Any] = []
    unknown = set(values) - {f.name for f in message.fields}
    if unknown:
        raise LinkProtocolError(f"{message.name} has no field {sorted(unknown)[0]!r}; "
                                f"its fields: {[f.name for f in message.fields]}")
    for f in message.fields:
        if f.name not in values:
            raise LinkProtocolError(f"{message.name}.{f.name} is missing")
        v = values[f.name]
        if f.is_array:
            items = list(v)
            if len(items) != f.length(ndof):
                raise LinkProtocolError(f"{message.name}.{f.name} needs {f.length(ndof)} values, got {len(items)}")
            flat += [float(x) if f.kind == "f32" else int(x) for x in items]
        else:
            flat.append(float(v) if f.kind == "f32" else int(v))
    try:
        return _layout(message, ndof).pack(*flat)
    except struct.error as exc:
        raise LinkProtocolError(f"{message.name}: {exc}") from None


def encode(name: str, seq: int, ndof: int, values: dict[str, Any] | None = None, version: int = VERSION) -> bytes:
    """The frame of message ``name`` with ``values`` (field name -> value or sequence), delimiter included."""
    if name not in BY_NAME:
        raise LinkProtocolError(f"unknown message {name!r}; the messages: {sorted(BY_NAME)}")
    message = BY_NAME[name]
    raw = HEADER.pack(version, message.code, seq & 0xFFFF) + encode_body(message, ndof, values or {})
    return cobs.encode(raw + CRC.pack(zlib.crc32(raw))) + DELIMITER


def _values(message: Message, ndof: int, body: bytes) -> dict[str, Any]:
    flat = list(_layout(message, ndof).unpack(body))
    out: dict[str, Any] = {}
    for f in message.fields:
        n = f.length(ndof)
        out[f.name] = tuple(flat[:n]) if f.is_array else flat[0]
        del flat[:n]
    return out


@dataclass
class FrameDecoder:
    """Bytes in, valid frames out, counting what was dropped (the same rules as the board)."""

    ndof: int
    counts: dict[str, int] = field(default_factory=lambda: dict.fromkeys(
        ("frames", "bad_crc", "malformed", "oversized", "wrong_version"), 0))
    _pending: bytearray = field(default_factory=bytearray)

    def feed(self, data: bytes) -> list[Frame]:
        frames: list[Frame] = []
        limit = HEADER.size + max_body_size(self.ndof) + CRC.size + 2  # COBS adds one byte a 254
        for byte in data:
            if byte != 0:
                self._pending.append(byte)
                continue
            encoded, self._pending = bytes(self._pending), bytearray()
            if not encoded:
                continue  # two delimiters in a row: an empty frame is how a sender resynchronises
            if len(encoded) > limit:
                self.counts["oversized"] += 1
                continue
            frame = self._decode(encoded)
            if frame is not None:
                frames.append(frame)
        return frames

    def _decode(self, encoded: bytes) -> Frame | None:
        try:
            raw = cobs.decode(encoded)
        except cobs.DecodeError:
            self.counts["malformed"] += 1
            return None
        if len(raw) < HEADER.size + CRC.size:
            self.counts["malformed"] += 1
            return None
        payload, (crc,) = raw[:-CRC.size], CRC.unpack(raw[-CRC.size:])
        if zlib.crc32(payload) != crc:
            self.counts["bad_crc"] += 1
            return None
        version, code, seq = HEADER.unpack(payload[:HEADER.size])
        message = BY_CODE.get(code)
        # HELLO_REPLY keeps its code and layout in every version: a board of another version
        # says which it speaks, and the client names both (the version handshake)
        if version != VERSION and message is not BY_NAME["HELLO_REPLY"]:
            self.counts["wrong_version"] += 1
            return None
        body = payload[HEADER.size:]
        if message is None or len(body) != message.body_size(self.ndof):
            self.counts["malformed"] += 1
            return None
        self.counts["frames"] += 1
        return Frame(version, message, seq, _values(message, self.ndof, body))

