"""Provides the frame listing: one line per row as text, a JSON object, or a CSV record."""

from __future__ import annotations

import csv
import json
import math
import struct
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from math import ceil, log10
from typing import Any, TextIO

from dissectors.values import Field
from sniffer import core
from sniffer.framing.pairing import (
    INF,
    RESOLVED,
    UNRESOLVED,
    coarse,
    latency_words,
    measure,
    shown_step,
    span_words,
    timing_note,
)
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.meaning.describe import VALUED_FLAGS, Describer, FrameDetail, Shared
from sniffer.model import Stamp
from sniffer.text import csv_row, json_line
from sniffer.vocab import STATUS_NAMES, Flag, Kind, Status

FORMATS = ("text", "jsonl", "csv")
KIND_NAMES = {
    Kind.NOISE: "noise",
    Kind.REQUEST: "request",
    Kind.RESPONSE: "response",
    Kind.EXCEPTION: "exception",
    Kind.UNKNOWN: "unknown",
    Kind.EVENT: "event",
}
CSV_COLUMNS = (
    "index",
    "t",
    "t_end",
    "direction",
    "kind",
    "unit",
    "function",
    "name",
    "length",
    "check_ok",
    "status",
    "latency_ms",
    "latency_max_ms",  # the bound where the timing only bounds the latency
    "summary",
    "problems",
    "raw",
    "fields",
    "channel",
    "peer",  # network captures: the sender's ip:port
)


# JSONL `timing`: what the row times are (see sniffer.model.Stamp); "synthetic" when the
# source had none and the times were made up from the baud rate
TIMING_NAMES = {stamp: stamp.value for stamp in Stamp} | {Stamp.NONE: "synthetic"}
SYNTHETIC_HEADER = (
    "# timing: synthetic: the source has no timestamps; times below are one character "
    "time per byte, and no latency is measured"
)


_SCALARS = frozenset((int, bool, float, str, type(None)))


def _jsonable(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, tuple):
        if _SCALARS.issuperset(map(type, value)):  # words or bits: one copy, no call each
            return list(value)
        return [_jsonable(v) for v in value]
    return value


def field_record(f: Field) -> dict[str, Any]:
    """One decoded field as JSON: name, value, text, span and, for a record or a list of
    records (FC 20/21 file records, FC 23's parts, FC 43/14 objects), `children` of the
    same shape. A list of register words or bits has every element in `value` and no
    `children` (element i spans 2 bytes from the field's start, or holds bit i % 8 of
    byte i // 8): that keeps a 125-register answer one short line."""
    rec: dict[str, Any] = {
        "name": f.name,
        "value": _jsonable(f.value),
        "text": f.text,
        "span": list(f.span),
    }
    if not isinstance(f.value, tuple):  # arrays make their children only when read
        children = f.children
        if children:
            rec["children"] = [field_record(c) for c in children]
    return rec


def _segment(child: Field, parent: Field) -> str:
    """A child's part of a dotted name: `3` for `objects[3]` under `objects`, else its name."""
    name = child.name
    if name.startswith(parent.name + "[") and name.endswith("]"):
        return name[len(parent.name) + 1 : -1]
    return name


def _flat_value(value: Any) -> str:
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, tuple):
        return " ".join(_flat_value(v) for v in value)
    return str(value)


def flat_fields(fields: Sequence[Field]) -> Iterator[tuple[str, str]]:
    """(dotted name, value) of every field that has a value, children after their parent:
    `sub_requests.0.file_number`, `objects.VendorName.value`. Lists of words or bits give
    one item with their values separated by spaces."""
    for f in fields:
        yield from _flat(f, f.name)


def _flat(f: Field, path: str) -> Iterator[tuple[str, str]]:
    if f.value is not None:
        yield path, _flat_value(f.value)
    if not isinstance(f.value, tuple):
        for child in f.children:
            yield from _flat(child, f"{path}.{_segment(child, f)}")


def fields_cell(fields: Sequence[Field]) -> str:
    """The CSV `fields` cell: `name=value` pairs joined by `; ` (values as plain text)."""
    return "; ".join(f"{name}={value}" for name, value in flat_fields(fields))


def record(d: FrameDetail, store: FrameStore | None = None) -> dict[str, Any]:
    """The JSONL object of a row. Keys keep their meaning as fields are added. With the
    `store`, `latency_ms` is the difference of the row times as listed (see
    `shown_latency_ms`)."""
    v = d.view
    rec: dict[str, Any] = {
        "index": v.index,
        "t": round(v.t, 6),  # to the microsecond, as recordings keep a start time
        "t_end": round(v.t_end, 6),
        "raw": v.raw.hex(),
        "mode": "ascii" if v.ascii else "tcp" if v.mbap else "rtu",
        "kind": KIND_NAMES[v.kind],
        "unit": v.unit if v.kind not in (Kind.NOISE, Kind.EVENT) else None,
        "function": v.function if v.kind not in (Kind.NOISE, Kind.EVENT) else None,
        "check_ok": v.check_ok,
        "problems": list(d.problem_texts),
        "channel": v.channel,
        "direction": d.direction,
        "name": d.name,
        "summary": d.summary,
    }
    if d.problems:
        rec["problem_details"] = problem_details(d)
    if d.label:
        rec["device"] = d.label
    if d.dissection is not None:
        rec["fields"] = [field_record(f) for f in d.dissection.fields]
    transaction = transaction_of(d, store)
    if transaction is not None:
        rec["transaction"] = transaction
    if d.registers:
        rec["registers"] = [
            {
                "table": r.table,
                "address": r.address,
                "name": r.name,
                "value": r.value,
                "unit": r.unit,
                "text": r.text,
                "raw": list(r.raw),
                "partial": r.partial,
            }
            for r in d.registers
        ]
    return rec


def problem_details(d: FrameDetail) -> list[dict[str, Any]]:
    """Each problem of a row as kind, severity, text and byte span (or null)."""
    return [
        {
            "kind": p.kind,
            "severity": p.severity,
            "text": p.text,
            "span": None if p.span is None else list(p.span),
        }
        for p in d.problems
    ]


def shown_latency_ms(d: FrameDetail, store: FrameStore | None = None) -> float | None:
    """A row's measured latency in ms as every listing gives it (`pairing.measure`: the
    difference of the row times as listed, to what the stamps hold), or None where the
    timing only bounds it (`latency_max_ms`) or cannot give it."""
    return None if d.latency_ms is None else round(d.latency_ms, 3)


def shown_latency_max_ms(d: FrameDetail) -> float | None:
    """A row's latency bound in ms (the latency is below it), where the timing gives no
    more; None otherwise."""
    return None if d.latency_max_ms is None else round(d.latency_max_ms, 3)


def transaction_of(d: FrameDetail, store: FrameStore | None = None) -> dict[str, Any] | None:
    """The `transaction` object of a row that is part of one (None for noise, events and
    frames that are not paired)."""
    v = d.view
    if v.kind not in (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION, Kind.UNKNOWN) or not v.status:
        return None
    req = v.index if v.kind == Kind.REQUEST or v.partner == NO_PARTNER else v.partner
    return {
        "id": req,
        "role": "request" if v.kind == Kind.REQUEST else "response",
        "latency_ms": shown_latency_ms(d, store),
        "latency_max_ms": shown_latency_max_ms(d),
        "status": STATUS_NAMES[v.status],
        "partner": None if v.partner == NO_PARTNER else v.partner,
    }


UPDATED_KEYS = ("transaction", "problems", "problem_details")


def update_record(d: FrameDetail, store: FrameStore | None = None) -> dict[str, Any]:
    """What the live listing learnt later about a row it listed earlier (its answer came,
    it timed out): `{"update": 40, "transaction": {...}, "problems": [...]}`, the keys of
    UPDATED_KEYS as they are now (`problem_details` only when there are problems, as in
    a row). It has no `raw`, so `select(.raw)` keeps only frames."""
    rec: dict[str, Any] = {
        "update": d.view.index,
        "transaction": transaction_of(d, store),
        "problems": list(d.problem_texts),
    }
    if d.problems:
        rec["problem_details"] = problem_details(d)
    return rec


def update_text(d: FrameDetail) -> str:
    """The text listing's line for an update: `update #40: timeout`, or `update #40: ok,
    answer #41 12.3ms`."""
    v = d.view
    line = f"update #{v.index}: {STATUS_NAMES[v.status]}"
    if v.partner != NO_PARTNER:
        line += f", answer #{v.partner}"
    shown = latency_words(shown_latency_ms(d), shown_latency_max_ms(d))
    return f"{line} {shown}" if shown else line


def _ms(value: float | None) -> str:
    return "" if value is None else f"{value:.3f}"


def time_text(t: float, origin: float, absolute: bool) -> str:
    if absolute:
        stamp = datetime.fromtimestamp(t, tz=UTC).astimezone()
        return stamp.strftime("%H:%M:%S.%f")
    return f"{t - origin:12.6f}"


def text_line(d: FrameDetail, origin: float, absolute: bool = False, peer: str = "") -> str:
    """One row as text; `peer` (a network row's sender, `ip:port`) follows the time."""
    v = d.view
    when = time_text(v.t, origin, absolute)
    if peer:
        when += f"  {peer:<21}"
    if v.kind == Kind.EVENT:
        return f"{when}  ---  {d.summary}"
    head, tail = _text_parts(d)
    lat = (
        ""
        if v.kind == Kind.REQUEST
        else _latency_text(shown_latency_ms(d), shown_latency_max_ms(d))
    )
    return when + head + lat + tail


def _text_parts(d: FrameDetail) -> tuple[str, str]:
    """What a frame's text line says before its latency and after it (the time and
    peer go first): all of it decided by the row's content, but for a slow answer's
    problem."""
    v = d.view
    if v.kind == Kind.NOISE:
        return f"  ???  noise {len(v.raw):3d}B  {v.raw[:24].hex(' ')}", ""
    unit = f"u{v.unit:<3d}"
    check = "ok " if v.check_ok else "BAD"
    fc = f"{v.function:02d}{'!' if v.exception else ' '}"
    status = STATUS_NAMES[v.status]
    head = f"  {d.direction}  {unit} {fc} {d.name[:28]:<28} {len(v.raw):3d}B {check} "
    head += f"{status:<9}"
    tail = f"  {d.summary}"
    if d.problems:
        tail += "  [" + "; ".join(d.problem_texts) + "]"
    return head, tail


def _text_spliced(tail: str, shared: Shared) -> tuple[str, ...] | None:
    """How the text line's part after its latency (`_text_parts`) is made of a content's
    value where it says one: for an FC 5 or 6 write or echo of 8 RTU bytes (`raw`),
    what comes before and after the value as its summary says it (`write 0x1234 to
    register 0x0064`, `coil 0x000A ON`: the first time the summary says it, before the
    address), checked by making the part again; `()` where it is not so made (rows of
    that content with other bytes are then listed on their own), None for any other
    content, whose text no value decides."""
    raw = shared.raw
    if len(raw) != 8 or raw[1] not in _SINGLE_WRITES:
        return None
    said = _said(raw)
    if said is None:
        return ()
    where = shared.summary.find(said)
    if where < 0 or not tail.startswith("  " + shared.summary):
        return ()
    where += 2
    made = (tail[:where], tail[where + len(said) :])
    return made if made[0] + said + made[1] == tail else ()


def _latency_text(ms: float | None, max_ms: float | None) -> str:
    shown = latency_words(ms, max_ms)
    return f" {shown:>9}" if shown else ""


def _json_float(x: float) -> str:
    """A float as `json.dumps` writes it."""
    return repr(x) if math.isfinite(x) else json.dumps(x)


def _json_item(key: str, value: Any) -> str:
    """`"key": value` as `json_line` writes it inside an object."""
    return json_line({key: value})[1:-1]


_ROW_KEYS = frozenset(("index", "t", "t_end", "channel", "transaction"))


def _json_parts(d: FrameDetail) -> tuple[str, str, str]:
    """The parts of a row's JSONL object that its content decides, encoded: the items
    between `t_end` and `channel`, those between `channel` and `transaction`, and
    `registers` (empty when there are none)."""
    rec = record(d)
    keys = [k for k in rec if k not in _ROW_KEYS]
    cut = list(rec).index("channel") - 3  # index, t and t_end come first
    registers = {"registers": rec["registers"]} if "registers" in rec else {}
    first = {k: rec[k] for k in keys[:cut]}
    second = {k: rec[k] for k in keys[cut:] if k != "registers"}
    return json_line(first)[1:-1], json_line(second)[1:-1], json_line(registers)[1:-1]


# (what follows the hex of the row's bytes in the first part, what comes before its
# values field in the second, what follows the values' text, where the values start in
# the bytes, how many there are, whether they are words or bits)
_Spliced = tuple[str, str, str, int, int, bool]
_WORDS = tuple(struct.Struct(f">{n}H") for n in range(128))
_WORD_VALUES = frozenset((3, 4, 16))  # answers to FC 3/4 reads, FC 16 writes
_BIT_VALUES = frozenset((1, 2, 15))  # answers to FC 1/2 reads, FC 15 writes
# each byte's bits as a listing says them, first bit first: `10100000` for 0x05, and
# as the JSON list has them, `1, 0, 1, 0, 0, 0, 0, 0`
_BYTE_BITS = tuple("".join("1" if b >> k & 1 else "0" for k in range(8)) for b in range(256))
_BYTE_LIST = tuple(", ".join(bits) for bits in _BYTE_BITS)


_SINGLE_WRITES = frozenset((5, 6))  # FC 5/6 writes and their echoes: one value, said
# as a FC 6 write's text says it, `0x1234`, from the two bytes' halves
_HEX_HIGH = tuple(f"0x{b:02X}" for b in range(256))
_HEX_LOW = tuple(f"{b:02X}" for b in range(256))
_COIL_SAID = {b"\xff\x00": "ON", b"\x00\x00": "OFF"}  # FC 5's well-formed values


def _said(raw: bytes) -> str | None:
    """How the text of `raw`, an 8-byte RTU FC 5 or 6 write or echo, says its value:
    `0x1234` for a register, `ON` or `OFF` for a coil (None for another coil value: a
    malformed write, whose text says more)."""
    if raw[1] == 6:
        return _HEX_HIGH[raw[4]] + _HEX_LOW[raw[5]]
    return _COIL_SAID.get(raw[4:6])


@dataclass(frozen=True, slots=True)
class _Single:
    """How the JSONL parts of an FC 5 or 6 write are made of its bytes (see
    `_single_spliced`): the first part after the hex of its bytes; the second part
    before the value as its summary says it, between that and the value field's number,
    and after the field's text (which says the value as the summary does)."""

    after_hex: str
    before_said: str
    before_number: str
    after_text: str


def _spliced(first: str, second: str, d: FrameDetail) -> _Spliced | _Single | None:
    """How the JSONL parts (`_json_parts`) of row `d`, an RTU frame whose `values` field
    holds words or bits of its own bytes (an answer to an FC 1-4 read, an FC 15 or 16
    write), are made of its bytes: so that `_splice` makes those of a frame with other
    values (Describer.contents gives such frames one content); None if the parts do not
    end that way (checked by making them again). Splicing costs a row a small part of
    what describing and encoding it would."""
    raw = d.view.raw
    n = len(raw)
    dissection = d.dissection
    if dissection is None or d.registers or d.view.flags & _MODE or n < 5:
        return None
    fc = raw[1]
    if fc in _SINGLE_WRITES:
        return _single_spliced(first, second, d)
    words = fc in _WORD_VALUES
    if not words and fc not in _BIT_VALUES:
        return None
    field = dissection.field("values")
    if field is None or type(field.value) is not tuple or field.span[1] != n - 2:
        return None
    at, count = field.span[0], len(field.value)
    size = n - 2 - at
    if not count or (size != 2 * count if words else size != (count + 7) // 8):
        return None
    if words and count >= len(_WORDS):
        return None
    head = f'"raw": "{raw.hex()}"'
    values = f'{{"name": "values", "value": [{_values_text(raw, at, count, words)}'
    where = second.rfind(values)
    if not first.startswith(head) or where < 0:
        return None
    made = (
        first[len(head) - 1 :],
        second[:where],
        second[where + len(values) :],
        at,
        count,
        words,
    )
    return made if _splice(made, raw) == (first, second) else None


def _values_text(raw: bytes, at: int, count: int, words: bool) -> str:
    """`1, 2], "text": "0x0001 0x0002`: the `count` words (or bits) of `raw` from byte
    `at` as its values field says them (as `json.dumps` writes the list, `WordsField`
    and `BitsField` the text)."""
    data = raw[at:-2]
    if words:
        numbers = _WORDS[count].unpack(data)
        # `0x0001 0x0002` from the bytes' hex in groups of two: one call in C rather
        # than a format per word
        text = "0x" + data.hex(" ", 2).upper().replace(" ", " 0x")
        return f'{", ".join(map(str, numbers))}], "text": "{text}'
    whole, rest = divmod(count, 8)
    parts = list(map(_BYTE_LIST.__getitem__, data[:whole]))
    if rest:
        parts.append(", ".join(_BYTE_BITS[data[whole]][:rest]))
    listed = ", ".join(parts)
    return f'{listed}], "text": "{listed.replace(", ", " ")}'


def _single_spliced(first: str, second: str, d: FrameDetail) -> _Single | None:
    """`_spliced` for row `d`, an FC 5 or 6 write or echo of 8 bytes whose value its
    summary says (`write 0x1234 to register 0x0064`, `coil 0x000A ON`; the first time
    the summary says it is the value, which it says before the address) and whose
    `value` field holds it (its number, and its text as the summary says it). None if
    the parts are not so made (checked by making them again)."""
    raw = d.view.raw
    if len(raw) != 8:
        return None
    said = _said(raw)
    head = f'"raw": "{raw.hex()}"'
    summary = _json_item("summary", d.summary)
    at = second.find(summary)
    if said is None or not first.startswith(head) or at < 0:
        return None
    where = summary.find(said, len('"summary": "'))
    before = '{"name": "value", "value": '
    value = f'{before}{raw[4] << 8 | raw[5]}, "text": "{said}'
    field = second.find(value + '"', at + len(summary))
    if where < 0 or field < 0:
        return None
    where += at
    made = _Single(
        first[len(head) - 1 :],
        second[:where],
        second[where + len(said) : field + len(before)],
        second[field + len(value) :],
    )
    return made if _splice(made, raw) == (first, second) else None


def _splice(spliced: _Spliced | _Single, raw: bytes) -> tuple[str, str] | None:
    """The JSONL parts of `raw`, a frame with other values (see `_spliced`); None for
    an FC 5 write of a value that is neither ON nor OFF (never given a content of
    other values: its text says more)."""
    if isinstance(spliced, _Single):
        said = _said(raw)
        if said is None:
            return None
        return (
            f'"raw": "{raw.hex()}{spliced.after_hex}',
            f"{spliced.before_said}{said}{spliced.before_number}{raw[4] << 8 | raw[5]}"
            f', "text": "{said}{spliced.after_text}',
        )
    after_hex, before_values, after_text, at, count, words = spliced
    return (
        f'"raw": "{raw.hex()}{after_hex}',
        f'{before_values}{{"name": "values", "value": '
        f"[{_values_text(raw, at, count, words)}{after_text}",
    )


_TRANSACTION_KINDS = frozenset((Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION, Kind.UNKNOWN))
_STATUS_JSON = tuple(json.dumps(name) for name in STATUS_NAMES)


def _transaction_json(
    store: FrameStore, i: int, kind: int, ms: float | None, max_ms: float | None, base: int = 0
) -> str:
    """`, "transaction": {...}` of row `i` as `transaction_of` gives it (empty when
    there is none), from the store's columns and the row's measured latency; rows
    numbered `base` on (see `Lister.base`)."""
    status = store.status[i]
    if kind not in _TRANSACTION_KINDS or not status:
        return ""
    partner = store.partner[i]
    request = kind == Kind.REQUEST
    req = (i if request or partner == NO_PARTNER else partner) + base
    shown = "null" if ms is None else _json_float(round(ms, 3))
    bound = "null" if max_ms is None else _json_float(round(max_ms, 3))
    return (
        f', "transaction": {{"id": {req}, "role": "{"request" if request else "response"}", '
        f'"latency_ms": {shown}, "latency_max_ms": {bound}, "status": {_STATUS_JSON[status]}, '
        f'"partner": {"null" if partner == NO_PARTNER else partner + base}}}'
    )


_DEVICE_SLOW = int(Flag.DEVICE_SLOW)
_MODE = int(Flag.ASCII | Flag.MBAP)
_REQUEST = int(Kind.REQUEST)
_OPEN = int(Status.OPEN)
_NO_STAMPS = (Stamp.NONE, Stamp.PRINT)


class Latencies:
    """Row latencies as `pairing.measure` gives them and the listings show them, made
    from the store's columns without a `Latency` object a row: for stamps that are
    neither none nor print times (those, and a resolution that is not finite, go to
    `measure`), the same operations on the same floats in the same order as `judge`, so
    the figures are the same to the bit (`tests/outputs/test_listing_fast.py` holds
    them to `measure`). The text a latency shows is kept per value: a polling capture
    shows few distinct ones."""

    def __init__(self) -> None:
        self.stamps: Stamp | None = None
        self.resolution = -1.0
        self._texts: dict[tuple[float, bool], str] = {}

    def _settle(self, store: FrameStore) -> None:
        """Take the store's stamps and resolution (a live store's may change)."""
        self.stamps, self.resolution = store.stamps, res = store.stamps, store.resolution
        self._fast = self.stamps not in _NO_STAMPS and res < INF
        step = self._step = shown_step(res)
        self._digits = max(0, -round(log10(step * 1000) - 1e-9))
        self._least = max(RESOLVED * res, UNRESOLVED)
        self._texts = {}

    def ms(self, store: FrameStore, i: int) -> tuple[float, bool] | None:
        """Row `i`'s latency in ms as `Latency.ms` gives it, and whether it is a bound;
        None where `measure` gives None."""
        if store.stamps is not self.stamps or store.resolution != self.resolution:
            self._settle(store)
        if not self._fast:
            measured = measure(store, i)
            return None if measured is None else (measured.ms, measured.bound)
        j = store.partner[i]
        if j == NO_PARTNER:
            return None
        req, resp = (j, i) if store.kind[i] != _REQUEST else (i, j)
        t, end = store.t[resp], store.t_end[req]
        raw = t - end
        step = self._step
        if not raw < self._least:
            value = round(t, 6) - round(end, 6)
            if value == value:
                value = round(value / step) * step
            return round(value * 1000, self._digits), False
        res = self.resolution
        if res > 0 and raw + res > 0:
            return round(ceil((raw + res) / step - 1e-9) * step * 1000, self._digits), True
        return None

    def text(self, store: FrameStore, i: int) -> str:
        """` {text:>9}`: row `i`'s latency as a text line shows it (`Latency.text`),
        empty where there is none."""
        found = self.ms(store, i)
        if found is None:
            return ""
        shown = self._texts.get(found)
        if shown is None:
            shown = _latency_shown(*found)
            if found[0] > 0 and len(self._texts) < 4096:  # (not -0.0, NaN: not one key)
                self._texts[found] = shown
        return shown


LISTING_RUN = 4096  # rows a call of the compiled loop takes at most (see _write_compiled)


def _latency_shown(ms: float, bound: bool) -> str:
    """` {text:>9}`: a latency as a text line shows it (`Latencies.text`)."""
    words = span_words(ms)
    return f" {'<' + words if bound else words:>9}"


def _template(shared: Shared | None, key: str) -> tuple[Any, ...] | None:
    """What the compiled loop keeps of a content for its next rows (sniffer/_core.c:
    listing_rows): its text line's parts (head, tail, whole) and `_text_spliced`'s
    splice, or its JSONL parts and splice (`_spliced`'s tuple, or a `_Single`'s four
    parts as a tuple), with the bytes they were made of and whether it is timed; None
    where the listing kept none. The loop splices a row's own value or values in as
    `_text_line` and `_splice` do."""
    if shared is None:
        return None
    parts = shared.memo.get(key)
    if parts is None:
        return None
    if key == "text":
        return (parts[0], parts[1], parts[2], shared.raw, shared.timed, parts[3])
    first, second, registers, spliced = parts
    if isinstance(spliced, _Single):
        single = spliced
        spliced = (single.after_hex, single.before_said, single.before_number, single.after_text)
    return (first, second, registers, spliced, shared.raw, shared.timed)


class Lister:
    """Writes rows to a text stream in one of FORMATS, flushing after every row.

    CSV cells go through `sniffer.text.csv_row`: text that a spreadsheet would run as a
    formula gets a leading `'` unless `raw_csv` (see `csv_cell`)."""

    def __init__(
        self,
        out: TextIO,
        fmt: str,
        describer: Describer,
        *,
        absolute: bool = False,
        raw_csv: bool = False,
        header: bool = True,
        updates: bool = False,
    ) -> None:
        """`updates`: this listing writes updates later (`write_updates`, live), so its
        text lines number the rows those may cite."""
        if fmt not in FORMATS:
            raise ValueError(f"format must be one of {', '.join(FORMATS)}, not {fmt!r}")
        self.out = out
        self.fmt = fmt
        self.describer = describer
        self.absolute = absolute
        self.origin: float | None = None
        self.raw_csv = raw_csv
        self._csv = csv.writer(out) if fmt == "csv" else None
        self._stamps: Stamp | None = None
        self._timing = ""  # the JSONL `timing` item for `_stamps`
        # what the times are worth is said once, before the first row (a parallel worker's
        # range goes without, as without the CSV header)
        self._noted = not header
        # text: rows listed while their transaction was open; an update cites them (and
        # their answers) by number, so their lines end with it (`  #40`)
        self._cited: set[int] = set()
        self.updates = updates
        self._latencies = Latencies()
        # the row number of the store's first row: rows of a segment of a capture (a
        # windowed pass, `sniffer.session.streamed`) are numbered as in the whole capture
        self.base = 0
        self._table: object | None = None  # the compiled core's parts (listing_table)
        if self._csv is not None and header:
            self._csv.writerow(CSV_COLUMNS)

    def write(self, rows: Iterable[int], flush: bool = True) -> int:
        """List `rows`; with `flush`, each row is written and flushed as it is made (a
        live listing), else rows are written in batches. With the compiled core, the
        text and JSONL lines of a replay are made in C (see `_write_compiled`)."""
        fast = core.FAST
        describer = self.describer
        store = describer.store
        if (
            fast is None
            or flush
            or self._csv is not None
            or self.absolute
            or self.updates
            or store.peers
            or type(describer).contents is not Describer.contents
            or type(describer).shared is not Describer.shared
            or describer.shared_size <= 0
            or type(store) is not FrameStore
        ):
            return self._write_rows(rows, flush)
        it = iter(rows)
        n = 0
        if self.origin is None or not self._noted:  # the first row's note and origin
            for i in it:
                n += self._write_rows((i,), False)
                break
            if self.origin is None:  # no rows
                return n
        return n + self._write_compiled(fast, it)

    def _write_compiled(self, fast: Any, rows: Iterator[int]) -> int:
        """`write` of a text or JSONL listing with the compiled core (sniffer/_core.c:
        listing_rows): the lines of the rows whose content it holds the parts of made
        there, as `_text_line` and `_json_line` make them; every other row by this
        class (`miss`), whose parts it keeps under the row's keys (`_template`). The
        rows it finds count as found for the describer's guard."""
        describer = self.describer
        store = describer.store
        store.sync()  # no column grows while the compiled loop holds them
        annotator = describer.annotator
        assert self.origin is not None
        json = self.fmt == "jsonl"
        latencies = self._latencies
        if store.stamps is not latencies.stamps or store.resolution != latencies.resolution:
            latencies._settle(store)
        measured = (
            (latencies._step, latencies._least, latencies._digits, latencies.resolution)
            if latencies._fast
            else None
        )
        if store.stamps != self._stamps:
            self._stamps = store.stamps
            self._timing = ", " + _json_item("timing", TIMING_NAMES[store.stamps])
        key = "jsonl" if json else "text"

        def miss(i: int) -> tuple[str, tuple[Any, ...] | None]:
            for _, shared in describer.contents((i,), values=False, writes=True):
                line = self._row_line(i, shared, "")
                if line is None:  # (not for a text or JSONL line)
                    raise AssertionError("a text or JSONL listing makes every row's line")
                return line, _template(shared, key)
            raise AssertionError("a row has a content or none")

        table = self._table
        if table is None:
            table = self._table = fast.listing_table()
        apart = (annotator.sunspec.units, annotator.windows_of)
        n = 0
        more = True
        while more:
            lines, count, found, more = fast.listing_rows(
                table, store, rows, store.notes, apart, annotator.bindings, store.links,
                _DEVICE_SLOW, _MODE, VALUED_FLAGS, miss, LISTING_RUN, self.origin, json,
                measured, _latency_shown, _STATUS_JSON, self._timing, self.base,
            )  # fmt: skip
            self.out.write(lines)
            describer.count_found(found)
            n += count
        return n

    def _write_rows(self, rows: Iterable[int], flush: bool) -> int:
        """`write` in Python: the reference, and what runs without the compiled core."""
        n = 0
        describer = self.describer
        store = describer.store
        pending: list[str] = []
        # text and JSONL lines are made from what rows of one content share, CSV records
        # from each row's details
        text = self.fmt == "text"
        # answers that differ only in their values may share a content: a text line
        # shows no value, a JSONL line has them spliced in (see `_json_line`)
        contents = (
            describer.contents(rows, values=False, writes=True)
            if self._csv is None
            else ((i, None) for i in rows)
        )
        for i, shared in contents:
            note = ""
            if not self._noted:
                self._noted = True
                note = self.timing_note()
                if note and text:
                    self.out.write(f"# {note}\n")
            if self.origin is None:
                self.origin = store.t[i]
                if text and store.stamps == Stamp.NONE and not note:
                    self.out.write(SYNTHETIC_HEADER + "\n")
            peer = store.peers.get(store.channel[i], "") if store.peers else ""
            line = self._row_line(i, shared, peer)
            if text and self.updates and line is not None:
                line = self._numbered(i, line)
            if note and line is not None and self.fmt == "jsonl":
                line = line[:-1] + ", " + _json_item("timing_note", note) + "}"
            n += 1
            if line is None:  # CSV: written by the csv module
                if flush:
                    self.out.flush()
            elif flush:
                self.out.write(line + "\n")
                self.out.flush()
            else:
                pending.append(line)
                if len(pending) >= 512:
                    pending.append("")
                    self.out.write("\n".join(pending))
                    pending.clear()
        if pending:
            pending.append("")
            self.out.write("\n".join(pending))
        return n

    def _row_line(self, i: int, shared: Shared | None, peer: str) -> str | None:
        """Row `i`'s text or JSONL line, from what rows of its content share where it can
        be, or written as a CSV record (None)."""
        line = None
        if shared is not None and not self.describer.store.flags[i] & _DEVICE_SLOW:
            if self.fmt == "text":
                line = self._text_line(i, shared, peer)
            elif self.fmt == "jsonl":
                line = self._json_line(i, shared, peer)
        if line is None:
            line = self._line(self.describer.detail(i), peer)
        return line

    def timing_note(self) -> str:
        """The sentence a listing starts with when its times are coarse (print times, a
        resolution of a millisecond or more) or synthetic: what is shown as a bound, or
        not at all, because of them (`pairing.timing_note`)."""
        store = self.describer.store
        if store.stamps != Stamp.NONE and not coarse(store.stamps, store.resolution):
            return ""
        return timing_note(store.stamps, store.resolution)

    def _numbered(self, i: int, line: str) -> str:
        """A text line with its row number where a later update may cite it: a request
        still open when listed (`update #40: ...`), and the answer of one
        (`..., answer #41`). Other lines have no number: nothing cites them."""
        store = self.describer.store
        if store.status[i] == _OPEN:
            self._cited.add(i)
            return f"{line}  #{i}"
        partner = store.partner[i]
        if partner != NO_PARTNER and partner in self._cited:
            self._cited.discard(partner)
            return f"{line}  #{i}"
        return line

    def _text_line(self, i: int, shared: Shared, peer: str) -> str | None:
        """Row `i`'s text line from what rows with its content share (see
        `Describer.shared`): made once per content, with the time and latency of the
        row put in; a request's line shows no latency, so none is measured for it.
        A polling capture repeats a few contents all day, so most rows cost only the
        formatting of their time. An FC 5/6 write's content is shared by writes of
        other values, whose own value is spliced into its summary (`_text_spliced`);
        None (`_line` makes it) where that cannot be."""
        store = self.describer.store
        parts = shared.memo.get("text")
        if parts is None:
            head, tail = _text_parts(self._bare(i, shared))
            parts = shared.memo["text"] = (head, tail, head + tail, _text_spliced(tail, shared))
        single: tuple[str, ...] | None = parts[3]
        if single is not None:  # an FC 5/6 write: the row's value may not be the content's
            at = store.offset[i]
            raw = bytes(store.streams[store.channel[i]][at : at + store.length[i]])
            if raw != shared.raw:
                said = _said(raw) if single else None
                if said is None:
                    return None
                tail = single[0] + said + single[1]
                parts = (parts[0], tail, parts[0] + tail, single)
        assert self.origin is not None
        t = store.t[i]
        when = time_text(t, self.origin, True) if self.absolute else f"{t - self.origin:12.6f}"
        if peer or store.peers:
            when += f"  {peer or f'ch{store.channel[i]}':<21}"
        if store.kind[i] == _REQUEST or not shared.timed or store.partner[i] == NO_PARTNER:
            return when + parts[2]
        shown = self._latencies.text(store, i)
        if not shown:
            return when + parts[2]
        return f"{when}{parts[0]}{shown}{parts[1]}"

    def _json_line(self, i: int, shared: Shared, peer: str) -> str | None:
        """Row `i`'s JSONL line from what rows with its content share, with the row's
        index, times, channel and transaction put in. None for a gateway's row, whose
        line says more: `_line` makes it. The parts a content decides are encoded once
        for all its rows, so a row costs its own keys and, for an answer with other
        values, the splice."""
        store = self.describer.store
        if i in store.links:
            return None
        kind = store.kind[i]
        ms = max_ms = None
        if shared.timed and store.partner[i] != NO_PARTNER:
            measured = self._latencies.ms(store, i)
            if measured is not None:
                if measured[1]:
                    max_ms = measured[0]
                else:
                    ms = measured[0]
        memo = shared.memo
        json_parts = memo.get("jsonl")
        raw = b""
        if shared.raw:  # the row's bytes, to tell an answer with other values
            at = store.offset[i]
            raw = bytes(store.streams[store.channel[i]][at : at + store.length[i]])
        if json_parts is None:
            if raw != shared.raw:
                return None  # the content of an answer with other values (not its own)
            bare = self._bare(i, shared)
            first, second, registers = _json_parts(bare)
            spliced = _spliced(first, second, bare) if raw else None
            memo["jsonl"] = json_parts = (first, second, registers, spliced)
        first, second, registers, spliced = json_parts
        if raw != shared.raw:  # an answer with other values (see Describer.contents)
            made = None if spliced is None else _splice(spliced, raw)
            if made is None:
                return None
            first, second = made
        line = (
            f'{{"index": {i + self.base}, "t": {_json_float(round(store.t[i], 6))}, '
            f'"t_end": {_json_float(round(store.t_end[i], 6))}, {first}, '
            f'"channel": {store.channel[i]}, {second}'
            f"{_transaction_json(store, i, kind, ms, max_ms, self.base)}"
        )
        if registers:
            line += ", " + registers
        if store.stamps != self._stamps:
            self._stamps = store.stamps
            self._timing = ", " + _json_item("timing", TIMING_NAMES[store.stamps])
        line += self._timing
        if peer:
            line += ", " + _json_item("peer", peer)
        return line + "}"

    def _bare(self, i: int, shared: Shared) -> FrameDetail:
        """Row `i`'s details without its latencies: all that the parts of its lines
        kept per content read (not a slow answer: its problems say its latency)."""
        c = shared
        view = self.describer.view(i)
        return FrameDetail(
            view, c.name, c.summary, c.dissection, c.registers, c.problems, None, c.label
        )

    def _line(self, d: FrameDetail, peer: str) -> str | None:
        """Row `d` as a text or JSONL line, or written as a CSV record (None)."""
        store = self.describer.store
        i = d.view.index
        if self.base:  # numbered as in the whole capture (the store's rows are read as i)
            v = d.view
            partner = v.partner if v.partner == NO_PARTNER else v.partner + self.base
            d = replace(d, view=replace(v, index=i + self.base, partner=partner))
        if self.fmt == "text":
            # with network rows about, the others name their channel in that column
            where = peer or (f"ch{store.channel[i]}" if store.peers else "")
            assert self.origin is not None
            return text_line(d, self.origin, self.absolute, where)
        if self.fmt == "jsonl":
            rec = record(d, store)
            rec["timing"] = TIMING_NAMES[store.stamps]
            if peer:
                rec["peer"] = peer
            if i in store.links:
                rec["gateway"] = store.links[i]
            return json_line(rec)
        assert self._csv is not None
        v = d.view
        self._csv_row(
            (
                v.index,
                f"{v.t:.6f}",
                f"{v.t_end:.6f}",
                d.direction,
                KIND_NAMES[v.kind],
                v.unit,
                v.function,
                d.name,
                len(v.raw),
                v.check_ok,
                d.status,
                _ms(shown_latency_ms(d, store)),
                _ms(shown_latency_max_ms(d)),
                d.summary,
                "; ".join(d.problem_texts),
                v.raw.hex(),
                "" if d.dissection is None else fields_cell(d.dissection.fields),
                v.channel,
                peer,
            )
        )
        return None

    def write_updates(self, rows: Iterable[int]) -> int:
        """One update per row listed earlier whose transaction has settled since (see
        `update_record`): a JSONL object, a text line, or a CSV row of kind `update`
        whose index is the row updated (status, latency and partner in their columns,
        the other cells empty)."""
        n = 0
        store = self.describer.store
        for i in rows:
            d = self.describer.detail(i)
            if self.fmt == "text":
                self.out.write(f"{'':12}  {update_text(d)}\n")
            elif self.fmt == "jsonl":
                self.out.write(json_line(update_record(d, store)) + "\n")
            else:
                v = d.view
                latency = _ms(shown_latency_ms(d, store))
                answer = "" if v.partner == NO_PARTNER else f"answer #{v.partner}"
                bound = _ms(shown_latency_max_ms(d))
                cells = (v.index, "", "", "", "update", "", "", "", "", "", d.status, latency)
                row = (*cells, bound, answer)
                self._csv_row((*row, *("",) * (len(CSV_COLUMNS) - len(row))))
            n += 1
        return n

    def _csv_row(self, cells: tuple[object, ...]) -> None:
        assert self._csv is not None
        self._csv.writerow(csv_row(cells, raw=self.raw_csv))
