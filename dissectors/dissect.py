"""Provides dissect(): one frame body in; its fields, meaning, problems and register data out.

The layouts are the construct schemas on each FunctionSpec (dissectors.functions); here a
frame is parsed with them, every parsed field becomes a `Field` with its byte span, and the
spec's `family` routine reads meaning into the fields: names, summaries, the checks a
layout cannot express (byte count against quantity, coil values, echoes), and the
register values the frame carries. Whatever is wrong with the bytes becomes a `Problem`;
nothing here raises on bus data.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from dataclasses import dataclass, replace
from dataclasses import field as dataclass_field
from typing import Any

from construct import ConstructError, Container

from dissectors.functions import (
    CONFORMITY_LEVELS,
    DIAGNOSTIC_SUB_FUNCTIONS,
    EXCEPTION_SCHEMA,
    FILE_REFERENCE_TYPE,
    FUNCTION_CLASSES,
    FUNCTIONS,
    LAST_FILE_RECORD,
    MEI_DEVICE_ID,
    MEI_TYPES,
    RAW_SCHEMA,
    READ_DEVICE_ID_CODES,
    BitValues,
    FunctionSpec,
    WordValues,
    device_object_name,
    exception_name,
    function_class,
    function_name,
)
from dissectors.values import Dissection, Field, Problem, RegisterData, Role

__all__ = ["Dissection", "Field", "Problem", "RegisterData", "Role", "dissect"]

ERROR = "error"
WARNING = "warning"
INFO = "info"

# Integer fields shown in decimal; every other integer is shown in hex at its width.
_DECIMAL = frozenset(
    {
        "quantity",
        "byte_count",
        "read_quantity",
        "write_quantity",
        "fifo_count",
        "event_count",
        "message_count",
        "number_of_objects",
        "file_number",
        "record_number",
        "record_length",
        "reference_type",
        "length",
        "read_device_id_code",
    }
)
_BIT_TABLES = frozenset({"coils", "discrete_inputs"})
_READ_NOUNS = {
    "coils": "coil",
    "discrete_inputs": "discrete input",
    "input_registers": "input register",
    "holding_registers": "holding register",
}
_WRITE_NOUNS = {"coils": "coil", "holding_registers": "register"}
_COIL_STATES = {0xFF00: "ON", 0x0000: "OFF"}
_RUN_STATES = {0xFF: "ON", 0x00: "OFF"}
_MORE_FOLLOWS = {0x00: "no", 0xFF: "yes"}
_STATUS_WORDS = {0x0000: "ready", 0xFFFF: "busy"}


# --- parsing ------------------------------------------------------------------------------


@dataclass(slots=True)
class _Parsed:
    """A body run through a schema: the (possibly partial) Container, where parsing
    stopped, and the field the frame ended in, if it ended too soon."""

    body: bytes
    values: Any
    end: int
    cut: tuple[str, int] | None


def _parse(schema: Any, body: bytes) -> _Parsed:
    stream = io.BytesIO(body)
    stream.seek(2)
    try:
        values = schema.parse_stream(stream)
    except ConstructError as error:
        partial = getattr(error, "partial", None)
        failed = getattr(error, "failed", ("data", 2))
        return _Parsed(body, partial if partial is not None else Container(), len(body), failed)
    return _Parsed(body, values, stream.tell(), None)


def _hex(value: int, width: int) -> str:
    return f"0x{value:0{2 * max(1, width)}X}"


def _fields(record: Any) -> dict[str, Field]:
    """The named fields of a parsed Record, in order, with their spans."""
    spans: dict[str, tuple[int, int]] = record.get("_spans", {})
    out: dict[str, Field] = {}
    for name, value in record.items():
        span = spans.get(name)
        if value is None or span is None or name.startswith("_"):
            continue
        out[name] = _field(name, value, span)
    return out


def _words_field(name: str, words: tuple[int, ...], span: tuple[int, int]) -> Field:
    start = span[0]
    children = tuple(
        Field(f"{name}[{index}]", word, f"0x{word:04X}", (start + 2 * index, start + 2 * index + 2))
        for index, word in enumerate(words)
    )
    return Field(name, tuple(words), " ".join(child.text for child in children), span, children)


def _bits_field(name: str, bits: tuple[int, ...], span: tuple[int, int]) -> Field:
    start = span[0]
    children = tuple(
        Field(f"{name}[{index}]", bit, str(bit), (start + index // 8, start + index // 8 + 1))
        for index, bit in enumerate(bits)
    )
    return Field(name, tuple(bits), " ".join(child.text for child in children), span, children)


def _field(name: str, value: Any, span: tuple[int, int]) -> Field:
    if isinstance(value, WordValues):
        return _words_field(name, value, span)
    if isinstance(value, BitValues):
        return _bits_field(name, value, span)
    if isinstance(value, bytes):
        return Field(name, value, value.hex(" ").upper(), span)
    if isinstance(value, int):
        text = str(value) if name in _DECIMAL else _hex(value, span[1] - span[0])
        return Field(name, value, text, span)
    if isinstance(value, dict):
        children = tuple(_fields(value).values())
        return Field(name, None, "", span, children)
    items = list(value)
    children = tuple(
        _field(f"{name}[{index}]", item, _item_span(item, span)) for index, item in enumerate(items)
    )
    noun = "item" if len(items) == 1 else "items"
    return Field(name, None, f"{len(items)} {noun}", span, children)


def _item_span(item: Any, outer: tuple[int, int]) -> tuple[int, int]:
    spans: dict[str, tuple[int, int]] = item.get("_spans", {}) if isinstance(item, dict) else {}
    if not spans:
        return (outer[0], outer[0])
    return (min(s[0] for s in spans.values()), max(s[1] for s in spans.values()))


# --- the work on one frame -----------------------------------------------------------------


@dataclass(slots=True)
class _Work:
    """One dissection in progress: what the family routines read and fill in."""

    body: bytes
    role: Role
    function: int
    spec: FunctionSpec | None
    parsed: _Parsed
    fields: dict[str, Field]
    request: _Parsed | None = None
    request_fields: dict[str, Field] = dataclass_field(default_factory=dict)
    problems: list[Problem] = dataclass_field(default_factory=list)
    data: list[RegisterData] = dataclass_field(default_factory=list)
    summary: str = ""

    @property
    def is_request(self) -> bool:
        return self.role is Role.REQUEST

    @property
    def table(self) -> str:
        return (self.spec.table or "") if self.spec is not None else ""

    def get(self, name: str) -> int | None:
        value = self.parsed.values.get(name)
        return value if isinstance(value, int) else None

    def asked(self, name: str) -> int | None:
        """An integer field of the paired request, if there is one."""
        if self.request is None:
            return None
        value = self.request.values.get(name)
        return value if isinstance(value, int) else None

    def values(self, name: str) -> tuple[int, ...]:
        found = self.fields.get(name)
        return found.value if found is not None and isinstance(found.value, tuple) else ()

    def span(self, name: str) -> tuple[int, int] | None:
        found = self.fields.get(name)
        return found.span if found is not None else None

    def problem(self, kind: str, severity: str, text: str, span: tuple[int, int] | None) -> None:
        self.problems.append(Problem(kind, severity, text, span))

    def retext(self, name: str, text: str) -> None:
        found = self.fields.get(name)
        if found is not None:
            self.fields[name] = replace(found, text=text)


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _address(value: int) -> str:
    return f"0x{value:04X}"


# --- checks every layout gets --------------------------------------------------------------


def _check_structure(w: _Work) -> None:
    body = w.body
    if w.parsed.cut is not None:
        name, start = w.parsed.cut
        where = "before" if start >= len(body) else "inside"
        w.problem("truncated", ERROR, f"frame ends {where} {name}", (start, len(body)))
    byte_count = w.fields.get("byte_count")
    if byte_count is not None and isinstance(byte_count.value, int):
        follow = len(body) - byte_count.span[1]
        if follow != byte_count.value:
            verb = "byte follows" if follow == 1 else "bytes follow"
            w.problem(
                "byte-count",
                ERROR,
                f"byte count {byte_count.value} but {follow} data {verb}",
                byte_count.span,
            )
    if w.parsed.end < len(body):
        extra = len(body) - w.parsed.end
        w.problem(
            "trailing-bytes",
            WARNING,
            f"{_count(extra, 'trailing byte')} after the PDU",
            (w.parsed.end, len(body)),
        )
    if w.spec is None:
        return
    for limit in w.spec.limits:
        value = w.get(limit.field)
        if value is None:
            continue
        if value > limit.high:
            text = f"{limit.field} {value} above the limit of {limit.high}"
        elif value < limit.low:
            text = f"{limit.field} {value} below the minimum of {limit.low}"
        else:
            continue
        w.problem("quantity", ERROR, text, w.span(limit.field))


def _pair(w: _Work, request: bytes | None) -> None:
    """Parse the paired request, when it is one for the same function code."""
    if request is None or w.is_request or len(request) < 2:
        return
    request = bytes(request)
    if request[1] != w.function:
        w.problem(
            "request-mismatch",
            WARNING,
            f"paired request is function {request[1]}, not {w.function}",
            None,
        )
        return
    if w.spec is None or w.spec.request_schema is None:
        return
    w.request = _parse(w.spec.request_schema, request)
    w.request_fields = _fields(w.request.values)


def _echo(w: _Work, names: tuple[str, ...] | None = None) -> None:
    """Compare fields of a response with the same fields of its request (all when `names`
    is None), down to the first level where they differ."""
    if w.request is None:
        return
    mine = {name: f for name, f in w.fields.items() if names is None or name in names}
    theirs = {name: f for name, f in w.request_fields.items() if names is None or name in names}
    _compare(w, mine, theirs, "", "")


def _compare(
    w: _Work, mine: dict[str, Field], theirs: dict[str, Field], parent_path: str, parent: str
) -> None:
    """Report the fields that differ, by path (`sub_requests[0].record_data[1]`): a record's
    fields are joined with a dot, an array's elements already carry the array's name."""
    assert w.request is not None
    for name, answered in mine.items():
        asked = theirs.get(name)
        if asked is None:
            continue
        if (
            w.body[answered.span[0] : answered.span[1]]
            == (w.request.body[asked.span[0] : asked.span[1]])
        ):
            continue
        if parent and name.startswith(f"{parent}["):
            path = parent_path[: len(parent_path) - len(parent)] + name
        else:
            path = f"{parent_path}.{name}" if parent_path else name
        mine_children = {child.name: child for child in answered.children}
        their_children = {child.name: child for child in asked.children}
        if mine_children and mine_children.keys() == their_children.keys():
            _compare(w, mine_children, their_children, path, name)
            continue
        w.problem(
            "echo",
            WARNING,
            f"echo of {path} is {answered.text}, the request had {asked.text}",
            answered.span,
        )


def _checked_values(
    w: _Work, quantity: int | None, quantity_name: str, *, from_request: bool
) -> tuple[int, ...]:
    """Check the `values` field against its byte count and the quantity that asked for it;
    cut coil and input bits to the quantity. Returns the real values."""
    found = w.fields.get("values")
    if found is None:
        return ()
    values = w.values("values")
    byte_count = w.get("byte_count")
    bits = w.table in _BIT_TABLES
    need: int | None = None
    if bits:
        if quantity is not None:
            need = (quantity + 7) // 8
            if len(values) >= quantity:
                padding = values[quantity : need * 8]
                if any(padding):
                    start = found.span[0] + quantity // 8
                    w.problem(
                        "padding",
                        INFO,
                        f"padding bits after {_count(quantity, 'value')} are not zero",
                        (start, min(found.span[1], found.span[0] + need)),
                    )
                values = values[:quantity]
                w.fields["values"] = _bits_field("values", values, found.span)
    else:
        if quantity is not None:
            need = 2 * quantity
        if byte_count is not None and byte_count % 2:
            w.problem(
                "odd-byte-count",
                ERROR,
                f"byte count {byte_count} is odd: registers are 2 bytes each",
                w.span("byte_count"),
            )
    if byte_count is not None and need is not None and byte_count != need:
        whose = "the request's " if from_request else ""
        w.problem(
            "byte-count",
            ERROR,
            f"byte count {byte_count} but {whose}{quantity_name} {quantity} needs {need}",
            w.span("byte_count"),
        )
    return values


# --- the families: what the fields of each layout mean -------------------------------------


def _read(w: _Work) -> None:
    noun = _READ_NOUNS.get(w.table, "value")
    if w.is_request:
        address, quantity = w.get("address"), w.get("quantity")
        if address is None or quantity is None:
            w.summary = f"read {noun}s"
        else:
            w.summary = f"read {_count(quantity, noun)} from {_address(address)}"
        return
    quantity = w.asked("quantity")
    values = _checked_values(w, quantity, "quantity", from_request=True)
    if "values" in w.fields:
        w.data.append(RegisterData(w.table, w.asked("address"), values, False))
    w.summary = _count(len(values), "value")


def _write_single(w: _Work) -> None:
    address, value = w.get("address"), w.get("value")
    if not w.is_request:
        _echo(w, ("address", "value"))
    if address is None or value is None:
        w.summary = f"write {_WRITE_NOUNS.get(w.table, 'value')}"
        return
    if w.table in _BIT_TABLES:
        state = _COIL_STATES.get(value)
        if state is None:
            w.problem(
                "coil-value",
                ERROR,
                f"coil value 0x{value:04X} is not 0xFF00 (ON) or 0x0000 (OFF)",
                w.span("value"),
            )
            w.summary = f"coil {_address(address)} 0x{value:04X}"
            return
        w.retext("value", state)
        w.summary = f"coil {_address(address)} {state}"
        w.data.append(RegisterData(w.table, address, (1 if state == "ON" else 0,), True))
        return
    w.summary = f"write 0x{value:04X} to register {_address(address)}"
    w.data.append(RegisterData(w.table, address, (value,), True))


def _write_multiple(w: _Work) -> None:
    noun = _WRITE_NOUNS.get(w.table, "value")
    address, quantity = w.get("address"), w.get("quantity")
    if w.is_request:
        values = _checked_values(w, quantity, "quantity", from_request=False)
        if "values" in w.fields:
            w.data.append(RegisterData(w.table, address, values, True))
        verb = "write"
    else:
        _echo(w, ("address", "quantity"))
        if w.request is not None:
            written = w.request_fields.get("values")
            if written is not None and isinstance(written.value, tuple):
                asked_quantity = w.asked("quantity")
                values = written.value
                if w.table in _BIT_TABLES and asked_quantity is not None:
                    values = values[:asked_quantity]
                w.data.append(RegisterData(w.table, w.asked("address"), values, True))
        verb = "wrote"
    if address is None or quantity is None:
        w.summary = f"{verb} {noun}s"
    else:
        w.summary = f"{verb} {_count(quantity, noun)} from {_address(address)}"


def _read_write(w: _Work) -> None:
    if w.is_request:
        write_address = w.get("write_address")
        write_quantity = w.get("write_quantity")
        values = _checked_values(w, write_quantity, "write_quantity", from_request=False)
        if "values" in w.fields:
            w.data.append(RegisterData(w.table, write_address, values, True))
        read_address, read_quantity = w.get("read_address"), w.get("read_quantity")
        if None in (read_address, read_quantity, write_address, write_quantity):
            w.summary = "read and write registers"
            return
        assert read_address is not None and read_quantity is not None
        assert write_address is not None and write_quantity is not None
        w.summary = (
            f"read {_count(read_quantity, 'register')} from {_address(read_address)}, "
            f"write {_count(write_quantity, 'register')} from {_address(write_address)}"
        )
        return
    values = _checked_values(w, w.asked("read_quantity"), "read_quantity", from_request=True)
    if "values" in w.fields:
        w.data.append(RegisterData(w.table, w.asked("read_address"), values, False))
    written = w.request_fields.get("values")
    if written is not None and isinstance(written.value, tuple):
        w.data.append(RegisterData(w.table, w.asked("write_address"), written.value, True))
    w.summary = _count(len(values), "value")


def _mask_write(w: _Work) -> None:
    if not w.is_request:
        _echo(w, ("address", "and_mask", "or_mask"))
    address, and_mask, or_mask = w.get("address"), w.get("and_mask"), w.get("or_mask")
    if address is None or and_mask is None or or_mask is None:
        w.summary = "mask write register"
        return
    w.summary = f"mask write register {_address(address)}: AND 0x{and_mask:04X}, OR 0x{or_mask:04X}"


def _fifo(w: _Work) -> None:
    if w.is_request:
        address = w.get("fifo_address")
        w.summary = (
            "read FIFO queue" if address is None else f"read FIFO queue at {_address(address)}"
        )
        return
    byte_count, fifo_count = w.get("byte_count"), w.get("fifo_count")
    if byte_count is not None and fifo_count is not None and byte_count != 2 + 2 * fifo_count:
        w.problem(
            "byte-count",
            ERROR,
            f"byte count {byte_count} but fifo_count {fifo_count} needs {2 + 2 * fifo_count}",
            w.span("byte_count"),
        )
    w.summary = f"FIFO: {_count(len(w.values('values')), 'value')}"


def _exception_status(w: _Work) -> None:
    status = w.get("status")
    if w.is_request:
        w.summary = "read exception status"
    elif status is None:
        w.summary = "exception status"
    else:
        w.retext("status", f"0x{status:02X} (bits {status:08b})")
        w.summary = f"exception status 0x{status:02X}"


def _restart_text(data: int) -> str:
    return {0xFF00: "clear the event log", 0x0000: "keep the event log"}.get(data, f"0x{data:04X}")


def _delimiter_text(data: int) -> str:
    return f"delimiter 0x{data >> 8:02X}"


_DIAGNOSTIC_DATA_TEXT: dict[int, Callable[[int], str]] = {
    0x01: _restart_text,
    0x03: _delimiter_text,
}


def _diagnostics(w: _Work) -> None:
    code = w.get("sub_function")
    if code is None:
        w.summary = "diagnostics"
        return
    sub = DIAGNOSTIC_SUB_FUNCTIONS.get(code)
    name = sub.name if sub is not None else f"reserved sub-function 0x{code:04X}"
    w.retext("sub_function", name)
    if sub is None:
        w.problem(
            "sub-function", INFO, f"sub-function 0x{code:04X} is reserved", w.span("sub_function")
        )
    data = w.fields.get("data")
    words = w.values("data")
    if data is not None and (data.span[1] - data.span[0]) % 2:
        w.problem(
            "odd-byte-count",
            ERROR,
            f"odd data length {data.span[1] - data.span[0]}: not whole 16-bit words",
            data.span,
        )
    w.summary = f"diagnostics: {name}"
    describe = _DIAGNOSTIC_DATA_TEXT.get(code)
    if describe is not None and len(words) == 1:
        w.retext("data", describe(words[0]))
    if w.is_request:
        allowed = sub.request_data if sub is not None else None
        if (
            allowed is not None
            and data is not None
            and (len(words) != 1 or words[0] not in allowed)
        ):
            choices = " or ".join(f"0x{value:04X}" for value in allowed)
            w.problem(
                "diagnostic-data",
                WARNING,
                f"data {data.text} should be {choices} for {name}",
                data.span,
            )
        return
    answer = sub.answer if sub is not None else "unknown"
    if answer == "none":
        w.problem("unexpected-response", WARNING, f"{name} gets no response", None)
    _echo(w, None if answer == "echo" else ("sub_function",))
    if answer == "count" and len(words) == 1:
        w.retext("data", str(words[0]))
        w.summary = f"diagnostics: {name}: {words[0]}"
    elif answer == "register" and len(words) == 1:
        w.summary = f"diagnostics: {name}: 0x{words[0]:04X}"


def _event_counter(w: _Work) -> None:
    if w.is_request:
        w.summary = "get comm event counter"
        return
    status, count = w.get("status"), w.get("event_count")
    if status is not None:
        w.retext("status", _STATUS_WORDS.get(status, f"0x{status:04X}"))
    if status is None or count is None:
        w.summary = "comm event counter"
        return
    w.summary = f"event counter {count}, {_STATUS_WORDS.get(status, f'status 0x{status:04X}')}"


def _event_log(w: _Work) -> None:
    if w.is_request:
        w.summary = "get comm event log"
        return
    status = w.get("status")
    if status is not None:
        w.retext("status", _STATUS_WORDS.get(status, f"0x{status:04X}"))
    count, messages = w.get("event_count"), w.get("message_count")
    events = w.fields.get("events")
    if status is None or count is None or messages is None:
        w.summary = "comm event log"
        return
    stored = len(events.value) if events is not None and isinstance(events.value, bytes) else 0
    w.summary = (
        f"event log: {_STATUS_WORDS.get(status, f'status 0x{status:04X}')}, "
        f"event count {count}, message count {messages}, {_count(stored, 'event')}"
    )


def _server_id(w: _Work) -> None:
    if w.is_request:
        w.summary = "report server id"
        return
    server = w.fields.get("server_id")
    run = w.get("run_indicator")
    state = None if run is None else _RUN_STATES.get(run)
    if run is not None and state is None:
        w.problem(
            "run-indicator",
            WARNING,
            f"run indicator 0x{run:02X} is not 0x00 (OFF) or 0xFF (ON)",
            w.span("run_indicator"),
        )
    if state is not None:
        w.retext("run_indicator", state)
    if server is None or run is None:
        w.summary = "server id"
        return
    w.summary = f"server id {server.text}, run indicator {state or f'0x{run:02X}'}"


def _check_file_items(w: _Work, items: Any) -> None:
    """Reference type 6 and record numbers up to 9999, for every file sub-request."""
    if not isinstance(items, list):
        return
    for index, item in enumerate(items):
        spans: dict[str, tuple[int, int]] = item.get("_spans", {})
        reference = item.get("reference_type")
        if isinstance(reference, int) and reference != FILE_REFERENCE_TYPE:
            w.problem(
                "reference-type",
                ERROR,
                f"reference type {reference} is not {FILE_REFERENCE_TYPE} in item {index}",
                spans.get("reference_type"),
            )
        record = item.get("record_number")
        if isinstance(record, int) and record > LAST_FILE_RECORD:
            w.problem(
                "record-number",
                ERROR,
                f"record number {record} above the limit of {LAST_FILE_RECORD} in item {index}",
                spans.get("record_number"),
            )


def _describe_file_items(items: Any) -> str:
    parts = []
    for item in items if isinstance(items, list) else ():
        file_number, record, length = (
            item.get("file_number"),
            item.get("record_number"),
            item.get("record_length"),
        )
        if isinstance(file_number, int) and isinstance(record, int) and isinstance(length, int):
            parts.append(f"file {file_number} record {record} ({_count(length, 'register')})")
    return ", ".join(parts)


def _file_read(w: _Work) -> None:
    if w.is_request:
        items = w.parsed.values.get("sub_requests")
        byte_count = w.get("byte_count")
        if byte_count is not None and byte_count % 7:
            w.problem(
                "byte-count",
                ERROR,
                f"byte count {byte_count} is not a multiple of 7",
                w.span("byte_count"),
            )
        _check_file_items(w, items)
        described = _describe_file_items(items)
        w.summary = f"read file record: {described}" if described else "read file record"
        return
    items = w.parsed.values.get("sub_responses")
    _check_file_items(w, items)
    records = items if isinstance(items, list) else []
    words = sum(len(item.get("record_data") or ()) for item in records)
    w.summary = f"file records: {_count(len(records), 'record')}, {_count(words, 'register')}"


def _file_write(w: _Work) -> None:
    items = w.parsed.values.get("sub_requests")
    _check_file_items(w, items)
    if not w.is_request:
        _echo(w)
    described = _describe_file_items(items)
    w.summary = f"write file record: {described}" if described else "write file record"


def _object_text(value: bytes) -> str:
    """A device string as text: UTF-8 where it decodes, control characters escaped."""
    text = value.decode("utf-8", errors="backslashreplace")
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode() for c in text)


def _mei(w: _Work) -> None:
    mei = w.get("mei_type")
    if mei is None:
        w.summary = "encapsulated interface transport"
        return
    mei_name = MEI_TYPES.get(mei)
    w.retext("mei_type", mei_name or f"unknown MEI type 0x{mei:02X}")
    if mei_name is None:
        w.problem("mei-type", INFO, f"MEI type 0x{mei:02X} is not defined", w.span("mei_type"))
    if mei != MEI_DEVICE_ID:
        data = w.fields.get("data")
        size = data.span[1] - data.span[0] if data is not None else 0
        w.summary = f"{mei_name or f'MEI type 0x{mei:02X}'}: {_count(size, 'data byte')}"
        return
    code = w.get("read_device_id_code")
    if code is not None:
        code_name = READ_DEVICE_ID_CODES.get(code)
        w.retext("read_device_id_code", code_name or str(code))
        if code_name is None and w.is_request:
            w.problem(
                "device-id-code",
                WARNING,
                f"read device id code {code} is not 1-4",
                w.span("read_device_id_code"),
            )
    if w.is_request:
        object_id = w.get("object_id")
        if object_id is not None:
            w.retext("object_id", device_object_name(object_id))
        if code is None or object_id is None:
            w.summary = "device id"
        else:
            code_text = READ_DEVICE_ID_CODES.get(code, f"code {code}")
            w.summary = f"device id request: {code_text}, object {device_object_name(object_id)}"
        return
    conformity = w.get("conformity_level")
    if conformity is not None:
        w.retext("conformity_level", CONFORMITY_LEVELS.get(conformity, f"0x{conformity:02X}"))
    more = w.get("more_follows")
    if more is not None:
        w.retext("more_follows", _MORE_FOLLOWS.get(more, f"0x{more:02X}"))
    next_id = w.get("next_object_id")
    if next_id is not None:
        w.retext("next_object_id", device_object_name(next_id))
    objects = w.fields.get("objects")
    named: list[Field] = []
    for item in objects.children if objects is not None else ():
        parts = {child.name: child for child in item.children}
        id_field, value = parts.get("object_id"), parts.get("value")
        if id_field is None or not isinstance(id_field.value, int):
            continue
        name = device_object_name(id_field.value)
        raw = value.value if value is not None and isinstance(value.value, bytes) else b""
        text = raw.decode("utf-8", errors="backslashreplace")
        named.append(Field(name, text, _object_text(raw), item.span, item.children))
    if objects is not None:
        w.fields["objects"] = replace(objects, children=tuple(named))
    listing = ", ".join(f"{item.name}={item.text}" for item in named)
    w.summary = f"device id: {listing}" if listing else "device id: no objects"
    if more == 0xFF and next_id is not None:
        w.summary += f"; more follows from {device_object_name(next_id)}"


def _exception(w: _Work) -> None:
    code = w.get("exception_code")
    if w.is_request:
        w.problem("role", WARNING, "exception response seen as a request", (1, 2))
    if code is None:
        w.summary = "exception"
        return
    name = exception_name(code)
    w.retext("exception_code", name)
    w.summary = f"exception {code:02X} {name}"


def _raw(w: _Work) -> None:
    klass = function_class(w.function)
    data = w.fields.get("data")
    size = data.span[1] - data.span[0] if data is not None else 0
    w.summary = f"{FUNCTION_CLASSES[klass]} function {w.function}: {_count(size, 'data byte')}"
    if klass == "reserved":
        w.problem("unknown-function", INFO, f"function code {w.function} is reserved", (1, 2))
    elif klass == "unknown":
        w.problem(
            "unknown-function",
            WARNING,
            f"function code {w.function} is not defined by the Modbus specification",
            (1, 2),
        )


FAMILIES: dict[str, Callable[[_Work], None]] = {
    "read": _read,
    "write_single": _write_single,
    "write_multiple": _write_multiple,
    "read_write": _read_write,
    "mask_write": _mask_write,
    "fifo": _fifo,
    "exception_status": _exception_status,
    "diagnostics": _diagnostics,
    "event_counter": _event_counter,
    "event_log": _event_log,
    "server_id": _server_id,
    "file_read": _file_read,
    "file_write": _file_write,
    "mei": _mei,
    "exception": _exception,
    "raw": _raw,
}
"""The routine for each FunctionSpec.family (plus exception responses)."""


# --- entry point ---------------------------------------------------------------------------


def dissect(body: bytes, role: Role, *, request: bytes | None = None) -> Dissection:
    """Take one frame apart.

    `body` is the unit byte and the PDU, without CRC or LRC. `request` is the paired
    request's body when a response is dissected: it tells how many coil bits are real,
    where read registers start, and what an echo should repeat. Never raises on any bytes.
    """
    body = bytes(body)
    if len(body) < 2:
        missing = "function" if body else "unit"
        return Dissection(
            unit=body[0] if body else 0,
            function=0,
            exception=False,
            role=role,
            name="Truncated frame",
            summary=f"frame too short: {_count(len(body), 'byte')}",
            fields=(),
            problems=(Problem("truncated", ERROR, f"frame ends before {missing}", (0, len(body))),),
            data=(),
        )
    unit, code = body[0], body[1]
    exception = code >= 0x80
    function = code & 0x7F
    spec = FUNCTIONS.get(function)
    if exception:
        schema, family = EXCEPTION_SCHEMA, "exception"
    elif spec is None or spec.family == "raw":
        schema, family = RAW_SCHEMA, "raw"
    else:
        schema = spec.request_schema if role is Role.REQUEST else spec.response_schema
        family = spec.family
    parsed = _parse(schema, body)
    w = _Work(body, role, function, spec, parsed, _fields(parsed.values))
    _check_structure(w)
    _pair(w, request)
    FAMILIES[family](w)
    if role is Role.RESPONSE and unit == 0:
        w.problem("broadcast-response", WARNING, "response from the broadcast address 0", (0, 1))
    summary = w.summary
    if role is Role.REQUEST and unit == 0:
        summary = f"broadcast: {summary}"
    return Dissection(
        unit=unit,
        function=function,
        exception=exception,
        role=role,
        name=function_name(function),
        summary=summary,
        fields=tuple(w.fields.values()),
        problems=tuple(w.problems),
        data=tuple(w.data),
    )
