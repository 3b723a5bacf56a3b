"""Provides the reader for Saleae Logic CSV exports of the Async Serial analyser.

Three shapes are read, recognised by their header line:

- Logic 1 (and Logic 2's "export" of one analyser): `Time [s],Value,Parity Error,Framing Error`,
  one row per byte: its start time, its value, `Error` in the error columns.
- Logic 2 data table export: `name,type,start_time,duration,data[,error...]`, one row per
  byte of each analyser (`name`), with its start and duration.
- early Logic 2: `Time [s],Analyzer Name,Decoded Protocol Result`.

Values as the analyser's display radix wrote them: hex `0x01`, binary `0b00000001`,
decimal `1`, ASCII (`A`, `' '`, `\\r`, `COMMA`, and `'1'` for a byte below 0x20 or above
0x7E: its decimal value in quotes), or ASCII & Hex (`'1'` TAB `(0x01)`, `P` TAB `(0x50)`:
the hex in brackets is the value).

Rows are read line by line, not by a CSV parser: a value may be a lone `"` (the byte
0x22 in the ASCII radices) or a stray CR, and a damaged file may hold a line longer than
any CSV field limit; such a row is read or becomes a warning naming its line, never an
error for the whole file; a line past `MAX_LINE` (1 MiB) is skipped unread, its warning
giving its length and first characters. A file whose lines end with CR alone is read too.

Each byte is one chunk with exact times (`Stamp.EXACT`): `t_start` the byte's start,
`t_end` its start plus its duration (or one character time when the export has none).
Parity and framing errors become event chunks after the byte they mark (the byte is kept).
Each analyser is its own channel; an analyser whose name says `master`/`request` or
`slave`/`response` gives that direction, with `Labels.CERTAIN` when every channel has one.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from sniffer.model import Chunk, Direction, Labels, LineSettings, SourceInfo, Stamp
from sniffer.sources.base import Capture, ReadOptions, Warnings
from sniffer.sources.logs.base import Spill, TextFile

SALEAE = "saleae"

_LOGIC1 = ("time [s]", "value", "parity error", "framing error")
_LOGIC2 = ("name", "type", "start_time", "duration", "data")
_EARLY2 = ("time [s]", "analyzer name", "decoded protocol result")
_MASTER_NAME = re.compile(r"master|request|\breq\b|query", re.I)
_SLAVE_NAME = re.compile(r"slave|response|\bresp\b|reply|answer", re.I)
_ASCII_NAMES = {
    "COMMA": ord(","),
    "' '": ord(" "),
    "SPACE": ord(" "),
    "\\r": 13,
    "\\n": 10,
    "\\t": 9,
    "\\0": 0,
    "\\a": 7,
    "\\b": 8,
    "\\f": 12,
    "\\v": 11,
}


def _header(line: str) -> tuple[str, ...]:
    return tuple(cell.strip().strip('"').lower() for cell in line.split(","))


def sniff_saleae(head: bytes) -> bool:
    """True when the first line is one of the three export headers."""
    first = re.split(rb"[\r\n]", head, maxsplit=1)[0]
    first = first.lstrip(b"\xef\xbb\xbf").decode("latin-1").strip()
    columns = _header(first)
    return columns[:4] == _LOGIC1 or columns[:5] == _LOGIC2 or columns[:3] == _EARLY2


_ASCII_HEX = re.compile(r"^.*?\s*\(0[xX]([0-9A-Fa-f]{1,2})\)$", re.S)


def parse_value(text: str) -> int | None:
    """A byte as the analyser printed it, or None."""
    if text and not text.strip(" "):
        return ord(" ")  # a space exported bare, as some versions do
    text = text.strip()
    if ascii_hex := _ASCII_HEX.match(text):
        return int(ascii_hex[1], 16)
    if len(text) >= 3 and text[0] == text[-1] == "'":
        inner = text[1:-1]
        if inner.isascii() and inner.isdigit() and len(inner) <= 3:
            value = int(inner)  # below 0x20 or above 0x7E: the decimal value, quoted
            return value if value < 256 else None
        return ord(inner) if len(inner) == 1 and ord(inner) < 256 else None
    if text in _ASCII_NAMES:
        return _ASCII_NAMES[text]
    try:
        if text[:2].lower() == "0x":
            value = int(text[2:], 16)
        elif text[:2].lower() == "0b":
            value = int(text[2:], 2)
        elif text[:2] == "\\x":
            value = int(text[2:], 16)
        elif text.isdigit() and len(text) > 1:
            value = int(text)
        elif len(text) == 1:
            value = ord(text)
        else:
            return None
    except ValueError:
        return None
    return value if 0 <= value < 256 else None


@dataclass(frozen=True, slots=True)
class _Row:
    number: int
    channel: int
    start: float
    duration: float | None
    value: int
    errors: tuple[str, ...]


def _error_events(text: str) -> tuple[str, ...]:
    low = text.strip().lower()
    if not low:
        return ()
    if "parity" in low:
        return ("parity error",)
    return ("framing error",)


def open_saleae(path: Path, options: ReadOptions) -> Capture:
    """Open a Saleae Async Serial CSV export.

    The file is read line by line, never whole: a first pass finds the analysers (the
    channels) and the warnings and keeps the rows on disk (`Spill`, about 40 bytes a
    row); the chunks come from them as they are consumed (or, without room for them,
    from a second pass over the file)."""
    # UTF-8, a byte that is not read as U+FFFD; lines cut at LF, or CR without any LF;
    # a line past MAX_LINE is skipped with a warning
    warnings = Warnings()
    text = replace(TextFile.survey(path, (), warnings), encoding="utf-8", errors="replace")
    where = str(path)
    names: dict[str, int] = {}
    found = False
    spill = Spill(_pack_row, _Row)
    for row in _rows(text, names, where, warnings):
        found = True
        spill.add(row)
    line = options.line(None)
    channels: dict[int, str] = {}
    directions: dict[int, Direction] = {}
    for name, channel in names.items():
        direction = Direction.UNKNOWN
        if len(names) > 1 and _MASTER_NAME.search(name):
            direction = Direction.MASTER
        elif len(names) > 1 and _SLAVE_NAME.search(name):
            direction = Direction.SLAVE
        directions[channel] = direction
        role = {Direction.MASTER: " (requests)", Direction.SLAVE: " (responses)"}.get(direction, "")
        channels[channel] = f"analyser {name!r}{role}"
    known = [d for d in directions.values() if d != Direction.UNKNOWN]
    labels = Labels.CERTAIN if known and len(known) == len(directions) else Labels.NONE
    if not channels:
        channels = {0: "Saleae async serial"}
    if not found:
        warnings.append(f"{where}: no bytes found in this Saleae export")
    warnings.close()
    info = SourceInfo(
        path=where,
        format=SALEAE,
        line=line,
        exact_timing=True,
        channels=channels,
        warnings=tuple(warnings),
        stamps=Stamp.EXACT,
        resolution=0.0,
        labels=labels,
    )
    if labels == Labels.NONE:
        directions = dict.fromkeys(directions, Direction.UNKNOWN)
    # the rows kept from the first pass, or (without room for them) a second pass over
    # the file: the same rows, their warnings already said
    rows = spill.replay()
    if rows is None:
        rows = _rows(text, dict(names), where, [])
    chunks = _chunks(rows, line, directions)
    return Capture(info=info, _chunks=chunks, warnings=warnings)


def _pack_row(row: _Row) -> tuple[Any, ...]:
    return (row.number, row.channel, row.start, row.duration, row.value, row.errors)


def _rows(text: TextFile, names: dict[str, int], where: str, warnings: list[str]) -> Iterator[_Row]:
    """The file's rows that read as bytes, in file order; each analyser's name gets its
    channel in `names` as it first appears, each row that does not read a warning."""
    lines = text.lines()
    first = next(lines, None)
    if first is None:
        return
    header = _header(first[1].lstrip("\ufeff"))
    if not first[1]:  # a header line past MAX_LINE: its columns as recognition read them
        header = _header(_first_line(text.path).lstrip("\ufeff"))
    for number, text_line in lines:
        if not text_line.strip():
            continue
        row = _cells(header, text_line, number, where, warnings)
        if row is None:
            continue
        item = _row(header, row, number, names, where, warnings)
        if item is not None:
            yield item


def _first_line(path: Path) -> str:
    """The start of the file's first line (4 KiB at most), as `sniff_saleae` reads it."""
    with path.open("rb") as handle:
        head = handle.read(4096)
    return re.split(rb"[\r\n]", head, maxsplit=1)[0].decode("utf-8", "replace")


def _cells(
    header: tuple[str, ...], line: str, number: int, where: str, warnings: list[str]
) -> list[str] | None:
    """A row's cells. Logic 1 rows are cut by hand: time first, the two error columns
    last, the value (whatever characters it holds) between them. The other exports
    quote their text cells, so each line goes through a CSV parser of its own."""
    if header[:4] == _LOGIC1:
        cells = line.split(",")
        if len(cells) <= 4:
            return cells
        return [cells[0], ",".join(cells[1:-2]), cells[-2], cells[-1]]
    try:
        return next(csv.reader([line]), [])
    except csv.Error as exc:
        warnings.append(f"{where} line {number}: cannot read the row ({exc}); the row is skipped")
        return None


def _unquoted(value: str) -> str:
    """A value without the double quotes a spreadsheet may have put around it; a lone `"`
    (the byte 0x22) stays."""
    text = value.strip()
    if len(text) >= 2 and text[0] == text[-1] == '"':
        return text[1:-1].replace('""', '"')
    return value


def _row(
    header: tuple[str, ...],
    row: Sequence[str],
    number: int,
    names: dict[str, int],
    where: str,
    warnings: list[str],
) -> _Row | None:
    def bad(reason: str) -> None:
        warnings.append(f"{where} line {number}: {reason}; the row is skipped")

    try:
        if header[:5] == _LOGIC2:
            if len(row) < 5:
                bad("fewer than 5 columns")
                return None
            name, kind = row[0].strip(), row[1].strip().lower()
            if kind not in ("data", "error", ""):
                return None  # other frame types an analyser may add (start, stop...)
            start, duration = float(row[2]), float(row[3])
            value_text = row[4]
            error_text = ",".join(row[5:]) if len(row) > 5 else ""
            if kind == "error" and not error_text:
                error_text = "framing"
            errors = _error_events(error_text)
        elif header[:4] == _LOGIC1:
            name, start, duration = "", float(row[0]), None
            value_text = _unquoted(row[1]) if len(row) > 1 else ""
            parity = row[2].strip() if len(row) > 2 else ""
            framing = row[3].strip() if len(row) > 3 else ""
            errors = (("parity error",) if parity else ()) + (("framing error",) if framing else ())
        else:
            name, start, duration = (row[1].strip() if len(row) > 1 else ""), float(row[0]), None
            value_text = row[2] if len(row) > 2 else ""
            note = ""
            if "(" in value_text:
                value_text, _, note = value_text.partition("(")
            if " " in value_text.strip():
                value_text, _, rest = value_text.strip().partition(" ")
                note += rest
            errors = _error_events(note) if "error" in note.lower() else ()
    except ValueError:
        bad("its time is not a number")
        return None
    value = parse_value(value_text)
    if value is None:
        bad(f"cannot read the value {value_text.strip()[:20]!r} as a byte")
        return None
    channel = names.setdefault(name, len(names))
    return _Row(number, channel, start, duration, value, errors)


def _chunks(
    rows: Iterable[_Row], line: LineSettings, directions: dict[int, Direction]
) -> Iterator[Chunk]:
    char = line.char_time
    for row in rows:
        duration = row.duration if row.duration is not None and row.duration > 0 else char
        t_end = row.start + duration
        direction = directions.get(row.channel, Direction.UNKNOWN)
        yield Chunk(
            data=bytes((row.value,)),
            t_start=row.start,
            t_end=t_end,
            channel=row.channel,
            direction=direction,
        )
        for event in row.errors:
            yield Chunk(
                data=b"", t_end=t_end, channel=row.channel, direction=direction, event=event
            )
