"""Provides the frame store: every frame, noise span and event of a capture in compact columns.

A day at 115200 baud is some 30 million frames, so frames are not Python objects: each
column is an `array` and the bytes of all frames sit in one `bytearray`. Dissection
happens later, on demand, for the rows somebody looks at.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass

from sniffer.framing import Flag, Kind, ascii_body

NO_PARTNER = -1


class Status:
    """What became of a transaction (stored per frame, for requests and answers alike)."""

    NONE = 0  # noise, events, frames not (yet) part of a transaction
    OK = 1
    EXCEPTION = 2
    TIMEOUT = 3  # a request that got no answer
    ORPHAN = 4  # an answer with no request
    BROADCAST = 5  # a request to address 0: no answer expected
    OPEN = 6  # a request still waiting (live), or the capture ended first

    NAMES = ("", "ok", "exception", "timeout", "orphan", "broadcast", "open")


@dataclass(frozen=True, slots=True)
class FrameView:
    """One stored row, materialised for display or export."""

    index: int
    raw: bytes
    t: float
    t_end: float
    kind: Kind
    unit: int
    function: int  # without the exception bit
    exception: bool
    flags: int
    channel: int
    partner: int
    status: int

    @property
    def ascii(self) -> bool:
        return bool(self.flags & Flag.ASCII)

    @property
    def check_ok(self) -> bool:
        return self.kind != Kind.NOISE and not self.flags & (Flag.CHECK_BAD | Flag.NON_HEX)

    def body(self) -> bytes:
        """Unit byte and PDU, without the CRC or LRC (empty for noise and events)."""
        if self.kind in (Kind.NOISE, Kind.EVENT):
            return b""
        if self.ascii:
            decoded = ascii_body(self.raw)
            return decoded[:-1] if decoded else b""
        return self.raw[:-2]


class FrameStore:
    """Columns of frames in capture order. `append` is a framer's sink."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.offset = array("Q")
        self.length = array("I")
        self.t = array("d")
        self.t_end = array("d")
        self.kind = array("B")
        self.unit = array("B")
        self.fc = array("B")  # the function byte as sent (exception bit included)
        self.flags = array("I")
        self.channel = array("B")
        self.partner = array("q")
        self.status = array("B")
        self.notes: dict[int, str] = {}  # event texts and other per-row notes
        self.bytes_total = 0

    def __len__(self) -> int:
        return len(self.t)

    def append(self, raw: bytes, t0: float, t1: float, kind: int, flags: int, channel: int) -> None:
        self.offset.append(len(self.data))
        self.length.append(len(raw))
        self.data += raw
        self.bytes_total += len(raw)
        self.t.append(t0)
        self.t_end.append(t1)
        self.kind.append(kind)
        if kind == Kind.NOISE or kind == Kind.EVENT:
            self.unit.append(0)
            self.fc.append(0)
        elif flags & Flag.ASCII:
            body = ascii_body(raw)
            self.unit.append(body[0] if body and len(body) > 0 else 0)
            self.fc.append(body[1] if body and len(body) > 1 else 0)
        else:
            self.unit.append(raw[0])
            self.fc.append(raw[1])
        self.flags.append(flags)
        self.channel.append(channel)
        self.partner.append(NO_PARTNER)
        self.status.append(Status.NONE)

    def add_event(self, t: float, text: str, channel: int = 0) -> None:
        self.notes[len(self)] = text
        self.append(b"", t, t, int(Kind.EVENT), 0, channel)

    def raw(self, i: int) -> bytes:
        start = self.offset[i]
        return bytes(self.data[start : start + self.length[i]])

    def view(self, i: int) -> FrameView:
        fc = self.fc[i]
        return FrameView(
            index=i,
            raw=self.raw(i),
            t=self.t[i],
            t_end=self.t_end[i],
            kind=Kind(self.kind[i]),
            unit=self.unit[i],
            function=fc & 0x7F,
            exception=bool(fc & 0x80) and self.kind[i] != Kind.NOISE,
            flags=self.flags[i],
            channel=self.channel[i],
            partner=self.partner[i],
            status=self.status[i],
        )

    def memory_bytes(self) -> int:
        """Bytes held by the columns (what a capture costs in memory)."""
        cols = (self.offset, self.length, self.t, self.t_end, self.kind, self.unit, self.fc)
        more = (self.flags, self.channel, self.partner, self.status)
        return len(self.data) + sum(c.itemsize * len(c) for c in (*cols, *more))
