"""Provides what one function code is, in one frozen object: `FunctionSpec`, with the
framing rules (`LengthRule`, `AnswerRule`) and legal quantities (`Limit`) it holds.

Lengths are RTU frame lengths: address + function + data + 2 CRC bytes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

if TYPE_CHECKING:
    from dissectors.pdu.work import Work

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


@dataclass(frozen=True, slots=True)
class Limit:
    """The legal range of a quantity field, wherever it appears in the code's frames."""

    field: str
    low: int
    high: int


def u16(frame: Buffer, pos: int) -> int:
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


ECHO_ANSWER = AnswerRule(0, quantity_pos=AnswerRule.ECHO)


Meaning = Callable[["Work"], None]
"""A meaning routine: reads meaning into the fields of one parsed frame (names, summary,
the checks a layout cannot express, the register values the frame carries)."""


@dataclass(frozen=True, slots=True)
class FunctionSpec:
    """Everything modscope knows about one function code.

    `request_schema` and `response_schema` are interpreted construct schemas for the
    data after the function code (the same object when both directions share a layout).
    `meaning` is the routine that gives the parsed fields their meaning, `family` its
    name, `table` the data table the code reads or writes, `limits` the legal quantities.
    A spec without `meaning` is dissected as raw data.
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
    meaning: Meaning | None = None
    broadcast_answered: bool = False  # a broadcast request of this code gets an answer
