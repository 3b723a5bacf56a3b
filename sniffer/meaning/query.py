"""Provides the filter language of the TUI's frame list and the CLI's --filter:
`unit:3 fc:3 status:timeout reg:"Trip" t:10-20 text`.

A query is a list of terms separated by spaces. `key:value` terms test a row's columns
(cheap: they scan the store's arrays); `reg:` and plain words need the row's details
(they dissect the candidates the column terms leave). Terms with different keys must
all hold; values of one key, given as a list (`unit:1,2`) or in several terms, are
alternatives. A `-` before a column term excludes what it names (`-fc:3`). Double
quotes keep spaces inside a value or a word.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from sniffer.vocab import Kind

KEYS = ("unit", "fc", "kind", "status", "reg", "t")
EXAMPLES = {
    "unit": "unit:3",
    "fc": "fc:3",
    "kind": "kind:request",
    "status": "status:timeout",
    "reg": 'reg:"Under Voltage"',
    "t": "t:10-20",
}

KIND_WORDS: dict[str, int] = {
    "request": Kind.REQUEST,
    "req": Kind.REQUEST,
    "response": Kind.RESPONSE,
    "resp": Kind.RESPONSE,
    "answer": Kind.RESPONSE,
    "exception": Kind.EXCEPTION,
    "exc": Kind.EXCEPTION,
    "noise": Kind.NOISE,
    "event": Kind.EVENT,
    "unknown": Kind.UNKNOWN,
}

STATUS_WORDS: dict[str, str] = {
    "ok": "ok",
    "exception": "exception",
    "exc": "exception",
    "timeout": "timeout",
    "t/o": "timeout",
    "orphan": "orphan",
    "broadcast": "broadcast",
    "open": "open",
    "check": "check",
    "crc": "check",
    "lrc": "check",
    "bad": "check",
    "noise": "noise",
    "event": "event",
    "problem": "problem",
    "problems": "problem",
    "error": "problem",
}

_TIME_SUFFIX = {"ms": 0.001, "s": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0}
_TOKEN = re.compile(r'\s*(-?)(?:([A-Za-z]+):)?("[^"]*"?|\S*)')


class QueryError(ValueError):
    """A filter that cannot be read; the message says what to write instead."""


@dataclass(frozen=True, slots=True)
class TimePoint:
    """Seconds from the capture's first row, or (clock) seconds after local midnight."""

    seconds: float
    clock: bool = False


@dataclass(frozen=True, slots=True)
class TimeSpan:
    start: TimePoint | None
    end: TimePoint | None


@dataclass(frozen=True, slots=True)
class Query:
    """A parsed filter. Empty sets mean: no condition on that column."""

    text: str = ""
    units: frozenset[int] = frozenset()
    not_units: frozenset[int] = frozenset()
    functions: frozenset[int] = frozenset()
    not_functions: frozenset[int] = frozenset()
    kinds: frozenset[int] = frozenset()
    not_kinds: frozenset[int] = frozenset()
    statuses: frozenset[str] = frozenset()
    not_statuses: frozenset[str] = frozenset()
    registers: tuple[str, ...] = ()  # lower-case parts of register names, any may match
    words: tuple[str, ...] = ()  # lower-case words, all must appear in the row's text
    time: TimeSpan | None = None

    @property
    def needs_detail(self) -> bool:
        """Whether rows must be dissected to decide (register names, free text)."""
        return bool(self.registers or self.words)

    @property
    def has_columns(self) -> bool:
        return bool(
            self.units
            or self.not_units
            or self.functions
            or self.not_functions
            or self.kinds
            or self.not_kinds
            or self.statuses
            or self.not_statuses
        )

    @property
    def empty(self) -> bool:
        return not (self.has_columns or self.needs_detail or self.time is not None)


def _numbers(key: str, value: str, low: int, high: int) -> set[int]:
    out: set[int] = set()
    for part in value.split(","):
        part = part.strip()
        if not part:
            raise QueryError(f"{key}:{value}: an empty value between commas; write e.g. {key}:1,2")
        a, sep, b = part.partition("-")
        try:
            first = int(a, 0)
            last = int(b, 0) if sep else first
        except ValueError:
            raise QueryError(
                f"{key}:{value}: {part!r} is not a number; write e.g. {key}:3, {key}:1,2 "
                f"or {key}:1-5"
            ) from None
        if not (low <= first <= high and low <= last <= high) or last < first:
            raise QueryError(f"{key}:{value}: values go from {low} to {high}")
        out.update(range(first, last + 1))
    if not out:
        raise QueryError(f"{key}: needs a value, e.g. {key}:3")
    return out


def _words(key: str, value: str, table: dict[str, int] | dict[str, str]) -> list[str]:
    out = []
    for part in value.lower().split(","):
        if not part:
            raise QueryError(
                f"{key}:{value}: an empty value between commas; write e.g. {EXAMPLES[key]}"
            )
        if part not in table:
            names = ", ".join(sorted({str(k) for k in table}))
            raise QueryError(f"{key}:{part} is not known; use one of {names}")
        out.append(part)
    return out


def parse_time_point(text: str) -> TimePoint:
    """`12.5`, `500ms`, `2m`, or a clock time `14:03:07.25` (local time of the capture)."""
    text = text.strip()
    if ":" in text:
        parts = text.split(":")
        if len(parts) > 3:
            raise QueryError(f"{text!r}: write a clock time as hh:mm or hh:mm:ss.fff")
        try:
            numbers = [float(p) for p in parts]
        except ValueError:
            raise QueryError(f"{text!r}: write a clock time as hh:mm or hh:mm:ss.fff") from None
        while len(numbers) < 3:
            numbers.append(0.0)
        h, m, s = numbers
        if not (0 <= h < 24 and 0 <= m < 60 and 0 <= s < 60) or h != int(h) or m != int(m):
            raise QueryError(
                f"{text!r} is not a clock time: hours go from 0 to 23, minutes and seconds "
                "from 0 to 59 (14:03:07.25)"
            )
        return TimePoint(h * 3600 + m * 60 + s, clock=True)
    match = re.fullmatch(r"([0-9]*\.?[0-9]+)\s*(ms|s|min|m|h)?", text)
    if match is None:
        raise QueryError(
            f"{text!r} is not a time; write seconds from the start (12.5, 500ms, 2m) "
            "or a clock time (14:03:07)"
        )
    return TimePoint(float(match.group(1)) * _TIME_SUFFIX[match.group(2) or "s"])


def parse_time_span(value: str) -> TimeSpan:
    """`10-20`, `10-` (from 10 on), `-20` (up to 20), `14:00-14:05`."""
    if value == "-":
        raise QueryError("t:-: give a start, an end or both, e.g. t:10-20, t:10- or t:-20")
    if value.startswith("-"):
        return TimeSpan(None, parse_time_point(value[1:]))
    if value.endswith("-"):
        return TimeSpan(parse_time_point(value[:-1]), None)
    a, sep, b = value.partition("-")
    if not sep:
        start = parse_time_point(a)
        return TimeSpan(start, TimePoint(start.seconds + 1.0, start.clock))
    start, end = parse_time_point(a), parse_time_point(b)
    if start.clock != end.clock:
        raise QueryError(
            f"t:{value}: both ends are seconds from the start (t:10-20) or both clock "
            "times (t:14:03-14:05)"
        )
    if end.seconds < start.seconds:
        raise QueryError(
            f"t:{value}: the end comes before the start; write the earlier time first (t:{b}-{a})"
        )
    return TimeSpan(start, end)


def parse_query(text: str) -> Query:
    """Parse a filter; raises QueryError with a hint when a term cannot be read."""
    numbers: dict[str, set[int]] = {}
    names: dict[str, set[str]] = {}
    registers: list[str] = []
    words: list[str] = []
    time: TimeSpan | None = None
    pos = 0
    while pos < len(text):
        match = _TOKEN.match(text, pos)
        if match is None or match.end() == pos:
            break
        pos = match.end()
        neg, value = match.group(1), match.group(3)
        key: str | None = match.group(2)
        if key is not None and not value and key.lower() not in KEYS:
            value, key = key + ":", None  # a word that ends with a colon
        if key is None and not value:
            if neg:
                raise QueryError("-: write the term to leave out right after it, e.g. -fc:3")
            continue
        term = f"{'-' if neg else ''}{key + ':' if key else ''}{value}"
        if '"' in value[1:-1] or (value.endswith('"') and not value.startswith('"')):
            raise QueryError(
                f"{term}: a quote inside a term; put quotes around the whole value or "
                'text (reg:"Under Voltage", "two words")'
            )
        if value.startswith('"') and pos < len(text) and not text[pos].isspace():
            raise QueryError(
                f"{term}{text[pos:].split()[0]}: text right after a closing quote; "
                "leave a space after it"
            )
        if value.startswith('"'):
            if len(value) < 2 or not value.endswith('"'):
                raise QueryError(
                    f'{term}: the quote is not closed; end the text with " '
                    f'(e.g. reg:"Under Voltage")'
                )
            value = value[1:-1]
            if not value.strip():
                raise QueryError(
                    f'{key + ":" if key else ""}"": empty quotes; put the text between them'
                )
        if key is None:
            if neg:
                raise QueryError(f"-{value}: only unit, fc, kind and status terms can be negated")
            if value:
                words.append(value.lower())
            continue
        key = key.lower()
        if key not in KEYS:
            raise QueryError(
                f"{key}:{value}: unknown key {key!r}; keys are {', '.join(KEYS)} "
                f'(put text with a colon in quotes: "{key}:{value}")'
            )
        if neg and key in ("reg", "t"):
            raise QueryError(f"-{key}:{value}: only unit, fc, kind and status terms can be negated")
        if not value:
            raise QueryError(f"{key}: needs a value, e.g. {EXAMPLES[key]}")
        slot = ("not_" if neg else "") + key
        if key == "unit":
            numbers.setdefault(slot, set()).update(_numbers(key, value, 0, 255))
        elif key == "fc":
            numbers.setdefault(slot, set()).update(_numbers(key, value, 1, 127))
        elif key == "kind":
            found = [KIND_WORDS[w] for w in _words(key, value, KIND_WORDS)]
            numbers.setdefault(slot, set()).update(found)
        elif key == "status":
            found_names = [STATUS_WORDS[w] for w in _words(key, value, STATUS_WORDS)]
            names.setdefault(slot, set()).update(found_names)
        elif key == "reg":
            registers.append(value.lower())
        else:
            if time is not None:
                raise QueryError(f"t:{value}: one time span per filter; keep one t: term")
            try:
                time = parse_time_span(value)
            except QueryError as exc:
                text_ = str(exc)
                raise QueryError(
                    text_ if text_.startswith("t:") else f"t:{value}: {text_}"
                ) from None

    def ints(slot: str) -> frozenset[int]:
        return frozenset(numbers.get(slot, ()))

    def strs(slot: str) -> frozenset[str]:
        return frozenset(names.get(slot, ()))

    return Query(
        text=text,
        units=ints("unit"),
        not_units=ints("not_unit"),
        functions=ints("fc"),
        not_functions=ints("not_fc"),
        kinds=ints("kind"),
        not_kinds=ints("not_kind"),
        statuses=strs("status"),
        not_statuses=strs("not_status"),
        registers=tuple(registers),
        words=tuple(words),
        time=time,
    )
