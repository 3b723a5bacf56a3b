"""Provides the function-code registry: one frozen spec per Modbus function code.

Each spec says, in one place, what the code is called, its class (public, user-defined,
reserved), and what a framer needs to predict frame lengths in both directions: the RTU
length of a request, of a normal response, and the exact response length a given
request implies. Construct schemas for request and response live on the same spec, with
the family of dissection routine that reads meaning into them, the data table, and the
legal quantities. The names tables (exception codes, diagnostic sub-functions, MEI types,
device identification objects, function code classes) live here too.

Lengths are RTU frame lengths: address + function + data + 2 CRC bytes.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

from construct import (
    Adapter,
    Bytes,
    Construct,
    ConstructError,
    Container,
    FormatField,
    GreedyBytes,
    If,
    ListContainer,
    Path,
    Renamed,
    SizeofError,
    StreamError,
    Struct,
    Subconstruct,
    evaluate,
    stream_write,
    this,
)

Buffer = bytes | bytearray | memoryview

# A walker computes a frame length by reading the frame: (buffer, start, available end)
# -> length, NEED_MORE when it must see more bytes, or IMPOSSIBLE.
Walker = Callable[[Buffer, int, int], int]
NEED_MORE = -1
IMPOSSIBLE = -2


@dataclass(frozen=True, slots=True)
class LengthRule:
    """How long a frame is: `base`, plus a byte count read at `count_pos` (1 or 2 bytes,
    big-endian) when `count_size` > 0, or what `walker` says."""

    base: int
    count_pos: int = 0
    count_size: int = 0
    walker: Walker | None = None

    @property
    def fixed(self) -> bool:
        return self.count_size == 0 and self.walker is None

    @property
    def min_needed(self) -> int:
        """Bytes that must be present before the length can be known."""
        if self.walker is not None:
            return 3
        if self.count_size:
            return self.count_pos + self.count_size
        return self.base

    def length(self, buf: Buffer, start: int, end: int) -> int:
        """Frame length at `start`, NEED_MORE or IMPOSSIBLE."""
        if self.walker is not None:
            return self.walker(buf, start, end)
        if self.count_size == 0:
            return self.base
        pos = start + self.count_pos
        if pos + self.count_size > end:
            return NEED_MORE
        if self.count_size == 1:
            return self.base + buf[pos]
        return self.base + (buf[pos] << 8 | buf[pos + 1])


def fixed(n: int) -> LengthRule:
    return LengthRule(base=n)


def counted(pos: int, base: int, size: int = 1) -> LengthRule:
    return LengthRule(base=base, count_pos=pos, count_size=size)


# --- construct building blocks ------------------------------------------------------------
# Schemas parse the PDU after the function code from a stream that holds the whole body
# (unit, function, data), so stream positions are byte offsets within the body. They are
# interpreted, never compiled: bus data is untrusted, and errors must keep their place.


class Unsigned(FormatField):  # type: ignore[misc]  # construct is untyped
    """A big-endian unsigned integer of 1 or 2 bytes: construct's FormatField (so it
    builds, sizes and compiles as one), parsed with a prepared struct and no helper call.
    Too few bytes raise the StreamError FormatField raises."""

    def __init__(self, size: int) -> None:
        super().__init__(">", {1: "B", 2: "H"}[size])
        self._unpack = struct.Struct(self.fmtstr).unpack

    def _parse(self, stream: Any, context: Any, path: Any) -> Any:
        data = stream.read(self.length)
        if len(data) != self.length:
            raise StreamError(
                "stream read less than specified amount, "
                f"expected {self.length}, found {len(data)}",
                path=path,
            )
        return self._unpack(data)[0]


UInt8 = Unsigned(1)
UInt16 = Unsigned(2)


_NO_CONTEXT, _FIELDS_ONLY, _FULL_CONTEXT = 0, 1, 2


def _context_use(sc: Any) -> int:
    """What parsing `sc` may read of its context: nothing (fixed-size numbers and bytes,
    our word and bit adapters over them), only fields of the Record by name (`Octets` of
    `this.name` bytes), or anything (all else: `this` expressions, nested Records,
    construct's own classes, `parsed` hooks)."""
    if type(sc) is Renamed:
        return _FULL_CONTEXT if sc.parsed is not None else _context_use(sc.subcon)
    if sc.parsed is not None:
        return _FULL_CONTEXT
    if type(sc) in (FormatField, Unsigned, _GREEDY_BYTES):
        return _NO_CONTEXT
    if type(sc) is Bytes:
        return _FULL_CONTEXT if callable(sc.length) else _NO_CONTEXT
    if type(sc) is Octets:
        if sc.named is not None:
            return _FIELDS_ONLY
        return _FULL_CONTEXT if callable(sc.length) else _NO_CONTEXT
    if type(sc) in (Words, Bits):
        return _context_use(sc.subcon)
    return _FULL_CONTEXT


_GREEDY_BYTES = type(GreedyBytes)


class Record(Struct):  # type: ignore[misc]  # construct is untyped
    """A Struct that remembers where each named field lies: `obj["_spans"][name]` is the
    (start, end) stream position of that field. When the data ends inside a field, the
    ConstructError raised carries `partial` (the fields read so far) and `failed`
    (the field's name and start), so a truncated frame still shows what it had.

    Parsing is construct's interpreter, field by field; what does not depend on the data
    is worked out once, here: a field that is only named (`"name" / UInt16`) is parsed
    by what it names, with the path the name adds; a field without a `parsed` hook by its
    `_parse`; and the Struct context is only built when a field may read more of it than
    the fields before it by name (`this.byte_count`), which the parsed fields serve."""

    def __init__(self, *subcons: Any, **subconskw: Any) -> None:
        super().__init__(*subcons, **subconskw)
        steps = []
        for sc in self.subcons:
            name, inner, suffix = sc.name, sc, ""
            if type(sc) is Renamed and sc.parsed is None:
                inner, suffix = sc.subcon, f" -> {sc.name}"
            parse = inner._parse if inner.parsed is None else inner._parsereport
            steps.append((name, parse, suffix))
        self._steps: tuple[tuple[str | None, Callable[..., Any], str], ...] = tuple(steps)
        use = max((_context_use(sc) for sc in self.subcons), default=_NO_CONTEXT)
        self._fields_only = use == _FIELDS_ONLY
        self._context: Any = None
        if use == _FULL_CONTEXT:
            # What every parse's context starts from: the parsing flags as construct sets
            # them for a parse (the only time `_parse` runs), and our fields.
            self._context = Container(
                _=None,
                _params=None,
                _root=None,
                _parsing=True,
                _building=False,
                _sizing=False,
                _subcons=self._subcons,
                _io=None,
                _index=None,
            )

    def _parse(self, stream: Any, outer: Any, path: Any) -> Any:
        obj = Container()
        spans: dict[str, tuple[int, int]] = {}
        obj["_spans"] = spans
        if self._context is not None:
            context = Container(self._context)
            context["_"] = outer
            context["_params"] = outer["_params"]
            context["_io"] = stream
            index = outer.get("_index")
            if index is not None:
                context["_index"] = index
            root = outer.get("_root")
            context["_root"] = context if root is None else root
        elif self._fields_only:
            context = obj  # the fields so far, by name: all that is looked up
        else:
            context = outer  # not looked at
        tell = stream.tell
        start = tell()
        for name, parse, suffix in self._steps:
            try:
                value = parse(stream, context, path + suffix)
            except ConstructError as error:
                partial = getattr(error, "partial", None)
                if name and partial is not None:
                    obj[name] = partial
                    spans[name] = (start, tell())
                error.partial = obj
                error.failed = (name or "data", start)
                raise
            end = tell()
            if name:
                obj[name] = value
                if self._context is not None:
                    context[name] = value
                spans[name] = (start, end)
            start = end
        if self._context is not None and context["_root"] is context:
            # Parsing is done: drop the context's reference to itself, so that it is freed
            # at once rather than left to the cycle collector.
            context["_root"] = None
        return obj


PARSE_CONTEXT: Any = Container(_parsing=True, _building=False, _sizing=False)
"""The outermost context of a parse, as `parse_stream` makes it. A Record never writes
to the context it is given (its fields go into its own), so one serves every parse."""
PARSE_CONTEXT["_params"] = PARSE_CONTEXT


def parse_body(schema: Any, stream: Any) -> Any:
    """`schema.parse_stream(stream)` for a Record (which has no `parsed` hook), without
    building the outer context each time: the Record reads from the stream's position on."""
    if schema.parsed is not None:
        return schema._parsereport(stream, PARSE_CONTEXT, "(parsing)")
    return schema._parse(stream, PARSE_CONTEXT, "(parsing)")


class Repeat(Subconstruct):  # type: ignore[misc]  # construct is untyped
    """`subcon` repeated `count` times, or for as long as it stays within `within` bytes
    (both may be `this` expressions; negative counts mean none). A truncated item keeps
    the items before it in the error's `partial`."""

    def __init__(self, subcon: Any, *, count: Any = None, within: Any = None) -> None:
        super().__init__(subcon)
        self.count = count
        self.within = within

    def _parse(self, stream: Any, context: Any, path: Any) -> Any:
        items = ListContainer()
        start = stream.tell()
        limit = None if self.within is None else start + evaluate(self.within, context)
        count = None if self.count is None else evaluate(self.count, context)
        index = 0
        while (count is None or index < count) and (limit is None or stream.tell() < limit):
            context._index = index
            before = stream.tell()
            try:
                items.append(self.subcon._parsereport(stream, context, path))
            except ConstructError as error:
                partial = getattr(error, "partial", None)
                if partial is not None:
                    items.append(partial)
                error.partial = items
                raise
            if stream.tell() == before:  # an empty item would repeat forever
                break
            index += 1
        return items

    def _build(self, obj: Any, stream: Any, context: Any, path: Any) -> Any:
        built = ListContainer()
        for index, item in enumerate(obj):
            context._index = index
            built.append(self.subcon._build(item, stream, context, path))
        return built

    def _sizeof(self, context: Any, path: Any) -> int:
        raise SizeofError("a repeat has no fixed size", path=path)


def _field_named_by(expression: Any) -> str | None:
    """The field name when `expression` is just `this.name` (which evaluates to
    `context[name]`), else None."""
    if type(expression) is not Path:
        return None
    name = expression.__getfield__()
    return name if isinstance(name, str) and repr(expression) == f"this[{name!r}]" else None


class Octets(Construct):  # type: ignore[misc]  # construct is untyped
    """`length` raw bytes (a `this` expression; negative means 0). With `exact`, fewer
    bytes than that is an error (the frame is truncated); without, it takes what there
    is, so a byte count that promises more than the frame holds still shows the data."""

    def __init__(self, length: Any, *, exact: bool = False) -> None:
        super().__init__()
        self.length = length
        self.exact = exact
        self.named = _field_named_by(length)

    def _parse(self, stream: Any, context: Any, path: Any) -> Any:
        if self.named is not None:  # this.name: the value of that field, looked up at once
            length = context[self.named]
        else:
            length = self.length(context) if callable(self.length) else self.length
        length = max(0, length)
        data = stream.read(length)
        if self.exact and len(data) != length:
            raise StreamError(f"expected {length} bytes, found {len(data)}", path=path)
        return data

    def _build(self, obj: Any, stream: Any, context: Any, path: Any) -> Any:
        data = bytes(obj)
        stream_write(stream, data, len(data), path)
        return data

    def _sizeof(self, context: Any, path: Any) -> int:
        raise SizeofError("octets have no fixed size", path=path)


class WordValues(tuple[int, ...]):
    """16-bit words, big-endian on the wire, as the `Words` adapter decodes them."""

    __slots__ = ()


class BitValues(tuple[int, ...]):
    """Bits (0 or 1) in address order, as the `Bits` adapter decodes them."""

    __slots__ = ()


_WORD_FORMATS = tuple(struct.Struct(f">{n}H") for n in range(129))


class _Packed(Adapter):  # type: ignore[misc]  # construct is untyped
    """An Adapter that parses its subcon by `_parse` when it has no `parsed` hook."""

    def _parse(self, stream: Any, context: Any, path: Any) -> Any:
        subcon = self.subcon
        if subcon.parsed is None:
            return self._decode(subcon._parse(stream, context, path), context, path)
        return self._decode(subcon._parsereport(stream, context, path), context, path)


class Words(_Packed):
    """Bytes as big-endian 16-bit words (an odd last byte is left out: a problem to report,
    not an error)."""

    def _decode(self, obj: Any, context: Any, path: Any) -> WordValues:
        n = len(obj) // 2
        unpack = _WORD_FORMATS[n] if n < len(_WORD_FORMATS) else struct.Struct(f">{n}H")
        return WordValues(unpack.unpack_from(obj))

    def _encode(self, obj: Any, context: Any, path: Any) -> bytes:
        return struct.pack(f">{len(obj)}H", *obj)


_BYTE_BITS = tuple(bytes((byte >> bit) & 1 for bit in range(8)) for byte in range(256))
"""The eight bits of each byte value, least significant first, as bytes of 0 and 1."""


class Bits(_Packed):
    """Packed coil or input bits: the first bit is the least significant bit of the first
    byte. Decodes every bit of every byte; the quantity the request asked for says how
    many of them are real."""

    def _decode(self, obj: Any, context: Any, path: Any) -> BitValues:
        return BitValues(b"".join([_BYTE_BITS[byte] for byte in obj]))

    def _encode(self, obj: Any, context: Any, path: Any) -> bytes:
        bits = list(obj)
        out = bytearray((len(bits) + 7) // 8)
        for index, bit in enumerate(bits):
            if bit:
                out[index // 8] |= 1 << (index % 8)
        return bytes(out)


# --- schemas, one per distinct layout ------------------------------------------------------

_ADDRESS_QUANTITY = Record("address" / UInt16, "quantity" / UInt16)
_EMPTY = Record()
_BITS_RESPONSE = Record(
    "byte_count" / UInt8,
    "values" / Bits(Octets(this.byte_count)),
)
_REGISTERS_RESPONSE = Record(
    "byte_count" / UInt8,
    "values" / Words(Octets(this.byte_count)),
)
_ADDRESS_VALUE = Record("address" / UInt16, "value" / UInt16)
_EXCEPTION_STATUS_RESPONSE = Record("status" / UInt8)
_DIAGNOSTICS = Record("sub_function" / UInt16, "data" / Words(GreedyBytes))
_EVENT_COUNTER_RESPONSE = Record("status" / UInt16, "event_count" / UInt16)
_EVENT_LOG_RESPONSE = Record(
    "byte_count" / UInt8,
    "status" / UInt16,
    "event_count" / UInt16,
    "message_count" / UInt16,
    "events" / Octets(this.byte_count - 6),
)
_WRITE_COILS_REQUEST = Record(
    "address" / UInt16,
    "quantity" / UInt16,
    "byte_count" / UInt8,
    "values" / Bits(Octets(this.byte_count)),
)
_WRITE_REGISTERS_REQUEST = Record(
    "address" / UInt16,
    "quantity" / UInt16,
    "byte_count" / UInt8,
    "values" / Words(Octets(this.byte_count)),
)
_SERVER_ID_RESPONSE = Record(
    "byte_count" / UInt8,
    "server_id" / Bytes(1),  # device specific; one byte is what devices and pymodbus send
    "run_indicator" / UInt8,
    "additional" / Octets(this.byte_count - 2),
)
FILE_REFERENCE_TYPE = 6
"""The only reference type the spec defines for file record sub-requests (FC 20, 21)."""

LAST_FILE_RECORD = 9999
"""Record numbers in a file run from 0 to 9999 (0x270F)."""

_FILE_READ_ITEM = Record(
    "reference_type" / UInt8,
    "file_number" / UInt16,
    "record_number" / UInt16,
    "record_length" / UInt16,
)
_FILE_READ_REQUEST = Record(
    "byte_count" / UInt8,
    "sub_requests" / Repeat(_FILE_READ_ITEM, count=this.byte_count // 7),
)
_FILE_READ_RESPONSE = Record(
    "byte_count" / UInt8,
    "sub_responses"
    / Repeat(
        Record(
            "length" / UInt8,
            "reference_type" / UInt8,
            "record_data" / Words(Octets(this.length - 1, exact=True)),
        ),
        within=this.byte_count,
    ),
)
_FILE_WRITE = Record(
    "byte_count" / UInt8,
    "sub_requests"
    / Repeat(
        Record(
            "reference_type" / UInt8,
            "file_number" / UInt16,
            "record_number" / UInt16,
            "record_length" / UInt16,
            "record_data" / Words(Octets(this.record_length * 2, exact=True)),
        ),
        within=this.byte_count,
    ),
)
_MASK_WRITE = Record("address" / UInt16, "and_mask" / UInt16, "or_mask" / UInt16)
_READ_WRITE_REQUEST = Record(
    "read_address" / UInt16,
    "read_quantity" / UInt16,
    "write_address" / UInt16,
    "write_quantity" / UInt16,
    "byte_count" / UInt8,
    "values" / Words(Octets(this.byte_count)),
)
_FIFO_REQUEST = Record("fifo_address" / UInt16)
_FIFO_RESPONSE = Record(
    "byte_count" / UInt16,
    "fifo_count" / UInt16,
    "values" / Words(Octets(this.fifo_count * 2)),
)
MEI_DEVICE_ID = 0x0E
MEI_CANOPEN = 0x0D
_IS_DEVICE_ID = this.mei_type == MEI_DEVICE_ID
_NOT_DEVICE_ID = this.mei_type != MEI_DEVICE_ID
_MEI_REQUEST = Record(
    "mei_type" / UInt8,
    "read_device_id_code" / If(_IS_DEVICE_ID, UInt8),
    "object_id" / If(_IS_DEVICE_ID, UInt8),
    "data" / If(_NOT_DEVICE_ID, GreedyBytes),  # MEI 13 CANopen and others: raw
)
_MEI_RESPONSE = Record(
    "mei_type" / UInt8,
    "read_device_id_code" / If(_IS_DEVICE_ID, UInt8),
    "conformity_level" / If(_IS_DEVICE_ID, UInt8),
    "more_follows" / If(_IS_DEVICE_ID, UInt8),
    "next_object_id" / If(_IS_DEVICE_ID, UInt8),
    "number_of_objects" / If(_IS_DEVICE_ID, UInt8),
    "objects"
    / If(
        _IS_DEVICE_ID,
        Repeat(
            Record(
                "object_id" / UInt8,
                "length" / UInt8,
                "value" / Octets(this.length, exact=True),
            ),
            count=this.number_of_objects,
        ),
    ),
    "data" / If(_NOT_DEVICE_ID, GreedyBytes),
)

EXCEPTION_SCHEMA: Any = Record("exception_code" / UInt8)
"""An exception response (function | 0x80): one exception code byte."""

RAW_SCHEMA: Any = Record("data" / GreedyBytes)
"""Any function code modscope has no layout for: the data as it is."""


# --- names ----------------------------------------------------------------------------------

FUNCTION_CLASSES: dict[str, str] = {
    "public": "public",
    "user": "user-defined",
    "reserved": "reserved",
    "unknown": "unknown",
}
"""What each function code class is called in plain text."""

EXCEPTION_CODES: dict[int, str] = {
    0x01: "illegal function",
    0x02: "illegal data address",
    0x03: "illegal data value",
    0x04: "server device failure",
    0x05: "acknowledge",
    0x06: "server device busy",
    0x08: "memory parity error",
    0x0A: "gateway path unavailable",
    0x0B: "gateway target device failed to respond",
}
"""The standard exception codes."""


def exception_name(code: int) -> str:
    """The standard name of an exception code, or "unknown exception"."""
    return EXCEPTION_CODES.get(code, "unknown exception")


@dataclass(frozen=True, slots=True)
class SubFunction:
    """One FC 8 diagnostics sub-function: its name, the request data the spec allows
    (None: any), and what the response carries: `echo` (the request again), `count`
    (a counter), `register` (the diagnostic register) or `none` (no response)."""

    code: int
    name: str
    request_data: tuple[int, ...] | None = (0x0000,)
    answer: str = "echo"


DIAGNOSTIC_SUB_FUNCTIONS: dict[int, SubFunction] = {
    sub.code: sub
    for sub in (
        SubFunction(0x00, "return query data", request_data=None),
        SubFunction(0x01, "restart communications option", request_data=(0x0000, 0xFF00)),
        SubFunction(0x02, "return diagnostic register", answer="register"),
        SubFunction(0x03, "change ASCII input delimiter", request_data=None),
        SubFunction(0x04, "force listen only mode", answer="none"),
        SubFunction(0x0A, "clear counters and diagnostic register"),
        SubFunction(0x0B, "return bus message count", answer="count"),
        SubFunction(0x0C, "return bus communication error count", answer="count"),
        SubFunction(0x0D, "return bus exception error count", answer="count"),
        SubFunction(0x0E, "return server message count", answer="count"),
        SubFunction(0x0F, "return server no response count", answer="count"),
        SubFunction(0x10, "return server NAK count", answer="count"),
        SubFunction(0x11, "return server busy count", answer="count"),
        SubFunction(0x12, "return bus character overrun count", answer="count"),
        SubFunction(0x14, "clear overrun counter and flag"),
    )
}
"""The FC 8 sub-functions the spec defines; every other sub-function code is reserved."""

MEI_TYPES: dict[int, str] = {
    MEI_CANOPEN: "CANopen general reference",
    MEI_DEVICE_ID: "read device identification",
}
"""FC 43 MEI types."""

READ_DEVICE_ID_CODES: dict[int, str] = {
    0x01: "basic",
    0x02: "regular",
    0x03: "extended",
    0x04: "one object",
}
"""FC 43 / MEI 14 read device id codes: which stream, or one specific object."""

CONFORMITY_LEVELS: dict[int, str] = {
    0x01: "basic, stream only",
    0x02: "regular, stream only",
    0x03: "extended, stream only",
    0x81: "basic, stream and individual",
    0x82: "regular, stream and individual",
    0x83: "extended, stream and individual",
}
"""FC 43 / MEI 14 conformity levels."""

DEVICE_ID_OBJECTS: dict[int, str] = {
    0x00: "VendorName",
    0x01: "ProductCode",
    0x02: "MajorMinorRevision",
    0x03: "VendorUrl",
    0x04: "ProductName",
    0x05: "ModelName",
    0x06: "UserApplicationName",
}
"""FC 43 / MEI 14 standard object names; 0x07-0x7F are reserved, 0x80-0xFF private."""


def device_object_name(object_id: int) -> str:
    """The name of a device identification object: standard, `private 0x80`, or
    `reserved 0x07`."""
    name = DEVICE_ID_OBJECTS.get(object_id)
    if name is not None:
        return name
    return f"{'private' if object_id >= 0x80 else 'reserved'} 0x{object_id:02X}"


@dataclass(frozen=True, slots=True)
class Limit:
    """The legal range of a quantity field, wherever it appears in the code's frames."""

    field: str
    low: int
    high: int


def _u16(frame: Buffer, pos: int) -> int:
    return int(frame[pos]) << 8 | int(frame[pos + 1])


@dataclass(frozen=True, slots=True)
class AnswerRule:
    """The exact length of the normal answer to a given request.

    `base + (quantity * per_item + round_up) // per_byte`, where quantity is the 16-bit
    value at `quantity_pos` of the request; `quantity_pos` = FIXED gives `base` alone,
    ECHO the request's own length; `walker` reads requests no formula describes.
    """

    base: int
    quantity_pos: int = -1
    per_item: int = 1
    round_up: int = 0
    per_byte: int = 1
    walker: Callable[[Buffer], int | None] | None = None

    FIXED: ClassVar[int] = -1
    ECHO: ClassVar[int] = -2

    def length(self, req: Buffer) -> int | None:
        """Answer length for request frame `req` (CRC included), None if unknown."""
        if self.walker is not None:
            return self.walker(req)
        if self.quantity_pos == AnswerRule.FIXED:
            return self.base
        if self.quantity_pos == AnswerRule.ECHO:
            return len(req)
        pos = self.quantity_pos
        if len(req) < pos + 2:
            return None
        quantity = int(req[pos]) << 8 | int(req[pos + 1])
        return self.base + (quantity * self.per_item + self.round_up) // self.per_byte


BITS_ANSWER = AnswerRule(5, quantity_pos=4, round_up=7, per_byte=8)
REGISTERS_ANSWER = AnswerRule(5, quantity_pos=4, per_item=2)
ECHO_ANSWER = AnswerRule(0, quantity_pos=AnswerRule.ECHO)


def _file_read_response(req: Buffer) -> int | None:
    # request: addr fc bytecount, then 7-byte sub-requests (ref type, file, record, length)
    if len(req) < 5:
        return None
    count = req[2]
    total = 0
    pos = 3
    end = min(len(req) - 2, 3 + count)
    while pos + 7 <= end:
        total += 2 + 2 * _u16(req, pos + 5)
        pos += 7
    return 5 + total if total else None


def _walk_device_id(buf: Buffer, start: int, end: int) -> int:
    """Length of a FC 43 frame: MEI 14 requests are 7 bytes; MEI 14 responses carry a
    list of objects (id, length, value); other MEI types are bounded by silence only."""
    if start + 3 > end:
        return NEED_MORE
    mei = buf[start + 2]
    if mei != 0x0E:
        return IMPOSSIBLE
    # response: addr fc mei code conformity more next count (id len value)* crc
    if start + 8 > end:
        return NEED_MORE
    count = buf[start + 7]
    pos = start + 8
    for _ in range(count):
        if pos + 2 > end:
            return NEED_MORE
        pos += 2 + buf[pos + 1]
    length = pos + 2 - start
    return length if length <= 256 else IMPOSSIBLE


def _walk_device_id_request(buf: Buffer, start: int, end: int) -> int:
    if start + 3 > end:
        return NEED_MORE
    return 7 if buf[start + 2] == 0x0E else IMPOSSIBLE


@dataclass(frozen=True, slots=True)
class FunctionSpec:
    """Everything modscope knows about one function code.

    `request_schema` and `response_schema` are interpreted construct schemas for the
    data after the function code (the same object when both directions share a layout).
    `family` names the dissection routine that gives the parsed fields their meaning,
    `table` the data table the code reads or writes, `limits` the legal quantities.
    """

    code: int
    name: str
    klass: str = "public"  # public | user | reserved | unknown
    request_length: LengthRule | None = None
    response_length: LengthRule | None = None
    answer: AnswerRule | None = None  # the normal answer's length, from the request
    echo: bool = False  # the normal response repeats the request byte for byte
    request_schema: Any = None
    response_schema: Any = None
    family: str = "raw"
    table: str | None = None  # coils | discrete_inputs | input_registers | holding_registers
    limits: tuple[Limit, ...] = ()


_SPECS: tuple[FunctionSpec, ...] = (
    FunctionSpec(
        1,
        "Read Coils",
        request_length=fixed(8),
        response_length=counted(2, 5),
        answer=BITS_ANSWER,
        request_schema=_ADDRESS_QUANTITY,
        response_schema=_BITS_RESPONSE,
        family="read",
        table="coils",
        limits=(Limit("quantity", 1, 2000),),
    ),
    FunctionSpec(
        2,
        "Read Discrete Inputs",
        request_length=fixed(8),
        response_length=counted(2, 5),
        answer=BITS_ANSWER,
        request_schema=_ADDRESS_QUANTITY,
        response_schema=_BITS_RESPONSE,
        family="read",
        table="discrete_inputs",
        limits=(Limit("quantity", 1, 2000),),
    ),
    FunctionSpec(
        3,
        "Read Holding Registers",
        request_length=fixed(8),
        response_length=counted(2, 5),
        answer=REGISTERS_ANSWER,
        request_schema=_ADDRESS_QUANTITY,
        response_schema=_REGISTERS_RESPONSE,
        family="read",
        table="holding_registers",
        limits=(Limit("quantity", 1, 125),),
    ),
    FunctionSpec(
        4,
        "Read Input Registers",
        request_length=fixed(8),
        response_length=counted(2, 5),
        answer=REGISTERS_ANSWER,
        request_schema=_ADDRESS_QUANTITY,
        response_schema=_REGISTERS_RESPONSE,
        family="read",
        table="input_registers",
        limits=(Limit("quantity", 1, 125),),
    ),
    FunctionSpec(
        5,
        "Write Single Coil",
        request_length=fixed(8),
        response_length=fixed(8),
        answer=ECHO_ANSWER,
        echo=True,
        request_schema=_ADDRESS_VALUE,
        response_schema=_ADDRESS_VALUE,
        family="write_single",
        table="coils",
    ),
    FunctionSpec(
        6,
        "Write Single Register",
        request_length=fixed(8),
        response_length=fixed(8),
        answer=ECHO_ANSWER,
        echo=True,
        request_schema=_ADDRESS_VALUE,
        response_schema=_ADDRESS_VALUE,
        family="write_single",
        table="holding_registers",
    ),
    FunctionSpec(
        7,
        "Read Exception Status",
        request_length=fixed(4),
        response_length=fixed(5),
        answer=AnswerRule(5),
        request_schema=_EMPTY,
        response_schema=_EXCEPTION_STATUS_RESPONSE,
        family="exception_status",
    ),
    FunctionSpec(
        8,
        "Diagnostics",
        request_length=fixed(8),
        response_length=fixed(8),
        answer=ECHO_ANSWER,
        echo=True,
        request_schema=_DIAGNOSTICS,
        response_schema=_DIAGNOSTICS,
        family="diagnostics",
    ),
    FunctionSpec(
        11,
        "Get Comm Event Counter",
        request_length=fixed(4),
        response_length=fixed(8),
        answer=AnswerRule(8),
        request_schema=_EMPTY,
        response_schema=_EVENT_COUNTER_RESPONSE,
        family="event_counter",
    ),
    FunctionSpec(
        12,
        "Get Comm Event Log",
        request_length=fixed(4),
        response_length=counted(2, 5),
        request_schema=_EMPTY,
        response_schema=_EVENT_LOG_RESPONSE,
        family="event_log",
    ),
    FunctionSpec(
        15,
        "Write Multiple Coils",
        request_length=counted(6, 9),
        response_length=fixed(8),
        answer=AnswerRule(8),
        request_schema=_WRITE_COILS_REQUEST,
        response_schema=_ADDRESS_QUANTITY,
        family="write_multiple",
        table="coils",
        limits=(Limit("quantity", 1, 1968),),
    ),
    FunctionSpec(
        16,
        "Write Multiple Registers",
        request_length=counted(6, 9),
        response_length=fixed(8),
        answer=AnswerRule(8),
        request_schema=_WRITE_REGISTERS_REQUEST,
        response_schema=_ADDRESS_QUANTITY,
        family="write_multiple",
        table="holding_registers",
        limits=(Limit("quantity", 1, 123),),
    ),
    FunctionSpec(
        17,
        "Report Server ID",
        request_length=fixed(4),
        response_length=counted(2, 5),
        request_schema=_EMPTY,
        response_schema=_SERVER_ID_RESPONSE,
        family="server_id",
    ),
    FunctionSpec(
        20,
        "Read File Record",
        request_length=counted(2, 5),
        response_length=counted(2, 5),
        answer=AnswerRule(0, walker=_file_read_response),
        request_schema=_FILE_READ_REQUEST,
        response_schema=_FILE_READ_RESPONSE,
        family="file_read",
    ),
    FunctionSpec(
        21,
        "Write File Record",
        request_length=counted(2, 5),
        response_length=counted(2, 5),
        answer=ECHO_ANSWER,
        echo=True,
        request_schema=_FILE_WRITE,
        response_schema=_FILE_WRITE,
        family="file_write",
    ),
    FunctionSpec(
        22,
        "Mask Write Register",
        request_length=fixed(10),
        response_length=fixed(10),
        answer=ECHO_ANSWER,
        echo=True,
        request_schema=_MASK_WRITE,
        response_schema=_MASK_WRITE,
        family="mask_write",
        table="holding_registers",
    ),
    FunctionSpec(
        23,
        "Read/Write Multiple Registers",
        request_length=counted(10, 13),
        response_length=counted(2, 5),
        answer=REGISTERS_ANSWER,
        request_schema=_READ_WRITE_REQUEST,
        response_schema=_REGISTERS_RESPONSE,
        family="read_write",
        table="holding_registers",
        limits=(Limit("read_quantity", 1, 125), Limit("write_quantity", 1, 121)),
    ),
    FunctionSpec(
        24,
        "Read FIFO Queue",
        request_length=fixed(6),
        response_length=counted(2, 6, size=2),
        request_schema=_FIFO_REQUEST,
        response_schema=_FIFO_RESPONSE,
        family="fifo",
        table="holding_registers",
        limits=(Limit("fifo_count", 0, 31),),
    ),
    FunctionSpec(
        43,
        "Encapsulated Interface Transport",
        request_length=LengthRule(base=0, walker=_walk_device_id_request),
        response_length=LengthRule(base=0, walker=_walk_device_id),
        request_schema=_MEI_REQUEST,
        response_schema=_MEI_RESPONSE,
        family="mei",
    ),
)

FUNCTIONS: dict[int, FunctionSpec] = {spec.code: spec for spec in _SPECS}
"""Every function code modscope knows, by code (without the exception bit)."""

EXCEPTION_LENGTH = 5
"""An exception response: address, function | 0x80, exception code, CRC."""


def function_class(code: int) -> str:
    """public, user (65-72, 100-110), reserved, or unknown, for a code without 0x80."""
    if code in FUNCTIONS:
        return FUNCTIONS[code].klass
    if 65 <= code <= 72 or 100 <= code <= 110:
        return "user"
    if code in (9, 10, 13, 14, 41, 42, 90, 125, 126, 127):
        return "reserved"
    return "unknown"


def function_name(code: int) -> str:
    """A readable name for any function code (without the exception bit)."""
    spec = FUNCTIONS.get(code)
    if spec is not None:
        return spec.name
    klass = function_class(code)
    return {"user": "User-defined", "reserved": "Reserved"}.get(klass, "Unknown") + f" {code}"
