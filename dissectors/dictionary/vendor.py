"""Provides vendor function layouts and Report Server ID fields, and their byte decoding.

Frames on the bus are not decoded here: `dissectors.pdu.vendor` compiles a dictionary's
functions into the registry, and `dissect()` takes vendor frames apart like any other.
`decode_fields` serves the dictionary's own checks and Report Server ID layouts."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from .decode import plain
from .model import no_names

FIELD_SIZES: Mapping[str, int] = {"u8": 1, "u16": 2, "u32": 4, "bytes": 0}
MAX_BYTES_SHOWN = 32


@dataclass(frozen=True, slots=True)
class VendorField:
    """One field of a vendor frame or of a Report Server ID answer."""

    name: str
    type: str  # "u8" | "u16" | "u32" | "bytes"
    length: int | None = None  # bytes: fixed length; None = the rest of the frame
    enum: Mapping[int, str] = field(default_factory=no_names)
    description: str = ""


@dataclass(frozen=True, slots=True)
class FieldValue:
    """One decoded field, with its byte span inside the data it came from."""

    name: str
    value: int | bytes | str | None
    text: str
    start: int
    end: int


@dataclass(frozen=True, slots=True)
class FieldsDecoded:
    """Fields decoded from data, and what did not fit the layout."""

    fields: tuple[FieldValue, ...]
    problems: tuple[str, ...]


def decode_fields(layout: Sequence[VendorField], data: bytes) -> FieldsDecoded:
    """Decode `data` (the bytes after the function code, before the check) by `layout`."""
    out: list[FieldValue] = []
    problems: list[str] = []
    pos = 0
    for spec in layout:
        size = FIELD_SIZES.get(spec.type, 0)
        if spec.type == "bytes":  # without length: the rest (only the last field may)
            size = spec.length if spec.length is not None else max(0, len(data) - pos)
        chunk = data[pos : pos + size]
        if len(chunk) < size:
            problems.append(f"'{spec.name}' needs {size} bytes, only {len(chunk)} present")
            out.append(
                FieldValue(spec.name, None, f"{spec.name} = ? (cut short)", pos, pos + len(chunk))
            )
            pos += len(chunk)
            break
        if spec.type == "bytes":
            shown = chunk[:MAX_BYTES_SHOWN].hex(" ").upper() if chunk else "(none)"
            if len(chunk) > MAX_BYTES_SHOWN:
                shown += f" … ({len(chunk)} bytes)"
            out.append(
                FieldValue(spec.name, bytes(chunk), f"{spec.name} = {shown}", pos, pos + size)
            )
        else:
            number = int.from_bytes(chunk, "big")
            name = spec.enum.get(number)
            digits = size * 2
            if name is not None:
                text = f"{spec.name} = {plain(name)} (0x{number:0{digits}X})"
                out.append(FieldValue(spec.name, name, text, pos, pos + size))
            else:
                text = f"{spec.name} = {number} (0x{number:0{digits}X})"
                if spec.enum:
                    text += " (undocumented)"
                    problems.append(
                        f"'{spec.name}' value {number} is not one of the documented values"
                    )
                out.append(FieldValue(spec.name, number, text, pos, pos + size))
        pos += size
    if pos < len(data):
        problems.append(f"{len(data) - pos} bytes after the last documented field")
    return FieldsDecoded(tuple(out), tuple(problems))


@dataclass(frozen=True, slots=True)
class VendorFunction:
    """A device-specific function code: its name and request/response layouts."""

    code: int
    name: str
    request: tuple[VendorField, ...] = ()
    response: tuple[VendorField, ...] = ()
    broadcast: bool = False
    description: str = ""
    line: int | None = None

    def decode_request(self, data: bytes) -> FieldsDecoded:
        return decode_fields(self.request, data)

    def decode_response(self, data: bytes) -> FieldsDecoded:
        return decode_fields(self.response, data)


@dataclass(frozen=True, slots=True)
class ReportServerId:
    """How a device fills the data of its function 17 answer (after the byte count)."""

    fields: tuple[VendorField, ...]
    line: int | None = None

    def decode(self, data: bytes) -> FieldsDecoded:
        return decode_fields(self.fields, data)
