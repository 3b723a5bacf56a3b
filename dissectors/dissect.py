"""Provides dissect(): one frame body in; its fields, meaning, problems and register data out.

The layouts are the construct schemas on each FunctionSpec (dissectors.functions); here a
frame is parsed with them, every parsed field becomes a `Field` with its byte span, and the
spec's `family` routine reads meaning into the fields: names, summaries, the checks a
layout cannot express (byte count against quantity, coil values, echoes), and the
register values the frame carries. Whatever is wrong with the bytes becomes a `Problem`;
nothing here raises on bus data.

Speed: what depends only on the function code and direction is worked out once (a plan
per code byte and direction); the fields of a register or bit array make their per-value
children and text when first read; the last requests' parses (and dissections) are kept
by their bytes, for the response paired with each and because a polling master sends
the same requests over and over; the output objects are built by `values.make_*`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from io import BytesIO
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
    Limit,
    WordValues,
    device_object_name,
    exception_name,
    function_class,
    function_name,
    parse_body,
)
from dissectors.values import (
    Dissection,
    Field,
    Problem,
    RegisterData,
    Role,
    make_dissection,
    make_field,
    make_lazy_field,
    make_problem,
    make_register_data,
)

__all__ = ["Dissection", "Field", "Problem", "RegisterData", "Role", "dissect"]

ERROR = "error"
WARNING = "warning"
INFO = "info"

_REQUEST = Role.REQUEST
_RESPONSE = Role.RESPONSE

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


class _Parsed:
    """A body run through a schema: the (possibly partial) Container, where parsing
    stopped, the field the frame ended in if it ended too soon, and the fields as parsed
    (before a family routine gives them meaning). A kept request's parse also holds the
    request's dissection, once made."""

    __slots__ = ("body", "cut", "dissection", "end", "fields", "schema", "values")

    def __init__(self, schema: Any, body: bytes) -> None:
        self.schema = schema
        self.body = body
        self.dissection: Dissection | None = None
        stream = BytesIO(body)
        stream.seek(2)
        try:
            values = parse_body(schema, stream)
        except ConstructError as error:
            partial = getattr(error, "partial", None)
            self.values = partial if partial is not None else Container()
            self.end = len(body)
            self.cut: tuple[str, int] | None = getattr(error, "failed", ("data", 2))
        else:
            self.values = values
            self.end = stream.tell()
            self.cut = None
        self.fields = _fields(self.values)


_BIT_TEXT = ("0", "1")


class _ArrayField(Field):
    """A field of register words or coil bits (`value`) whose text and one child per value
    are made the first time they are read: most frames are never shown."""

    __slots__ = ()

    def __getattr__(self, name: str) -> Any:
        # Only reached for a slot not filled yet: `text` or `children`.
        values = self.value
        assert isinstance(values, tuple)
        made: Any
        if name == "children":
            made = self._children(values)
        elif name == "text":
            made = self._text(values)
        else:
            raise AttributeError(name)
        object.__setattr__(self, name, made)
        return made

    def _children(self, values: tuple[int, ...]) -> tuple[Field, ...]:
        raise NotImplementedError

    def _text(self, values: tuple[int, ...]) -> str:
        raise NotImplementedError


class _WordsField(_ArrayField):
    """16-bit words; each child has the two bytes its word came from."""

    __slots__ = ()

    def _children(self, values: tuple[int, ...]) -> tuple[Field, ...]:
        start, base = self.span[0], self.name
        return tuple(
            make_field(f"{base}[{i}]", word, f"0x{word:04X}", (start + 2 * i, start + 2 * i + 2))
            for i, word in enumerate(values)
        )

    def _text(self, values: tuple[int, ...]) -> str:
        return " ".join(map("0x{:04X}".format, values))


class _BitsField(_ArrayField):
    """Coil or input bits, 0 or 1; each child has the byte its bit came from."""

    __slots__ = ()

    def _children(self, values: tuple[int, ...]) -> tuple[Field, ...]:
        start, base = self.span[0], self.name
        return tuple(
            make_field(f"{base}[{i}]", bit, _BIT_TEXT[bit], (start + i // 8, start + i // 8 + 1))
            for i, bit in enumerate(values)
        )

    def _text(self, values: tuple[int, ...]) -> str:
        return " ".join(map(_BIT_TEXT.__getitem__, values))


def _fields(record: Any) -> dict[str, Field]:
    """The named fields of a parsed Record, in order, with their spans."""
    spans: dict[str, tuple[int, int]] = record.get("_spans", _NO_SPANS)
    out: dict[str, Field] = {}
    for name, span in spans.items():
        value = record[name]
        if type(value) is int:  # most fields are numbers
            out[name] = make_field(name, value, _number_text(name, value, span), span)
        elif value is not None:
            out[name] = _field(name, value, span)
    return out


_NO_SPANS: dict[str, tuple[int, int]] = {}  # never written to
_HEX_HIGH = tuple(f"0x{byte:02X}" for byte in range(256))
_HEX_LOW = tuple(f"{byte:02X}" for byte in range(256))


def _number_text(name: str, value: int, span: tuple[int, int]) -> str:
    """A number in decimal (counts and quantities) or in hex at its width."""
    if name in _DECIMAL:
        return str(value)
    width = span[1] - span[0]
    if width == 2 and 0 <= value <= 0xFFFF:
        return _HEX_HIGH[value >> 8] + _HEX_LOW[value & 0xFF]
    if width == 1 and 0 <= value <= 0xFF:
        return _HEX_HIGH[value]
    return f"0x{value:0{2 * max(1, width)}X}"


def _field(name: str, value: Any, span: tuple[int, int]) -> Field:
    kind = type(value)
    if kind is int:
        return make_field(name, value, _number_text(name, value, span), span)
    if kind is WordValues:
        return make_lazy_field(_WordsField, name, tuple(value), span)
    if kind is BitValues:
        return make_lazy_field(_BitsField, name, tuple(value), span)
    if kind is bytes:
        return make_field(name, value, value.hex(" ").upper(), span)
    if isinstance(value, dict):
        children = tuple(_fields(value).values())
        return make_field(name, None, "", span, children)
    items = list(value)
    children = tuple(
        _field(f"{name}[{index}]", item, _item_span(item, span)) for index, item in enumerate(items)
    )
    noun = "item" if len(items) == 1 else "items"
    return make_field(name, None, f"{len(items)} {noun}", span, children)


def _item_span(item: Any, outer: tuple[int, int]) -> tuple[int, int]:
    spans: dict[str, tuple[int, int]] = item.get("_spans", {}) if isinstance(item, dict) else {}
    if not spans:
        return (outer[0], outer[0])
    return (min(s[0] for s in spans.values()), max(s[1] for s in spans.values()))


# --- requests seen: parsed once, dissected once --------------------------------------------

_SEEN: dict[bytes, _Parsed] = {}
_SEEN_AT_MOST = 64  # a polling cycle's requests; more only burdens the cycle collector


def _keep(body: bytes, parsed: _Parsed) -> None:
    """Keep a request's parse: its response is dissected with it next, and a polling
    master sends the same requests over and over. Kept parses are only read."""
    if len(_SEEN) >= _SEEN_AT_MOST:
        _SEEN.clear()
    _SEEN[body] = parsed


def _request_parse(schema: Any, body: bytes) -> _Parsed:
    """A request for a known function code, parsed, or as it was when last seen."""
    parsed = _SEEN.get(body)
    if parsed is None or parsed.schema is not schema:
        parsed = _Parsed(schema, body)
        _keep(body, parsed)
    return parsed


# --- what each code byte in each direction is dissected with -------------------------------


@dataclass(frozen=True, slots=True)
class _Plan:
    """How frames with one code byte, in one direction, are dissected."""

    schema: Any
    family: str
    routine: Callable[[_Work], None]
    spec: FunctionSpec | None
    function: int
    exception: bool
    name: str
    table: str
    limits: tuple[Limit, ...]  # those of the fields the layout has
    is_request: bool
    keep: bool  # a request of a known function: its parse is kept for its response
    reuse: bool  # a kept request's parse serves (a request, or an echo in the same layout)
    counted: bool  # the layout has a byte_count field
    checked: bool  # the layout has a byte_count field or quantities with limits


def _plan(code: int, role: Role) -> _Plan:
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
    keep = role is Role.REQUEST and family not in ("exception", "raw")
    names = {sc.name for sc in schema.subcons}
    counted = "byte_count" in names
    limits = tuple(limit for limit in (spec.limits if spec else ()) if limit.field in names)
    return _Plan(
        schema=schema,
        family=family,
        routine=FAMILIES[family],
        spec=spec,
        function=function,
        exception=exception,
        name=function_name(function),
        table=(spec.table or "") if spec is not None else "",
        limits=limits,
        is_request=role is Role.REQUEST,
        keep=keep,
        reuse=keep or (spec is not None and schema is spec.request_schema),
        counted=counted,
        checked=counted or bool(limits),
    )


# --- the work on one frame -----------------------------------------------------------------


class _Work:
    """One dissection in progress: what the family routines read and fill in."""

    __slots__ = (
        "body",
        "data",
        "fields",
        "function",
        "is_request",
        "parsed",
        "plan",
        "problems",
        "record",
        "request",
        "request_fields",
        "summary",
        "table",
    )

    def __init__(self, body: bytes, plan: _Plan, parsed: _Parsed, fields: dict[str, Field]) -> None:
        self.body = body
        self.plan = plan
        self.is_request = plan.is_request
        self.function = plan.function
        self.table = plan.table
        self.parsed = parsed
        self.record: Any = parsed.values  # the parsed Container
        self.fields = fields
        self.request: _Parsed | None = None
        self.request_fields: dict[str, Field] = _NO_FIELDS
        self.problems: tuple[Problem, ...] = ()
        self.data: tuple[RegisterData, ...] = ()
        self.summary = ""

    def get(self, name: str) -> int | None:
        value = self.record.get(name)
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
        self.problems += (make_problem(kind, severity, text, span),)

    def carries(self, address: int | None, values: tuple[int, ...], write: bool) -> None:
        """Record values of the frame's data table from `address` on."""
        self.data += (make_register_data(self.table, address, values, write),)

    def retext(self, name: str, text: str) -> None:
        found = self.fields.get(name)
        if found is not None:
            self.fields[name] = make_field(
                found.name, found.value, text, found.span, found.children
            )


_NO_FIELDS: dict[str, Field] = {}  # never written to


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _address(value: int) -> str:
    if 0 <= value <= 0xFFFF:
        return _HEX_HIGH[value >> 8] + _HEX_LOW[value & 0xFF]
    return f"0x{value:04X}"


# --- checks every layout gets --------------------------------------------------------------


def _check_structure(w: _Work, size: int) -> None:
    parsed = w.parsed
    if parsed.cut is not None:
        name, start = parsed.cut
        where = "before" if start >= size else "inside"
        w.problem("truncated", ERROR, f"frame ends {where} {name}", (start, size))
    byte_count = w.fields.get("byte_count") if w.plan.counted else None
    if byte_count is not None and isinstance(byte_count.value, int):
        follow = size - byte_count.span[1]
        if follow != byte_count.value:
            verb = "byte follows" if follow == 1 else "bytes follow"
            w.problem(
                "byte-count",
                ERROR,
                f"byte count {byte_count.value} but {follow} data {verb}",
                byte_count.span,
            )
    if parsed.end < size:
        extra = size - parsed.end
        w.problem(
            "trailing-bytes",
            WARNING,
            f"{_count(extra, 'trailing byte')} after the PDU",
            (parsed.end, size),
        )
    for limit in w.plan.limits:
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


def _pair(w: _Work, request: bytes) -> None:
    """Parse the paired request, when it is one for the same function code."""
    if len(request) < 2:
        return
    if type(request) is not bytes:
        request = bytes(request)
    if request[1] != w.function:
        w.problem(
            "request-mismatch",
            WARNING,
            f"paired request is function {request[1]}, not {w.function}",
            None,
        )
        return
    spec = w.plan.spec
    if spec is None or spec.request_schema is None:
        return
    w.request = _request_parse(spec.request_schema, request)
    w.request_fields = w.request.fields


def _echo(w: _Work, names: tuple[str, ...] | None = None) -> None:
    """Compare fields of a response with the same fields of its request (all when `names`
    is None), down to the first level where they differ."""
    if w.request is None:
        return
    mine = w.fields if names is None else {n: f for n, f in w.fields.items() if n in names}
    _compare(w, mine, w.request_fields, "", "")


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
    values = found.value if isinstance(found.value, tuple) else ()
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
                w.fields["values"] = make_lazy_field(_BitsField, "values", values, found.span)
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
    if w.is_request:
        noun = _READ_NOUNS.get(w.table, "value")
        values = w.record
        address, quantity = values.get("address"), values.get("quantity")
        if isinstance(address, int) and isinstance(quantity, int):
            w.summary = f"read {_count(quantity, noun)} from {_address(address)}"
        else:
            w.summary = f"read {noun}s"
        return
    request = w.request
    asked = _NO_VALUES if request is None else request.values
    quantity = asked.get("quantity")
    if not isinstance(quantity, int):
        quantity = None
    values = _checked_values(w, quantity, "quantity", from_request=True)
    if "values" in w.fields:
        address = asked.get("address")
        w.carries(address if isinstance(address, int) else None, values, False)
    w.summary = "1 value" if len(values) == 1 else f"{len(values)} values"


_NO_VALUES: dict[str, Any] = {}  # never written to


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
        w.carries(address, (1 if state == "ON" else 0,), True)
        return
    w.summary = f"write 0x{value:04X} to register {_address(address)}"
    w.carries(address, (value,), True)


def _write_multiple(w: _Work) -> None:
    noun = _WRITE_NOUNS.get(w.table, "value")
    address, quantity = w.get("address"), w.get("quantity")
    if w.is_request:
        values = _checked_values(w, quantity, "quantity", from_request=False)
        if "values" in w.fields:
            w.carries(address, values, True)
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
                w.carries(w.asked("address"), values, True)
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
            w.carries(write_address, values, True)
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
        w.carries(w.asked("read_address"), values, False)
    written = w.request_fields.get("values")
    if written is not None and isinstance(written.value, tuple):
        w.carries(w.asked("write_address"), written.value, True)
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
        named.append(make_field(name, text, _object_text(raw), item.span, item.children))
    if objects is not None:
        w.fields["objects"] = make_field(
            objects.name, objects.value, objects.text, objects.span, tuple(named)
        )
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


_REQUEST_PLANS = tuple(_plan(code, Role.REQUEST) for code in range(256))
_RESPONSE_PLANS = tuple(_plan(code, Role.RESPONSE) for code in range(256))
"""The plan for each code byte (function, with the exception bit), by direction."""


def dissect(body: bytes, role: Role, *, request: bytes | None = None) -> Dissection:
    """Take one frame apart.

    `body` is the unit byte and the PDU, without CRC or LRC. `request` is the paired
    request's body when a response is dissected: it tells how many coil bits are real,
    where read registers start, and what an echo should repeat. Never raises on any bytes.
    """
    if type(body) is not bytes:
        body = bytes(body)
    if len(body) < 2:
        missing = "function" if body else "unit"
        return make_dissection(
            unit=body[0] if body else 0,
            function=0,
            exception=False,
            role=role,
            name="Truncated frame",
            summary=f"frame too short: {_count(len(body), 'byte')}",
            fields=(),
            problems=(
                make_problem("truncated", ERROR, f"frame ends before {missing}", (0, len(body))),
            ),
            data=(),
        )
    size = len(body)
    unit, code = body[0], body[1]
    plan = (_REQUEST_PLANS if role is _REQUEST else _RESPONSE_PLANS)[code]
    parsed = _SEEN.get(body) if plan.reuse else None
    if parsed is not None and parsed.schema is plan.schema:
        if plan.keep and parsed.dissection is not None:
            return parsed.dissection  # the same request again: the same dissection
        fields = parsed.fields.copy()  # the kept parse's own stay as they were parsed
    else:
        parsed = _Parsed(plan.schema, body)
        if plan.keep:
            _keep(body, parsed)
            fields = parsed.fields.copy()
        else:
            fields = parsed.fields
    w = _Work(body, plan, parsed, fields)
    if plan.checked or parsed.cut is not None or parsed.end != size:
        _check_structure(w, size)
    if request is not None and not plan.is_request:
        _pair(w, request)
    plan.routine(w)
    summary = w.summary
    if unit == 0:
        if plan.is_request:
            summary = f"broadcast: {summary}"
        else:
            w.problem(
                "broadcast-response", WARNING, "response from the broadcast address 0", (0, 1)
            )
    result = make_dissection(
        unit,
        plan.function,
        plan.exception,
        role,
        plan.name,
        summary,
        tuple(fields.values()),
        w.problems,
        w.data,
    )
    if plan.keep:
        parsed.dissection = result
    return result
