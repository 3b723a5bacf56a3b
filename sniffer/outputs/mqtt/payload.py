"""Provides what goes over MQTT: `raw` messages (chunks as pcapng blocks) and JSON bodies.

A `raw` message is one pcapng enhanced packet block (little-endian, timestamps in
nanoseconds) of link type 250 (RTAC serial), so any pcapng tool can take it apart:

- interface id: the chunk's channel (the `interface` message names each channel);
- timestamp: the chunk's `t_end` (Unix seconds, or seconds from the capture's start);
- the RTAC header time: the chunk's `t_start` (microseconds), or 0 when unknown;
- the RTAC event type: RX start for bytes read; framing error, parity error, break,
  capture complete, control lines, or capture data lost for the other events;
- `epb_flags` bits 0-1: 2 (outbound) sent by the master, 1 (inbound) sent by a slave,
  0 direction unknown (what a passive tap on one port sees);
- `opt_comment`: the event and its note (`port lost: /dev/ttyUSB0 vanished`), or a
  data chunk's note;
- `epb_packetid` (option 5, 8 bytes): the publisher's count of reads, 1 for its first, so
  that a watcher sees a message the broker (or the publisher's full buffer) dropped.

`chunk_from_raw(raw_payload(c)) == c` for every chunk whose `t_start` is a whole number
of microseconds (all pcapng and live sources), so a subscriber frames what the publisher
framed, byte for byte.
"""

from __future__ import annotations

import datetime as dt
import math
import re
import struct
from dataclasses import dataclass
from typing import Any

from sniffer.model import Chunk, Direction
from sniffer.sources.linktypes import (
    BLOCK_EPB,
    EPB_DIRECTION_MASK,
    EPB_FLAG_INBOUND,
    EPB_FLAG_OUTBOUND,
    EPB_FLAGS,
    OPT_COMMENT,
    OPT_ENDOFOPT,
    RTAC_CAPTURE_COMPLETE,
    RTAC_CAPTURE_DATA_LOST,
    RTAC_DATA_RX_START,
    RTAC_EVENTS,
    RTAC_FRAMING_ERROR,
    RTAC_PARITY_ERROR,
    RTAC_SERIAL_BREAK,
    RTAC_STATUS_CHANGE,
    build_rtac,
    parse_rtac,
)

NS = 1_000_000_000
EVENT_TYPES = {
    "framing error": RTAC_FRAMING_ERROR,
    "parity error": RTAC_PARITY_ERROR,
    "break": RTAC_SERIAL_BREAK,
    "capture complete": RTAC_CAPTURE_COMPLETE,
    "control lines": RTAC_STATUS_CHANGE,
}
_FLAGS = {
    Direction.MASTER: EPB_FLAG_OUTBOUND,
    Direction.SLAVE: EPB_FLAG_INBOUND,
    Direction.UNKNOWN: 0,
}
_DIRECTIONS = {v: k for k, v in _FLAGS.items()}
_EPB_HEAD = struct.Struct("<IIIIIII")  # type, length, interface, ts high, ts low, cap, orig


class PayloadError(ValueError):
    """A `raw` message that is not a block modscope can read (the text says why)."""


def _option(code: int, value: bytes) -> bytes:
    return struct.pack("<HH", code, len(value)) + value + b"\0" * (-len(value) % 4)


EPB_PACKETID = 5


@dataclass(frozen=True, slots=True)
class RawMessage:
    """What a `raw` message carries: the chunk and the publisher's count (None if absent)."""

    chunk: Chunk
    sequence: int | None


def raw_payload(chunk: Chunk, sequence: int | None = None) -> bytes:
    """One chunk as a pcapng enhanced packet block (module doc)."""
    t_end = max(chunk.t_end, 0.0)
    whole = math.floor(t_end)
    ticks = whole * NS + round((t_end - whole) * NS)
    start = 0.0 if chunk.t_start is None else max(chunk.t_start, 0.0)
    if chunk.event:
        event = EVENT_TYPES.get(chunk.event, RTAC_CAPTURE_DATA_LOST)
        comment = chunk.event + (f": {chunk.note}" if chunk.note else "")
    else:
        event, comment = RTAC_DATA_RX_START, chunk.note
    packet = build_rtac(start, chunk.data, event, 0)
    options = _option(EPB_FLAGS, struct.pack("<I", _FLAGS[chunk.direction]))
    if comment:
        options += _option(OPT_COMMENT, comment.encode("utf-8"))
    if sequence is not None:
        options += _option(EPB_PACKETID, struct.pack("<Q", sequence))
    options += struct.pack("<HH", OPT_ENDOFOPT, 0)
    body = (
        struct.pack(
            "<IIIII", chunk.channel, ticks >> 32, ticks & 0xFFFFFFFF, len(packet), len(packet)
        )
        + packet
        + b"\0" * (-len(packet) % 4)
        + options
    )
    total = 12 + len(body)
    return struct.pack("<II", BLOCK_EPB, total) + body + struct.pack("<I", total)


def chunk_from_raw(payload: bytes) -> Chunk:
    """The chunk a `raw` message carries. PayloadError names what is wrong."""
    return read_raw(payload).chunk


def read_raw(payload: bytes) -> RawMessage:
    """The chunk and sequence a `raw` message carries. PayloadError names what is wrong."""
    if len(payload) < _EPB_HEAD.size + 4:
        raise PayloadError(f"{len(payload)} bytes, shorter than an enhanced packet block")
    kind, total, channel, high, low, caplen, _orig = _EPB_HEAD.unpack_from(payload)
    if kind != BLOCK_EPB:
        raise PayloadError(f"block type 0x{kind:08X}, not an enhanced packet block (6)")
    if total != len(payload) or total % 4:
        raise PayloadError(f"block length {total} does not match the message's {len(payload)}")
    start = _EPB_HEAD.size
    if start + caplen > total - 4:
        raise PayloadError(f"packet of {caplen} bytes does not fit a block of {total}")
    record = parse_rtac(payload[start : start + caplen])
    if record is None:
        raise PayloadError(f"packet of {caplen} bytes is shorter than the 12-byte RTAC header")
    flags = 0
    comment = ""
    sequence: int | None = None
    pos = start + caplen + (-caplen % 4)
    while pos + 4 <= total - 4:
        code, length = struct.unpack_from("<HH", payload, pos)
        pos += 4
        if code == OPT_ENDOFOPT or pos + length > total - 4:
            break
        value = payload[pos : pos + length]
        if code == EPB_FLAGS and length >= 4:
            (flags,) = struct.unpack_from("<I", value)
        elif code == OPT_COMMENT:
            comment = value.decode("utf-8", errors="replace")
        elif code == EPB_PACKETID and length == 8:
            (sequence,) = struct.unpack("<Q", value)
        pos += length + (-length % 4)
    ticks = (high << 32) | low
    t_end = ticks / NS  # int / int: correctly rounded, so whole-ns times come back equal
    t_start = record.seconds if record.seconds > 0 else None
    direction = _DIRECTIONS.get(flags & EPB_DIRECTION_MASK, Direction.UNKNOWN)
    if record.event == RTAC_DATA_RX_START:
        chunk = Chunk(record.data, t_end, t_start, channel, direction, note=comment)
        return RawMessage(chunk, sequence)
    event, note = RTAC_EVENTS.get(record.event, ("data lost", ""))
    if comment:
        said, sep, rest = comment.partition(": ")
        event, note = (said, rest) if sep else (comment, "")
    chunk = Chunk(record.data, t_end, t_start, channel, direction, event=event, note=note)
    return RawMessage(chunk, sequence)


# -- names and times ---------------------------------------------------------------------------


def slug(name: str) -> str:
    """A topic level from a register name: `04.9A: Power Factor` -> `04-9a-power-factor`."""
    text = re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-")
    return text or "value"


def iso_time(t: float) -> str | None:
    """ISO 8601 UTC time of a Unix time; None for times relative to the capture's start."""
    if t < 86400 * 366:  # seconds from the start of a capture, not a date
        return None
    stamp = dt.datetime.fromtimestamp(t, dt.UTC)
    return stamp.isoformat(timespec="microseconds").replace("+00:00", "Z")


@dataclass(frozen=True, slots=True)
class RegisterKey:
    """A value's place on a unit: table, address and name (names can repeat)."""

    unit: int
    table: str
    address: int
    name: str


class Slugs:
    """Topic levels for the named registers of each unit, unique within the unit: a name
    that repeats gets its table and address appended (`voltage-input-registers-2`)."""

    def __init__(self) -> None:
        self._by_key: dict[RegisterKey, str] = {}
        self._taken: dict[int, dict[str, RegisterKey]] = {}

    def add(self, key: RegisterKey) -> str:
        found = self._by_key.get(key)
        if found is not None:
            return found
        taken = self._taken.setdefault(key.unit, {})
        base = slug(key.name)
        chosen = base
        if chosen in taken:
            chosen = f"{base}-{slug(key.table)}-{key.address}"
        taken[chosen] = key
        self._by_key[key] = chosen
        return chosen


def json_value(value: Any) -> Any:
    """A value JSON can carry: NaN and infinities become None."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
