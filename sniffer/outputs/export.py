"""Provides the exporters: frames for Wireshark (pcapng, link type 252), CSV/JSONL tables.

Wireshark export (the default, `modbus-tcp`): one packet per frame, link type 252
(exported PDU) naming Wireshark's Modbus/TCP dissector (`mbtcp`) with address tags, then
the frame's unit and PDU behind an MBAP header. Requests go from 192.0.2.1 port 1024
(the master) to 192.0.2.2 port 502 (the slaves), answers and exceptions back, so
Wireshark classifies every function code as query or response with no configuration;
the MBAP transaction id is the request's row number (modulo 65536), so Wireshark pairs
each answer with its request and shows the time between them. The packet comment
starts with the frame as it was on the line (`RTU 01 03 ... c4 0b; CRC c4 0b right`, or
`ASCII ":0103...\\r\\n"; LRC FA right` for a Modbus ASCII frame, as a JSON string), then
every problem modscope found. A frame whose CRC or LRC is wrong also has the EPB
CRC-error bit (bit 24). EPB flags carry the direction as seen from the master:
requests outbound (2), answers inbound (1). Rows whose direction is unknown go out as
queries (their comment says so). Noise spans and source events (reconnect, data lost)
go out for the `data` dissector, with a comment. A Modbus TCP row of a network
capture goes out the same way, its own MBAP header in the comment (`Modbus/TCP 00 07
...`). modscope reads such an export back as
the same frames: the comment gives back the bytes of the line, CRC and all.

`rtu` export (`export --as rtu`): the same packets, but each holds the RTU frame byte
for byte for Wireshark's `mbrtu` dissector (which classifies only FC 1-4, 15, 16 and
exceptions without a port preference, decodes nothing under 5 bytes and no unit 0); an
ASCII frame is given as the equivalent RTU frame with a computed CRC, and its comment
says so.

Tables: `frames` (the listing: text, JSONL or CSV), `transactions` (one row per request
with its answer, latency and status; answers without a request get a row too) and
`registers` (one row per register value: named by the device dictionary for bound
units, raw 16-bit words or bits for the others).
"""

from __future__ import annotations

import csv
import json
import struct
from collections.abc import Iterable, Iterator
from math import floor
from typing import Any, BinaryIO, TextIO, cast

from dissectors import mbap
from dissectors.envelope import open_ascii, open_rtu, rtu_frame
from sniffer import __version__, core
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.framing.tcp import MBAP
from sniffer.meaning.describe import VALUED_FLAGS, Describer, FrameDetail, Shared
from sniffer.model import LineSettings, Stamp
from sniffer.outputs.listing import (
    FORMATS,
    KIND_NAMES,
    shown_latency_max_ms,
    shown_latency_ms,
)
from sniffer.sources.linktypes import MBTCP_PORT, TcpEnds, build_mbtcp_pdu
from sniffer.sources.pcap import SEPARATION_MARGIN
from sniffer.sources.pcapng_writer import (
    EPB_FLAG_CRC_ERROR,
    EPB_FLAG_INBOUND,
    EPB_FLAG_OUTBOUND,
    LINKTYPE_WIRESHARK_UPPER_PDU,
    PcapngWriter,
    describe_interface,
    upper_pdu_record,
)
from sniffer.text import csv_row, json_line
from sniffer.vocab import STATUS_NAMES, Flag, Kind

WHATS = ("frames", "transactions", "registers")
PCAP_STYLES = ("modbus-tcp", "rtu")  # export --as: what each packet hands Wireshark
MASTER_IP = bytes((192, 0, 2, 1))  # TEST-NET-1 (RFC 5737): never a real host
SLAVE_IP = bytes((192, 0, 2, 2))
MASTER_PORT = 1024
TO_SLAVE = TcpEnds(MASTER_IP, SLAVE_IP, MASTER_PORT, MBTCP_PORT)
TO_MASTER = TcpEnds(SLAVE_IP, MASTER_IP, MBTCP_PORT, MASTER_PORT)
EXPORT_FORMATS = (*FORMATS, "pcapng", "parquet")
EXTENSIONS = {
    ".pcapng": "pcapng",
    ".parquet": "parquet",
    ".csv": "csv",
    ".jsonl": "jsonl",
    ".ndjson": "jsonl",
    ".json": "jsonl",
    ".txt": "text",
    ".log": "text",
}
TRANSACTION_COLUMNS = (
    "request", "t", "unit", "device", "function", "name", "request_summary",
    "response", "t_response", "latency_ms", "latency_max_ms", "status", "exception_code",
    "response_summary", "problems", "request_raw", "response_raw",
)  # fmt: skip
REGISTER_COLUMNS = (
    "index", "t", "unit", "device", "access", "table", "address", "name", "value",
    "value_unit", "text", "raw", "partial", "check_ok",
)  # fmt: skip


# -- Wireshark ---------------------------------------------------------------------------


def packet_for(d: FrameDetail) -> tuple[bytes, int, str]:
    """(link type 252 packet for `mbrtu`, EPB flags, comment) for one row (`--as rtu`)."""
    v = d.view
    problems = list(d.problem_texts)
    if v.kind == Kind.EVENT:
        return upper_pdu_record(b"", "data"), 0, d.summary or "event"
    if v.kind == Kind.NOISE:
        return upper_pdu_record(v.raw, "data"), 0, "; ".join(problems)
    flags = 0
    if v.kind == Kind.REQUEST:
        flags |= EPB_FLAG_OUTBOUND
    elif v.kind in (Kind.RESPONSE, Kind.EXCEPTION):
        flags |= EPB_FLAG_INBOUND
    if v.flags & Flag.CHECK_BAD:
        flags |= EPB_FLAG_CRC_ERROR
    if v.mbap:  # a Modbus TCP frame as it was, MBAP header and PDU
        return upper_pdu_record(v.raw, "mbtcp"), flags, "; ".join(problems)
    if v.ascii:
        envelope = open_ascii(v.raw)
        sent, want = envelope.sent, envelope.expected
        if sent is None or want is None or len(envelope.body) < 2:
            problems.insert(0, "Modbus ASCII frame that is not hex; exported as bytes")
            return upper_pdu_record(v.raw, "data"), flags, "; ".join(problems)
        verdict = "right" if sent == want else f"wrong, expected {want:02X}"
        problems.insert(
            0, f"carried as Modbus ASCII with LRC {sent:02X} ({verdict}); CRC computed here"
        )
        return upper_pdu_record(rtu_frame(envelope.body)), flags, "; ".join(problems)
    return upper_pdu_record(v.raw), flags, "; ".join(problems)


def _transaction_id(d: FrameDetail, base: int) -> int:
    """The MBAP transaction id: the request's row number, so an answer shares its
    request's id; an answer with no request, a broadcast or an unknown frame its own.
    Rows are numbered in the capture: the store's row `i` is row `base + i`."""
    v = d.view
    if v.kind != Kind.REQUEST and v.partner != NO_PARTNER:
        return (base + v.partner) & 0xFFFF
    return (base + v.index) & 0xFFFF


def line_bytes_text(raw: bytes, ascii_mode: bool) -> tuple[str, str, bytes | None]:
    """(`RTU 01 03 ...` or `ASCII ":01..\\r\\n"`, the check and its verdict, the unit and
    PDU) of a frame's bytes as the line carried them; the body is None when an ASCII
    frame is not hex."""
    if ascii_mode:
        envelope = open_ascii(raw)
        text = "ASCII " + json.dumps(raw.decode("latin-1"))
        sent, want = envelope.sent, envelope.expected
        if sent is None or want is None:
            return text, envelope.check_text or "no LRC", None
        check = envelope.check_text or f"LRC {sent:02X} right"
        return text, check, envelope.body
    rtu = open_rtu(raw)
    text = "RTU " + raw.hex(" ")
    if rtu.sent is None:
        return text, rtu.check_text, rtu.body or None
    return text, rtu.check_text or f"CRC {raw[-2]:02x} {raw[-1]:02x} right", rtu.body


def tcp_packet_for(d: FrameDetail) -> tuple[bytes, int, str]:
    """(link type 252 packet for `mbtcp`, EPB flags, comment) for one row (the default
    export: see the module's docstring)."""
    return _tcp_packet(d)[:3]


def _tcp_packet(d: FrameDetail, base: int = 0) -> tuple[bytes, int, str, int | None]:
    """`tcp_packet_for`, and where in the packet the MBAP transaction id lies (None
    when the packet has none); `base`: see `_transaction_id`."""
    v = d.view
    problems = list(d.problem_texts)
    if v.kind in (Kind.EVENT, Kind.NOISE):
        return (*packet_for(d), None)
    flags = 0
    if v.kind == Kind.REQUEST:
        flags |= EPB_FLAG_OUTBOUND
    elif v.kind in (Kind.RESPONSE, Kind.EXCEPTION):
        flags |= EPB_FLAG_INBOUND
    if v.flags & Flag.CHECK_BAD:
        flags |= EPB_FLAG_CRC_ERROR
    if v.flags & MBAP:  # a Modbus TCP row: its own header goes in the comment
        body: bytes | None = mbap.body(v.raw)
        head = "Modbus/TCP " + v.raw.hex(" ")
    else:
        shown, check, body = line_bytes_text(v.raw, v.ascii)
        problems = [p for p in problems if p != check]
        head = f"{shown}; {check}"
    if body is None or len(body) < 2:
        note = "not a Modbus frame that Wireshark can take; exported as bytes"
        return upper_pdu_record(v.raw, "data"), flags, "; ".join([head, note, *problems]), None
    if v.kind == Kind.UNKNOWN:
        problems.insert(0, "direction unknown; exported as a query")
    ends = TO_MASTER if v.kind in (Kind.RESPONSE, Kind.EXCEPTION) else TO_SLAVE
    packet = build_mbtcp_pdu(ends, _transaction_id(d, base), body[0], body[1:])
    # the MBAP header (id, protocol, length, unit) ends where the PDU begins
    at = len(packet) - (len(body) - 1) - 7
    return packet, flags, "; ".join([head, *problems]), at


class _Blocks:
    """Where the exporter's pcapng writer writes: the blocks are kept until the
    exporter passes them on, so that it can reuse a packet block's bytes."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []

    def write(self, data: bytes) -> int:
        self.parts.append(data)
        return len(data)

    def flush(self) -> None:
        pass


_EPB_TIME = struct.Struct("<II")  # an enhanced packet block's time: high and low words
_TID = struct.Struct(">H")
_DEVICE_SLOW = int(Flag.DEVICE_SLOW)
_REQUEST = int(Kind.REQUEST)
_MODE = int(Flag.ASCII | Flag.MBAP)
TICKS = 1_000_000_000  # the writer's default resolution (nanoseconds)
# what an exported packet's time is said to be, by the capture's stamps: each packet is
# stamped at its frame's end as the capture placed it (read ends stay read ends, good to
# the resolution the capture had, which the reader then takes as it is)
_EXPORTED_STAMPS = {Stamp.FRAME_START: Stamp.FRAME_END}
EXPORT_RUN = 4096  # rows a call of the compiled loop takes at most (see _write_compiled)


class PcapExporter:
    """Writes rows of a session's store as link type 252 packets, flushed after every
    `write`: for Wireshark's Modbus/TCP dissector (`style` "modbus-tcp", the default) or
    byte for byte for its RTU dissector ("rtu").

    A packet's block is the same for every row with the same content (see
    `Describer.shared`) but for its time and, for Modbus/TCP, its transaction id: the
    first such row's block is written by the pcapng writer and kept as a template,
    the next ones are that template with their time and id put in, and, for an answer
    with other values, its bytes (see `_spliced`): a polling capture repeats a few
    contents all day, so most rows never reach the pcapng writer. With the compiled
    core the templates are filled in C (see `_write_compiled`).

    A capture may be written a segment at a time (`sniffer.session.streamed`), each
    segment's rows a store of their own: `timing` gives the interface block what the
    times are worth over the whole capture (`exported_timing` with `Moves`; by default
    it is found from `describer.store`), and `base`, set before each segment's rows are
    written, the capture's number of the store's first row, which the transaction ids
    count from. The templates hold no row number, so they serve every segment."""

    def __init__(
        self,
        stream: BinaryIO,
        describer: Describer,
        line: LineSettings,
        *,
        name: str = "modscope",
        style: str = "modbus-tcp",
        header: bool = True,
        timing: tuple[Stamp, float] | None = None,
    ) -> None:
        if style not in PCAP_STYLES:
            raise ValueError(f"style must be one of {', '.join(PCAP_STYLES)}, not {style!r}")
        self.style = style
        self.packet_for = self._tcp_packet if style == "modbus-tcp" else self._rtu_packet
        self.describer = describer
        self.stream = stream
        self.line = line
        self._blocks = _Blocks()
        self.writer = PcapngWriter(
            cast(BinaryIO, self._blocks), application=f"modscope {__version__}"
        )
        # the times' worth goes with them, so that reading the export back gives the
        # latencies the capture gave, to what it says they are worth (`exported_timing`)
        if header and timing is None:
            timing = exported_timing(describer.store, line)
        self.interface = self.writer.add_interface(
            LINKTYPE_WIRESHARK_UPPER_PDU,
            name=name,
            description=describe_interface(line, timing=timing),
        )
        if not header:  # a parallel worker's range: its packets only
            self._blocks.parts.clear()
        self._pass_on()
        self.packets = 0
        self.base = 0  # the capture's number of the store's first row
        self._key = f"pcapng {self.style} {self.interface}"  # its templates' key in a memo
        self._last: Shared | None = None  # see `_rows`
        self._table: object | None = None  # the compiled core's templates (export_table)
        self._char = line.char_time  # a byte's time on the line (see `packet_time`)

    def _tcp_packet(self, d: FrameDetail) -> tuple[bytes, int, str, int | None]:
        return _tcp_packet(d, self.base)

    @staticmethod
    def _rtu_packet(d: FrameDetail) -> tuple[bytes, int, str, int | None]:
        return (*packet_for(d), None)

    def _pass_on(self) -> None:
        parts = self._blocks.parts
        if parts:
            self.stream.write(b"".join(parts))
            parts.clear()
        self.stream.flush()

    def write(self, rows: Iterable[int]) -> int:
        """Write the packets of `rows`, in order; returns how many."""
        describer = self.describer
        fast = core.FAST
        if (
            fast is not None
            and type(describer).contents is Describer.contents
            and type(describer).shared is Describer.shared
            and describer.shared_size > 0
            and type(describer.store) is FrameStore
        ):
            n = self._write_compiled(fast, rows)
        else:
            n = self._rows(rows)
        self._pass_on()
        self.packets += n
        return n

    def _write_compiled(self, fast: Any, rows: Iterable[int]) -> int:
        """`write` with the compiled core (sniffer/_core.c: export_rows): the blocks of the
        rows it holds a template for made there, every other row by `_rows` (`miss`),
        whose template it keeps under the row's keys. Its keys are the contents' (see
        `Describer.contents`) and, for a Modbus/TCP packet, keys of rows whose packet
        differs only in the bytes spliced in (`ex_packet_key` says which), so that most
        writes, echoes and exceptions of a polling capture take no new template. The rows
        it finds count as found for the describer's guard. What is left of the cost is
        the few rows handed to `_rows`, each of which describes a content and makes its
        template."""
        describer = self.describer
        store = describer.store
        store.sync()  # no column grows while the compiled loop holds them
        annotator = describer.annotator
        alike = self.style == "modbus-tcp"
        key = self._key
        parts = self._blocks.parts
        self._pass_on()

        def miss(i: int) -> tuple[bytes, _Template | None]:
            self._rows((i,))
            block = parts.pop()
            shared = self._last
            return block, None if shared is None else shared.memo.get(key)

        table = self._table
        if table is None:
            table = self._table = fast.export_table()
        columns = _PacketColumns(store)
        apart = (annotator.sunspec.units, annotator.windows_of)
        it = iter(rows)
        n = 0
        more = True
        while more:
            blocks, count, found, more = fast.export_rows(
                table, columns, it, store.notes, apart, annotator.bindings, alike,
                _DEVICE_SLOW, _MODE, VALUED_FLAGS, miss, EXPORT_RUN, self._char, _MBAP_FLAG,
                self.base,
            )  # fmt: skip
            self.stream.write(blocks)
            describer.count_found(found)
            n += count
        return n

    def _rows(self, rows: Iterable[int]) -> int:
        """The blocks of `rows`, in order, into the writer's blocks (the pure-Python core,
        and the compiled core's rows it has no template for); `_last` is the content of
        the last row (None if it had none)."""
        n = 0
        describer = self.describer
        store = describer.store
        kinds, partners, flags = store.kind, store.partner, store.flags
        streams, offsets, lengths, channels = (
            store.streams,
            store.offset,
            store.length,
            store.channel,
        )
        parts = self._blocks.parts
        append = parts.append
        key = self._key
        shared: Shared | None = None
        # a Modbus/TCP packet reads no register value: answers that differ only in their
        # values may share a content (see Describer.contents); their bytes are spliced
        # into the template, or, if it cannot take them, the row is written on its own
        alike = self.style == "modbus-tcp"
        char = self._char
        base = self.base
        for i, shared in describer.contents(rows, values=not alike):
            t = packet_time(store, i, char)
            if t < 0.0:
                t = 0.0
            if shared is None or flags[i] & _DEVICE_SLOW:
                self._write(describer.detail(i), t)
                n += 1
                continue
            template = shared.memo.get(key)
            if template is None:
                c = shared
                view = describer.view(i)
                # what a packet says besides its time and id: no latency (not a slow answer)
                d = FrameDetail(
                    view, c.name, c.summary, c.dissection, c.registers, c.problems, None, c.label
                )
                shared.memo[key] = self._template(d, t)
                n += 1
                continue
            first, head, middle, tail, spliced = template
            if alike:
                at = offsets[i]
                raw = bytes(streams[channels[i]][at : at + lengths[i]])
                if raw != first:
                    if spliced is None or tail is None:
                        self._write(describer.detail(i), t)
                        n += 1
                        continue
                    tail = _splice(spliced, raw)
            whole = floor(t)  # `time_ticks(t, TICKS)`, inline
            ticks = whole * TICKS + round((t - whole) * TICKS)
            if tail is None:
                append(head + _EPB_TIME.pack(ticks >> 32, ticks & 0xFFFFFFFF) + middle)
            else:
                partner = partners[i]
                tid = base + (partner if kinds[i] != _REQUEST and partner != NO_PARTNER else i)
                append(
                    head
                    + _EPB_TIME.pack(ticks >> 32, ticks & 0xFFFFFFFF)
                    + middle
                    + _TID.pack(tid & 0xFFFF)
                    + tail
                )
            n += 1
            if len(parts) >= 1024:
                self._pass_on()
        self._last = shared if n else None
        return n

    def _write(self, d: FrameDetail, t: float) -> tuple[bytes, int | None]:
        """Write row `d`'s packet with the writer; returns its block and where in the
        packet the transaction id lies (None when it has none)."""
        packet, flags, comment, at = self.packet_for(d)
        self.writer.write_packet(self.interface, t, packet, flags=flags, comment=comment or None)
        return self._blocks.parts[-1], at

    def _template(self, d: FrameDetail, t: float) -> _Template:
        """Write row `d`'s packet; returns its block as a template for the rows of its
        content: the row's bytes; the block's bytes before the time, those between the
        time and the transaction id (or to the end), and those after the id (None when
        the packet has no id); then, for an RTU frame whose bytes the block shows as
        they are (in the PDU and as hex in the comment), where they lie in those last
        bytes (see `_splice`)."""
        block, at = self._write(d, t)
        v = d.view
        # the block: type, length, interface (12 bytes), time (8), two lengths (8), packet
        if at is None:
            return v.raw, block[:12], block[20:], None, None
        tail = block[28 + at + 2 :]
        spliced = None if v.flags & _MODE else _spliced(tail, v.raw)
        return v.raw, block[:12], block[20 : 28 + at], tail, spliced


_MBAP_FLAG = int(Flag.MBAP)


def packet_time(store: FrameStore, i: int, char_time: float) -> float:
    """The time of row `i`'s packet: a frame's end, read back as the frame starting its
    bytes' line time before; for an answer that took longer than that (split over two
    host reads), its start plus its line time, so that read back it starts where the
    capture placed it and its latency (from its request's end, which that packet's time
    gives) is the capture's. (An answer placed in less than its line time keeps its
    end: `exported_timing` counts the difference.)"""
    t, end = store.t[i], store.t_end[i]
    if store.kind[i] in (Kind.RESPONSE, Kind.EXCEPTION) and not store.flags[i] & _MBAP_FLAG:
        return min(end, t + store.length[i] * char_time)
    return end


class _PacketColumns:
    """A store's columns as the compiled export reads them (sniffer/_core.c:
    export_rows), which makes each packet's time (`packet_time`) from `t` and `t_end`
    as it goes: nothing is kept per row."""

    __slots__ = (
        "channel",
        "fc",
        "flags",
        "kind",
        "length",
        "offset",
        "partner",
        "status",
        "streams",
        "t",
        "t_end",
        "unit",
    )

    def __init__(self, store: FrameStore) -> None:
        self.kind, self.flags, self.offset = store.kind, store.flags, store.offset
        self.length, self.channel, self.partner = store.length, store.channel, store.partner
        self.status, self.unit, self.fc = store.status, store.unit, store.fc
        self.streams, self.t, self.t_end = store.streams, store.t, store.t_end


def exported_timing(
    store: FrameStore, line: LineSettings, moved: float | None = None
) -> tuple[Stamp, float]:
    """What the times of an export of `store` are worth, said in its interface
    description: the capture's stamps, and its resolution widened by what one time per
    packet loses. Read back, each frame starts its bytes' line time before its packet's
    time (`packet_time`), and at least t3.5 after the frame before (modscope's reader
    keeps exported frames apart so): a request's end or an answer's start the capture
    placed closer than that (an answer within t3.5, a frame squeezed after another)
    moves, so each latency read back is good to the capture's resolution plus the
    largest such move (`largest_move`; `moved`, when given, is that move found over
    the capture a segment at a time by `Moves`, not over `store`'s rows)."""
    stamps = _EXPORTED_STAMPS.get(store.stamps, store.stamps)
    if moved is None:
        moved = largest_move(store, line)[0]
    if moved < 1e-6:  # (the microseconds a recording keeps its times to)
        moved = 0.0
    return stamps, store.resolution + moved


def largest_move(
    store: FrameStore, line: LineSettings, last: float | None = None
) -> tuple[float, float | None]:
    """`exported_timing`'s largest move over `store`'s rows (by the compiled core's
    `export_moved` when there is one), and the end of its last frame as read back (None:
    no frame); `last`: that of the frame before its first row (None: none)."""
    store.sync()
    char, apart = line.char_time, line.t35 + SEPARATION_MARGIN
    fast = core.FAST
    if fast is not None and type(store) is FrameStore:
        found: tuple[float, float | None] = fast.export_moved(store, char, apart, _MBAP_FLAG, last)
        return found
    return _largest_move(store, char, apart, last)


class Moves:
    """`exported_timing`'s largest move over a capture read a segment at a time
    (`sniffer.session.streamed.learn`): each segment's store `add`ed in turn, the end
    of the frame before carried from one segment to the next, as one store of every row
    gives it."""

    def __init__(self, line: LineSettings) -> None:
        self.line = line
        self.moved = 0.0
        self.last: float | None = None  # the end of the last frame added, as read back

    def add(self, store: FrameStore) -> None:
        moved, self.last = largest_move(store, self.line, self.last)
        self.moved = max(self.moved, moved)


def _largest_move(
    store: FrameStore, char: float, apart: float, last: float | None
) -> tuple[float, float | None]:
    """`largest_move` in Python (see sniffer/_core.c: export_moved)."""
    moved = 0.0
    kinds, flags = store.kind, store.flags
    for i, (t, n) in enumerate(zip(store.t, store.length, strict=True)):
        kind = kinds[i]
        if kind == Kind.EVENT or flags[i] & Flag.MBAP or not n:
            continue
        at = packet_time(store, i, char)
        start = at - n * char if last is None else max(at - n * char, last + apart)
        last = max(at, start)
        if kind == Kind.REQUEST:
            moved = max(moved, abs(last - store.t_end[i]))
        elif kind != Kind.NOISE:
            moved = max(moved, abs(start - t))
    return moved, last


_Spliced = tuple[bytes, bytes, bytes, bytes]
_Template = tuple[bytes, bytes, bytes, bytes | None, _Spliced | None]


def _spliced(tail: bytes, raw: bytes) -> _Spliced | None:
    """How the block's bytes after the transaction id are made of an RTU frame's bytes
    `raw`: (the bytes before its PDU, before its hex in the comment, between that and
    its CRC's hex, and after), so that `_splice` puts another frame of the
    same length, unit, code and byte count in; None if the block does not show `raw`
    that way (checked by making it again).

    An answer that differs from another only in its values is described alike (see
    Describer.contents): its packet is the other's with its own bytes put in, a small
    part of the cost of describing and writing it."""
    n = len(raw)
    pdu_end = 5 + n - 3  # protocol id, length and unit (5 bytes), then the PDU: raw[1:-2]
    said = f"RTU {raw.hex(' ')}; CRC {raw[-2:].hex(' ')} right".encode()
    start = tail.find(said, pdu_end)
    if n < 5 or start < 0:
        return None
    hex_at = start + 4
    crc_at = hex_at + 3 * n - 1 + 6
    made = (
        tail[:5],
        tail[pdu_end:hex_at],
        tail[hex_at + 3 * n - 1 : crc_at],
        tail[crc_at + 5 :],
    )
    return made if _splice(made, raw) == tail else None


def _splice(spliced: _Spliced, raw: bytes) -> bytes:
    """The bytes after the transaction id with `raw`'s bytes put in (see `_spliced`)."""
    pdu, text, crc, rest = spliced
    return b"".join(
        (pdu, raw[1:-2], text, raw.hex(" ").encode(), crc, raw[-2:].hex(" ").encode(), rest)
    )


# -- transactions and registers -------------------------------------------------------------


def _exception_code(d: FrameDetail) -> int | None:
    if not d.view.exception:
        return None
    found = d.dissection.field("exception_code") if d.dissection is not None else None
    return found.value if found is not None and isinstance(found.value, int) else None


def transaction_records(
    describer: Describer, rows: Iterable[int], base: int = 0
) -> Iterator[dict[str, Any]]:
    """One record per request (with its answer, if any) and per answer without request;
    rows numbered `base` on (a segment of a capture: `sniffer.session.streamed`)."""
    store = describer.store
    for i in rows:
        kind = store.kind[i]
        if kind == Kind.REQUEST:
            req: FrameDetail | None = describer.detail(i)
            j = store.partner[i]
            resp = describer.detail(j) if j != NO_PARTNER else None
        elif kind in (Kind.RESPONSE, Kind.EXCEPTION, Kind.UNKNOWN) and (
            store.partner[i] == NO_PARTNER
        ):
            req, resp = None, describer.detail(i)
        else:
            continue
        main = req if req is not None else resp
        assert main is not None
        v = main.view
        problems = [*(req.problem_texts if req else ()), *(resp.problem_texts if resp else ())]
        # the answer's latency pair, as the listing gives it (pairing.measure)
        latency = bound = None
        if req is not None and resp is not None:
            latency, bound = shown_latency_ms(resp), shown_latency_max_ms(resp)
        yield {
            "request": req.view.index + base if req else None,
            "t": req.view.t if req else None,
            "unit": v.unit,
            "device": main.label,
            "function": v.function,
            "name": main.name,
            "request_summary": req.summary if req else "",
            "response": resp.view.index + base if resp else None,
            "t_response": resp.view.t if resp else None,
            "latency_ms": latency,
            "latency_max_ms": bound,
            "status": STATUS_NAMES[v.status] or KIND_NAMES[Kind(v.kind)],
            "exception_code": _exception_code(resp) if resp else None,
            "response_summary": resp.summary if resp else "",
            "problems": list(dict.fromkeys(problems)),
            "request_raw": req.view.raw.hex() if req else "",
            "response_raw": resp.view.raw.hex() if resp else "",
        }


def register_records(
    describer: Describer, rows: Iterable[int], base: int = 0
) -> Iterator[dict[str, Any]]:
    """One record per register or bit value a frame carries (named where a dictionary
    binds the unit; raw values otherwise); rows numbered `base` on."""
    store = describer.store
    for i in rows:
        if store.kind[i] not in (Kind.REQUEST, Kind.RESPONSE):
            continue
        d = describer.detail(i)
        v = d.view
        common = {"index": v.index + base, "t": v.t, "unit": v.unit, "device": d.label}
        if d.registers:
            for r in d.registers:
                yield {
                    **common,
                    "access": "write" if v.kind == Kind.REQUEST else "read",
                    "table": r.table,
                    "address": r.address,
                    "name": r.name,
                    "value": r.value,
                    "value_unit": r.unit,
                    "text": r.text,
                    "raw": list(r.raw),
                    "partial": r.partial,
                    "check_ok": v.check_ok,
                }
            continue
        if d.dissection is None:
            continue
        for data in d.dissection.data:
            if data.address is None:
                continue
            for k, value in enumerate(data.values):
                yield {
                    **common,
                    "access": "write" if data.write else "read",
                    "table": data.table,
                    "address": data.address + k,
                    "name": "",
                    "value": value,
                    "value_unit": "",
                    "text": str(value),
                    "raw": [value],
                    "partial": False,
                    "check_ok": v.check_ok,
                }


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6f}".rstrip("0").rstrip(".") if value == value else "nan"
    if isinstance(value, list):
        joiner = "; " if value and isinstance(value[0], str) else " "
        return joiner.join(str(x) for x in value)
    return str(value)


def write_table(
    out: TextIO,
    fmt: str,
    columns: tuple[str, ...],
    records: Iterable[dict[str, Any]],
    *,
    raw_csv: bool = False,
    header: bool = True,
) -> int:
    """Records as JSONL or CSV (with a header row unless not `header`). Returns the
    number written. CSV cells go through `sniffer.text.csv_cell` (formula guard unless
    `raw_csv`)."""
    n = 0
    if fmt == "csv":
        writer = csv.writer(out)
        if header:
            writer.writerow(columns)
        for rec in records:
            writer.writerow(csv_row((_cell(rec.get(c)) for c in columns), raw=raw_csv))
            n += 1
    elif fmt == "jsonl":
        for rec in records:
            out.write(json_line(rec) + "\n")
            n += 1
    else:
        raise ValueError(f"{fmt} cannot hold this table; use csv or jsonl")
    return n
