"""Provides the construct building blocks the function-code layouts are written with.

Schemas parse the PDU after the function code from a stream that holds the whole body
(unit, function, data), so stream positions are byte offsets within the body. They are
interpreted, never compiled: bus data is untrusted, and errors must keep their place.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

from construct import (
    Adapter,
    Bytes,
    Construct,
    ConstructError,
    Container,
    FormatField,
    GreedyBytes,
    ListContainer,
    Path,
    Renamed,
    SizeofError,
    StreamError,
    Struct,
    Subconstruct,
    evaluate,
    stream_write,
)


class Unsigned(FormatField):  # type: ignore[misc]  # construct is untyped
    """A big-endian unsigned integer of 1, 2 or 4 bytes: construct's FormatField (so it
    builds, sizes and compiles as one), parsed with a prepared struct and no helper call.
    Too few bytes raise the StreamError FormatField raises."""

    def __init__(self, size: int) -> None:
        super().__init__(">", {1: "B", 2: "H", 4: "I"}[size])
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
    the fields before it by name (`this.byte_count`), which the parsed fields serve.

    This reaches into construct's private parse hooks (`_parse`, `_parsereport`,
    `_subcons`), which is why construct is pinned below 2.11. construct's public API
    would do it as a Struct with a `Tell` between fields, parsed by `parse`: several
    times slower on a register answer, and a truncated frame would lose the fields read
    before the cut. So the hooks stay; the tests of
    every function code's vectors catch a construct release that changes them."""

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


WORD_FORMATS = tuple(struct.Struct(f">{n}H") for n in range(129))


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
        unpack = WORD_FORMATS[n] if n < len(WORD_FORMATS) else struct.Struct(f">{n}H")
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


RAW_SCHEMA: Any = Record("data" / GreedyBytes)
"""Any function code modscope has no layout for: the data as it is."""
