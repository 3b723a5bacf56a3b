"""Provides the reader of evcc trace logs (`log: trace`, or `levels: {area: trace}`).

evcc hands each Modbus device's connection a logger of its own log area; its Modbus
library (grid-x/modbus, as evcc's fork ships it) prints every frame through it, and evcc
prefixes the area, the level and Go's `log.Ldate|log.Ltime` time:

    [delta ] TRACE 2024/07/29 11:25:25 modbus: send 01 03 06 40 00 02 c5 57
    [delta ] TRACE 2024/07/29 11:25:25 modbus: recv 01 03 04 00 00 00 00 fa 33

RTU (serial and over TCP/UDP), Modbus TCP (the whole ADU, MBAP header first) and
serial ASCII frames are printed `% x` (ASCII frames as their characters: `3a 30 31 ...`);
ASCII over TCP, and serial ASCII in old versions, as a Go quoted string with the escape
sequences written out (`send ":0103002E0005C9\\r\\n"`). Old versions said `sending` and
`received`. A journald or Docker prefix before the area is skipped.

`send` is what evcc sent (it is the client: MASTER), `recv` what it got back. The time
is when the line was printed, to the whole second (resolution 1 s): a send line is
printed just before the write, a recv line after the answer was read. The library's
other lines (`modbus: read error: ...`, `connection reset, reconnecting`) are events.
Each area is a connection: a Modbus TCP area gets its own pair of channels.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

from sniffer.model import Direction, Labels
from sniffer.sources.logs.base import ANSI, Lines, LogRecord, ParsedLog, hex_tokens, parse_stamp

EVCC = "evcc"

LINE = re.compile(
    r"\[(?P<area>[^\[\]]*?)\s*\]\s+(?P<level>TRACE|DEBUG|INFO|WARN|ERROR|FATAL)\s+"
    r"(?P<stamp>\d{4}/\d\d/\d\d \d\d:\d\d:\d\d(?:\.\d+)?)\s+modbus:\s*(?P<msg>.*?)\s*$"
)
IO = re.compile(r"^(send|recv|sending|received)\b\s*(.*)$")
_GO_ESCAPES = {
    "a": 7,
    "b": 8,
    "f": 12,
    "n": 10,
    "r": 13,
    "t": 9,
    "v": 11,
    "\\": 92,
    '"': 34,
    "'": 39,
}
_HEX = re.compile(r"^[0-9A-Fa-f]+$")


def go_unquote(body: str) -> bytes | None:
    """The bytes of a Go quoted string (`%q`: `":0103\\r\\n"`), or None if it is not one.
    Printable characters stand for their UTF-8 bytes; `\\xNN` for a byte that is not
    printable or not UTF-8; `\\uNNNN`, `\\UNNNNNNNN` and octal `\\NNN` as Go writes them."""
    if len(body) < 2 or body[0] != '"' or body[-1] != '"':
        return None
    inner = body[1:-1]
    out = bytearray()
    i = 0
    while i < len(inner):
        char = inner[i]
        if char == '"':
            return None
        if char != "\\":
            out += char.encode("utf-8", errors="surrogatepass")
            i += 1
            continue
        nxt = inner[i + 1 : i + 2]
        if nxt in _GO_ESCAPES:
            out.append(_GO_ESCAPES[nxt])
            i += 2
        elif nxt in ("x", "u", "U"):
            width = {"x": 2, "u": 4, "U": 8}[nxt]
            digits = inner[i + 2 : i + 2 + width]
            if len(digits) != width or not _HEX.match(digits):
                return None
            code = int(digits, 16)
            if nxt == "x":
                out.append(code)
            elif code > 0x10FFFF:
                return None
            else:
                out += chr(code).encode("utf-8", errors="surrogatepass")
            i += 2 + width
        elif nxt and nxt in "01234567":
            digits = inner[i + 1 : i + 4]
            if len(digits) != 3 or any(d not in "01234567" for d in digits) or int(digits, 8) > 255:
                return None
            out.append(int(digits, 8))
            i += 4
        else:
            return None
    return bytes(out)


def frame_bytes(body: str) -> bytes | None:
    if body.startswith('"'):
        return go_unquote(body)
    if " " not in body and len(body) % 2 == 0 and _HEX.match(body):
        return bytes.fromhex(body)  # `%x`, as the earliest versions printed
    return hex_tokens(body)


def parse_evcc(lines: Lines, where: str, parsed: ParsedLog) -> Iterator[LogRecord]:
    parsed.labels, parsed.client = Labels.HINT, "evcc"
    parsed.channel_label = "evcc trace (send: evcc's requests, recv: answers)"
    for number, raw_line in lines():
        yield from parsed.flush()
        match = LINE.search(ANSI.sub("", raw_line))
        if match is None:
            continue
        area = match["area"].strip()
        stamp = parse_stamp(match["stamp"])
        io = IO.match(match["msg"])
        if io is None:
            parsed.event(number, stamp, f"{area}: modbus: {match['msg']}", area)
            continue
        body = io[2]
        if not body:
            continue  # an empty read
        data = frame_bytes(body)
        if not data:
            parsed.warnings.append(
                f"{where} line {number}: cannot read {body[:30]!r} as the bytes of a frame; "
                "the line is skipped (a cut or edited line?)"
            )
            continue
        direction = Direction.MASTER if io[1].startswith("send") else Direction.SLAVE
        parsed.servers.setdefault(area, area)
        parsed.records.append(LogRecord(data, number, stamp, direction, conn=area))
    yield from parsed.flush()
