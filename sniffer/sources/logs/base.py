"""Provides what every log reader shares: the file's text and lines, printed times,
records (bytes or an event, with the line's time and direction), and the chunks made of
them, on one channel for a serial log or a channel per connection direction for a log of
Modbus TCP (see `route`).

A record is what one logged line (or block) shows: bytes with the direction its label
gives, or an event (an error or a notice the program printed, no bytes). Chunks keep the
file's order; `t_end` is the printed time. Nothing here raises on content.
"""

from __future__ import annotations

import codecs
import marshal
import re
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from datetime import datetime
from pathlib import Path
from typing import Any, BinaryIO, Generic, TypeVar

from sniffer.model import Chunk, Direction, Labels, LineSettings, Stamp
from sniffer.sources.base import Warnings
from sniffer.sources.net.carrier import MBAP_CARRIERS, MODBUS_TCP, ChannelLabel, Votes

T = TypeVar("T")
DAY = 86_400.0
ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")
HEX2 = re.compile(r"^[0-9A-Fa-f]{2}$")

# ---------------------------------------------------------------- text and time


def decode_text(raw: bytes) -> str | None:
    """The file's text: UTF-8, else GBK (sscom saves its logs so), else None for binary."""
    if b"\0" in raw:
        return None
    for encoding in ("utf-8", "gbk"):
        try:
            return raw.decode(encoding)
        except UnicodeDecodeError:
            continue
    return None


def decode_head(head: bytes) -> str | None:
    """Like decode_text, for the first bytes of a file (a character may be cut at the end)."""
    if b"\0" in head:
        return None
    for encoding in ("utf-8", "gbk"):
        text = head.decode(encoding, errors="replace")
        if text.count("\ufffd") <= 2:
            return text
    return None


# ---------------------------------------------------------------- the file, line by line

BLOCK = 1 << 20  # bytes read at a time
MAX_LINE = 1 << 20  # bytes a line may hold (before its line end); a longer one is skipped
LONG_HEAD = 40  # characters of a skipped line's start said in its warning
Lines = Callable[[], Iterator[tuple[int, str]]]
"""A file's numbered lines, from the start again at each call (a reader may go over the
file more than once: what it decides from the whole file first, then its records)."""


def numbered(lines: Iterable[str]) -> Lines:
    """`Lines` over lines held in memory, numbered from 1."""
    return lambda: enumerate(lines, start=1)


def long_line(where: str, number: int, length: int, head: str) -> str:
    """The warning for a line longer than `MAX_LINE` bytes, skipped: no log or export
    writes such a line, so it is damage (a file of binary junk, a line end lost); its
    first characters and its length are said, not its text."""
    return (
        f"{where} line {number}: a line of {length:,} bytes, more than the {MAX_LINE:,} a "
        f"line may hold; the line is skipped (it starts {head!r})"
    )


@dataclass(frozen=True, slots=True)
class LongLine:
    """A line longer than `MAX_LINE`, read on to its end in pieces and not kept: its
    length in bytes (without its line end) and its first bytes."""

    length: int
    head: bytes


@dataclass(frozen=True, slots=True)
class TextFile:
    """A text file read line by line, never whole: its encoding (as `decode_text` would
    choose for the whole file: UTF-8, else GBK, else Latin-1, which takes any byte; a file
    with a NUL byte is Latin-1) and where its lines end (LF, or CR in a file without any
    LF), both found by one pass over the file. Lines are as `split_lines` cuts them.

    A line longer than `MAX_LINE` bytes is read on to its end a block at a time and not
    kept: `lines` gives it as an empty line (nothing readable) and puts a warning
    (`long_line`) in `warnings`, once however many times the file is read.
    Memory: a block of `BLOCK` bytes and a line of at most `MAX_LINE`."""

    path: Path
    encoding: str
    cut: bytes
    size: int
    errors: str = "strict"  # how a byte the encoding does not take is read
    warnings: list[str] = field(default_factory=list, compare=False)
    said: list[int] = field(default_factory=lambda: [0], compare=False)  # the last long line told

    @classmethod
    def survey(
        cls,
        path: Path,
        encodings: Sequence[str] = ("utf-8", "gbk"),
        warnings: list[str] | None = None,
    ) -> TextFile:
        """The file's encoding (the first of `encodings` the whole file decodes as,
        else Latin-1) and line ends; `warnings` is where its long lines are told."""
        nul = has_lf = False
        size = 0
        first = codecs.getincrementaldecoder(encodings[0])() if encodings else None
        with path.open("rb") as handle:
            while block := handle.read(BLOCK):
                size += len(block)
                nul = nul or b"\0" in block
                has_lf = has_lf or b"\n" in block
                if first is not None and not nul and not _decodes(first, block, False):
                    first = None
        encoding = "latin-1"
        if not nul and first is not None and _decodes(first, b"", True):
            encoding = encodings[0]
        elif not nul:
            encoding = next((n for n in encodings[1:] if _whole_decodes(path, n)), encoding)
        cut = b"\n" if has_lf else b"\r"
        return cls(path, encoding, cut, size, warnings=[] if warnings is None else warnings)

    def lines(self) -> Iterator[tuple[int, str]]:
        """The numbered lines, from the first."""
        number = 0
        with self.path.open("rb") as handle:
            for raw in self._raw_lines(handle):
                number += 1
                if isinstance(raw, LongLine):
                    self._tell(number, raw)
                    yield number, ""
                else:
                    yield number, raw.decode(self.encoding, self.errors)

    def _tell(self, number: int, line: LongLine) -> None:
        if number > self.said[0]:  # a later pass over the file told it already
            self.said[0] = number
            head = line.head.decode(self.encoding, "replace")
            self.warnings.append(long_line(str(self.path), number, line.length, head))

    def count(self) -> int:
        """How many lines `lines` gives."""
        with self.path.open("rb") as handle:
            return sum(1 for _ in self._raw_lines(handle))

    def _raw_lines(self, handle: BinaryIO) -> Iterator[bytes | LongLine]:
        limit = MAX_LINE
        if self.cut == b"\n":
            read = handle.readline
            while raw := read(limit + 1):
                if len(raw) > limit and not raw.endswith(b"\n"):
                    yield _read_on(read, raw)
                    continue
                if raw.endswith(b"\n"):
                    raw = raw[:-1]
                yield raw[:-1] if raw.endswith(b"\r") else raw
            return
        # no LF in the file: lines end at CR, and a file ending with CR has an empty last
        # line (as `split_lines` has it)
        rest = b""
        long: LongLine | None = None  # the start of a long line read on
        seen = False
        while block := handle.read(BLOCK):
            seen = True
            if long is not None:
                end = block.find(b"\r")
                if end < 0:
                    long = LongLine(long.length + len(block), long.head)
                    continue
                yield LongLine(long.length + end, long.head)
                long, block = None, block[end + 1 :]
            parts = (rest + block).split(b"\r")
            rest = parts.pop()
            for part in parts:
                yield part if len(part) <= limit else LongLine(len(part), part[:LONG_HEAD])
            if len(rest) > limit:
                long, rest = LongLine(len(rest), rest[:LONG_HEAD]), b""
        if long is not None:
            yield long
        elif seen:
            yield rest if len(rest) <= limit else LongLine(len(rest), rest[:LONG_HEAD])

    def lines_reversed(self, total: int) -> Iterator[tuple[int, str]]:
        """The numbered lines from the last to the first (`total`: how many there are),
        read backwards a block at a time (a long line as in `lines`)."""
        number = total + 1
        for raw in self._raw_reversed():
            number -= 1
            if isinstance(raw, LongLine):
                self._tell(number, raw)
                yield number, ""
            else:
                yield number, raw.decode(self.encoding, self.errors)

    def _raw_reversed(self) -> Iterator[bytes | LongLine]:
        limit, cut = MAX_LINE, self.cut
        with self.path.open("rb") as handle:
            end = handle.seek(0, 2)
            if end == 0:
                return
            pos, rest, last = end, b"", True
            long: LongLine | None = None  # the end of a long line, read back from its end
            while pos > 0:
                step = min(BLOCK, pos)
                pos -= step
                handle.seek(pos)
                block = handle.read(step)
                if long is not None:
                    start = block.rfind(cut)
                    piece = block[start + 1 :]
                    long = LongLine(long.length + len(piece), (piece + long.head)[:LONG_HEAD])
                    if start < 0:
                        continue
                    last = False
                    yield long
                    long, block = None, block[:start]
                parts = (block + rest).split(cut)
                rest = parts[0]
                for part in reversed(parts[1:]):
                    if last and cut == b"\n" and part == b"":
                        last = False
                        continue  # the LF that ends the file starts no line
                    last = False
                    yield self._trim(part) if len(part) <= limit else self._trim_long(part)
                if len(rest) > limit:
                    long, rest = LongLine(len(rest), rest[:LONG_HEAD]), b""
            if long is not None:
                yield long
            else:
                yield self._trim(rest) if len(rest) <= limit else self._trim_long(rest)

    def _trim(self, raw: bytes) -> bytes:
        return raw[:-1] if self.cut == b"\n" and raw.endswith(b"\r") else raw

    @staticmethod
    def _trim_long(raw: bytes) -> LongLine:
        """A long line as `_raw_lines` gives it (a CR before its LF counts in its length)."""
        return LongLine(len(raw), raw[:LONG_HEAD])


def _read_on(read: Callable[[int], bytes], start: bytes) -> LongLine:
    """A line longer than `MAX_LINE` whose first bytes are `start`, read on to its LF (or
    the file's end) a block at a time."""
    length = len(start)
    piece = start
    while not piece.endswith(b"\n"):
        piece = read(BLOCK)
        if not piece:
            return LongLine(length, start[:LONG_HEAD])
        length += len(piece)
    return LongLine(length - 1, start[:LONG_HEAD])


def _decodes(decoder: codecs.IncrementalDecoder, block: bytes, final: bool) -> bool:
    try:
        decoder.decode(block, final)
    except UnicodeDecodeError:
        return False
    return True


def _whole_decodes(path: Path, encoding: str) -> bool:
    decoder = codecs.getincrementaldecoder(encoding)()
    with path.open("rb") as handle:
        while block := handle.read(BLOCK):
            if not _decodes(decoder, block, False):
                return False
    return _decodes(decoder, b"", True)


def split_lines(text: str) -> list[str]:
    """The file's lines as an editor numbers them: cut at LF (a CR before it dropped), or
    at CR in a file that has no LF at all. A CR inside a line stays in it, so a stray CR
    neither shifts the line numbers warnings give nor cuts a line in two."""
    if "\n" not in text:
        return text.split("\r") if text else []
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [line[:-1] if line.endswith("\r") else line for line in lines]


_TIME_PATTERNS = (
    # 2024-05-01 12:00:00,123 / 2024-05-01T12:00:00.123 / 2024/05/01 12:00:00
    re.compile(
        r"(?P<y>\d{4})[-/](?P<mo>\d\d)[-/](?P<d>\d\d)[T ]"
        r"(?P<h>\d\d):(?P<mi>\d\d):(?P<s>\d\d)(?:[.,](?P<f>\d+))?"
    ),
    # 26/02/2020 10:12:34.567 (day first; month first where the day cannot be a month)
    re.compile(
        r"(?P<d>\d\d)[/.](?P<mo>\d\d)[/.](?P<y>\d{4})[ @]+"
        r"(?P<h>\d\d):(?P<mi>\d\d):(?P<s>\d\d)(?:[.,](?P<f>\d+))?"
    ),
    # 12:00:00.123 (seconds since midnight)
    re.compile(r"(?P<h>\d{1,2}):(?P<mi>\d\d):(?P<s>\d\d)(?:[.,:](?P<f>\d{1,9}))?"),
)


@dataclass(frozen=True, slots=True)
class Stamped:
    """A time read from a line: seconds (Unix time with a date, else since midnight),
    its resolution, whether it carried a date, and where the line goes on after it."""

    seconds: float
    resolution: float
    dated: bool
    end: int


# digits of a fraction of a second that can change a float: a damaged or hostile line's
# thousands more (Python refuses int() past 4,300 digits) are read as these many
FRACTION_DIGITS = 18


def fraction_digits(digits: str | None) -> tuple[float, float]:
    """The value of the digits after a decimal point, and their resolution (a unit in the
    last place, never finer than FRACTION_DIGITS allows): ("123") is (0.123, 0.001)."""
    if not digits:
        return 0.0, 1.0
    kept = digits[:FRACTION_DIGITS]
    return int(kept) / 10 ** len(kept), 10.0 ** -len(kept)


_LEAD = re.compile(r"\s*(\[)?\s*")
_CLOSE = re.compile(r"\s*\]")


def parse_stamp(text: str, pos: int = 0) -> Stamped | None:
    """The time at `pos` in `text` (optionally in brackets), or None. Forms: see _TIME_PATTERNS."""
    lead = _LEAD.match(text, pos)
    start = lead.end() if lead else pos
    bracket = bool(lead and lead[1])
    for index, pattern in enumerate(_TIME_PATTERNS):
        match = pattern.match(text, start)
        if match is None:
            continue
        end = match.end()
        if bracket:
            close = _CLOSE.match(text, end)
            if close is None:
                return None
            end = close.end()
        fraction, resolution = fraction_digits(match["f"])
        hour, minute, second = int(match["h"]), int(match["mi"]), int(match["s"])
        if hour > 23 or minute > 59 or second > 60:
            return None
        if index == 2:
            return Stamped(hour * 3600 + minute * 60 + second + fraction, resolution, False, end)
        year, month, day = int(match["y"]), int(match["mo"]), int(match["d"])
        if index == 1 and month > 12 and day <= 12:
            month, day = day, month
        try:
            moment = datetime(year, month, day, hour, minute, min(second, 59))
        except (ValueError, OverflowError):
            return None
        return Stamped(moment.timestamp() + fraction, resolution, True, end)
    return None


def hex_tokens(text: str) -> bytes | None:
    """Bytes written as two hex digits each, separated by white space (`01 03 0A`), or
    None when any token is not that."""
    tokens = text.split()
    if not tokens or not all(HEX2.match(t) for t in tokens):
        return None
    return bytes(int(t, 16) for t in tokens)


def event_kind(text: str) -> str:
    """`error` for a line that tells of a failure (error, timeout, failed, wrong check),
    else `info`: the name an event line's chunk carries."""
    return "error" if _FAILURE.search(text) else "info"


_FAILURE = re.compile(
    r"error|timed? ?out|fail|wrong|invalid|exception|refused|reset|lost|incomplete"
    r"|no response|not respond|unable|cannot|can't",
    re.I,
)

# ---------------------------------------------------------------- records


@dataclass(frozen=True, slots=True)
class LogRecord:
    """What one log line (or block) shows: bytes, or an event (`event` names it, `note`
    says it, no bytes); its line number, time and direction; the connection or device it
    names (`conn`, for a log of several Modbus TCP connections)."""

    data: bytes
    line: int
    stamp: Stamped | None
    direction: Direction
    event: str = ""
    note: str = ""
    conn: str = ""


@dataclass
class ParsedLog:
    """What a format's parser found: records, warnings, and what the file says about itself.

    `client` names the logging program and `servers` what each connection (`conn`) talks
    to, for the channel labels of a Modbus TCP log; `server_port` is the port the file
    names (or 502 when it says Modbus TCP), which tips an undecided connection to Modbus
    TCP. `notes` are what the reader decided (a reversed order, a side not logged).

    A parser is a generator over the file's lines (`Parser`): it puts each line's records
    in `records` and hands them on (`flush`) as it goes, so a file of any size is read in
    the memory of a few lines. What a parser decides from the whole file before its
    records (hex or decimal, a client's log or a server's) it keeps in `surveyed`, so that
    a second pass (`again`) need not decide it anew; `reverse` says the records are in
    time order read from the last line to the first (CAS Modbus Scanner)."""

    records: list[LogRecord] = field(default_factory=list)
    warnings: list[str] = field(default_factory=Warnings)
    notes: list[str] = field(default_factory=list)
    labels: Labels = Labels.NONE
    line: LineSettings | None = None
    channel_label: str = ""
    client: str = ""
    servers: dict[str, str] = field(default_factory=dict)
    server_port: int = 0
    surveyed: dict[str, bool] = field(default_factory=dict)
    reverse: bool = False

    def flush(self) -> Iterator[LogRecord]:
        """The records found since the last call, handed on and forgotten."""
        if self.records:
            yield from self.records
            self.records.clear()

    def again(self) -> ParsedLog:
        """A copy for a second pass over the file: what was decided, no records, warnings
        or notes (the first pass has them)."""
        return replace(self, records=[], warnings=Warnings(), notes=[], servers=dict(self.servers))

    def event(
        self, number: int, stamp: Stamped | None, text: str, conn: str = "", kind: str = ""
    ) -> None:
        """Record an event line: `kind`, else `error` or `info` by its words; the text as
        its note."""
        text = text.strip()
        if text:
            kind = kind or event_kind(text)
            self.records.append(LogRecord(b"", number, stamp, Direction.UNKNOWN, kind, text, conn))


SPILL_BATCH = 4096  # records written to the spill at a time
SPILL_LIMIT = 1 << 30  # bytes a spill may take on disk; past that the file is parsed again
_DIRECTIONS = {int(d): d for d in Direction}


class Spill(Generic[T]):
    """A first pass's items kept on disk for the second pass, so that it does not parse
    the file again: an unnamed temporary file (gone when closed, or when the program
    ends), written a batch at a time as tuples (`pack`, read back by `unpack`); a log
    record takes about 60 bytes, half the size of its ESPHome log line. When it cannot be
    written (no room, no temporary folder) or would pass `SPILL_LIMIT` it is dropped, and
    `replay` gives None: the file is parsed again."""

    def __init__(self, pack: Callable[[T], tuple[Any, ...]], unpack: Callable[..., T]) -> None:
        self._pack, self._unpack = pack, unpack
        self._batch: list[tuple[Any, ...]] = []
        self._offsets: list[int] = []
        self._file: BinaryIO | None
        try:
            self._file = tempfile.TemporaryFile()  # noqa: SIM115 (closed by replay or drop)
        except OSError:
            self._file = None

    def add(self, item: T) -> None:
        if self._file is None:
            return
        self._batch.append(self._pack(item))
        if len(self._batch) >= SPILL_BATCH:
            self._write()

    def _write(self) -> None:
        if self._file is None:
            return
        try:
            self._offsets.append(self._file.tell())
            marshal.dump(self._batch, self._file)
            if self._file.tell() > SPILL_LIMIT:
                self.drop()
        except OSError:
            self.drop()
        self._batch = []

    def drop(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def replay(self, reverse: bool = False) -> Iterator[T] | None:
        """The items in the order they were added (or the last first), once; None when
        the spill was dropped."""
        if self._batch:
            self._write()
        if self._file is None:
            return None
        return self._items(self._file, reverse)

    def _items(self, handle: BinaryIO, reverse: bool) -> Iterator[T]:
        unpack = self._unpack
        try:
            handle.flush()
            for offset in reversed(self._offsets) if reverse else self._offsets:
                handle.seek(offset)
                batch = marshal.load(handle)
                for fields in reversed(batch) if reverse else batch:
                    yield unpack(*fields)
        finally:
            self.drop()


def _pack_record(record: LogRecord) -> tuple[Any, ...]:
    stamp = record.stamp
    return (
        record.data,
        record.line,
        None if stamp is None else (stamp.seconds, stamp.resolution, stamp.dated, stamp.end),
        int(record.direction),
        record.event,
        record.note,
        record.conn,
    )


def _unpack_record(
    data: bytes,
    line: int,
    stamp: tuple[float, float, bool, int] | None,
    direction: int,
    event: str,
    note: str,
    conn: str,
) -> LogRecord:
    return LogRecord(
        data,
        line,
        None if stamp is None else Stamped(*stamp),
        _DIRECTIONS[direction],
        event,
        note,
        conn,
    )


def record_spill() -> Spill[LogRecord]:
    """A spill of log records."""
    return Spill(_pack_record, _unpack_record)


Parser = Callable[[Lines, str, ParsedLog], Iterator[LogRecord]]
"""A format's parser: `parse(lines, where, parsed)` yields the records of `lines` (a
file named `where`), putting warnings and what it learns of the file in `parsed`."""


def collect(parse: Parser, lines: Sequence[str], where: str) -> ParsedLog:
    """The whole parse of lines held in memory: the records in `records`."""
    parsed = ParsedLog()
    records = list(parse(numbered(lines), where, parsed))
    parsed.records = records
    return parsed


def stamps_of(records: Iterable[LogRecord]) -> tuple[Stamp, float]:
    """What the records' times mean: print times with the coarsest resolution any line
    has, or none."""
    resolution: float | None = None
    for record in records:
        if record.stamp is not None:
            resolution = max(resolution or 0.0, record.stamp.resolution)
    if resolution is None:
        return Stamp.NONE, 0.0
    return Stamp.PRINT, resolution


def record_chunks(
    records: Iterable[LogRecord],
    line: LineSettings,
    where: str,
    warnings: list[str],
    channel: Callable[[LogRecord], int] | None = None,
) -> Iterator[Chunk]:
    """Chunks of `records` in file order, `t_end` = the printed time, on the channel
    `channel` gives (0 without it).

    Times never go backwards: a time of day that falls by more than 12 hours is taken as
    the next day; a smaller fall (a clock step, threads printing out of order) keeps the
    previous time, with one warning. A record without a time follows the previous one by
    one character time per byte (`t_start` = the previous time): so does every record of
    a file without times. An event without a time takes the previous record's.
    """
    char = line.char_time
    t_prev: float | None = None
    day_offset = 0.0
    warned_back = False
    for record in records:
        ch = channel(record) if channel is not None else 0
        if record.event:
            t = _event_time(record, t_prev, day_offset)
            t_prev = t if t_prev is None else max(t, t_prev)
            yield Chunk(
                data=b"",
                t_end=t_prev,
                channel=ch,
                direction=record.direction,
                event=record.event,
                note=record.note,
            )
            continue
        if record.stamp is None:
            base = t_prev if t_prev is not None else 0.0
            t_end = base + char * max(len(record.data), 1)
            yield Chunk(
                data=record.data, t_end=t_end, t_start=base, channel=ch, direction=record.direction
            )
            t_prev = t_end
            continue
        t = record.stamp.seconds + day_offset
        if t_prev is not None and t < t_prev:
            if not record.stamp.dated and t_prev - t > DAY / 2:
                day_offset += DAY
                t += DAY
            else:
                if not warned_back:
                    warned_back = True
                    warnings.append(
                        f"{where} line {record.line}: the time goes back by "
                        f"{t_prev - t:.3f} s; such lines keep the previous line's time"
                    )
                t = t_prev
        t_prev = t
        yield Chunk(data=record.data, t_end=t, channel=ch, direction=record.direction)


def _event_time(record: LogRecord, t_prev: float | None, day_offset: float) -> float:
    if record.stamp is None:
        return t_prev if t_prev is not None else 0.0
    t = record.stamp.seconds + day_offset
    if t_prev is not None and not record.stamp.dated and t_prev - t > DAY / 2:
        t += DAY  # the next day's first line may be an event
    return t


# ---------------------------------------------------------------- Modbus TCP logs

MAX_PAIRS = 128  # channel pairs: the frame store keeps a channel number in one byte


@dataclass
class Summary:
    """What a first pass over a log's records found, in the memory of a few counters per
    connection: how many records, whether any has bytes, the times' meaning, and each
    connection's evidence for `route` (its carrier votes; whether its frames read as a
    client's or a server's)."""

    count: int = 0
    data: bool = False
    resolution: float | None = None
    conns: dict[str, Votes] = field(default_factory=dict)
    sides: dict[str, list[int]] = field(default_factory=dict)  # conn: [agree, disagree]

    def add(self, record: LogRecord) -> None:
        self.count += 1
        if record.stamp is not None:
            self.resolution = max(self.resolution or 0.0, record.stamp.resolution)
        if record.event or not record.data:
            return
        self.data = True
        votes = self.conns.get(record.conn)
        if votes is None:
            votes = self.conns[record.conn] = Votes()
            self.sides[record.conn] = [0, 0]
        votes.add(record.data)
        if record.direction != Direction.UNKNOWN:
            request = _request_like(record.data)
            if request is not None:
                self.sides[record.conn][request != (record.direction == Direction.MASTER)] += 1

    def stamps(self) -> tuple[Stamp, float]:
        """What the records' times mean (as `stamps_of`)."""
        if self.resolution is None:
            return Stamp.NONE, 0.0
        return Stamp.PRINT, self.resolution


@dataclass(frozen=True, slots=True)
class Routing:
    """Where each record goes: the channel table, how a record is read (`adjust`: its
    direction swapped where a connection's content shows the log was a server's, an
    event's set to its channel's), whether any connection carries Modbus TCP (`network`:
    framed by MBAP headers, paired by transaction id), and what to tell the user."""

    channels: dict[int, str]
    network: bool
    channel: Callable[[LogRecord], int]
    adjust: Callable[[LogRecord], LogRecord]
    notes: tuple[str, ...] = ()


def route(parsed: ParsedLog, summary: Summary, name: str) -> Routing:
    """The channels of a parsed log. A log whose connections carry RTU or ASCII frames is
    one serial stream on channel 0. A log with Modbus TCP frames (an MBAP header, no
    check) gets a pair of channels per connection (`conn`): `2k` for what the client sends,
    `2k + 1` for what the server sends, labelled as network captures are
    (`sniffer.sources.net.carrier`); its frames are framed by their MBAP length and paired
    by transaction id. Whether a connection carries Modbus TCP is decided by its bytes,
    as for a network capture (`Votes`), with the port the file names as the tie-break.
    `summary` is what a pass over the records found (`Summary`)."""
    conns = list(summary.conns)
    votes = summary.conns
    carriers = {c: votes[c].verdict("tcp", parsed.server_port, final=True) for c in conns}
    if not any(carrier in MBAP_CARRIERS for carrier in carriers.values()):
        label = parsed.channel_label or name
        return Routing({0: label}, False, lambda record: 0, lambda record: record)
    pairs = {conn: min(k, MAX_PAIRS - 1) for k, conn in enumerate(conns)}
    # a connection reads as a server's log when what it sent reads as answers and what
    # it received as requests more often than the other way
    swapped = {
        c for c in conns if carriers[c] == MODBUS_TCP and summary.sides[c][1] > summary.sides[c][0]
    }
    notes = tuple(
        f"the frames of {_conn_name(parsed, c)} read as a server's log: what it sent are "
        "answers, what it received requests; they are read so"
        for c in swapped
    )

    # an event goes on its connection's client channel, whose direction it carries:
    # a channel's first chunk gives the channel its direction
    def adjust(record: LogRecord) -> LogRecord:
        if record.event:
            return replace(record, direction=Direction.MASTER)
        if record.conn in swapped:
            return replace(record, direction=_flip(record.direction))
        return record

    channels: dict[int, str] = {}
    client = _token(parsed.client or "client")
    for conn, k in pairs.items():
        server = _token(parsed.servers.get(conn) or conn or "server")
        if carriers[conn] == MODBUS_TCP:
            channels[2 * k] = ChannelLabel("tcp", client, server, MODBUS_TCP, Direction.MASTER).text
            channels[2 * k + 1] = ChannelLabel(
                "tcp", server, client, MODBUS_TCP, Direction.SLAVE
            ).text
        else:
            channels[2 * k] = f"{name} {conn or 'serial'}: sent".strip()
            channels[2 * k + 1] = f"{name} {conn or 'serial'}: received".strip()

    def channel(record: LogRecord) -> int:
        k = pairs.get(record.conn, 0)
        return 2 * k + (1 if record.direction == Direction.SLAVE else 0)

    return Routing(channels, True, channel, adjust, notes)


def _flip(direction: Direction) -> Direction:
    return {Direction.MASTER: Direction.SLAVE, Direction.SLAVE: Direction.MASTER}.get(
        direction, direction
    )


def _token(text: str) -> str:
    """A name fit for a channel label (no spaces)."""
    return re.sub(r"\s+", "_", text.strip()) or "?"


def _conn_name(parsed: ParsedLog, conn: str) -> str:
    server = parsed.servers.get(conn) or conn
    return f"the connection to {server}" if server else "the log"


def _request_like(frame: bytes) -> bool | None:
    """Whether an MBAP frame reads as a request (True) or an answer (False), for the
    reads whose two layouts differ (FC 1-4: a request is 12 bytes, an answer carries
    its byte count), else None."""
    if len(frame) < 9 or frame[7] not in (1, 2, 3, 4):
        return None
    if frame[8] == len(frame) - 9:
        return False
    return True if len(frame) == 12 else None
