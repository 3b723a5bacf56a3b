"""Provides readers for the text logs people post: ESPHome `uart_debug`, pymodbus and
libmodbus debug output, and serial monitors (tio, sscom, Serial Port Monitor, generic
`time TX: hex` lines).

Each log is read line by line into records (bytes, the line's printed time if any, the
direction its label gives), then into chunks on channel 0: one chunk per logged line or
block, `t_end` = the printed time. A line the reader cannot use becomes a warning naming
the file and line number; nothing here raises on content.

What the logs say, and how far to trust it (see docs/formats.md):

- ESPHome `uart_debug`: `[12:34:56][D][uart_debug:158]: >>> 01:03:00:00:00:02:C4:0B`.
  `>>>` is what ESPHome sent (Direction.MASTER: ESPHome is the Modbus master), `<<<`
  what it received (SLAVE). A log with only `<<<` lines is ESPHome listening on a bus
  it does not drive: no direction. Bytes as hex (`%02X` with any one-character
  separator), decimal, string (`"\\x01\\x03"`) or binary (`0b00000001 (0x01)`). Print
  time, 1 s (`[12:34:56]`) or 1 ms (`[12:34:56.789]`).
- pymodbus: `send: 0x1 0x3 ...` / `recv: 0x1 0x3 ... extra data: ...` (3.x) and
  `SEND:` / `RECV:` (2.x), after any logging prefix. The client's own sends are MASTER.
  Print time of the logging record (`2024-05-01 12:00:00,123`), or none.
- libmodbus (`modbus_set_debug`): `[01][03]...` is what the program sent, `<01><03>...`
  what it received; a client's sends are MASTER, a server's (its log says `Waiting for an
  indication`) are SLAVE. No time at all. `Opening /dev/ttyUSB0 at 9600 bauds (N, 8, 1)`
  gives the line settings.
- serial monitors: an optional time (`[2024-05-01 12:00:00.123]`, `12:00:00.123`,
  `[26/02/2020 10:12:34]`), an optional direction (`TX`/`RX`, `>`/`<`, sscom's
  `发→◇`/`收←◆`, Serial Port Monitor's `Written data`/`Read data` block headers), then
  hex bytes. What the monitoring program sent (TX, written) is MASTER, what it received
  SLAVE. Print time.

Files without any time get synthetic times (one character time per byte, increasing),
and say so (`Stamp.NONE`).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

from dissectors.checks import crc_bytes
from sniffer.model import Chunk, Direction, Labels, LineSettings, SourceInfo, Stamp
from sniffer.sources.base import Capture, ReadOptions

ESPHOME = "esphome"
PYMODBUS = "pymodbus"
LIBMODBUS = "libmodbus"
MONITOR = "monitor"
LOG_FORMATS = (ESPHOME, PYMODBUS, LIBMODBUS, MONITOR)

DAY = 86_400.0
_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")

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


def _decode_head(head: bytes) -> str | None:
    """Like decode_text, for the first bytes of a file (a character may be cut at the end)."""
    if b"\0" in head:
        return None
    for encoding in ("utf-8", "gbk"):
        text = head.decode(encoding, errors="replace")
        if text.count("\ufffd") <= 2:
            return text
    return None


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


def _fraction(digits: str | None) -> tuple[float, float]:
    if not digits:
        return 0.0, 1.0
    return int(digits) / 10 ** len(digits), 10.0 ** -len(digits)


def parse_stamp(text: str, pos: int = 0) -> Stamped | None:
    """The time at `pos` in `text` (optionally in brackets), or None. Forms: see _TIME_PATTERNS."""
    lead = re.compile(r"\s*(\[)?\s*").match(text, pos)
    start = lead.end() if lead else pos
    bracket = bool(lead and lead[1])
    for index, pattern in enumerate(_TIME_PATTERNS):
        match = pattern.match(text, start)
        if match is None:
            continue
        end = match.end()
        if bracket:
            close = re.compile(r"\s*\]").match(text, end)
            if close is None:
                return None
            end = close.end()
        fraction, resolution = _fraction(match["f"])
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
        except ValueError:
            return None
        return Stamped(moment.timestamp() + fraction, resolution, True, end)
    return None


# ---------------------------------------------------------------- records to chunks


@dataclass(frozen=True, slots=True)
class LogRecord:
    """Bytes one log line (or block) shows, with its line number, time and direction."""

    data: bytes
    line: int
    stamp: Stamped | None
    direction: Direction


@dataclass
class ParsedLog:
    """What a format's parser found: records, warnings, and what the file says about itself."""

    records: list[LogRecord] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    labels: Labels = Labels.NONE
    line: LineSettings | None = None
    channel_label: str = ""


def _stamps_of(records: Sequence[LogRecord]) -> tuple[Stamp, float]:
    stamped = [r.stamp for r in records if r.stamp is not None]
    if not stamped:
        return Stamp.NONE, 0.0
    return Stamp.PRINT, max(s.resolution for s in stamped)


def record_chunks(
    records: Sequence[LogRecord], line: LineSettings, where: str, warnings: list[str]
) -> Iterator[Chunk]:
    """Chunks of `records` in file order, on channel 0, `t_end` = the printed time.

    Times never go backwards: a time of day that falls by more than 12 hours is taken as
    the next day; a smaller fall (a clock step, threads printing out of order) keeps the
    previous time, with one warning. A record without a time follows the previous one by
    one character time per byte (`t_start` = the previous time): so does every record of
    a file without times.
    """
    char = line.char_time
    t_prev: float | None = None
    day_offset = 0.0
    warned_back = False
    for record in records:
        if record.stamp is None:
            base = t_prev if t_prev is not None else 0.0
            t_end = base + char * max(len(record.data), 1)
            yield Chunk(data=record.data, t_end=t_end, t_start=base, direction=record.direction)
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
        yield Chunk(data=record.data, t_end=t, direction=record.direction)


Parser = Callable[[Sequence[str], str], ParsedLog]


def open_log(path: Path, options: ReadOptions, kind: str) -> Capture:
    """Open a text log of format `kind` (one of LOG_FORMATS)."""
    raw = path.read_bytes()
    text = decode_text(raw)
    if text is None:
        text = raw.decode("latin-1")
    lines = text.splitlines()
    parsed = PARSERS[kind](lines, str(path))
    line = options.line(parsed.line)
    stamps, resolution = _stamps_of(parsed.records)
    warnings = list(parsed.warnings)
    if not parsed.records:
        warnings.append(f"{path}: no bytes found in this {FORMAT_NAMES[kind]} log")
    info = SourceInfo(
        path=str(path),
        format=kind,
        line=line,
        channels={0: parsed.channel_label or FORMAT_NAMES[kind]},
        warnings=tuple(warnings),
        stamps=stamps,
        resolution=resolution,
        labels=parsed.labels,
    )
    chunks = record_chunks(parsed.records, line, str(path), warnings)
    return Capture(info=info, _chunks=chunks, warnings=warnings)


# ---------------------------------------------------------------- ESPHome

_ESPHOME = re.compile(r"\[uart_debug(?::\d+)?\]:?\s*(<<<|>>>)\s?(.*)$")
_ESP_BINARY = re.compile(r"0b[01]{8} \(0x([0-9A-Fa-f]{2})\)")
_ESP_ESCAPES = {
    "a": 7,
    "b": 8,
    "t": 9,
    "n": 10,
    "v": 11,
    "f": 12,
    "r": 13,
    "e": 27,
    '"': 34,
    "'": 39,
    "\\": 92,
}
_HEX2 = re.compile(r"^[0-9A-Fa-f]{2}$")
_DEC = re.compile(r"^\d{1,3}$")


def _esp_string(body: str) -> bytes | None:
    if len(body) < 2 or not body.startswith('"') or not body.endswith('"'):
        return None
    inner = body[1:-1]
    out = bytearray()
    i = 0
    while i < len(inner):
        char = inner[i]
        if char != "\\":
            code = ord(char)
            if code > 255:
                return None
            out.append(code)
            i += 1
            continue
        nxt = inner[i + 1 : i + 2]
        if nxt == "x" and _HEX2.match(inner[i + 2 : i + 4]):
            out.append(int(inner[i + 2 : i + 4], 16))
            i += 4
        elif nxt in _ESP_ESCAPES:
            out.append(_ESP_ESCAPES[nxt])
            i += 2
        else:
            return None
    return bytes(out)


def _esp_tokens(body: str) -> list[str]:
    """Numbers separated by one separator character (`:` by default, any the user chose)."""
    body = body.strip()
    if not body:
        return []
    separator = next((c for c in body if not c.isalnum()), "")
    tokens = body.split(separator) if separator else [body]
    return [t.strip() for t in tokens]


def parse_esphome(lines: Sequence[str], where: str) -> ParsedLog:
    found: list[tuple[int, Stamped | None, str, str]] = []
    for number, raw_line in enumerate(lines, start=1):
        line = _ANSI.sub("", raw_line)
        match = _ESPHOME.search(line)
        if match is None:
            continue
        found.append((number, parse_stamp(line), match[1], match[2].rstrip()))
    # hex (`%02X`) or decimal, for the whole file (the setting is per device): a line with
    # a two-character token with a letter or a leading zero is hex, one with a token of one
    # or three digits decimal; the larger count wins (a cut line cannot turn the file)
    hex_lines = decimal_lines = 0
    for _, _, _, body in found:
        if body.startswith('"') or _ESP_BINARY.search(body):
            continue
        tokens = _esp_tokens(body)
        if any(len(t) == 2 and (t[0] == "0" or not t.isdigit()) for t in tokens):
            hex_lines += 1
        elif any(len(t) != 2 and _DEC.match(t) for t in tokens):
            decimal_lines += 1
    decimal = decimal_lines > hex_lines
    parsed = ParsedLog()
    arrows = {arrow for _, _, arrow, _ in found}
    sent = Direction.MASTER
    received = Direction.SLAVE if ">>>" in arrows else Direction.UNKNOWN
    parsed.labels = Labels.HINT if ">>>" in arrows else Labels.NONE
    parsed.channel_label = (
        "ESPHome uart_debug (>>> sent by ESPHome: master, <<< received)"
        if ">>>" in arrows
        else "ESPHome uart_debug (<<< only: listening, no direction)"
    )
    for number, stamp, arrow, body in found:
        data: bytes | None
        if body.startswith('"'):
            data = _esp_string(body)
        elif _ESP_BINARY.search(body):
            data = bytes(int(h, 16) for h in _ESP_BINARY.findall(body))
        else:
            tokens = _esp_tokens(body)
            if decimal:
                ok = all(_DEC.match(t) and int(t) < 256 for t in tokens)
                data = bytes(int(t) for t in tokens) if ok else None
            else:
                ok = all(_HEX2.match(t) for t in tokens)
                data = bytes(int(t, 16) for t in tokens) if ok else None
        if not data:
            parsed.warnings.append(
                f"{where} line {number}: cannot read the bytes of this uart_debug line "
                f"({body[:40]!r}); the line is skipped (a cut line or another log format?)"
            )
            continue
        direction = sent if arrow == ">>>" else received
        parsed.records.append(LogRecord(data, number, stamp, direction))
    return parsed


# ---------------------------------------------------------------- pymodbus

_PYMODBUS = re.compile(r"(?<![A-Za-z])(send|recv|SEND|RECV):\s*((?:0x[0-9a-fA-F]{1,2}\b\s*)*)(.*)$")
_PYMODBUS_REPEAT = re.compile(r"\bRepeating\.\.\.\.")


def parse_pymodbus(lines: Sequence[str], where: str) -> ParsedLog:
    parsed = ParsedLog(labels=Labels.HINT)
    parsed.channel_label = "pymodbus client log (send: master, recv: answers)"
    tcp_warned = False
    for number, raw_line in enumerate(lines, start=1):
        line = _ANSI.sub("", raw_line)
        if _PYMODBUS_REPEAT.search(line):
            parsed.warnings.append(
                f"{where} line {number}: pymodbus wrote 'Repeating....' and left out "
                "repeated lines; the frames it left out cannot be read back"
            )
            continue
        match = _PYMODBUS.search(line)
        if match is None:
            continue
        rest = match[3].strip()
        if rest and not rest.startswith(("extra data:", "old_data:", "old data:")):
            parsed.warnings.append(
                f"{where} line {number}: cannot read {rest[:30]!r} as bytes; the line is "
                "skipped (a cut or edited line?)"
            )
            continue
        data = bytes(int(token, 16) for token in match[2].split())
        if not data:
            continue  # `recv:` with nothing new: a read that returned no bytes
        if (
            not tcp_warned
            and len(data) >= 8
            and data[2:4] == b"\0\0"
            and int.from_bytes(data[4:6], "big") == len(data) - 6
            and crc_bytes(data[:-2]) != data[-2:]
        ):
            tcp_warned = True
            parsed.warnings.append(
                f"{where} line {number}: these bytes look like Modbus TCP (an MBAP header), "
                "not a serial line; modscope reads serial RTU and ASCII"
            )
        direction = Direction.MASTER if match[1].lower() == "send" else Direction.SLAVE
        stamp = parse_stamp(line)
        parsed.records.append(LogRecord(data, number, stamp, direction))
    return parsed


# ---------------------------------------------------------------- libmodbus

_LIBMODBUS_TOKEN = re.compile(r"\[([0-9A-Fa-f]{2})\]|<([0-9A-Fa-f]{2})>")
_LIBMODBUS_OPEN = re.compile(r"at (\d+) bauds? \(([NEO]), ([5-8]), ([12])\)")


def parse_libmodbus(lines: Sequence[str], where: str) -> ParsedLog:
    text = "\n".join(lines)
    server = "Waiting for an indication" in text and "Waiting for a confirmation" not in text
    sent, received = (
        (Direction.SLAVE, Direction.MASTER) if server else (Direction.MASTER, Direction.SLAVE)
    )
    parsed = ParsedLog(labels=Labels.HINT)
    role = "server" if server else "client"
    parsed.channel_label = f"libmodbus {role} debug ([..] sent, <..> received)"
    if opening := _LIBMODBUS_OPEN.search(text):
        try:
            parsed.line = LineSettings(
                baud=int(opening[1]),
                parity=opening[2],
                bytesize=int(opening[3]),
                stopbits=int(opening[4]),
            )
        except ValueError as exc:
            parsed.warnings.append(f"{where}: the line settings it names are unusable: {exc}")
    for number, line in enumerate(lines, start=1):
        current: Direction | None = None
        data = bytearray()
        for match in _LIBMODBUS_TOKEN.finditer(line):
            direction = sent if match[1] is not None else received
            if current is not None and direction != current and data:
                parsed.records.append(LogRecord(bytes(data), number, None, current))
                data = bytearray()
            current = direction
            data.append(int(match[1] or match[2], 16))
        if data and current is not None:
            parsed.records.append(LogRecord(bytes(data), number, None, current))
    return parsed


# ---------------------------------------------------------------- serial monitors

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
_BLOCK_HEADER = re.compile(r"\b(Written data|Write|Read data|Read)\b(?:\s*\(([^)]*)\))?", re.I)
_HEX_RUN = re.compile(r"((?:[0-9A-Fa-f]{2}(?: |$))*[0-9A-Fa-f]{2})(?=\s{2,}|\s*$|\s*[^\w\s])")
_LOOKS_HEX = re.compile(r"\s*[0-9A-Fa-f]{2}(?: [0-9A-Fa-f]{2}|\s*$)")


def _hex_bytes(text: str) -> bytes | None:
    """Hex bytes at the start of `text`: pairs of hex digits separated by single spaces,
    ending at the line's end, at an ASCII column (two or more spaces) or at a symbol
    (sscom's `□`)."""
    match = _HEX_RUN.match(text.strip())
    return None if match is None else bytes.fromhex(match[1])


def parse_monitor(lines: Sequence[str], where: str) -> ParsedLog:
    parsed = ParsedLog()
    labelled = False
    block: tuple[int, Stamped | None, Direction] | None = None
    block_data = bytearray()

    def close() -> None:
        nonlocal block
        if block is not None and block_data:
            parsed.records.append(LogRecord(bytes(block_data), block[0], block[1], block[2]))
        block_data.clear()
        block = None

    for number, raw_line in enumerate(lines, start=1):
        line = _ANSI.sub("", raw_line).rstrip()
        if not line.strip():
            close()
            continue
        stamp = parse_stamp(line)
        rest = line[stamp.end :] if stamp else line
        rest = rest.strip()
        if rest.startswith("- "):
            rest = rest[2:].lstrip()
        header = _BLOCK_HEADER.match(rest)
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
    parsed.labels = Labels.HINT if labelled else Labels.NONE
    parsed.channel_label = (
        "serial monitor (TX/written: master, RX/read: answers)"
        if labelled
        else "serial monitor (no direction)"
    )
    return parsed


PARSERS: dict[str, Parser] = {
    ESPHOME: parse_esphome,
    PYMODBUS: parse_pymodbus,
    LIBMODBUS: parse_libmodbus,
    MONITOR: parse_monitor,
}
FORMAT_NAMES = {
    ESPHOME: "ESPHome uart_debug",
    PYMODBUS: "pymodbus debug",
    LIBMODBUS: "libmodbus debug",
    MONITOR: "serial monitor",
}

# ---------------------------------------------------------------- recognition

_SNIFF_LINES = 400


def sniff_log(head: bytes) -> str | None:
    """The log format of a file starting with `head`, or None. Decided by the lines each
    tool prints: at least one `uart_debug` arrow line, pymodbus `send:`/`recv:` line or
    libmodbus line of bracketed bytes; at least two serial monitor lines of three or more
    hex bytes (and more such lines than other text lines)."""
    text = _decode_head(head)
    if text is None:
        return None
    lines = text.splitlines()[:_SNIFF_LINES]
    scores = dict.fromkeys(LOG_FORMATS, 0)
    other = 0
    for raw_line in lines:
        line = _ANSI.sub("", raw_line)
        if _ESPHOME.search(line):
            scores[ESPHOME] += 1
        elif (match := _PYMODBUS.search(line)) and match[2].strip():
            scores[PYMODBUS] += 1
        elif len(_LIBMODBUS_TOKEN.findall(line)) >= 2 and not _LIBMODBUS_TOKEN.sub("", line).strip(
            " \t?"
        ):
            scores[LIBMODBUS] += 1
        elif line.strip():
            parsed = parse_monitor([line], "")
            if parsed.records and len(parsed.records[0].data) >= 3:
                scores[MONITOR] += 1
            elif not _BLOCK_HEADER.search(line):
                other += 1
    for kind in (ESPHOME, PYMODBUS, LIBMODBUS):
        if scores[kind]:
            return kind
    if scores[MONITOR] >= 2 and scores[MONITOR] > other:
        return MONITOR
    return None
