"""Provides the identification family: FC 43 Encapsulated Interface Transport (MEI 14
Read Device Identification; MEI 13 CANopen and others as raw data), with its layouts,
framing rules, meaning and the device identification tables."""

from __future__ import annotations

from construct import GreedyBytes, If, this

from dissectors.pdu.schema import Octets, Record, Repeat, UInt8
from dissectors.pdu.spec import (
    IMPOSSIBLE,
    NEED_MORE,
    Buffer,
    FunctionSpec,
    LengthRule,
)
from dissectors.pdu.work import INFO, WARNING, Work, plural
from dissectors.values import Field, make_field

MEI_DEVICE_ID = 0x0E
MEI_CANOPEN = 0x0D
_IS_DEVICE_ID = this.mei_type == MEI_DEVICE_ID
_NOT_DEVICE_ID = this.mei_type != MEI_DEVICE_ID
MEI_REQUEST = Record(
    "mei_type" / UInt8,
    "read_device_id_code" / If(_IS_DEVICE_ID, UInt8),
    "object_id" / If(_IS_DEVICE_ID, UInt8),
    "data" / If(_NOT_DEVICE_ID, GreedyBytes),  # MEI 13 CANopen and others: raw
)
MEI_RESPONSE = Record(
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


_MORE_FOLLOWS = {0x00: "no", 0xFF: "yes"}


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


def _object_text(value: bytes) -> str:
    """A device string as text: UTF-8 where it decodes, control characters escaped."""
    text = value.decode("utf-8", errors="backslashreplace")
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode() for c in text)


def mei(w: Work) -> None:
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
        w.summary = f"{mei_name or f'MEI type 0x{mei:02X}'}: {plural(size, 'data byte')}"
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


SPECS: tuple[FunctionSpec, ...] = (
    FunctionSpec(
        43,
        "Encapsulated Interface Transport",
        request_length=LengthRule(base=0, walker=_walk_device_id_request),
        response_length=LengthRule(base=0, walker=_walk_device_id),
        request_schema=MEI_REQUEST,
        response_schema=MEI_RESPONSE,
        family="mei",
        meaning=mei,
    ),
)
"""The identification family's codes."""
