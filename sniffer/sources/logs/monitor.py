"""Provides the reader of serial monitor logs: tio, sscom, Serial Port Monitor, and
generic `time TX: hex` lines.

An optional time (`[2024-05-01 12:00:00.123]`, `12:00:00.123`, `[26/02/2020 10:12:34]`),
an optional direction (`TX`/`RX`, `>`/`<`, sscom's `发→◇`/`收←◆`, Serial Port Monitor's
`Written data`/`Read data` block headers), then hex bytes. What the monitoring program
sent (TX, written) is MASTER, what it received SLAVE. Print time.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

from sniffer.model import Direction, Labels
from sniffer.sources.logs.base import ANSI, Lines, LogRecord, ParsedLog, Stamped, parse_stamp

MONITOR = "monitor"

_SENT_WORDS = (
    r"TX|Tx|tx|SEND|Send|send|SENT|Sent|sent|Written|Write|OUT|Out|W"
    r"|-->|->|>>|>|发送|发→◇|发→|发|→"
)
_RECEIVED_WORDS = (
    r"RX|Rx|rx|RECEIVED|Received|RECEIVE|Receive|RECV|Recv|recv|Read|IN|In|R"
    r"|<--|<-|<<|<|接收|收←◆|收←|收|←"
)
_DIRECTION = re.compile(
    rf"^\s*[\[(]?(?:(?P<sent>{_SENT_WORDS})|(?P<received>{_RECEIVED_WORDS}))[\])]?\s*[:：]?\s*"
)
BLOCK_HEADER = re.compile(r"\b(Written data|Write|Read data|Read)\b(?:\s*\(([^)]*)\))?", re.I)
_HEX_RUN = re.compile(r"((?:[0-9A-Fa-f]{2}(?: |$))*[0-9A-Fa-f]{2})(?=\s{2,}|\s*$|\s*[^\w\s])")
_LOOKS_HEX = re.compile(r"\s*[0-9A-Fa-f]{2}(?: [0-9A-Fa-f]{2}|\s*$)")


def _hex_bytes(text: str) -> bytes | None:
    """Hex bytes at the start of `text`: pairs of hex digits separated by single spaces,
    ending at the line's end, at an ASCII column (two or more spaces) or at a symbol
    (sscom's `□`)."""
    match = _HEX_RUN.match(text.strip())
    return None if match is None else bytes.fromhex(match[1])


def parse_monitor(lines: Lines, where: str, parsed: ParsedLog) -> Iterator[LogRecord]:
    labelled = False
    block: tuple[int, Stamped | None, Direction] | None = None
    block_data = bytearray()

    def close() -> None:
        nonlocal block
        if block is not None and block_data:
            parsed.records.append(LogRecord(bytes(block_data), block[0], block[1], block[2]))
        block_data.clear()
        block = None

    for number, raw_line in lines():
        yield from parsed.flush()
        line = ANSI.sub("", raw_line).rstrip()
        if not line.strip():
            close()
            continue
        stamp = parse_stamp(line)
        rest = line[stamp.end :] if stamp else line
        rest = rest.strip()
        if rest.startswith("- "):
            rest = rest[2:].lstrip()
        header = BLOCK_HEADER.match(rest)
        if header and _hex_bytes(rest[header.end() :]) is None:
            close()
            written = header[1].lower().startswith("writ")
            block = (number, stamp, Direction.MASTER if written else Direction.SLAVE)
            labelled = True
            continue
        direction = Direction.UNKNOWN
        if (marker := _DIRECTION.match(rest)) and _LOOKS_HEX.match(rest, marker.end()):
            direction = Direction.MASTER if marker["sent"] else Direction.SLAVE
            rest = rest[marker.end() :]
        data = _hex_bytes(rest)
        if data is None:
            close()
            if direction != Direction.UNKNOWN:
                parsed.warnings.append(
                    f"{where} line {number}: cannot read {rest.strip()[:30]!r} as hex "
                    "bytes; the line is skipped"
                )
            continue
        if stamp is None and direction == Direction.UNKNOWN and block is not None:
            block_data.extend(data)  # a hex line inside a Written/Read data block
            continue
        close()
        if direction != Direction.UNKNOWN:
            labelled = True
        parsed.records.append(LogRecord(data, number, stamp, direction))
    close()
    yield from parsed.flush()
    parsed.labels = Labels.HINT if labelled else Labels.NONE
    parsed.channel_label = (
        "serial monitor (TX/written: master, RX/read: answers)"
        if labelled
        else "serial monitor (no direction)"
    )
