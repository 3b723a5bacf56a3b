"""Provides the frozen values a device dictionary is made of: spaces, entries, parameters."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

TABLES = ("coils", "discrete_inputs", "input_registers", "holding_registers")
BIT_TABLES = frozenset({"coils", "discrete_inputs"})
REGISTER_TABLES = frozenset({"input_registers", "holding_registers"})
INPUT_TABLES = frozenset({"discrete_inputs", "input_registers"})
TABLE_NAMES: Mapping[str, str] = MappingProxyType(
    {
        "coils": "coils",
        "coil": "coils",
        "discrete_inputs": "discrete_inputs",
        "discrete": "discrete_inputs",
        "input_registers": "input_registers",
        "input": "input_registers",
        "holding_registers": "holding_registers",
        "holding": "holding_registers",
    }
)

WORD_ORDERS: Mapping[str, str] = MappingProxyType(
    {
        "high_first": "high_first",
        "low_first": "low_first",
        "high_first_swapped": "high_first_swapped",
        "low_first_swapped": "low_first_swapped",
        "ABCD": "high_first",
        "CDAB": "low_first",
        "BADC": "high_first_swapped",
        "DCBA": "low_first_swapped",
    }
)
WORD_ORDER_LETTERS: Mapping[str, str] = MappingProxyType(
    {
        "high_first": "ABCD",
        "low_first": "CDAB",
        "high_first_swapped": "BADC",
        "low_first_swapped": "DCBA",
    }
)

ACCESS = ("r", "w", "rw")
MODEL_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]*\Z")


@dataclass(frozen=True, slots=True)
class TypeInfo:
    """What a value type is made of: registers, kind of value, signedness, bits."""

    name: str
    words: int  # registers it occupies; 0 for str, whose `length` decides
    kind: str  # "int" | "float" | "str" | "bool"
    signed: bool
    bits: int


TYPES: Mapping[str, TypeInfo] = MappingProxyType(
    {
        info.name: info
        for info in (
            TypeInfo("bool", 1, "bool", False, 1),
            TypeInfo("u8", 1, "int", False, 8),
            TypeInfo("s8", 1, "int", True, 8),
            TypeInfo("u16", 1, "int", False, 16),
            TypeInfo("s16", 1, "int", True, 16),
            TypeInfo("u32", 2, "int", False, 32),
            TypeInfo("s32", 2, "int", True, 32),
            TypeInfo("u64", 4, "int", False, 64),
            TypeInfo("s64", 4, "int", True, 64),
            TypeInfo("f32", 2, "float", True, 32),
            TypeInfo("f64", 4, "float", True, 64),
            TypeInfo("str", 0, "str", False, 0),
        )
    }
)

EMPTY_NAMES: Mapping[int, str] = MappingProxyType({})


def no_names() -> Mapping[int, str]:
    """The empty, read-only name table (a dataclass default)."""
    return EMPTY_NAMES


def canonical_table(name: str) -> str:
    """The long table name for any accepted spelling; ValueError for anything else."""
    try:
        return TABLE_NAMES[name]
    except KeyError:
        known = ", ".join(TABLES)
        raise ValueError(f"unknown Modbus table {name!r}: use one of {known}") from None


@dataclass(frozen=True, slots=True)
class FlagBit:
    """A bit that qualifies a value: the word shown when it is clear and when it is set."""

    clear: str = ""
    set: str = ""


@dataclass(frozen=True, slots=True)
class ValueSpec:
    """How to turn the raw words (or bit) of one value into a number, name or text."""

    type: str = "u16"
    byte: str | None = None  # "high" | "low" for u8/s8
    bit: int | None = None
    width: int = 1
    length: int = 0  # str: registers
    word_order: str = "high_first"
    scale: int | float = 1
    offset: int | float = 0
    precision: int | None = None
    unit: str = ""
    sign_bit: int | None = None
    flag_bits: Mapping[int, FlagBit] = field(default_factory=lambda: MappingProxyType({}))
    enum: Mapping[int, str] = field(default_factory=no_names)
    special: Mapping[int, str] = field(default_factory=no_names)  # named raw values, no enum
    bits: Mapping[int, str] = field(default_factory=no_names)
    min: int | float | None = None
    max: int | float | None = None
    default: int | float | str | bool | None = None
    access: str = "rw"
    description: str = ""
    notes: tuple[str, ...] = ()

    @property
    def size(self) -> int:
        """Registers (or bits, in the bit tables) the value occupies."""
        if self.type == "str":
            return self.length
        return TYPES[self.type].words

    @property
    def raw_bits(self) -> int:
        """Width of the raw integer the value is read from (a field's width for `bit`)."""
        if self.bit is not None:
            return self.width
        return TYPES[self.type].bits

    @property
    def is_flag(self) -> bool:
        """A single bit shown as on/off (a coil, an input, or one bit of a register)."""
        return self.type == "bool"

    @property
    def scaled(self) -> bool:
        return self.scale != 1 or self.offset != 0 or isinstance(self.scale, float)

    def type_text(self) -> str:
        """The type as `describe` shows it: `u16`, `bit 3`, `bits 4-7`, `u8 high`, `f32 CDAB`."""
        if self.bit is not None:
            if self.width == 1:
                return f"bit {self.bit}"
            return f"bits {self.bit}-{self.bit + self.width - 1}"
        text = self.type
        if self.byte is not None:
            text += f" {self.byte}"
        elif self.type == "str":
            text += f"[{self.length}]"
        wide = TYPES[self.type].words > 1 or self.word_order != "high_first"
        if wide and self.type not in ("bool", "u8", "s8"):
            text += f" {WORD_ORDER_LETTERS[self.word_order]}"
        if self.scaled:
            text += f"*{self.scale:g}" if self.scale != 1 else ""
            text += f"{self.offset:+g}" if self.offset else ""
        return text


@dataclass(frozen=True, slots=True)
class Entry:
    """One named value at a place in one table."""

    table: str
    address: int  # PDU address of the first element
    name: str
    spec: ValueSpec
    ref: str = ""  # the place as the manual writes it
    line: int | None = None

    @property
    def size(self) -> int:
        return self.spec.size

    @property
    def end(self) -> int:
        """One past the last element."""
        return self.address + self.spec.size

    @property
    def type(self) -> str:
        return self.spec.type

    @property
    def unit(self) -> str:
        return self.spec.unit

    @property
    def access(self) -> str:
        return self.spec.access


@dataclass(frozen=True, slots=True)
class Parameter:
    """One parameter of a stateful window, selected by its number."""

    number: int
    name: str
    spec: ValueSpec
    line: int | None = None


@dataclass(frozen=True, slots=True)
class Space:
    """One way the manual writes numbers that land in one table."""

    name: str
    table: str
    prefix: str = ""
    suffix: str = ""
    radix: int = 10
    first: int = 0
    pdu: int = 0
    bit_first: int = 0
    width: int | None = None

    def match(self, ref: str) -> RefMatch | None:
        """How this space reads `ref`, or None when the ref is not written its way."""
        text = ref.strip()
        if not text.lower().startswith(self.prefix.lower()):
            return None
        body = text[len(self.prefix) :]
        bit: int | None = None
        head, dot, tail = body.rpartition(".")
        if dot:
            if not tail.isdigit() or not head:
                return None
            body, bit = head, _bounded_int(tail, 10) - self.bit_first
        if self.suffix:
            if not body.lower().endswith(self.suffix.lower()):
                return None
            body = body[: len(body) - len(self.suffix)]
        digits = "0123456789abcdef"[: self.radix]
        if not body or any(char not in digits for char in body.lower()):
            return None
        if self.width is not None and len(body) != self.width:
            return None
        number = _bounded_int(body, self.radix)
        address = self.pdu + number - self.first
        return RefMatch(self, address, bit, len(self.prefix), len(self.suffix))

    def format(self, address: int, bit: int | None = None) -> str:
        """The manual's way of writing PDU `address` (and a bit of it)."""
        number = address - self.pdu + self.first
        if number < 0:
            text = f"pdu {address}"
        else:
            digits = f"{number:X}" if self.radix == 16 else str(number)
            if self.width is not None:
                digits = digits.rjust(self.width, "0")
            text = f"{self.prefix}{digits}{self.suffix}"
        if bit is not None:
            text += f".{bit + self.bit_first}"
        return text

    def example(self) -> str:
        """A ref this space parses, for messages."""
        return self.format(self.pdu)


@dataclass(frozen=True, slots=True)
class RefMatch:
    """A ref read by one space: the PDU address (maybe out of range) and bit."""

    space: Space
    address: int
    bit: int | None
    prefix_length: int
    suffix_length: int


@dataclass(frozen=True, slots=True)
class Timing:
    """Device timing rules, in milliseconds."""

    response_ms: int | float | None = None
    long_response_ms: int | float | None = None
    long_response_functions: tuple[int, ...] = ()
    quiet_after_write_ms: int | float | None = None
    quiet_after_functions: tuple[int, ...] = ()


@dataclass(frozen=True, slots=True)
class RegisterValue:
    """One decoded dictionary value, as read or written on the bus."""

    table: str
    address: int
    name: str
    value: int | float | str | bool | None
    unit: str
    text: str
    raw: tuple[int, ...]
    partial: bool = False
    problems: tuple[str, ...] = ()


MAX_REF_DIGITS = 32  # more digits than any register or bit number has (nor needs)


def _bounded_int(digits: str, radix: int) -> int:
    """`digits` read in `radix`; a number longer than MAX_REF_DIGITS (leading zeros
    aside) is read as radix ** MAX_REF_DIGITS, out of every range the caller checks, so
    that a damaged file's thousand-digit ref is refused as out of range (int() would
    raise on a number of more than 4300 digits, and printing one would too)."""
    significant = digits.lstrip("0")
    if len(significant) > MAX_REF_DIGITS:
        return int(radix**MAX_REF_DIGITS)
    return int(significant or "0", radix)
