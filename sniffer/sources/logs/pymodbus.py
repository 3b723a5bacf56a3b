"""Provides the reader of pymodbus debug logs, asynchronous and synchronous clients.

What pymodbus writes (its `Log.debug`, after any logging prefix), by version:

- 3.x asynchronous client (and every 3.8+ transport): `send: 0x1 0x3 ...`, and
  `recv: 0x1 0x3 ... extra data: ...` (3.10+; `old_data: ... addr=...` before). A recv
  line shows one read: an answer may span several.
- 2.x and 3.0-3.7 synchronous clients (the transaction manager): `SEND: 0x1 0x3 ...`,
  `RECV: ...` (one whole answer), with `Processing: ...` repeating what was received.
- 3.8+ synchronous clients log nothing of what they send: only `Processing: ...`, the
  bytes held so far (a line after `wait for more data` repeats the bytes before it), and,
  with local echo, `sync recv skipping (local_echo): ...` (the request heard back). Such a
  log gives the answers without their requests, and a note says so.
- 3.0-3.3 servers: `send: [ReadHoldingRegistersResponse (1,3)]- 0103...` (plain hex).

The client's own sends are MASTER, what it received SLAVE. A server's log, told by
what pymodbus decoded from what it received (`Factory Request[...]`, `-> ...Request(`),
reads the other way round (and a Modbus TCP log's frames are checked, `base.route`).
Print time of the logging record (`2024-05-01 12:00:00,123`), or none. `Repeating....`
stands for lines pymodbus left out: a warning says the frames cannot be read back.
Lines telling of a failure (`Transaction failed`, `No response received`, `Incomplete
message received`, ...) are events. Modbus TCP (an MBAP header in front of each frame)
is framed as Modbus TCP.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

from sniffer.model import Direction, Labels
from sniffer.sources.logs.base import ANSI, Lines, LogRecord, ParsedLog, Stamped, parse_stamp

PYMODBUS = "pymodbus"

_HEXLIFY = r"((?:0x[0-9a-fA-F]{1,2}\b\s*)*)"  # pymodbus's hexlify_packets: `0x1 0x3 0xc4`
BYTES_LINE = re.compile(rf"(?<![A-Za-z])(send|recv|SEND|RECV):\s*{_HEXLIFY}(.*)$")
PROCESSING = re.compile(rf"(?<![A-Za-z])Processing:\s*{_HEXLIFY}(.*)$")
_SERVER_SEND = re.compile(r"^\[[^\]]*\]-\s*(?:b')?([0-9a-fA-F]*)'?\s*$")
_ECHO = re.compile(rf"recv skipping \((?:partial )?local_echo\):\s*{_HEXLIFY}")
_CLEANUP = re.compile(rf"Cleanup recv buffer before send:\s*{_HEXLIFY}")
_WAITING = re.compile(r"wait for more data|Frame - not ready|Incomplete frame|Short frame")
_REPEAT = re.compile(r"\bRepeating\.\.\.\.")
# pymodbus's decoding of what it received (2.x-3.6 `Factory Request[...]`, 3.8+
# `decoded PDU function_code(3 sub -1) -> ReadHoldingRegistersRequest(...)`)
_DECODED_REQUEST = re.compile(r"Factory Request\[|-> \w+Request\(")
_DECODED_RESPONSE = re.compile(r"Factory Response\[|-> \w+Response\(")
_CONNECTING = re.compile(r"Connecting to (\S+?):(\d{1,5})\.?\s*$")
_EVENT = re.compile(
    r"Transaction failed|No response received|Incomplete message received|Frame check failed"
    r"|Frame CRC check failed|ERROR: request ask|Connection to .* failed|Not connected, trying"
    r"|Modbus IO exception|Server not responding|CLOSING CONNECTION|Wrong local echo"
    r"|did not (?:sync )?receive local echo|Connection unexpectedly closed"
)


def _hexlified(text: str) -> bytes:
    return bytes(int(token, 16) for token in text.split())


def _survey(lines: Lines, parsed: ParsedLog) -> None:
    # what pymodbus made of what it received: requests on a server, answers on a client
    requests = answers = 0
    found_io = False
    for _, line in lines():
        requests += len(_DECODED_REQUEST.findall(line))
        answers += len(_DECODED_RESPONSE.findall(line))
        found_io = found_io or BYTES_LINE.search(line) is not None
    parsed.surveyed["server"] = requests > answers
    parsed.surveyed["found_io"] = found_io


def parse_pymodbus(lines: Lines, where: str, parsed: ParsedLog) -> Iterator[LogRecord]:
    if not parsed.surveyed:
        _survey(lines, parsed)
    server, found_io = parsed.surveyed["server"], parsed.surveyed["found_io"]
    parsed.labels, parsed.client = Labels.HINT, "client" if server else "pymodbus"
    if server:
        parsed.servers[""] = "pymodbus"
        parsed.channel_label = "pymodbus server log (recv: requests, send: its answers)"
    else:
        parsed.channel_label = "pymodbus log (send: the client's requests, recv: answers)"
    sent, received = (
        (Direction.SLAVE, Direction.MASTER) if server else (Direction.MASTER, Direction.SLAVE)
    )
    data_found = echoed = False
    pending = b""  # a 3.8+ synchronous client's bytes held while a frame is incomplete
    for number, raw_line in lines():
        for record in parsed.flush():
            data_found = data_found or bool(record.data)
            echoed = echoed or record.direction == Direction.MASTER
            yield record
        line = ANSI.sub("", raw_line)
        if _REPEAT.search(line):
            parsed.warnings.append(
                f"{where} line {number}: pymodbus wrote 'Repeating....' and left out "
                "repeated lines; the frames it left out cannot be read back"
            )
            continue
        stamp = parse_stamp(line)
        if connecting := _CONNECTING.search(line):
            parsed.servers[""] = f"{connecting[1]}:{connecting[2]}"
            parsed.server_port = int(connecting[2])
        if event := _EVENT.search(line):
            parsed.event(number, stamp, line[event.start() :])
        if match := BYTES_LINE.search(line):
            _bytes_line(parsed, match, number, stamp, where, (sent, received))
            continue
        if found_io:
            continue  # `Processing:` and the like repeat what send/recv lines showed
        if echo := _ECHO.search(line):
            if data := _hexlified(echo[1]):
                parsed.records.append(LogRecord(data, number, stamp, Direction.MASTER))
            pending = b""
        elif cleanup := _CLEANUP.search(line):
            if data := _hexlified(cleanup[1]):
                parsed.records.append(LogRecord(data, number, stamp, Direction.SLAVE))
            pending = b""
        elif processing := PROCESSING.search(line):
            if rest := processing[2].strip():
                parsed.warnings.append(
                    f"{where} line {number}: cannot read {rest[:30]!r} as bytes; the line "
                    "is skipped (a cut or edited line?)"
                )
                pending = b""
                continue
            held = _hexlified(processing[1])
            data = held[len(pending) :] if pending and held.startswith(pending) else held
            if data:
                parsed.records.append(LogRecord(data, number, stamp, Direction.SLAVE))
            pending = held
        elif not _WAITING.search(line):
            pending = b""  # a frame was decoded (or given up): the next buffer starts anew
    for record in parsed.flush():
        data_found = data_found or bool(record.data)
        echoed = echoed or record.direction == Direction.MASTER
        yield record
    if not found_io and data_found:
        parsed.channel_label = "pymodbus synchronous client log (Processing: answers)"
        parsed.notes.append(
            f"{where}: a pymodbus synchronous client (3.8 and later) logs what it received "
            "(`Processing:`) but not what it sent: the requests are not in this log"
            + (", except those heard back as local echo" if echoed else "")
        )


def _bytes_line(
    parsed: ParsedLog,
    match: re.Match[str],
    number: int,
    stamp: Stamped | None,
    where: str,
    directions: tuple[Direction, Direction],
) -> None:
    rest = match[3].strip()
    data = _hexlified(match[2])
    if not data and (server := _SERVER_SEND.match(rest)) and len(server[1]) % 2 == 0:
        data, rest = bytes.fromhex(server[1]), ""  # a 3.0-3.3 server's `send: [...]- 0103`
    if rest and not rest.startswith(("extra data:", "old_data:", "old data:")):
        parsed.warnings.append(
            f"{where} line {number}: cannot read {rest[:30]!r} as bytes; the line is "
            "skipped (a cut or edited line?)"
        )
        return
    if not data:
        return  # `recv:` with nothing new: a read that returned no bytes
    direction = directions[0] if match[1].lower() == "send" else directions[1]
    parsed.records.append(LogRecord(data, number, stamp, direction))
