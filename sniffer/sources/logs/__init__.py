"""Provides readers for the text logs people post: ESPHome `uart_debug`, pymodbus debug
logs, libmodbus debug output (`mbpoll -v`), evcc traces, ModbusTools logs, CAS Modbus
Scanner logs and serial monitors (tio, sscom, Serial Port Monitor, generic `time TX: hex`
lines). One module per format says what its lines look like and what they promise.

Each log is read line by line into records (bytes or an event, the line's printed time
if any, the direction its label gives), then into chunks (`base.record_chunks`): one
chunk per logged line or block, `t_end` = the printed time; event lines (errors and
notices the program printed) become event chunks. A serial log is one stream on channel
0; a log of Modbus TCP frames gets a pair of channels per connection and is framed as
Modbus TCP (`base.route`). A line the reader cannot use becomes a warning naming the
file and line number (past 20 of a kind, a count: `sniffer.sources.base.Warnings`); a
line longer than `base.MAX_LINE` bytes is read on to its end unkept and skipped, with a
warning giving its length and first characters; nothing here raises on content. Files
without any time get synthetic times (one character time per byte, increasing), and say
so (`Stamp.NONE`).

The format is recognised from the content (`sniff_log`), never from the file's name.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from functools import partial
from pathlib import Path

from sniffer.model import Labels, SourceInfo
from sniffer.sources.base import Capture, ReadOptions, Warnings
from sniffer.sources.logs.base import (
    ANSI,
    Lines,
    LogRecord,
    ParsedLog,
    Parser,
    Stamped,
    Summary,
    TextFile,
    collect,
    decode_head,
    decode_text,
    hex_tokens,
    numbered,
    parse_stamp,
    record_chunks,
    record_spill,
    route,
    split_lines,
)
from sniffer.sources.logs.cas import CAS, parse_cas
from sniffer.sources.logs.cas import FRAME as CAS_FRAME
from sniffer.sources.logs.cas import LINE as CAS_LINE
from sniffer.sources.logs.esphome import ESPHOME, parse_esphome
from sniffer.sources.logs.esphome import LINE as ESPHOME_LINE
from sniffer.sources.logs.evcc import EVCC, parse_evcc
from sniffer.sources.logs.evcc import IO as EVCC_IO
from sniffer.sources.logs.evcc import LINE as EVCC_LINE
from sniffer.sources.logs.evcc import frame_bytes as evcc_bytes
from sniffer.sources.logs.libmodbus import LIBMODBUS, parse_libmodbus
from sniffer.sources.logs.libmodbus import TOKEN as LIBMODBUS_TOKEN
from sniffer.sources.logs.modbustools import LINE as MODBUSTOOLS_LINE
from sniffer.sources.logs.modbustools import MODBUSTOOLS, frame_bytes, parse_modbustools
from sniffer.sources.logs.monitor import BLOCK_HEADER, MONITOR, parse_monitor
from sniffer.sources.logs.pymodbus import BYTES_LINE, PROCESSING, PYMODBUS, parse_pymodbus

__all__ = [
    "LOG_FORMATS",
    "PARSERS",
    "LogRecord",
    "ParsedLog",
    "Stamped",
    "decode_text",
    "open_log",
    "parse_stamp",
    "record_chunks",
    "sniff_log",
]

LOG_FORMATS = (ESPHOME, PYMODBUS, LIBMODBUS, EVCC, MODBUSTOOLS, CAS, MONITOR)

STREAMS: dict[str, Parser] = {
    ESPHOME: parse_esphome,
    PYMODBUS: parse_pymodbus,
    LIBMODBUS: parse_libmodbus,
    EVCC: parse_evcc,
    MODBUSTOOLS: parse_modbustools,
    CAS: parse_cas,
    MONITOR: parse_monitor,
}
# each format's whole parse of lines held in memory (`collect`)
PARSERS: dict[str, Callable[[Sequence[str], str], ParsedLog]] = {
    kind: partial(collect, parse) for kind, parse in STREAMS.items()
}
FORMAT_NAMES = {
    ESPHOME: "ESPHome uart_debug",
    PYMODBUS: "pymodbus debug",
    LIBMODBUS: "libmodbus debug",
    EVCC: "evcc trace",
    MODBUSTOOLS: "ModbusTools",
    CAS: "CAS Modbus Scanner",
    MONITOR: "serial monitor",
}


def open_log(path: Path, options: ReadOptions, kind: str) -> Capture:
    """Open a text log of format `kind` (one of LOG_FORMATS).

    The file is read line by line, never whole: a first pass gathers the warnings, what
    the file says about itself and what routing needs (`Summary`), and keeps the records
    on disk (`Spill`); the chunks come from them, as they are consumed (or, without the
    spill, from a second pass over the file). Memory stays a few blocks and lines
    whatever the file's size (a line past `MAX_LINE` is skipped with a warning), and the
    warnings a few of each kind (`Warnings`: the rest are counted)."""
    parse = STREAMS[kind]
    where = str(path)
    parsed = ParsedLog()
    warnings = parsed.warnings
    text = TextFile.survey(path, warnings=warnings)
    summary = Summary()
    spill = record_spill()
    for record in parse(text.lines, where, parsed):
        summary.add(record)
        spill.add(record)
    line = options.line(parsed.line)
    stamps, resolution = summary.stamps()
    if not summary.data:
        warnings.append(f"{path}: no bytes found in this {FORMAT_NAMES[kind]} log")
    Warnings.bound(warnings)
    routing = route(parsed, summary, FORMAT_NAMES[kind])
    info = SourceInfo(
        path=str(path),
        format=kind,
        line=line,
        channels=routing.channels,
        warnings=tuple(warnings),
        stamps=stamps,
        resolution=resolution,
        # a connection's two directions are what the program wrote to its socket and
        # what it read back: they cannot be confused (whose side the log is from is
        # checked against the frames, `route`), and Modbus TCP framing needs them
        labels=Labels.CERTAIN if routing.network else parsed.labels,
        notes=(*parsed.notes, *routing.notes),
        network=routing.network,
    )

    def records() -> Iterator[LogRecord]:
        spilled = spill.replay(parsed.reverse)
        if spilled is None:  # no spill: the file is parsed again
            lines: Lines = text.lines
            if parsed.reverse:
                lines = partial(text.lines_reversed, text.count())
            spilled = parse(lines, where, parsed.again())
        for record in spilled:
            yield routing.adjust(record)

    chunks = record_chunks(records(), line, where, warnings, routing.channel)
    return Capture(info=info, _chunks=chunks, warnings=warnings)


# ---------------------------------------------------------------- recognition

_SNIFF_LINES = 400
_SPECIFIC = (ESPHOME, EVCC, MODBUSTOOLS, CAS, PYMODBUS, LIBMODBUS)


def _line_kind(line: str) -> str | None:
    """The format whose byte lines look like `line`, if any."""
    if ESPHOME_LINE.search(line):
        return ESPHOME
    evcc = EVCC_LINE.search(line)
    io = EVCC_IO.match(evcc["msg"]) if evcc else None
    if io and evcc_bytes(io[2]):
        return EVCC
    # a frame's bytes in hex, or an ASCII frame as ModbusLib writes it (`: 01 03 ...`)
    tools = MODBUSTOOLS_LINE.match(line)
    text = tools["text"] if tools and tools["flag"] in ("Tx", "Rx") else ""
    if hex_tokens(text) or (text.startswith(": ") and frame_bytes(text)):
        return MODBUSTOOLS
    cas = CAS_LINE.match(line)
    frame = CAS_FRAME.match(cas["rest"]) if cas else None
    if frame and hex_tokens(frame["hex"]):
        return CAS
    if ((io := BYTES_LINE.search(line)) and io[2].strip()) or (
        (held := PROCESSING.search(line)) and held[1].strip()
    ):
        return PYMODBUS
    tokens = LIBMODBUS_TOKEN.findall(line)
    if len(tokens) >= 2 and not LIBMODBUS_TOKEN.sub("", line).strip(" \t?"):
        return LIBMODBUS
    return None


def sniff_log(head: bytes) -> str | None:
    """The log format of a file starting with `head`, or None. Decided by the lines each
    tool prints: at least one byte line of ESPHome (`uart_debug` arrows), evcc
    (`modbus: send`), ModbusTools (`'Device' Tx:`), CAS Modbus Scanner (`=> Poll:`),
    pymodbus (`send:`, `recv:`, `Processing:` with `0x` bytes) or libmodbus (bracketed
    bytes), the most frequent winning; else at least two serial monitor lines of three
    or more hex bytes (and more such lines than other text lines)."""
    text = decode_head(head)
    if text is None:
        return None
    lines = split_lines(text)[:_SNIFF_LINES]
    scores = dict.fromkeys(LOG_FORMATS, 0)
    other = 0
    for raw_line in lines:
        line = ANSI.sub("", raw_line)
        kind = _line_kind(line)
        if kind is not None:
            scores[kind] += 1
        elif line.strip():
            records = list(parse_monitor(numbered([line]), "", ParsedLog()))
            if records and len(records[0].data) >= 3:
                scores[MONITOR] += 1
            elif not BLOCK_HEADER.search(line):
                other += 1
    best = max(_SPECIFIC, key=lambda kind: scores[kind])
    if scores[best]:
        return best
    if scores[MONITOR] >= 2 and scores[MONITOR] > other:
        return MONITOR
    return None
