"""Provides device-specific function codes compiled from a device dictionary's
`[[function]]` tables into the same specs as the public codes: a construct layout per
direction, fixed-length framing rules where the layout has a fixed size, and a meaning
routine that names enumerated values and reports the undocumented ones. `dissect()` then
takes a vendor frame apart like any other: fields with byte spans, named values, problems.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from construct import GreedyBytes

from dissectors.dictionary.decode import plain
from dissectors.dictionary.vendor import VendorField, VendorFunction
from dissectors.pdu.schema import Octets, Record, Unsigned
from dissectors.pdu.spec import AnswerRule, FunctionSpec, fixed
from dissectors.pdu.work import WARNING, Work

_NUMBERS = {"u8": 1, "u16": 2, "u32": 4}


def _construct(field: VendorField) -> Any:
    size = _NUMBERS.get(field.type)
    if size is not None:
        return Unsigned(size)
    if field.length is not None:
        return Octets(field.length, exact=True)
    return GreedyBytes  # the rest of the frame: only the last field may


def _schema(layout: Sequence[VendorField]) -> Any:
    return Record(*(plain(field.name) / _construct(field) for field in layout))


def _rtu_length(layout: Sequence[VendorField]) -> int | None:
    """RTU length of a frame with this layout (unit, function, data, CRC), None if it
    varies."""
    size = 0
    for field in layout:
        if field.type in _NUMBERS:
            size += _NUMBERS[field.type]
        elif field.length is not None:
            size += field.length
        else:
            return None
    return 2 + size + 2


class _Meaning:
    """The meaning routine of one vendor function: names enumerated values, reports the
    values its dictionary does not document, and lists the fields in the summary."""

    __slots__ = ("name", "request", "response")

    def __init__(self, function: VendorFunction) -> None:
        self.name = plain(function.name)
        self.request = tuple((plain(f.name), f) for f in function.request)
        self.response = tuple((plain(f.name), f) for f in function.response)

    def __call__(self, w: Work) -> None:
        parts: list[str] = []
        for name, spec in self.request if w.is_request else self.response:
            found = w.fields.get(name)
            if found is None:
                continue
            value = found.value
            if isinstance(value, int):
                digits = 2 * _NUMBERS.get(spec.type, 1)
                meaning = spec.enum.get(value)
                if meaning is not None:
                    text = f"{plain(meaning)} (0x{value:0{digits}X})"
                else:
                    text = f"{value} (0x{value:0{digits}X})"
                    if spec.enum:
                        w.problem(
                            "undocumented-value",
                            WARNING,
                            f"{name} value {value} is not one of the documented values",
                            found.span,
                        )
                w.retext(name, text)
                parts.append(f"{name} = {text}")
            elif isinstance(value, bytes):
                parts.append(f"{name} = {found.text or '(none)'}")
        w.summary = ", ".join(parts) if parts else self.name


def compile_vendor(function: VendorFunction) -> FunctionSpec:
    """The spec of a device's own function code, from its dictionary entry."""
    request = _rtu_length(function.request)
    response = _rtu_length(function.response)
    return FunctionSpec(
        function.code,
        function.name,
        klass="user",
        request_length=fixed(request) if request is not None else None,
        response_length=fixed(response) if response is not None else None,
        answer=AnswerRule(response) if response is not None else None,
        request_schema=_schema(function.request),
        response_schema=_schema(function.response),
        family="vendor",
        meaning=_Meaning(function),
        broadcast_answered=function.broadcast,
    )
