"""Provides the pcap and pcapng readers for serial link types 147, 250 and 252.

Packets of Ethernet-family link types (Ethernet, Linux cooked, raw IP, loopback) go to
`sniffer.sources.net`, which gives a channel per TCP/UDP connection direction.

pcap: both byte orders, microsecond and nanosecond magics (and the "modified" variant with
a longer record header). pcapng: both byte orders, several sections and interfaces,
SHB/IDB/EPB/SPB and the obsolete PB; `if_tsresol`, `if_tsoffset`, `opt_comment` (kept as
the chunk's note) and `epb_flags`/`pack_flags`. Other blocks are skipped.

Each interface is its own chunk channel (numbered across sections in file order). Chunk
`t_end` is the packet time.

Direction (see `packet_direction`):
- an interface whose modscope description names a role (`master`/`slave`) gives that
  role to all its packets;
- link type 252 holds frames exported from a master's point of view: flags outbound (2)
  -> MASTER, inbound (1) -> SLAVE;
- link types 147 and 250 hold what a port read. A passive tap sees everything inbound, so
  inbound (1) -> UNKNOWN; outbound (2), or an RTAC `DATA_TX_START` record, means the
  capturing host sent it -> MASTER.

Link type 250: the RTAC header time is the chunk's `t_start` when it lies before the
packet time (by less than a minute); RTAC events become event chunks ("framing error",
"parity error", "data lost", "break", "control lines" with the line states as note),
after the data chunk when the record carries bytes too.

Link type 252: packets for `mbrtu` hold one RTU frame; packets for `mbtcp` (modscope's
default Wireshark export) hold one MBAP header and PDU, read back as the line's bytes the
packet comment gives (`RTU 01 03 ...`, `ASCII ":01..."`) or else as the RTU frame of the
unit and PDU. Each packet is one frame; requests and answers stay on their interface's
channel, in file order, their EPB flags a hint (see `sniffer.framing.pipeline`). `t_end` is the
packet time and `t_start` one
frame length earlier, moved later where needed so that every frame starts at least t3.5
after the previous one on its channel ends (and `t_end` no earlier than `t_start`): the
framer then never joins two frames. Times move only where frames are closer than t3.5
(a fast slave's answer), by at most that much.

A modscope `if_description` (see `linktypes`) gives the interface's line settings; the
first one found is the capture's. SPBs carry no time: their bytes are placed one
character time per byte after the interface's previous packet.
"""

from __future__ import annotations

import json
import math
import os
import struct
from array import array
from collections.abc import Generator, Iterator
from dataclasses import dataclass, field
from io import BufferedReader
from pathlib import Path
from typing import BinaryIO

import sniffer.sources.net as net
from dissectors.envelope import open_ascii, rtu_frame
from sniffer import core
from sniffer.model import Chunk, Direction, Labels, LineSettings, SourceInfo, Stamp
from sniffer.sources.base import MAX_TIME, Capture, ReadOptions
from sniffer.sources.detect import PCAP_MAGICS
from sniffer.sources.linktypes import (
    BLOCK_EPB,
    BLOCK_IDB,
    BLOCK_PB,
    BLOCK_SHB,
    BLOCK_SPB,
    EPB_DIRECTION_MASK,
    EPB_FLAG_INBOUND,
    EPB_FLAG_OUTBOUND,
    EPB_FLAGS,
    IF_DESCRIPTION,
    IF_NAME,
    IF_TSOFFSET,
    IF_TSRESOL,
    LINKTYPE_RTAC_SERIAL,
    LINKTYPE_USER0,
    LINKTYPE_WIRESHARK_UPPER_PDU,
    OPT_COMMENT,
    OPT_ENDOFOPT,
    RTAC_DATA_RX_START,
    RTAC_DATA_TX_START,
    RTAC_EVENTS,
    RTAC_HEADER,
    RTAC_HEADER_LEN,
    RTAC_STATUS_CHANGE,
    InterfaceNote,
    UpperPdu,
    control_lines_text,
    open_mbap,
    parse_interface_description,
    parse_rtac,
    parse_upper_pdu,
)
from sniffer.sources.reads import MAX_BATCH_BYTES, MAX_BATCH_SPAN, Reads, batching_enabled

MAX_BLOCK = 1 << 26  # 64 MiB: anything larger is taken as damage, not data
LINKTYPE_NAMES = {
    LINKTYPE_USER0: "USER0 raw serial",
    LINKTYPE_RTAC_SERIAL: "RTAC serial",
    LINKTYPE_WIRESHARK_UPPER_PDU: "exported PDU",
}
SEPARATION_MARGIN = 1e-6  # beyond t3.5, so float rounding of Unix times cannot undo it
RTAC_MAX_LEAD = 60.0  # seconds an RTAC header time may precede its packet time


# channels are one byte in the frame store: interfaces past this many (a damaged file, not
# a serial capture) are described but not read. An interface of a later section described
# byte for byte as one of an earlier section (a `cat` of recordings: each section names the
# same ports) goes on in that one's channel, so this bounds interfaces that differ, or are
# in one section together, not sections
MAX_INTERFACES = 128


def packet_direction(linktype: int, role: Direction, flags: int | None) -> Direction:
    """Direction of a packet from its interface's role and its EPB flags (module doc)."""
    if role != Direction.UNKNOWN:
        return role
    bits = (flags or 0) & EPB_DIRECTION_MASK
    if linktype == LINKTYPE_WIRESHARK_UPPER_PDU:
        if bits == EPB_FLAG_OUTBOUND:
            return Direction.MASTER
        if bits == EPB_FLAG_INBOUND:
            return Direction.SLAVE
        return Direction.UNKNOWN
    return Direction.MASTER if bits == EPB_FLAG_OUTBOUND else Direction.UNKNOWN


@dataclass
class _Interface:
    """One capture interface and the reading state that belongs to it."""

    linktype: int
    channel: int
    line: LineSettings
    label: str
    note: InterfaceNote = field(default_factory=lambda: InterfaceNote(None))
    ticks_per_second: int = 1_000_000
    offset_seconds: int = 0
    snaplen: int = 0
    last_end: float | None = None
    warned: bool = False


class _PacketDecoder:
    """Turns packets of one interface into chunks, by link type."""

    def __init__(self, warnings: list[str], network: net.NetDecoder | None = None) -> None:
        self.warnings = warnings
        self.other_dissectors: set[str] = set()
        self.network = network  # Ethernet-family link types go here (sniffer.sources.net)

    def chunks(
        self,
        iface: _Interface,
        t: float | None,
        data: bytes,
        flags: int | None,
        comment: str,
        offset: int,
    ) -> Iterator[Chunk]:
        if self.network is not None and iface.linktype in net.NET_LINKTYPES:
            when = t if t is not None else iface.last_end or 0.0  # an SPB has no time
            yield from self.network.packet(iface.linktype, when, data)
            return
        if iface.linktype not in LINKTYPE_NAMES:
            if not iface.warned:
                iface.warned = True
                self.warnings.append(
                    f"{iface.label}: link type {iface.linktype} is not serial data "
                    "(147, 250 or 252); its packets are skipped"
                )
            return
        if t is None:  # an SPB: no time of its own
            t = (iface.last_end or 0.0) + len(data) * iface.line.char_time
        if iface.linktype == LINKTYPE_USER0:
            yield from self._user0(iface, t, data, flags, comment)
        elif iface.linktype == LINKTYPE_RTAC_SERIAL:
            yield from self._rtac(iface, t, data, flags, comment, offset)
        else:
            yield from self._upper_pdu(iface, t, data, flags, comment, offset)

    def _user0(
        self, iface: _Interface, t: float, data: bytes, flags: int | None, comment: str
    ) -> Iterator[Chunk]:
        iface.last_end = t
        if data:
            direction = packet_direction(iface.linktype, iface.note.role, flags)
            yield Chunk(
                data=data, t_end=t, channel=iface.channel, direction=direction, note=comment
            )

    def _rtac(
        self,
        iface: _Interface,
        t: float,
        data: bytes,
        flags: int | None,
        comment: str,
        offset: int,
    ) -> Iterator[Chunk]:
        iface.last_end = t
        record = parse_rtac(data)
        if record is None:
            self.warnings.append(
                f"RTAC packet at byte offset {offset} is {len(data)} bytes, shorter than "
                "its 12-byte header; skipped"
            )
            return
        if record.event == RTAC_DATA_TX_START and not (flags or 0) & EPB_DIRECTION_MASK:
            flags = EPB_FLAG_OUTBOUND
        direction = packet_direction(iface.linktype, iface.note.role, flags)
        lead = t - record.seconds
        t_start = record.seconds if 0.0 < lead < RTAC_MAX_LEAD else None
        if record.data:
            yield Chunk(
                data=record.data,
                t_end=t,
                t_start=t_start,
                channel=iface.channel,
                direction=direction,
                note=comment,
            )
        event, note = RTAC_EVENTS.get(
            record.event, ("unknown event", f"RTAC event type 0x{record.event:02X}")
        )
        if record.event == RTAC_STATUS_CHANGE:
            note = control_lines_text(record.control_lines)
        if event and comment:
            # a recorder's comment says what happened: "port lost: ...", "reconnect: ..."
            said, _, rest = comment.partition(":")
            if rest:
                event, note = said.strip(), rest.strip()
            else:
                note = comment
        if event:
            yield Chunk(
                data=b"",
                t_end=t,
                channel=iface.channel,
                direction=direction,
                event=event,
                note=note,
            )

    def _upper_pdu(
        self,
        iface: _Interface,
        t: float,
        data: bytes,
        flags: int | None,
        comment: str,
        offset: int,
    ) -> Iterator[Chunk]:
        record = parse_upper_pdu(data)
        if record is None:
            self.warnings.append(
                f"exported-PDU packet at byte offset {offset} has broken tags; skipped"
            )
            return
        known = ("mbrtu", "mbtcp", "data")  # data: noise and events in modscope's exports
        if record.dissector == "mbtcp":
            frame = exported_mbtcp_frame(record.pdu, comment)
            if frame is None:
                self.warnings.append(
                    f"{iface.label}: exported PDU for 'mbtcp' at byte offset {offset} is not "
                    "one Modbus/TCP frame; passed on as bytes"
                )
            else:
                record = UpperPdu(record.dissector, frame)
        if record.dissector not in known and record.dissector not in self.other_dissectors:
            self.other_dissectors.add(record.dissector)
            self.warnings.append(
                f"{iface.label}: exported PDUs for dissector {record.dissector!r}, expected "
                "'mbrtu' or 'mbtcp'; passed on as bytes"
            )
        if not record.pdu:
            return
        line = iface.line
        t_start = t - len(record.pdu) * line.char_time
        if iface.last_end is not None:
            t_start = max(t_start, iface.last_end + line.t35 + SEPARATION_MARGIN)
        t_end = max(t, t_start)
        iface.last_end = t_end
        direction = packet_direction(iface.linktype, iface.note.role, flags)
        yield Chunk(
            data=record.pdu,
            t_end=t_end,
            t_start=t_start,
            channel=iface.channel,
            direction=direction,
            note=comment,
        )


def exported_mbtcp_frame(adu: bytes, comment: str) -> bytes | None:
    """The serial frame of one exported Modbus/TCP PDU: the line's bytes that modscope's
    export keeps at the head of the comment (`RTU 01 03 ...` or `ASCII ":01..."`) when
    they carry the same unit and PDU, else the RTU frame of the unit and PDU with its
    CRC. None unless `adu` is one MBAP header and its PDU."""
    body = open_mbap(adu)
    if body is None:
        return None
    head = comment.split(";", 1)[0]
    if head.startswith("RTU "):
        try:
            raw = bytes.fromhex(head[4:])
        except ValueError:
            raw = b""
        if raw[:-2] == body:
            return raw
    elif head.startswith("ASCII "):
        try:
            text, _end = json.JSONDecoder().raw_decode(comment, 6)
            raw = text.encode("latin-1") if isinstance(text, str) else b""
        except (ValueError, UnicodeEncodeError):
            raw = b""
        if raw and open_ascii(raw).body == body:
            return raw
    return rtu_frame(body)


def _stamps(linktype: int) -> Stamp:
    """What a packet time means: a frame's end for exported PDUs, a read's end otherwise."""
    return Stamp.FRAME_END if linktype == LINKTYPE_WIRESHARK_UPPER_PDU else Stamp.READ_END


def _file_size(handle: BinaryIO) -> int:
    return os.fstat(handle.fileno()).st_size


# ---------------------------------------------------------------- pcap


@dataclass(frozen=True, slots=True)
class _PcapHeader:
    order: str
    nanoseconds: bool
    modified: bool
    linktype: int
    snaplen: int


def _pcap_header(head: bytes) -> _PcapHeader:
    (magic,) = struct.unpack_from("<I", head)
    order, nanoseconds, modified = PCAP_MAGICS[magic]
    snaplen, network = struct.unpack_from(order + "II", head, 16)
    return _PcapHeader(order, nanoseconds, modified, network & 0xFFFF, snaplen)


def open_pcap(path: Path, options: ReadOptions, head: bytes) -> Capture:
    """Open a pcap file (detected from `head`); one interface, channel 0."""
    line = options.line(None)
    if len(head) < 24:
        info = SourceInfo(path=str(path), format="pcap", line=line)
        warning = f"truncated pcap file header at byte offset 0: {len(head)} of 24 bytes"
        return Capture(info=info, _chunks=iter(()), warnings=[warning])
    header = _pcap_header(head)
    name = LINKTYPE_NAMES.get(header.linktype, f"link type {header.linktype}")
    label = f"pcap {name}"
    iface = _Interface(
        linktype=header.linktype,
        channel=0,
        line=line,
        label=label,
        ticks_per_second=1_000_000_000 if header.nanoseconds else 1_000_000,
        snaplen=header.snaplen,
    )
    warnings: list[str] = []
    info = SourceInfo(
        path=str(path),
        format="pcap",
        line=line,
        channels={0: label},
        stamps=_stamps(header.linktype),
        resolution=1e-9 if header.nanoseconds else 1e-6,
    )
    info, network = net.for_capture(
        info, [(0, header.linktype)], options, warnings, nanoseconds=header.nanoseconds
    )
    return Capture(
        info=info,
        _chunks=_pcap_chunks(path, header, iface, warnings, network),
        warnings=warnings,
    )


def _pcap_chunks(
    path: Path,
    header: _PcapHeader,
    iface: _Interface,
    warnings: list[str],
    network: net.NetDecoder | None = None,
) -> Iterator[Chunk]:
    decoder = _PacketDecoder(warnings, network)
    yield from _pcap_records(path, header, iface, decoder, warnings)
    if network is not None:
        yield from network.finish()


def _pcap_records(
    path: Path,
    header: _PcapHeader,
    iface: _Interface,
    decoder: _PacketDecoder,
    warnings: list[str],
) -> Iterator[Chunk]:
    record = struct.Struct(header.order + ("IIIIIHBB" if header.modified else "IIII"))
    with path.open("rb") as handle:
        size = _file_size(handle)
        offset = 24
        if batching_enabled() and iface.linktype in PLAIN_HEADER:
            # runs of data packets as batches; the loop below reads on from a damaged or
            # truncated record, with its warning
            offset = yield from _bulk_pcap_records(handle, header, record, iface, decoder)
        handle.seek(offset)
        while offset < size:
            raw = handle.read(record.size)
            if len(raw) < record.size:
                warnings.append(
                    f"truncated pcap record header at byte offset {offset}: "
                    f"{len(raw)} of {record.size} bytes; reading stopped there"
                )
                return
            secs, frac, incl_len = record.unpack(raw)[:3]
            if incl_len > MAX_BLOCK:
                warnings.append(
                    f"corrupt pcap record at byte offset {offset}: length {incl_len}; "
                    "reading stopped there"
                )
                return
            if offset + record.size + incl_len > size:
                warnings.append(
                    f"truncated pcap record at byte offset {offset}: {incl_len} bytes "
                    f"announced, {size - offset - record.size} present; reading stopped there"
                )
                return
            data = handle.read(incl_len)
            if len(data) < incl_len:  # the file shrank since its size was taken
                warnings.append(
                    f"truncated pcap record at byte offset {offset}: {incl_len} bytes "
                    f"announced, {len(data)} present (the file shrank while it was read); "
                    "reading stopped there"
                )
                return
            t = secs + frac / iface.ticks_per_second
            yield from decoder.chunks(iface, t, data, None, "", offset)
            offset += record.size + incl_len


def _refill(
    handle: BufferedReader, buf: bytearray, view: memoryview, pos: int, end: int, want: int
) -> tuple[bytearray, memoryview, int, int]:
    """The bulk walks' next piece of the file: what `buf[pos:end]` holds moved to the front
    and up to `want` bytes read behind it, into the same buffer (`readinto`) unless it
    is too small. Returns the buffer, its view, where its bytes end and how many were
    read (0 at the end of the file). The file offset of the buffer's start is then that
    of `pos` before.

    One buffer, reused: reading into a new bytes object, then joining it to the rest in
    another, would have the kernel fault in and zero fresh memory twice a piece, which
    on a day's capture is most of the system time."""
    keep = end - pos
    if keep + want > len(buf):
        grown = bytearray(keep + want)
        grown[:keep] = view[pos:end]
        view.release()
        buf, view = grown, memoryview(grown)
    elif keep and pos:
        view[:keep] = bytes(view[pos:end])
    got = handle.readinto(view[keep : keep + want]) or 0
    return buf, view, keep + got, got


def _bulk_pcap_records(
    handle: BufferedReader,
    header: _PcapHeader,
    record: struct.Struct,
    iface: _Interface,
    decoder: _PacketDecoder,
) -> Generator[Chunk, None, int]:
    """Walk a pcap file of a link type in `PLAIN_HEADER` in large reads and pass runs of
    its data packets as `Reads` batches (as `_bulk_blocks` does for pcapng); other
    whole records go through the decoder one by one. Returns the offset of the first
    record that is damaged or cut short (or the file's size), from which `_pcap_records`
    reads on and says what is wrong."""
    size = _file_size(handle)
    skip = PLAIN_HEADER[iface.linktype]
    ticks = iface.ticks_per_second
    rtac_head, rx_start = RTAC_HEADER, RTAC_DATA_RX_START
    fast = core.FAST
    big = header.order == ">"
    # no EPB flags here: a data packet's direction is the interface's (UNKNOWN in pcap)
    direction = packet_direction(iface.linktype, iface.note.role, None)
    handle.seek(24)
    buf = bytearray(BULK_READ)
    view = memoryview(buf)
    end = 0  # the file from offset `base` is in buf[:end]
    base = 24
    pos = 0
    parts: list[bytes] = []
    ends: array[int] = array("q")
    t_starts: array[float] = array("d")
    t_ends: array[float] = array("d")
    b_bytes = 0
    b_first = 0.0

    def batch() -> Reads:
        nonlocal ends, t_starts, t_ends
        iface.last_end = t_ends[-1]
        reads = _batch_of(parts, ends, t_starts, t_ends, iface.channel, direction)
        ends, t_starts, t_ends = array("q"), array("d"), array("d")
        return reads

    while True:
        if pos + record.size > end:
            buf, view, end, got = _refill(handle, buf, view, pos, end, BULK_READ)
            base, pos = base + pos, 0
            if got:
                continue
            if parts:
                yield batch()
            return base
        if fast is not None:
            # the compiled copy of the data packet branch below
            pos, cut, _, b_bytes, b_first, data, e, ts, te = fast.bulk_pcap(
                view[:end], pos, size - base, big, record.size, skip, ticks, bool(parts),
                b_bytes, b_first,
            )  # fmt: skip
            if e:
                parts.append(data)
                ends.frombytes(e)
                t_starts.frombytes(ts)
                t_ends.frombytes(te)
            if cut:
                yield batch()
                continue
            if pos + record.size > end:
                continue
        secs, frac, length = record.unpack_from(buf, pos)[:3]
        offset = base + pos
        if length > MAX_BLOCK or offset + record.size + length > size:
            if parts:
                yield batch()
            return offset
        if pos + record.size + length > end:
            buf, view, end, got = _refill(
                handle, buf, view, pos, end, max(BULK_READ, record.size + length)
            )
            base, pos = base + pos, 0
            if got:
                continue
            if parts:  # the file is shorter than when it was opened
                yield batch()
            return offset
        data_at = pos + record.size
        t = secs + frac / ticks
        if length > skip and 0.0 <= t < MAX_TIME:
            t_start = math.nan
            event = rx_start
            if skip:
                r_secs, r_usecs, event, _lines, _footer = rtac_head.unpack_from(buf, data_at)
                seconds = r_secs + r_usecs / 1e6
                if 0.0 < t - seconds < RTAC_MAX_LEAD:
                    t_start = seconds
            if event == rx_start:
                if parts and (t - b_first > MAX_BATCH_SPAN or b_bytes > MAX_BATCH_BYTES):
                    yield batch()
                if not parts:
                    b_bytes, b_first = 0, t
                parts.append(bytes(buf[data_at + skip : data_at + length]))
                b_bytes += length - skip
                ends.append(b_bytes)
                t_starts.append(t_start)
                t_ends.append(t)
                pos = data_at + length
                continue
        if parts:
            yield batch()
        data = bytes(buf[data_at : data_at + length])
        yield from decoder.chunks(iface, t, data, None, "", offset)
        pos = data_at + length


# ---------------------------------------------------------------- pcapng


@dataclass(frozen=True, slots=True)
class _Block:
    offset: int
    type: int
    body: bytes
    order: str


def _blocks(
    handle: BinaryIO, warnings: list[str], offset: int = 0, order: str = "<"
) -> Iterator[_Block]:
    """Every complete block of a pcapng file from `offset` (in a section of byte order
    `order`); a damaged one ends the walk with a warning."""
    size = _file_size(handle)
    handle.seek(offset)
    while offset < size:
        header = handle.read(8)
        if len(header) < 8:
            warnings.append(
                f"truncated pcapng block at byte offset {offset}: {len(header)} bytes of "
                "its header; reading stopped there"
            )
            return
        prefix = b""
        if header[:4] == b"\x0a\x0d\x0d\x0a":
            prefix = handle.read(4)
            if len(prefix) < 4:
                warnings.append(
                    f"truncated pcapng section header at byte offset {offset}; "
                    "reading stopped there"
                )
                return
            if prefix == b"\x4d\x3c\x2b\x1a":
                order = "<"
            elif prefix == b"\x1a\x2b\x3c\x4d":
                order = ">"
            else:
                warnings.append(
                    f"corrupt pcapng section header at byte offset {offset}: no byte-order "
                    "magic; reading stopped there"
                )
                return
        elif offset == 0:
            warnings.append("pcapng file does not start with a section header")
            return
        block_type, total = struct.unpack(order + "II", header)
        if total < 12 + len(prefix) or total % 4 or total > MAX_BLOCK:
            warnings.append(
                f"corrupt pcapng block at byte offset {offset}: length {total}; "
                "reading stopped there"
            )
            return
        if offset + total > size:
            warnings.append(
                f"truncated pcapng block at byte offset {offset}: {total} bytes announced, "
                f"{size - offset} present; reading stopped there"
            )
            return
        body = prefix + handle.read(total - 12 - len(prefix))
        tail = handle.read(4)
        if len(body) + len(tail) < total - 8:  # the file shrank since its size was taken
            warnings.append(
                f"truncated pcapng block at byte offset {offset}: {total} bytes announced, "
                f"{8 + len(body) + len(tail)} present (the file shrank while it was read); "
                "reading stopped there"
            )
            return
        (trailer,) = struct.unpack(order + "I", tail)
        if trailer != total:
            warnings.append(
                f"corrupt pcapng block at byte offset {offset}: its lengths differ "
                f"({total} and {trailer}); reading stopped there"
            )
            return
        yield _Block(offset, block_type, body, order)
        offset += total


def _options(body: bytes, start: int, order: str) -> list[tuple[int, bytes]]:
    """The options of a block body from `start`; a malformed tail is ignored."""
    found: list[tuple[int, bytes]] = []
    pos = start
    while pos + 4 <= len(body):
        code, length = struct.unpack_from(order + "HH", body, pos)
        pos += 4
        if code == OPT_ENDOFOPT or pos + length > len(body):
            break
        found.append((code, body[pos : pos + length]))
        pos += length + (-length % 4)
    return found


def _text(value: bytes) -> str:
    return value.split(b"\0", 1)[0].decode("utf-8", errors="replace")


def _comment(options: list[tuple[int, bytes]]) -> str:
    return "\n".join(_text(value) for code, value in options if code == OPT_COMMENT)


def _flags(options: list[tuple[int, bytes]], order: str) -> int | None:
    for code, value in options:
        if code == EPB_FLAGS and len(value) >= 4:
            flags: int = struct.unpack_from(order + "I", value)[0]
            return flags
    return None


class _Section:
    """Interfaces of the file: a new section header starts a new list of ids."""

    def __init__(self, options: ReadOptions, warnings: list[str]) -> None:
        self.options = options
        self.warnings = warnings
        self.current: list[_Interface] = []
        self.all: list[_Interface] = []
        self.file_line: LineSettings | None = None
        self.unknown: set[tuple[int, int]] = set()
        # channels by their interface's description (byte order, IDB body): a later
        # section's interface described alike goes on in the same channel
        self.described: dict[tuple[str, bytes], list[int]] = {}
        self.in_section: set[int] = set()  # channels of the current section
        # how many of each description's channels the current section has taken: they
        # are taken in order, so the next free one is found without a scan (#30.7)
        self.taken: dict[tuple[str, bytes], int] = {}
        self.left_out = 0  # interfaces past MAX_INTERFACES
        self.no_line = options.line(None)  # the line of an interface that is not read

    def new_section(self) -> None:
        self.current = []
        self.in_section = set()
        self.taken = {}

    def add(self, block: _Block) -> _Interface:
        order, body = block.order, block.body
        key = (order, bytes(body))
        same = self.described.get(key, []) if len(body) >= 8 else []
        # a section takes a description's channels first to last (a new channel is added
        # to the list only once the section took all of them): the next is the free one
        taken = self.taken.get(key, 0)
        free = same[taken] if taken < len(same) else None
        if len(body) >= 8:
            self.taken[key] = taken + 1
        if free is not None:  # the same interface as in an earlier section (see above)
            linktype, _reserved, snaplen = struct.unpack_from(order + "HHI", body)
            iface = self._interface(linktype, snaplen, _options(body, 8, order), order, free)
            self.current.append(iface)
            self.in_section.add(free)
            return iface
        channel = len(self.all)
        if channel >= MAX_INTERFACES:
            if channel == MAX_INTERFACES:
                self.warnings.append(
                    f"interface description at byte offset {block.offset} is the "
                    f"{channel + 1}th; modscope reads {MAX_INTERFACES} interfaces at most, "
                    "the packets of the others are skipped"
                )
            iface = _Interface(-1, channel, self.no_line, f"interface {channel}")
            iface.warned = True
        elif len(body) < 8:
            self.warnings.append(
                f"corrupt interface description at byte offset {block.offset}; "
                "its packets are skipped"
            )
            iface = _Interface(-1, channel, self.no_line, f"interface {channel}")
        else:
            linktype, _reserved, snaplen = struct.unpack_from(order + "HHI", body)
            iface = self._interface(linktype, snaplen, _options(body, 8, order), order, channel)
            self.described.setdefault(key, []).append(channel)
        self.current.append(iface)
        self.all.append(iface)
        self.in_section.add(channel)
        return iface

    def _interface(
        self,
        linktype: int,
        snaplen: int,
        options: list[tuple[int, bytes]],
        order: str,
        channel: int,
    ) -> _Interface:
        name = description = ""
        ticks = 1_000_000
        offset_seconds = 0
        for code, value in options:
            if code == IF_NAME:
                name = _text(value)
            elif code == IF_DESCRIPTION:
                description = _text(value)
            elif code == IF_TSRESOL and value:
                exponent = value[0] & 0x7F
                ticks = 2**exponent if value[0] & 0x80 else 10**exponent
            elif code == IF_TSOFFSET and len(value) >= 8:
                (offset_seconds,) = struct.unpack_from(order + "q", value)
        note = parse_interface_description(description)
        if note.line is not None:
            if self.file_line is None:
                self.file_line = note.line
            elif note.line != self.file_line:
                self.warnings.append(
                    f"interface {channel} records {note.line.describe()}, another "
                    f"{self.file_line.describe()}; each interface is read with its own"
                )
        kind = LINKTYPE_NAMES.get(linktype, f"link type {linktype}")
        label = f"{name or description or f'interface {channel}'} ({kind})"
        return _Interface(
            linktype=linktype,
            channel=channel,
            line=self.options.line(note.line),
            label=label,
            note=note,
            ticks_per_second=ticks,
            offset_seconds=offset_seconds,
            snaplen=snaplen,
        )

    def get(self, index: int, offset: int) -> _Interface | None:
        if 0 <= index < len(self.current):
            return self.current[index]
        if (len(self.all), index) not in self.unknown:
            self.unknown.add((len(self.all), index))
            self.warnings.append(
                f"packet at byte offset {offset} names interface {index}, which the "
                "section has not described; its packets are skipped"
            )
        return None


def open_pcapng(path: Path, options: ReadOptions) -> Capture:
    """Open a pcapng file: interfaces before the first packet describe the capture."""
    early: list[str] = []
    section = _Section(options, early)
    stamps, labels = Stamp.READ_END, Labels.NONE
    with path.open("rb") as handle:
        for block in _blocks(handle, early):
            if block.type == BLOCK_SHB:
                section.new_section()
            elif block.type == BLOCK_IDB:
                section.add(block)
            elif block.type in (BLOCK_EPB, BLOCK_SPB, BLOCK_PB):
                stamps, labels = _first_packet_says(block, section)
                break
    line = options.line(section.file_line)
    channels = {iface.channel: iface.label for iface in section.all}
    roles = [iface.note.role for iface in section.all]
    resolution = 0.0
    said = [iface.note for iface in section.all if iface.note.stamps is not None]
    if said:  # a modscope export: its times are worth what its source's were
        stamps, resolution = said[0].stamps or stamps, said[0].resolution or 0.0
    info = SourceInfo(
        path=str(path),
        format="pcapng",
        line=line,
        channels=channels,
        recorded_line=section.file_line,
        stamps=stamps,
        resolution=resolution,
        # interfaces with a modscope role are one port per direction; EPB flags are hints
        labels=Labels.CERTAIN if roles and Direction.UNKNOWN not in roles else labels,
    )
    warnings: list[str] = []
    linktypes = [(iface.channel, iface.linktype) for iface in section.all]
    nanoseconds = any(iface.ticks_per_second > 1_000_000 for iface in section.all)
    info, network = net.for_capture(info, linktypes, options, warnings, nanoseconds=nanoseconds)
    return Capture(
        info=info,
        _chunks=_pcapng_chunks(path, options, info, warnings, network),
        warnings=warnings,
    )


def _first_packet_says(block: _Block, section: _Section) -> tuple[Stamp, Labels]:
    """What a capture's timestamps mean and how far its directions hold, judged from its
    first packet: link type 250 records that carry their start time are exact (else the
    packet time is a read's end); EPB direction flags are a writer's hint (252 frames are
    stamped at their end)."""
    if block.type != BLOCK_EPB or len(block.body) < 20:
        return Stamp.READ_END, Labels.NONE
    index, high, low, caplen = struct.unpack_from(block.order + "IIII", block.body)
    iface = section.current[index] if 0 <= index < len(section.current) else None
    if iface is None or 20 + caplen > len(block.body):
        return Stamp.READ_END, Labels.NONE
    flags = _flags(_options(block.body, 20 + caplen + (-caplen % 4), block.order), block.order)
    labelled = bool((flags or 0) & EPB_DIRECTION_MASK) or iface.note.role != Direction.UNKNOWN
    labels = Labels.HINT if labelled else Labels.NONE
    if iface.linktype == LINKTYPE_RTAC_SERIAL and iface.note.line is None:
        # another tool's RTAC records: a header time before the packet's is the first
        # byte's (modscope's own recordings estimate it from the read and the baud rate)
        record = parse_rtac(block.body[20 : 20 + caplen])
        t = ((high << 32) | low) / iface.ticks_per_second + iface.offset_seconds
        lead = t - record.seconds if record is not None else -1.0
        return (Stamp.EXACT if 0.0 < lead < RTAC_MAX_LEAD else Stamp.READ_END), labels
    if iface.linktype == LINKTYPE_WIRESHARK_UPPER_PDU:
        return Stamp.FRAME_END, labels
    return Stamp.READ_END, labels


def _pcapng_chunks(
    path: Path,
    options: ReadOptions,
    info: SourceInfo,
    warnings: list[str],
    network: net.NetDecoder | None = None,
) -> Iterator[Chunk]:
    decoder = _PacketDecoder(warnings, network)
    yield from _pcapng_blocks(path, options, info, decoder, warnings)
    if network is not None:
        yield from network.finish()


def _pcapng_blocks(
    path: Path,
    options: ReadOptions,
    info: SourceInfo,
    decoder: _PacketDecoder,
    warnings: list[str],
) -> Iterator[Chunk]:
    section = _Section(options, warnings)
    with path.open("rb") as handle:
        offset, order = 0, "<"
        if batching_enabled():
            stopped = yield from _bulk_blocks(handle, section, decoder, info, warnings)
            if stopped is None:
                return
            offset, order = stopped  # a block the bulk walk does not check: walk on slowly
        for block in _blocks(handle, warnings, offset, order):
            if not (yield from _one_block(block, section, decoder, info, warnings)):
                return


def _one_block(
    block: _Block,
    section: _Section,
    decoder: _PacketDecoder,
    info: SourceInfo,
    warnings: list[str],
) -> Generator[Chunk, None, bool]:
    """Read one block; False when reading must stop there."""
    if block.type == BLOCK_SHB:
        major = (
            struct.unpack_from(block.order + "H", block.body, 4)[0] if len(block.body) >= 16 else -1
        )
        if major != 1:
            warnings.append(
                f"pcapng section at byte offset {block.offset} has version {major}, "
                "not 1; reading stopped there"
            )
            return False
        section.new_section()
        return True
    if block.type == BLOCK_IDB:
        iface = section.add(block)
        if decoder.network is None or iface.linktype not in net.NET_LINKTYPES:
            info.channels.setdefault(iface.channel, iface.label)
        return True
    yield from _packet_block(block, section, decoder, warnings)
    return True


BULK_READ = 1 << 22  # bytes read from the file at a time by the bulk walks

# Link types whose data packets the bulk walks batch, with the length of the header before
# the bytes read: an RTAC record's (only its "data received" records are taken), none for
# USER0. Their packets mean the same thing: the bytes of one read, stamped at its end (an
# RTAC header may add the first byte's time), in a direction the EPB flags or the
# interface's role give (packet_direction).
PLAIN_HEADER = {LINKTYPE_RTAC_SERIAL: RTAC_HEADER_LEN, LINKTYPE_USER0: 0}


def _bulk_blocks(
    handle: BufferedReader,
    section: _Section,
    decoder: _PacketDecoder,
    info: SourceInfo,
    warnings: list[str],
) -> Generator[Chunk, None, tuple[int, str] | None]:
    """Walk the file in large reads and pass runs of data packets (`PLAIN_HEADER`: link
    type 250 data records, link type 147 packets) of one interface as `Reads` batches,
    without a Python object per packet.

    Only blocks whose lengths all agree, that lie wholly in the file, are taken here;
    other blocks (section and interface headers, comments, events, other link types)
    are read by the same code as in the block-by-block walk. At the first block this
    walk cannot vouch for (damage, a truncated end) it stops and returns that block's
    offset and byte order, and the block-by-block walk carries on from there with its
    warnings. None: the whole file was read.

    Its cost on 1M frames, 16 ms reads and one frame per packet: docs/performance.md.
    """
    size = _file_size(handle)
    handle.seek(0)
    buf = bytearray(BULK_READ)
    view = memoryview(buf)
    end = 0  # the file from offset `base` is in buf[:end] (see _refill)
    base = 0
    pos = 0  # position in buf of the next block

    def refill(want: int) -> int:
        nonlocal buf, view, end, base, pos
        buf, view, end, got = _refill(handle, buf, view, pos, end, want)
        base, pos = base + pos, 0
        return got

    order = "<"
    head = struct.Struct(order + "II")
    epb = struct.Struct(order + "IIIII")  # type, length, interface, time high, low
    flags_head = struct.pack(order + "HH", EPB_FLAGS, 4)
    flags_value = struct.Struct(order + "I")
    rtac_head = RTAC_HEADER
    rx_start = RTAC_DATA_RX_START
    # the compiled walk over data records (sniffer.core), given the section's interfaces
    fast = core.FAST
    fast_ifaces = _FastInterfaces(section)
    # the batch being gathered
    parts: list[bytes] = []
    ends: array[int] = array("q")
    t_starts: array[float] = array("d")  # NaN: not known
    t_ends: array[float] = array("d")
    b_iface: _Interface | None = None
    b_index = -1  # b_iface's index in the section while `parts` is not empty, else -1
    b_dir = Direction.UNKNOWN
    b_bytes = 0
    b_first = 0.0
    directions: dict[tuple[int, int | None], Direction] = {}  # by channel and EPB flags

    def batch() -> Reads:
        nonlocal ends, t_starts, t_ends, b_index
        assert b_iface is not None
        b_iface.last_end = t_ends[-1]
        reads = _batch_of(parts, ends, t_starts, t_ends, b_iface.channel, b_dir)
        ends, t_starts, t_ends = array("q"), array("d"), array("d")
        b_index = -1
        return reads

    while True:
        if pos + 12 > end:
            if refill(BULK_READ):
                continue
            if parts:
                yield batch()
            return None if base + pos == size else (base + pos, order)
        if fast is not None and base + pos and fast_ifaces.usable:
            # the compiled copy of the data packet branch below, up to the first block it
            # does not take (that block is then looked at here, as without it)
            pos, cut, b_index, direction_value, b_bytes, b_first, data, e, ts, te = (
                fast.bulk_epbs(
                    view[:end], pos, size - base, order == ">", fast_ifaces.entries, b_index,
                    int(b_dir), b_bytes, b_first,
                )
            )  # fmt: skip
            if e:
                b_iface = section.current[b_index]
                # Direction(value) without the enum call, which costs more than a lookup
                b_dir = _DIRECTIONS[direction_value]
                parts.append(data)
                ends.frombytes(e)
                t_starts.frombytes(ts)
                t_ends.frombytes(te)
            if cut:
                yield batch()
                continue
            if pos + 12 > end:
                continue
        block_type, total = head.unpack_from(buf, pos)
        offset = base + pos
        if block_type == BLOCK_SHB:
            magic = bytes(buf[pos + 8 : pos + 12])
            if magic not in (b"\x4d\x3c\x2b\x1a", b"\x1a\x2b\x3c\x4d"):
                if parts:
                    yield batch()
                return offset, order
            order = "<" if magic == b"\x4d\x3c\x2b\x1a" else ">"
            head = struct.Struct(order + "II")
            epb = struct.Struct(order + "IIIII")
            flags_head = struct.pack(order + "HH", EPB_FLAGS, 4)
            flags_value = struct.Struct(order + "I")
            block_type, total = head.unpack_from(buf, pos)
        elif offset == 0:
            return 0, order  # not a pcapng start: the slow walk says so
        if total < 12 or total % 4 or total > MAX_BLOCK or offset + total > size:
            if parts:
                yield batch()
            return offset, order
        if pos + total > end:
            if refill(max(BULK_READ, total)):
                continue
            if parts:  # the file is shorter than when it was opened
                yield batch()
            return offset, order
        if flags_value.unpack_from(buf, pos + total - 4)[0] != total:
            if parts:
                yield batch()
            return offset, order
        if block_type == BLOCK_EPB and total >= 36:
            _, _, index, high, low = epb.unpack_from(buf, pos)
            caplen = flags_value.unpack_from(buf, pos + 20)[0]
            iface = section.current[index] if index < len(section.current) else None
            tail = pos + 28 + caplen + (-caplen % 4)
            stop = pos + total - 4
            flags: int | None = None
            # the payload's header: RTAC records carry one, USER0 packets are the bytes
            skip = -1 if iface is None else PLAIN_HEADER.get(iface.linktype, -1)
            fast_record = skip >= 0 and caplen > skip and tail <= stop
            if fast_record and tail != stop:
                fast_record = (
                    stop - tail == 12
                    and buf[tail : tail + 4] == flags_head
                    and buf[tail + 8 : stop] == b"\0\0\0\0"
                )
                flags = flags_value.unpack_from(buf, tail + 4)[0]
            if fast_record:
                assert iface is not None
                data_at = pos + 28
                t_start = math.nan
                secs = usecs = 0
                event = rx_start
                if skip:
                    secs, usecs, event, _lines, _footer = rtac_head.unpack_from(buf, data_at)
                t = ((high << 32) | low) / iface.ticks_per_second + iface.offset_seconds
                if event == rx_start and 0.0 <= t < MAX_TIME:
                    direction = directions.get((iface.channel, flags))
                    if direction is None:
                        direction = directions[iface.channel, flags] = packet_direction(
                            iface.linktype, iface.note.role, flags
                        )
                    if parts and (
                        iface is not b_iface
                        or direction != b_dir
                        or t - b_first > MAX_BATCH_SPAN
                        or b_bytes > MAX_BATCH_BYTES
                    ):
                        yield batch()
                    if not parts:
                        b_iface, b_index, b_dir, b_bytes, b_first = iface, index, direction, 0, t
                    if skip:
                        seconds = secs + usecs / 1e6
                        lead = t - seconds
                        if 0.0 < lead < RTAC_MAX_LEAD:
                            t_start = seconds
                    parts.append(bytes(buf[data_at + skip : data_at + caplen]))
                    b_bytes += caplen - skip
                    ends.append(b_bytes)
                    t_starts.append(t_start)
                    t_ends.append(t)
                    pos += total
                    continue
        if parts:
            yield batch()
        block = _Block(offset, block_type, bytes(buf[pos + 8 : pos + total - 4]), order)
        pos += total
        if not (yield from _one_block(block, section, decoder, info, warnings)):
            return None
        if block_type == BLOCK_SHB:
            directions.clear()
            fast_ifaces = _FastInterfaces(section)
        elif block_type == BLOCK_IDB:
            directions.clear()
            fast_ifaces.add(section.current[-1])


_DIRECTIONS = tuple(sorted(Direction))  # by value: 0, 1, 2


# interface entries past which the compiled walk is left out: it reads its list anew on
# each call, so a section of 40,000 interface descriptions (all but 128 of them unread,
# see MAX_INTERFACES) would cost 40,000 entries per block (#30.7); such a section is
# read by the Python walk, which gives the same chunks
FAST_INTERFACES = 1024


class _FastInterfaces:
    """What the compiled walk needs of each interface of the section, by index
    (`_fast_interface`), kept one entry at a time as interfaces are described and without
    the Nones at its end (an index past the list is left to the Python walk, as a None).
    `usable`: short enough for the compiled walk (FAST_INTERFACES)."""

    def __init__(self, section: _Section) -> None:
        self.entries: list[tuple[int, int, int, int] | None] = []
        self.nones = 0  # Nones described after the last entry
        for iface in section.current:
            self.add(iface)

    def add(self, iface: _Interface) -> None:
        entry = _fast_interface(iface)
        if entry is None:
            self.nones += 1
            return
        self.entries.extend([None] * self.nones)
        self.nones = 0
        self.entries.append(entry)

    @property
    def usable(self) -> bool:
        return len(self.entries) <= FAST_INTERFACES


def _fast_interface(iface: _Interface) -> tuple[int, int, int, int] | None:
    """What the compiled walk needs of an interface: ticks per second, offset seconds,
    role and the length of the header before the bytes read of one of a link type in
    `PLAIN_HEADER` (None for the others, and where those numbers are out of the range it
    computes times for exactly)."""
    skip = PLAIN_HEADER.get(iface.linktype, -1)
    fits = (
        skip >= 0 and 0 < iface.ticks_per_second <= 1 << 62 and abs(iface.offset_seconds) < 1 << 53
    )
    if not fits:
        return None
    return (iface.ticks_per_second, iface.offset_seconds, int(iface.note.role), skip)


def _packet_block(
    block: _Block, section: _Section, decoder: _PacketDecoder, warnings: list[str]
) -> Iterator[Chunk]:
    order, body = block.order, block.body
    if block.type in (BLOCK_EPB, BLOCK_PB):
        if len(body) < 20:
            warnings.append(f"corrupt packet block at byte offset {block.offset}; skipped")
            return
        if block.type == BLOCK_EPB:
            index, high, low, caplen = struct.unpack_from(order + "IIII", body)
        else:
            index, _drops, high, low, caplen = struct.unpack_from(order + "HHIII", body)
        if 20 + caplen > len(body):
            warnings.append(
                f"corrupt packet block at byte offset {block.offset}: {caplen} bytes "
                "announced, the block is shorter; skipped"
            )
            return
        iface = section.get(index, block.offset)
        if iface is None:
            return
        opts = _options(body, 20 + caplen + (-caplen % 4), order)
        ticks = (high << 32) | low
        t = ticks / iface.ticks_per_second + iface.offset_seconds
        data = body[20 : 20 + caplen]
        yield from decoder.chunks(iface, t, data, _flags(opts, order), _comment(opts), block.offset)
    elif block.type == BLOCK_SPB:
        if len(body) < 4:
            warnings.append(f"corrupt simple packet block at byte offset {block.offset}; skipped")
            return
        iface = section.get(0, block.offset)
        if iface is None:
            return
        (original,) = struct.unpack_from(order + "I", body)
        length = min(original, len(body) - 4)
        if iface.snaplen:
            length = min(length, iface.snaplen)
        yield from decoder.chunks(iface, None, body[4 : 4 + length], None, "", block.offset)


def _batch_of(
    parts: list[bytes],
    ends: array[int],
    t_starts: array[float],
    t_ends: array[float],
    channel: int,
    direction: Direction,
) -> Reads:
    """The reads gathered in `parts` (emptied here) and the arrays as one batch; a NaN
    start time stands for none."""
    first = t_starts[0]
    reads = Reads(
        b"".join(parts),
        t_ends[-1],
        None if math.isnan(first) else first,
        channel,
        direction,
        ends=ends,
        t_starts=t_starts,
        t_ends=t_ends,
    )
    parts.clear()
    return reads
