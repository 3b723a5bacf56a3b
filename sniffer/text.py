"""Provides safe plain text for anything that came from a device or a file.

Device strings are data, never markup or terminal control: control characters are
escaped as `\\xNN` and long strings are cut with an ellipsis. Views render the result as
plain text (never through a markup parser).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable

MAX_TEXT = 400
CSV_TEXT_LIMIT = 1 << 20  # a CSV cell keeps its whole text (raw hex of a frame included)
# A spreadsheet runs a cell starting with one of these as a formula (OWASP "CSV
# injection"); tab and CR are listed there too, and never survive `plain` unescaped.
FORMULA_START = frozenset("=+-@\t\r")
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
# what `plain` escapes; text with none of it is returned as it is (one regex search in C
# instead of a Python loop over its characters: most text has nothing to escape)
# bidirectional controls too (U+202A-202E, U+2066-2069, marks): they reorder what a
# terminal shows after them (Trojan Source, CVE-2021-42574)
_BIDI = frozenset((0x061C, 0x200E, 0x200F, *range(0x202A, 0x202F), *range(0x2066, 0x206A)))
_UNSAFE = re.compile(
    r"[\x00-\x1f\x7f-\x9f\u2028\u2029\u061c\u200e\u200f\u202a-\u202e\u2066-\u2069]"
)


def plain(text: str, limit: int = MAX_TEXT) -> str:
    """`text` with control characters escaped and at most `limit` characters."""
    if len(text) <= limit and _UNSAFE.search(text) is None:
        return text
    out = []
    for ch in text:
        code = ord(ch)
        if code < 0x20 or 0x7F <= code < 0xA0 or code in (0x2028, 0x2029) or code in _BIDI:
            out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}")
        else:
            out.append(ch)
    result = "".join(out)
    if len(result) > limit:
        result = result[: limit - 1] + "…"
    return result


def plain_lines(text: str, limit: int = 4000) -> str:
    """Several lines of text (a report made from file strings) with each line `plain`:
    the line breaks stay, every other control character is escaped."""
    return "\n".join(plain(line, limit) for line in text.split("\n"))


# JSON escapes C0 controls itself; these reach a terminal raw with ensure_ascii=False
_JSON_UNSAFE = {c: f"\\u{c:04x}" for c in (*range(0x7F, 0xA0), 0x2028, 0x2029)}


def json_line(record: object) -> str:
    """`record` as one line of JSON, non-ASCII text kept readable, and the control
    characters JSON itself leaves raw (DEL, C1, line/paragraph separators) escaped, so
    a JSONL listing on a terminal cannot drive it."""
    line = json.dumps(record, ensure_ascii=False)
    return line if line.isascii() and "\x7f" not in line else line.translate(_JSON_UNSAFE)


def csv_cell(value: object, *, raw: bool = False) -> str | int | float:
    """One CSV cell that a spreadsheet shows as text and never runs.

    Numbers stay numbers: an int or a float, or a string that is exactly a decimal
    number (a time or a latency we formatted, `-1.5`), is written as it is; a spreadsheet
    reads it as a number, which cannot run. Every other text goes through `plain`
    (control characters escaped, so nothing reaches a terminal that `cat`s the file) and,
    when it starts with `=`, `+`, `-` or `@` (after any spaces), gets a leading `'`,
    which spreadsheets take as "this is text" and do not show. `raw` (the `--raw-csv`
    option) leaves that `'` out, for programs that read the file and never a spreadsheet."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int) or (isinstance(value, float) and math.isfinite(value)):
        return value
    text = plain(str(value), CSV_TEXT_LIMIT)
    first = text.lstrip(" ")[:1]  # " =1+1": spreadsheets that trim spaces run it too
    if raw or not first or first not in FORMULA_START or _NUMBER.fullmatch(text.strip(" ")):
        return text
    return "'" + text


def csv_row(values: Iterable[object], *, raw: bool = False) -> list[str | int | float]:
    """`csv_cell` of every value: the one way a CSV row is written."""
    return [csv_cell(value, raw=raw) for value in values]
