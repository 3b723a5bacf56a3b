"""Provides the reader of libmodbus debug output (`modbus_set_debug`, `mbpoll -v`).

libmodbus prints what the program sent as `[01][03]...` and what it received as
`<01><03>...`, with no time. A client's sends are MASTER; a server's (its log says
`Waiting for an indication`) are answers. Serial (RTU) frames carry their CRC; Modbus
TCP frames carry an MBAP header and no check, and are framed as Modbus TCP.

What else the output says: `Opening /dev/ttyUSB0 at 9600 bauds (N, 8, 1)` gives the line
settings; `Connecting to 192.168.1.20:502` (`[192.168.1.20]:502` from `modbus_new_tcp_pi`,
as mbpoll uses), mbpoll's `Communication.........: 192.168.1.20, port 502, ...` and
`Protocol configuration: ModBus TCP` name the server; `Client connection accepted from
...` the client of a server. Its error lines (`ERROR Connection timed out: select`,
`ERROR CRC received ...`, `Invalid transaction ID ...`, mbpoll's `Read ... failed: ...`)
are events.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

from sniffer.model import Direction, Labels, LineSettings
from sniffer.sources.logs.base import Lines, LogRecord, ParsedLog

LIBMODBUS = "libmodbus"

TOKEN = re.compile(r"\[([0-9A-Fa-f]{2})\]|<([0-9A-Fa-f]{2})>")
_RUN = re.compile(r"\s*(?:(?:\[[0-9A-Fa-f]{2}\]|<[0-9A-Fa-f]{2}>)\s*)+")
_OPENING = re.compile(r"at (\d{1,9}) bauds? \(([NEO]), ([5-8]), ([12])\)")
_CONNECTING = re.compile(r"Connecting to \[?([^\]\s]+?)\]?:(\d{1,5})\s*$")
_MBPOLL_TCP = re.compile(r"^Communication\.+: (\S+), port (\d{1,5}),")
_ACCEPTED = re.compile(r"Client connection accepted from (\S+?)\.?\s*$")
_EVENT = re.compile(
    r"^(ERROR\b.*|The responding slave .*|Invalid (?:transaction|protocol) ID .*"
    r"|Bytes flushed .*|Confirmation to ignore|Request for slave .* ignored.*"
    r"|(?:Read|Write) .* failed: .*)$"
)


def _survey(lines: Lines, parsed: ParsedLog, where: str) -> None:
    """What the whole output says: a server's or a client's, mbpoll over TCP, the line."""
    indication = confirmation = mbpoll_tcp = False
    opening: re.Match[str] | None = None
    for _, line in lines():
        indication = indication or "Waiting for an indication" in line
        confirmation = confirmation or "Waiting for a confirmation" in line
        mbpoll_tcp = mbpoll_tcp or "Protocol configuration: ModBus TCP" in line
        opening = opening or _OPENING.search(line)
    server = indication and not confirmation
    parsed.surveyed["server"] = server
    parsed.labels, parsed.client = Labels.HINT, "client" if server else "libmodbus"
    if server:
        parsed.servers[""] = "libmodbus"
    role = "server" if server else "client"
    parsed.channel_label = f"libmodbus {role} debug ([..] sent, <..> received)"
    if mbpoll_tcp:
        parsed.client, parsed.server_port = "mbpoll", 502
    if opening:
        try:
            parsed.line = LineSettings(
                baud=int(opening[1]),
                parity=opening[2],
                bytesize=int(opening[3]),
                stopbits=int(opening[4]),
            )
        except ValueError as exc:
            parsed.warnings.append(f"{where}: the line settings it names are unusable: {exc}")


def parse_libmodbus(lines: Lines, where: str, parsed: ParsedLog) -> Iterator[LogRecord]:
    if not parsed.surveyed:
        _survey(lines, parsed, where)
    server = parsed.surveyed["server"]
    sent, received = (
        (Direction.SLAVE, Direction.MASTER) if server else (Direction.MASTER, Direction.SLAVE)
    )
    for number, line in lines():
        yield from parsed.flush()
        _names(parsed, line, server)
        if event := _EVENT.match(line.strip()):
            parsed.event(number, None, event[1])
            continue
        run = _RUN.search(line)
        if run is None or (
            len(TOKEN.findall(run[0])) == 1 and line[run.end() :].lstrip().startswith(":")
        ):
            continue  # no bytes; or mbpoll's `[10]: 13`, a reference and its value
        current: Direction | None = None
        data = bytearray()
        for match in TOKEN.finditer(run[0]):
            direction = sent if match[1] is not None else received
            if current is not None and direction != current and data:
                parsed.records.append(LogRecord(bytes(data), number, None, current))
                data = bytearray()
            current = direction
            data.append(int(match[1] or match[2], 16))
        if data and current is not None:
            parsed.records.append(LogRecord(bytes(data), number, None, current))
        if event := _EVENT.match(line[run.end() :].strip()):
            parsed.event(number, None, event[1])  # stderr's line written into stdout's
    yield from parsed.flush()


def _names(parsed: ParsedLog, line: str, server: bool) -> None:
    """The server's (or, on a server, the client's) address, where a line names it."""
    found = _CONNECTING.search(line) or _MBPOLL_TCP.match(line.strip())
    if found and not server:
        parsed.servers[""] = f"{found[1]}:{found[2]}"
        parsed.server_port = int(found[2])
    elif (accepted := _ACCEPTED.search(line)) and server:
        parsed.client = accepted[1]
        parsed.server_port = parsed.server_port or 502
