"""Provides the reader of ESPHome `uart_debug` logs.

`[12:34:56][D][uart_debug:158]: >>> 01:03:00:00:00:02:C4:0B`. `>>>` is what ESPHome sent
(Direction.MASTER: ESPHome is the Modbus master), `<<<` what it received (SLAVE). A log
with only `<<<` lines is ESPHome listening on a bus it does not drive: no direction.
Bytes as hex (`%02X` with any one-character separator), decimal, string (`"\\x01\\x03"`)
or binary (`0b00000001 (0x01)`). Print time, 1 s (`[12:34:56]`) or 1 ms
(`[12:34:56.789]`).
"""

from __future__ import annotations

import re
from collections.abc import Iterator

from sniffer.model import Direction, Labels
from sniffer.sources.logs.base import ANSI, HEX2, Lines, LogRecord, ParsedLog, parse_stamp

ESPHOME = "esphome"

LINE = re.compile(r"\[uart_debug(?::\d+)?\]:?\s*(<<<|>>>)\s?(.*)$")
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
        if nxt == "x" and HEX2.match(inner[i + 2 : i + 4]):
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


def _found(lines: Lines) -> Iterator[tuple[int, str, str, str]]:
    """The uart_debug lines: number, the line (without colour codes), arrow, bytes."""
    for number, raw_line in lines():
        line = ANSI.sub("", raw_line)
        match = LINE.search(line)
        if match is not None:
            yield number, line, match[1], match[2].rstrip()


def _survey(lines: Lines, parsed: ParsedLog) -> None:
    # hex (`%02X`) or decimal, for the whole file (the setting is per device): a line with
    # a two-character token with a letter or a leading zero is hex, one with a token of one
    # or three digits decimal; the larger count wins (a cut line cannot turn the file)
    hex_lines = decimal_lines = 0
    sent = False
    for _, _, arrow, body in _found(lines):
        sent = sent or arrow == ">>>"
        if body.startswith('"') or _ESP_BINARY.search(body):
            continue
        tokens = _esp_tokens(body)
        if any(len(t) == 2 and (t[0] == "0" or not t.isdigit()) for t in tokens):
            hex_lines += 1
        elif any(len(t) != 2 and _DEC.match(t) for t in tokens):
            decimal_lines += 1
    parsed.surveyed["decimal"] = decimal_lines > hex_lines
    parsed.surveyed["sent"] = sent


def parse_esphome(lines: Lines, where: str, parsed: ParsedLog) -> Iterator[LogRecord]:
    if not parsed.surveyed:
        _survey(lines, parsed)
    decimal, sent_lines = parsed.surveyed["decimal"], parsed.surveyed["sent"]
    sent = Direction.MASTER
    received = Direction.SLAVE if sent_lines else Direction.UNKNOWN
    parsed.labels = Labels.HINT if sent_lines else Labels.NONE
    parsed.channel_label = (
        "ESPHome uart_debug (>>> sent by ESPHome: master, <<< received)"
        if sent_lines
        else "ESPHome uart_debug (<<< only: listening, no direction)"
    )
    for number, line, arrow, body in _found(lines):
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
                ok = all(HEX2.match(t) for t in tokens)
                data = bytes.fromhex("".join(tokens)) if ok else None
        if not data:
            parsed.warnings.append(
                f"{where} line {number}: cannot read the bytes of this uart_debug line "
                f"({body[:40]!r}); the line is skipped (a cut line or another log format?)"
            )
            continue
        direction = sent if arrow == ">>>" else received
        yield LogRecord(data, number, parse_stamp(line), direction)
