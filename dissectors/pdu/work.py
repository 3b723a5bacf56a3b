"""Provides the work on one frame that every meaning routine shares: the parse with byte
spans, the fields made from it, the checks every layout gets, pairing with the request
and echo comparison, and the `Work` object the routines read and fill in.

Speed: the fields of a register or bit array make their per-value children and text when
first read; the last requests' parses (and dissections) are kept by their bytes, for the
response paired with each and because a polling master sends the same requests over and
over; the output objects are built by `values.make_*`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from io import BytesIO
from typing import Any

from construct import ConstructError, Container

from dissectors.pdu.schema import BitValues, WordValues, parse_body
from dissectors.pdu.spec import FunctionSpec, Limit
from dissectors.values import (
    Dissection,
    Field,
    Problem,
    RegisterData,
    make_field,
    make_lazy_field,
    make_problem,
    make_register_data,
)

ERROR = "error"
WARNING = "warning"
INFO = "info"

# Integer fields shown in decimal; every other integer is shown in hex at its width.
DECIMAL = frozenset(
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
BIT_TABLES = frozenset({"coils", "discrete_inputs"})

# --- parsing ------------------------------------------------------------------------------


class Parsed:
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


class WordsField(_ArrayField):
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


class BitsField(_ArrayField):
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
HEX_HIGH = tuple(f"0x{byte:02X}" for byte in range(256))
HEX_LOW = tuple(f"{byte:02X}" for byte in range(256))


def _number_text(name: str, value: int, span: tuple[int, int]) -> str:
    """A number in decimal (counts and quantities) or in hex at its width."""
    if name in DECIMAL:
        return str(value)
    width = span[1] - span[0]
    if width == 2 and 0 <= value <= 0xFFFF:
        return HEX_HIGH[value >> 8] + HEX_LOW[value & 0xFF]
    if width == 1 and 0 <= value <= 0xFF:
        return HEX_HIGH[value]
    return f"0x{value:0{2 * max(1, width)}X}"


def _field(name: str, value: Any, span: tuple[int, int]) -> Field:
    kind = type(value)
    if kind is int:
        return make_field(name, value, _number_text(name, value, span), span)
    if kind is WordValues:
        return make_lazy_field(WordsField, name, tuple(value), span)
    if kind is BitValues:
        return make_lazy_field(BitsField, name, tuple(value), span)
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

SEEN: dict[bytes, Parsed] = {}
_SEEN_AT_MOST = 64  # a polling cycle's requests; more only burdens the cycle collector


def keep(body: bytes, parsed: Parsed) -> None:
    """Keep a request's parse: its response is dissected with it next, and a polling
    master sends the same requests over and over. Kept parses are only read."""
    if len(SEEN) >= _SEEN_AT_MOST:
        SEEN.clear()
    SEEN[body] = parsed


def request_parse(schema: Any, body: bytes) -> Parsed:
    """A request for a known function code, parsed, or as it was when last seen."""
    parsed = SEEN.get(body)
    if parsed is None or parsed.schema is not schema:
        parsed = Parsed(schema, body)
        keep(body, parsed)
    return parsed


# --- what each code byte in each direction is dissected with -------------------------------


@dataclass(frozen=True, slots=True)
class Plan:
    """How frames with one code byte, in one direction, are dissected."""

    schema: Any
    family: str
    routine: Callable[[Work], None]
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
    words_answer: bool = False  # an FC 3/4 answer: well-formed ones have a shortcut


# --- the work on one frame -----------------------------------------------------------------


class Work:
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

    def __init__(self, body: bytes, plan: Plan, parsed: Parsed, fields: dict[str, Field]) -> None:
        self.body = body
        self.plan = plan
        self.is_request = plan.is_request
        self.function = plan.function
        self.table = plan.table
        self.parsed = parsed
        self.record: Any = parsed.values  # the parsed Container
        self.fields = fields
        self.request: Parsed | None = None
        self.request_fields: dict[str, Field] = NO_FIELDS
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


NO_FIELDS: dict[str, Field] = {}  # never written to


def plural(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def address_text(value: int) -> str:
    if 0 <= value <= 0xFFFF:
        return HEX_HIGH[value >> 8] + HEX_LOW[value & 0xFF]
    return f"0x{value:04X}"


# --- checks every layout gets --------------------------------------------------------------


def check_structure(w: Work, size: int) -> None:
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
            f"{plural(extra, 'trailing byte')} after the PDU",
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


def pair(w: Work, request: bytes) -> None:
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
    w.request = request_parse(spec.request_schema, request)
    w.request_fields = w.request.fields


def echo(w: Work, names: tuple[str, ...] | None = None) -> None:
    """Compare fields of a response with the same fields of its request (all when `names`
    is None), down to the first level where they differ."""
    if w.request is None:
        return
    mine = w.fields if names is None else {n: f for n, f in w.fields.items() if n in names}
    _compare(w, mine, w.request_fields, "", "")


def _compare(
    w: Work, mine: dict[str, Field], theirs: dict[str, Field], parent_path: str, parent: str
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
