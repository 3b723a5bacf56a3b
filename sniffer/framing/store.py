"""Provides the frame store: every frame, noise span and event of a capture in compact columns.

A day at 115200 baud is some 30 million frames, so frames are not Python objects: each
column is an `array` and the bytes of all frames sit in one `bytearray`. Dissection
happens later, on demand, for the rows somebody looks at.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass
from typing import Any

from dissectors import mbap
from dissectors.envelope import ascii_body
from sniffer import core
from sniffer.model import Stamp
from sniffer.vocab import BAD_CHECK, Flag, Kind, Status

NO_PARTNER = -1
# plain ints for per-row tests: `int & IntFlag` goes through the enum's operator and
# makes a new member each time, many times the cost of `&` on two ints
_ASCII, _MBAP, _BAD_CHECK = int(Flag.ASCII), int(Flag.MBAP), int(BAD_CHECK)
_NOISE, _EVENT = int(Kind.NOISE), int(Kind.EVENT)
_KINDS = {int(k): k for k in Kind}


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
        return bool(self.flags & _ASCII)

    @property
    def mbap(self) -> bool:
        """A Modbus TCP frame: raw is the MBAP header and the PDU."""
        return bool(self.flags & _MBAP)

    @property
    def check_ok(self) -> bool:
        return self.kind != _NOISE and not self.flags & _BAD_CHECK

    def body(self) -> bytes:
        """Unit byte and PDU, without the CRC or LRC or MBAP header (empty for noise and
        events)."""
        if self.kind == _NOISE or self.kind == _EVENT:
            return b""
        if self.flags & _MBAP:
            return mbap.body(self.raw)
        if self.flags & _ASCII:
            decoded = ascii_body(self.raw)
            return decoded[:-1] if decoded else b""
        return self.raw[:-2]


class FrameStore:
    """Columns of rows (frames, noise spans, events) in capture order.

    The bytes of each channel are kept once, as read, in `streams[channel]`; a row
    points into its channel's stream by offset and length. Framers append rows; pairing
    fills `partner` and `status`, which `sync()` keeps as long as the other columns.
    """

    def __init__(self, streams: dict[int, bytearray] | None = None) -> None:
        self.streams: dict[int, bytearray] = streams if streams is not None else {}
        self.offset = array("Q")
        self.length = array("H")  # frames are at most 513 bytes, noise spans 256
        self.t = array("d")
        self.t_end = array("d")
        self.kind = array("B")
        self.unit = array("B")
        self.fc = array("B")  # the function byte as sent (exception bit included)
        self.flags = array("I")
        self.channel = array("B")
        self.partner = array("i")
        self.status = array("B")
        self.notes: dict[int, str] = {}  # event texts and other per-row notes
        self.fill_channel = 0  # the channel of rows appended without one (see sync)
        # what the row times mean (the source's stamps) and how fine they are, in
        # seconds (0: not known); latencies are measured with them (pairing.measure)
        self.stamps = Stamp.READ_END
        self.resolution = 0.0
        # network captures, per channel: the sender's and the server's `ip:port` (see
        # sniffer.framing.tcp.NetPipeline)
        self.peers: dict[int, str] = {}
        self.servers: dict[int, str] = {}
        # both sides of a gateway: row -> its link (`peer` row, `delay_ms`, `verdict`,
        # `text`; see sniffer.analysis.gateway.mark_links)
        self.links: dict[int, dict[str, object]] = {}

    def __len__(self) -> int:
        return len(self.t)

    def stream(self, channel: int) -> bytearray:
        """The bytes read on `channel` so far (created empty on first use)."""
        found = self.streams.get(channel)
        if found is None:
            found = self.streams[channel] = bytearray()
        return found

    @property
    def bytes_total(self) -> int:
        return sum(len(s) for s in self.streams.values())

    def sync(self) -> None:
        """Complete rows a framer's fast path appended with seven columns only: flags
        (none), channel (`fill_channel`), partner (none) and status (none) are added in
        bulk, which is cheaper than four appends a row."""
        n = len(self.t)
        missing = n - len(self.flags)
        if missing > 0:
            self.flags.frombytes(bytes(4 * missing))
            self.channel.frombytes(bytes([self.fill_channel]) * missing)
        missing = n - len(self.status)
        if missing > 0:
            self.status.frombytes(bytes(missing))
            # -1 is all bits set in any byte order: bytes, not a list of ints (which the
            # array converts one by one, an argument parse each, ~300 instructions a row)
            self.partner.frombytes(_ALL_ONES * missing)

    def pair_rows(self, pairs: array[int]) -> None:
        """Record answered requests: `pairs` (int64) is flat, request row then answer row."""
        partner, status, fc = self.partner, self.status, self.fc
        fast = core.FAST
        if fast is not None:  # the compiled copy of the loop below (one step a pair)
            fast.pair_rows(partner, status, fc, pairs)
            return
        for k in range(0, len(pairs), 2):
            req = pairs[k]
            resp = pairs[k + 1]
            partner[req] = resp
            partner[resp] = req
            status[req] = status[resp] = Status.EXCEPTION if fc[resp] & 0x80 else Status.OK

    def add_row(
        self, channel: int, offset: int, length: int, t0: float, t1: float, kind: int, flags: int
    ) -> None:
        self.sync()
        stream = self.streams[channel]
        unit = fc = 0
        if kind != Kind.NOISE and kind != Kind.EVENT:
            if flags & Flag.ASCII:
                body = ascii_body(bytes(stream[offset : offset + length]))
                if body is not None and len(body) > 1:
                    unit, fc = body[0], body[1]
            elif flags & Flag.MBAP:
                if length > mbap.HEADER_SIZE:
                    unit, fc = stream[offset + 6], stream[offset + 7]
            elif length >= 2:
                unit, fc = stream[offset], stream[offset + 1]
        self.offset.append(offset)
        self.length.append(length)
        self.t.append(t0)
        self.t_end.append(t1)
        self.kind.append(kind)
        self.unit.append(unit)
        self.fc.append(fc)
        self.flags.append(flags)
        self.channel.append(channel)
        self.partner.append(NO_PARTNER)
        self.status.append(Status.NONE)

    def copy_row(self, other: FrameStore, i: int) -> None:
        """Append row `i` of `other`, a store sharing this one's streams (unpaired)."""
        self.sync()
        if i in other.notes:
            self.notes[len(self)] = other.notes[i]
        self.offset.append(other.offset[i])
        self.length.append(other.length[i])
        self.t.append(other.t[i])
        self.t_end.append(other.t_end[i])
        self.kind.append(other.kind[i])
        self.unit.append(other.unit[i])
        self.fc.append(other.fc[i])
        self.flags.append(other.flags[i])
        self.channel.append(other.channel[i])
        self.partner.append(NO_PARTNER)
        self.status.append(Status.NONE)

    def add_event(self, t: float, text: str, channel: int = 0) -> None:
        self.stream(channel)
        self.notes[len(self)] = text
        offset = len(self.streams[channel])
        self.add_row(channel, offset, 0, t, t, int(Kind.EVENT), int(Flag.LINE_EVENT))

    def raw(self, i: int) -> bytes:
        start = self.offset[i]
        return bytes(self.streams[self.channel[i]][start : start + self.length[i]])

    def view(self, i: int) -> FrameView:
        self.sync()
        fc = self.fc[i]
        kind = _KINDS[self.kind[i]]
        return FrameView(
            index=i,
            raw=self.raw(i),
            t=self.t[i],
            t_end=self.t_end[i],
            kind=kind,
            unit=self.unit[i],
            function=fc & 0x7F,
            exception=bool(fc & 0x80) and kind != _NOISE and kind != _EVENT,
            flags=self.flags[i],
            channel=self.channel[i],
            partner=self.partner[i],
            status=self.status[i],
        )

    def memory_bytes(self) -> int:
        """Bytes held by the streams and the columns (what a capture costs in memory)."""
        cols: list[array[Any]] = [getattr(self, name) for name in COLUMNS]
        return self.bytes_total + sum(c.itemsize * len(c) for c in cols)


# the per-row columns of a FrameStore, in the order the sidecar index keeps them
COLUMNS: tuple[str, ...] = (
    "offset", "length", "t", "t_end", "kind", "unit", "fc", "flags", "channel", "partner", "status",
)  # fmt: skip

_ALL_ONES = b"\xff" * array("i").itemsize  # NO_PARTNER (-1) in one partner cell
