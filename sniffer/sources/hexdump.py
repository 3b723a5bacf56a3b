"""Provides the hex text dump readers: `socat -x -v` logs and text2pcap-style dumps.

socat: each transfer is a header line `> 2024/05/01 12:00:00.123456  length=8 from=0
to=7` followed by lines of hex bytes (and an ASCII column), then `--`. `>` (first address
to second) is Direction.MASTER, `<` Direction.SLAVE: labels on one stream (channel 0) in
the order socat relayed them, hints in the pipeline's sense. The header
time is local wall-clock time and becomes the chunk's `t_end`. socat 1.7.4 prints the
microseconds as nine digits (`.000821692` for .821692 s): a file whose nine-digit
fractions are all below 1,000,000 is read that way.

text2pcap (as `od -Ax -tx1` writes, which text2pcap reads): each line is an offset of
more than two hex digits, a colon, space or tab, then bytes as two hex digits; offset 0
starts a packet; an offset smaller than expected cuts the previous line (its ASCII
column looked like hex); any other unexpected offset ends the packet with a warning.
Lines starting with `#` are comments. The text between packets may start with a
direction (`I` inbound: Direction.SLAVE; `O` outbound: Direction.MASTER, the master's
point of view, as text2pcap -D writes it; both on channel 0, as labels) and a time, which
becomes the packet's `t_end`. Times understood: ISO 8601 (`2024-05-01T12:00:00.5Z`,
a space instead of `T`, an optional UTC offset; none means local time),
`2024/05/01 12:00:00.5`, a time of day `12:00:00.5` (seconds since midnight), and
plain seconds `1714564800.5`. Packets without a time follow the previous one by one
character time per byte, as raw bytes do.

Both are read a block at a time. A line longer than `MAX_LINE` (1 MiB; no dump writes
one) is read on to its end unkept and skipped with a warning giving its line, length and
first characters: in a socat log it is a line that holds no bytes (a record missing them
says so), in a text2pcap dump text between packets (it ends the packet before it).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path

from sniffer.model import Chunk, Direction, Labels, LineSettings, SourceInfo, Stamp
from sniffer.sources.base import Capture, ReadOptions, Warnings
from sniffer.sources.detect import SOCAT_HEADER
from sniffer.sources.logs import base as logs_base
from sniffer.sources.logs.base import LONG_HEAD, LongLine

_HEX_RUN = re.compile(r"^ ((?:[0-9A-Fa-f]{2} )*[0-9A-Fa-f]{2})(?: |$)")
_OFFSET = re.compile(r"^[\s>]*([0-9A-Fa-f]{3,})(?:[:\s]|$)(.*)$")
_BYTE = re.compile(r"^[0-9A-Fa-f]{2}$")
_DIRECTION = re.compile(r"^([IO])(?:\s+|$)(.*)$")
_ISO = re.compile(
    r"^(\d{4})-(\d\d)-(\d\d)[T ](\d\d):(\d\d):(\d\d)(?:[.,](\d+))?"
    r"\s*(Z|[+-]\d\d:?\d\d)?(?:\s|$)"
)
_SLASHED = re.compile(r"^(\d{4})/(\d\d)/(\d\d)[ T](\d\d):(\d\d):(\d\d)(?:\.(\d+))?(?:\s|$)")
_TIME_OF_DAY = re.compile(r"^(\d{1,2}):(\d\d):(\d\d)(?:\.(\d+))?(?:\s|$)")
# seconds: any number int() takes (it refuses more than 4,300 digits); a time past 2286
# is then reported as impossible, as for any other form
_SECONDS = re.compile(r"^(\d{1,4000})\.(\d+)(?:\s|$)")
_TIME_FRACTION = re.compile(r"^[\d/:T -]*\d[.,](\d+)")
_MASTER_LABEL = {0: "> (first address to second)", 1: "< (second address to first)"}


def _fraction(digits: str | None) -> float:
    return logs_base.fraction_digits(digits)[0]


def _wall_clock(fields: tuple[str, ...], fraction: float, zone: str | None) -> float | None:
    """Unix time of a date and time (local time unless `zone` says otherwise)."""
    try:
        year, month, day, hour, minute, second = (int(f) for f in fields)
        tzinfo = None
        if zone == "Z":
            tzinfo = UTC
        elif zone:
            sign = -1 if zone[0] == "-" else 1
            digits = zone[1:].replace(":", "")
            delta = timedelta(hours=int(digits[:2]), minutes=int(digits[2:]))
            tzinfo = timezone(sign * delta)
        moment = datetime(year, month, day, hour, minute, second, tzinfo=tzinfo)
        return moment.timestamp() + fraction
    except (ValueError, OverflowError, OSError):
        return None


def parse_time(text: str) -> float | None:
    """The time at the start of `text` in one of the forms in the module doc, or None."""
    if match := _ISO.match(text):
        return _wall_clock(match.groups()[:6], _fraction(match[7]), match[8])
    if match := _SLASHED.match(text):
        return _wall_clock(match.groups()[:6], _fraction(match[7]), None)
    if match := _TIME_OF_DAY.match(text):
        hours, minutes, seconds = int(match[1]), int(match[2]), int(match[3])
        return hours * 3600 + minutes * 60 + seconds + _fraction(match[4])
    if match := _SECONDS.match(text):
        return int(match[1]) + _fraction(match[2])
    return None


# ---------------------------------------------------------------- socat


# the files are read a block at a time, never whole: as Latin-1 (every byte one
# character, so a line's length is its length in bytes) and cut where `str.splitlines`
# cuts (LF, CR, CR LF, VT, FF, FS, GS, RS, NEL); a line past MAX_LINE bytes is read on
# to its end unkept and skipped, with a warning (`long_line`)
_BLOCK = 1 << 20
_ENDS = ("\r\n", "\n", "\r", "\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85")


def _lines(path: Path, warnings: list[str] | None = None) -> Iterator[tuple[int, str]]:
    """The file's lines with their line ends (`str.splitlines(keepends=True)` of the
    whole text), read a block at a time, each with its length: a line longer than
    `MAX_LINE` is given as "" with its length (line end included), and told in
    `warnings`."""
    limit = logs_base.MAX_LINE
    rest = ""
    long: LongLine | None = None  # the start of a long line read on; the end of it in `rest`
    number = 0

    def told(line: LongLine, end: str) -> tuple[int, str]:
        if warnings is not None:
            head = line.head.decode("latin-1")
            warnings.append(logs_base.long_line(str(path), number, line.length, head))
        return line.length + len(end), ""

    with path.open("rb") as handle:
        while block := handle.read(_BLOCK):
            lines = (rest + block.decode("latin-1")).splitlines(keepends=True)
            rest = lines.pop()
            if rest.endswith(_ENDS) and not rest.endswith("\r"):
                lines.append(rest)  # complete (a CR may yet be followed by its LF)
                rest = ""
            for line in lines:
                number += 1
                bare = _bare(line)
                if long is not None:
                    long = LongLine(long.length + len(bare), long.head)
                    yield told(long, line[len(bare) :])
                    long = None
                elif len(bare) > limit:
                    head = bare[:LONG_HEAD].encode("latin-1")
                    yield told(LongLine(len(bare), head), line[len(bare) :])
                else:
                    yield len(line), line
            if long is None and len(rest) - rest.endswith("\r") > limit:
                long = LongLine(0, rest[:LONG_HEAD].encode("latin-1"))
            if long is not None:  # keep the last character: a CR may be followed by LF
                long = LongLine(long.length + len(rest) - 1, long.head)
                rest = rest[-1:]
    if long is not None:
        number += 1
        bare = _bare(rest)
        yield told(LongLine(long.length + len(bare), long.head), rest[len(bare) :])
    elif rest:
        number += 1
        bare = _bare(rest)
        if len(bare) > limit:
            yield told(LongLine(len(bare), bare[:LONG_HEAD].encode("latin-1")), rest[len(bare) :])
        else:
            yield len(rest), rest


def _bare(line: str) -> str:
    """A line without its line end (as `str.splitlines()` gives it)."""
    for end in _ENDS:
        if line.endswith(end):
            return line[: -len(end)]
    return line


def _pieces(path: Path) -> Iterator[str]:
    """The file's text in pieces of about a block, each ending at an LF (where a
    multi-line regular expression's `^` matches at the next piece's start). A stretch of
    more than `MAX_LINE` bytes without an LF is left out, up to its LF (no socat header
    is that long; `_lines` skips such a line)."""
    limit = logs_base.MAX_LINE
    rest = ""
    skip = False  # leaving out a stretch without an LF, up to its LF
    with path.open("rb") as handle:
        while block := handle.read(_BLOCK):
            text = rest + block.decode("latin-1")
            if skip:
                end = text.find("\n")
                if end < 0:
                    rest = ""
                    continue
                skip, text = False, text[end + 1 :]
            cut = text.rfind("\n") + 1
            rest = text[cut:]
            if cut:
                yield text[:cut]
            if len(rest) > limit:
                skip, rest = True, ""
    if rest:
        yield rest


def _socat_microsecond_bug(path: Path) -> bool:
    nine = other = 0
    for piece in _pieces(path):
        for match in SOCAT_HEADER.finditer(piece):
            digits = match[8]
            if not digits:
                continue
            if len(digits) == 9 and digits.startswith("000"):
                nine += 1
            else:
                other += 1
    return bool(nine) and not other


def open_socat(path: Path, options: ReadOptions) -> Capture:
    """Open a `socat -x -v` log."""
    micro_bug = _socat_microsecond_bug(path)
    line = options.line(None)
    # both directions pass through socat in turn: one stream, `>`/`<` as labels
    info = SourceInfo(
        path=str(path),
        format="socat",
        line=line,
        channels={0: "socat (> and < labels)"},
        stamps=Stamp.PRINT,
        resolution=1e-6,
        labels=Labels.HINT,
    )
    warnings = Warnings()
    chunks = _socat_chunks(_lines(path, warnings), micro_bug, warnings)
    return Capture(info=info, _chunks=chunks, warnings=warnings)


@dataclass
class _SocatRecord:
    direction: str
    t: float
    length: int
    line_number: int
    offset: int
    data: bytearray


def _socat_chunks(
    lines: Iterable[tuple[int, str]], micro_bug: bool, warnings: list[str]
) -> Iterator[Chunk]:
    record: _SocatRecord | None = None
    offset = 0

    def finish(rec: _SocatRecord) -> Iterator[Chunk]:
        if len(rec.data) < rec.length:
            warnings.append(
                f"socat record at line {rec.line_number} (byte offset {rec.offset}) announces "
                f"{rec.length} bytes but has {len(rec.data)}; the record is skipped"
            )
            return
        master = rec.direction == ">"
        yield Chunk(
            data=bytes(rec.data),
            t_end=rec.t,
            channel=0,
            direction=Direction.MASTER if master else Direction.SLAVE,
        )

    for number, (size, raw_line) in enumerate(lines, start=1):
        line_offset = offset
        offset += size
        line = raw_line.rstrip("\r\n")  # "" for a line past MAX_LINE: nothing readable
        header = SOCAT_HEADER.match(line)
        if header:
            if record is not None:
                yield from finish(record)
            digits = header[8]
            if micro_bug and digits and len(digits) == 9:
                fraction = int(digits) / 1e6
            else:
                fraction = _fraction(digits)
            t = _wall_clock(tuple(header.groups()[1:7]), fraction, None)
            if t is None:
                warnings.append(f"socat header at line {number} has an impossible time; skipped")
                record = None
                continue
            record = _SocatRecord(header[1], t, int(header[9]), number, line_offset, bytearray())
            continue
        if record is None:
            continue
        if line.strip() == "--":
            yield from finish(record)
            record = None
            continue
        hexes = _HEX_RUN.match(line)
        if hexes is None:
            continue
        data = bytes.fromhex(hexes[1])
        room = record.length - len(record.data)
        if len(data) > room:
            warnings.append(
                f"socat record at line {record.line_number} has more bytes than its "
                f"length={record.length}; the extra ones at line {number} are ignored"
            )
            data = data[:room]
        record.data += data
    if record is not None:
        yield from finish(record)


# ---------------------------------------------------------------- text2pcap


_DIRECTIONS = {"O": Direction.MASTER, "I": Direction.SLAVE}


def _survey(lines: Iterable[tuple[int, str]]) -> tuple[bool, Stamp, float]:
    """Whether the text between packets gives directions (`I`, `O`), and what the packet
    times are: print times with their coarsest resolution, or none."""
    directions = False
    stamps, resolution = Stamp.NONE, 0.0
    for _, text_line in lines:
        raw_line = _bare(text_line)
        rest = raw_line.strip()
        if not rest or rest.startswith("#") or _OFFSET.match(raw_line):
            continue
        if direction := _DIRECTION.match(rest):
            directions = True
            rest = direction[2].strip()
        if parse_time(rest) is None:
            continue
        fraction = _TIME_FRACTION.match(rest)
        stamps = Stamp.PRINT
        resolution = max(resolution, 10.0 ** -len(fraction[1]) if fraction else 1.0)
    return directions, stamps, resolution


def open_hexdump(path: Path, options: ReadOptions) -> Capture:
    """Open a text2pcap-style hex dump."""
    line = options.line(None)
    # O and I lines are one logger's sends and receives in turn: one stream, labelled
    directions, stamps, resolution = _survey(_lines(path))
    info = SourceInfo(
        path=str(path),
        format="hexdump",
        line=line,
        channels={0: "hexdump (O/I labels)" if directions else "hexdump"},
        stamps=stamps,
        resolution=resolution,
        labels=Labels.HINT if directions else Labels.NONE,
    )
    warnings = Warnings()
    chunks = _hexdump_chunks(_lines(path, warnings), line, warnings)
    return Capture(info=info, _chunks=chunks, warnings=warnings)


def _line_bytes(rest: str) -> bytes:
    """The bytes after an offset: two-hex-digit tokens up to the first other token."""
    out = bytearray()
    for token in rest.split():
        if not _BYTE.match(token):
            break
        out.append(int(token, 16))
    return bytes(out)


@dataclass
class _Packet:
    data: bytearray
    last_offset: int  # offset of the most recent line
    last_length: int  # bytes that line contributed
    t: float | None
    direction: str


def _hexdump_chunks(
    lines: Iterable[tuple[int, str]], line: LineSettings, warnings: list[str]
) -> Iterator[Chunk]:
    packet: _Packet | None = None
    t_prev = 0.0
    pending_time: float | None = None
    pending_direction = ""
    preamble_open = True  # the next preamble line is the first after a packet
    skipping = False  # after an unexpected offset, until the next offset 0
    char = line.char_time

    def finish(p: _Packet) -> Iterator[Chunk]:
        nonlocal t_prev
        if not p.data:
            return
        t = p.t if p.t is not None else t_prev + len(p.data) * char
        t_start = None if p.t is not None else t_prev
        t_prev = t
        direction = _DIRECTIONS.get(p.direction, Direction.UNKNOWN)
        yield Chunk(data=bytes(p.data), t_end=t, t_start=t_start, direction=direction)

    offset = 0
    for number, (size, raw_line) in enumerate(lines, start=1):
        line_offset = offset
        offset += size
        stripped = raw_line.strip()
        if not stripped and not raw_line and size:
            stripped = "\0"  # a line past MAX_LINE, skipped: text between packets, unread
        if not stripped or stripped.startswith("#"):
            continue
        match = _OFFSET.match(raw_line.rstrip("\r\n"))
        if match is None:  # preamble text between packets
            if packet is not None:
                yield from finish(packet)
                packet = None
            if preamble_open:
                preamble_open = False
                rest = stripped
                if direction := _DIRECTION.match(rest):
                    pending_direction = direction[1]
                    rest = direction[2].strip()
                pending_time = parse_time(rest)
            continue
        position = int(match[1], 16)
        data = _line_bytes(match[2])
        if position == 0:
            if packet is not None:
                yield from finish(packet)
            packet = _Packet(bytearray(data), 0, len(data), pending_time, pending_direction)
            pending_time, pending_direction = None, ""
            preamble_open = True
            skipping = False
            continue
        if packet is None or skipping:
            continue
        expected = packet.last_offset + packet.last_length
        if packet.last_offset < position <= expected:
            cut = expected - position  # the previous line's ASCII column looked like hex
            if cut:
                del packet.data[len(packet.data) - cut :]
            packet.data += data
            packet.last_offset, packet.last_length = position, len(data)
            continue
        warnings.append(
            f"hexdump line {number} (byte offset {line_offset}): offset {position:#x}, "
            f"expected {expected:#x}; the packet ends there"
        )
        yield from finish(packet)
        packet = None
        skipping = True
    if packet is not None:
        yield from finish(packet)
