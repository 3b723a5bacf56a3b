"""Provides the function-code registry: one frozen spec per Modbus function code.

Each spec says, in one place, what the code is called, its class (public, user-defined,
reserved), and what a framer needs to predict frame lengths in both directions: the RTU
length of a request, of a normal response, and the exact response length a given
request implies. Construct schemas for request and response live on the same spec.

Lengths are RTU frame lengths: address + function + data + 2 CRC bytes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

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


def _u16(frame: Buffer, pos: int) -> int:
    return int(frame[pos]) << 8 | int(frame[pos + 1])


def _bits_response(req: Buffer) -> int | None:
    if len(req) < 8:
        return None
    quantity = _u16(req, 4)
    return 5 + (quantity + 7) // 8


def _registers_response(req: Buffer) -> int | None:
    if len(req) < 8:
        return None
    return 5 + 2 * _u16(req, 4)


def _same_length(req: Buffer) -> int | None:
    return len(req)


def _read_write_response(req: Buffer) -> int | None:
    if len(req) < 13:
        return None
    return 5 + 2 * _u16(req, 4)


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
    """Everything modscope knows about one function code."""

    code: int
    name: str
    klass: str = "public"  # public | user | reserved | unknown
    request_length: LengthRule | None = None
    response_length: LengthRule | None = None
    response_for: Callable[[Buffer], int | None] | None = None
    echo: bool = False  # the normal response repeats the request byte for byte
    request_schema: Any = None
    response_schema: Any = None


_SPECS: tuple[FunctionSpec, ...] = (
    FunctionSpec(1, "Read Coils", request_length=fixed(8),
                 response_length=counted(2, 5), response_for=_bits_response),
    FunctionSpec(2, "Read Discrete Inputs", request_length=fixed(8),
                 response_length=counted(2, 5), response_for=_bits_response),
    FunctionSpec(3, "Read Holding Registers", request_length=fixed(8),
                 response_length=counted(2, 5), response_for=_registers_response),
    FunctionSpec(4, "Read Input Registers", request_length=fixed(8),
                 response_length=counted(2, 5), response_for=_registers_response),
    FunctionSpec(5, "Write Single Coil", request_length=fixed(8),
                 response_length=fixed(8), response_for=_same_length, echo=True),
    FunctionSpec(6, "Write Single Register", request_length=fixed(8),
                 response_length=fixed(8), response_for=_same_length, echo=True),
    FunctionSpec(7, "Read Exception Status", request_length=fixed(4),
                 response_length=fixed(5), response_for=lambda req: 5),
    FunctionSpec(8, "Diagnostics", request_length=fixed(8),
                 response_length=fixed(8), response_for=_same_length, echo=True),
    FunctionSpec(11, "Get Comm Event Counter", request_length=fixed(4),
                 response_length=fixed(8), response_for=lambda req: 8),
    FunctionSpec(12, "Get Comm Event Log", request_length=fixed(4),
                 response_length=counted(2, 5)),
    FunctionSpec(15, "Write Multiple Coils", request_length=counted(6, 9),
                 response_length=fixed(8), response_for=lambda req: 8),
    FunctionSpec(16, "Write Multiple Registers", request_length=counted(6, 9),
                 response_length=fixed(8), response_for=lambda req: 8),
    FunctionSpec(17, "Report Server ID", request_length=fixed(4),
                 response_length=counted(2, 5)),
    FunctionSpec(20, "Read File Record", request_length=counted(2, 5),
                 response_length=counted(2, 5), response_for=_file_read_response),
    FunctionSpec(21, "Write File Record", request_length=counted(2, 5),
                 response_length=counted(2, 5), response_for=_same_length, echo=True),
    FunctionSpec(22, "Mask Write Register", request_length=fixed(10),
                 response_length=fixed(10), response_for=_same_length, echo=True),
    FunctionSpec(23, "Read/Write Multiple Registers", request_length=counted(10, 13),
                 response_length=counted(2, 5), response_for=_read_write_response),
    FunctionSpec(24, "Read FIFO Queue", request_length=fixed(6),
                 response_length=counted(2, 6, size=2)),
    FunctionSpec(43, "Encapsulated Interface Transport",
                 request_length=LengthRule(base=0, walker=_walk_device_id_request),
                 response_length=LengthRule(base=0, walker=_walk_device_id)),
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
