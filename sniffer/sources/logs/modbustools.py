"""Provides the reader of ModbusTools logs (serhmarch/ModbusTools: its client and server
log views, exported or copied).

Each line is `TIME 'SOURCE' FLAG: TEXT`, or `'SOURCE' FLAG: TEXT` with time stamps
turned off. TIME follows the `Log.FormatDateTime` setting, by default
`dd.MM.yyyy hh:mm:ss.zzz` (`14.05.2025 09:57:07.113`, resolution 1 ms). SOURCE is the
device (or port) the line is about. FLAG is `Tx` (bytes the program sent), `Rx` (bytes
it received), or `Error`, `Warn`, `Info`, `Debug`, whose lines are events, not bytes
(`Error: RTU. Wrong CRC`, `Info: Start polling`).

Bytes as ModbusLib writes them: `01 03 00 00 00 0A C5 CD ` (RTU, and Modbus TCP with its
MBAP header) or, for ASCII, the frame's characters with its hex digits paired and CR LF
named: `: 01 03 00 00 00 02 FA CR LF ` stands for `:010300000002FA\\r\\n`.

The client (it logs `Start polling`) sends requests: its Tx is MASTER. The server (it
logs `Start`, `New Connection: ...`) answers: its Tx is SLAVE. Each SOURCE is a
connection, so a Modbus TCP log gets a pair of channels per device.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

from sniffer.model import Direction, Labels
from sniffer.sources.logs.base import ANSI, HEX2, Lines, LogRecord, ParsedLog, parse_stamp

MODBUSTOOLS = "modbustools"

LINE = re.compile(
    r"^(?P<stamp>.*?)\s*'(?P<source>[^']*)'\s+(?P<flag>Tx|Rx|Error|Warn|Info|Debug):\s?"
    r"(?P<text>.*?)\s*$"
)
_SERVER_INFO = re.compile(r"^(Start|Stop|New Connection: .*|Close Connection: .*)$")
_NEW_CONNECTION = re.compile(r"^New Connection: (\S+)")
_CLIENT_INFO = re.compile(r"^(Start polling|Finish polling)$")
_NAMED = {"CR": 13, "LF": 10}
_KINDS = {"Error": "error", "Warn": "warning", "Info": "info", "Debug": "debug"}


def frame_bytes(text: str) -> bytes | None:
    """The bytes of a Tx/Rx text: hex pairs (RTU, TCP), or an ASCII frame's characters
    (`: 01 03 ... FA CR LF`), None if neither."""
    tokens = text.split()
    if not tokens:
        return None
    if all(HEX2.match(t) for t in tokens):
        return bytes(int(t, 16) for t in tokens)
    out = bytearray()
    for token in tokens:
        if token in _NAMED:
            out.append(_NAMED[token])
        elif token.isascii():
            out += token.encode("ascii")
        else:
            return None
    return bytes(out)


def _found(lines: Lines) -> Iterator[tuple[int, re.Match[str]]]:
    for number, raw_line in lines():
        match = LINE.match(ANSI.sub("", raw_line))
        if match is not None:
            yield number, match


def parse_modbustools(lines: Lines, where: str, parsed: ParsedLog) -> Iterator[LogRecord]:
    if not parsed.surveyed:
        serving = client = False
        for _, match in _found(lines):
            if match["flag"] == "Info":
                serving = serving or bool(_SERVER_INFO.match(match["text"]))
                client = client or bool(_CLIENT_INFO.match(match["text"]))
        parsed.surveyed["server"] = serving and not client
    server = parsed.surveyed["server"]
    sent, received = (
        (Direction.SLAVE, Direction.MASTER) if server else (Direction.MASTER, Direction.SLAVE)
    )
    parsed.labels, parsed.client = Labels.HINT, "client" if server else "ModbusTools"
    role = "server" if server else "client"
    parsed.channel_label = f"ModbusTools {role} log (Tx sent, Rx received)"
    unread_time = False
    for number, match in _found(lines):
        yield from parsed.flush()
        stamp = parse_stamp(match["stamp"]) if match["stamp"].strip() else None
        if match["stamp"].strip() and stamp is None and not unread_time:
            unread_time = True
            parsed.warnings.append(
                f"{where} line {number}: cannot read the time {match['stamp'].strip()[:30]!r}; "
                "lines whose time cannot be read keep their place in the file"
            )
        source, flag, text = match["source"], match["flag"], match["text"]
        if flag not in ("Tx", "Rx"):
            if server and (peer := _NEW_CONNECTION.match(text)):
                parsed.client = peer[1]
            parsed.event(number, stamp, f"{source}: {text}", source, _KINDS[flag])
            continue
        data = frame_bytes(text)
        if not data:
            parsed.warnings.append(
                f"{where} line {number}: cannot read {text[:30]!r} as the bytes of a frame; "
                "the line is skipped (a cut or edited line?)"
            )
            continue
        direction = sent if flag == "Tx" else received
        if server:
            parsed.servers.setdefault(source, "ModbusTools")
        else:
            parsed.servers.setdefault(source, source)
        parsed.records.append(LogRecord(data, number, stamp, direction, conn=source))
    yield from parsed.flush()
