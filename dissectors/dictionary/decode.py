"""Provides value decoding: raw register words or bits to numbers, names and plain text.

Nothing here raises on device data: any words give a value, a text and maybe problems.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from decimal import Decimal
from typing import NamedTuple

from .model import TYPES, Entry, RegisterValue, ValueSpec

MAX_TEXT = 128  # characters shown of a string that came from a device


def plain(text: str, limit: int = MAX_TEXT) -> str:
    """`text` with control and other unprintable characters escaped, capped at `limit`."""
    out: list[str] = []
    for char in text:
        if char == "\\":
            out.append("\\\\")
        elif char.isprintable():
            out.append(char)
        elif ord(char) < 0x100:
            out.append(f"\\x{ord(char):02x}")
        else:
            out.append(f"\\u{ord(char):04x}")
    joined = "".join(out)
    if len(joined) > limit:
        return joined[: limit - 1] + "…"
    return joined


def device_string(data: bytes) -> str:
    """Characters from a device: up to the first NUL, trailing blanks dropped, escaped."""
    data = data.split(b"\x00", 1)[0].rstrip(b" ")
    return plain(data.decode("latin-1"))


def swap_bytes(word: int) -> int:
    return ((word & 0xFF) << 8) | (word >> 8)


def ordered_words(words: Sequence[int], order: str) -> list[int]:
    """Words rearranged to most significant first, per a word order name."""
    out = list(words)
    if order.startswith("low_first"):
        out.reverse()
    if order.endswith("_swapped"):
        out = [swap_bytes(word) for word in out]
    return out


def combine(words: Sequence[int], order: str) -> int:
    """The unsigned integer that `words` (as read, in address order) hold."""
    value = 0
    for word in ordered_words(words, order):
        value = (value << 16) | word
    return value


def to_signed(value: int, bits: int) -> int:
    if value & (1 << (bits - 1)):
        return value - (1 << bits)
    return value


def number_text(value: int | float) -> str:
    """A limit or enum key as a person would write it: 600, 0.5, 1e-05."""
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, int):
        return str(value)
    if math.isnan(value):
        return "NaN"
    return repr(value)


def decimals_of(value: int | float) -> int:
    """Decimal places a scale or offset is written with (0.01 -> 2, 1.0 -> 1, 10 -> 0)."""
    if isinstance(value, int) or not math.isfinite(value):
        return 0
    exponent = Decimal(repr(value)).as_tuple().exponent
    return min(max(0, -exponent), 10) if isinstance(exponent, int) else 0


class Shown(NamedTuple):
    """A number as decoded and as text (without unit)."""

    value: int | float
    text: str


def float_text(value: float, digits: int) -> Shown:
    """A float rounded to `digits` significant digits, and its text (400.0, 0.95, NaN)."""
    if math.isnan(value):
        return Shown(value, "NaN")
    if math.isinf(value):
        return Shown(value, "inf" if value > 0 else "-inf")
    rounded = float(f"{value:.{digits}g}")
    if rounded == 0:
        rounded = 0.0
    if rounded.is_integer() and abs(rounded) < 1e15:
        return Shown(rounded, f"{int(rounded)}.0")
    return Shown(rounded, repr(rounded))


@dataclass(frozen=True, slots=True)
class Decoded:
    """One value decoded from complete words."""

    value: int | float | str | bool | None
    shown: str  # the value as text, with unit and qualifiers
    number: int | float | None  # what the documented range applies to
    undocumented: int | None = None  # a raw value the entry's enum does not name


def scaled(spec: ValueSpec, number: int | float, is_float: bool) -> Shown:
    """Apply scale, offset and precision to a raw number."""
    if spec.scaled:
        result: int | float = number * spec.scale + spec.offset
    else:
        result = number
    if not math.isfinite(result):
        return float_text(float(result), 7)
    if spec.precision is not None:
        if spec.precision == 0:
            return Shown(round(result), str(round(result)))
        rounded = round(float(result), spec.precision) + 0.0
        return Shown(rounded, f"{rounded:.{spec.precision}f}")
    if is_float:
        return float_text(float(result), 7 if spec.type == "f32" else 15)
    if isinstance(result, int):
        return Shown(result, str(result))
    places = max(decimals_of(spec.scale), decimals_of(spec.offset))
    rounded = round(result, places) + 0.0
    if places == 0:
        return Shown(rounded, f"{int(rounded)}.0" if rounded.is_integer() else repr(rounded))
    return Shown(rounded, f"{rounded:.{places}f}")


def raw_integer(spec: ValueSpec, words: Sequence[int]) -> int:
    """The raw unsigned integer of a complete register value (not str, not float)."""
    first = words[0] if words else 0
    if spec.bit is not None:
        return (first >> spec.bit) & ((1 << spec.width) - 1)
    if spec.type in ("u8", "s8"):
        return first >> 8 if spec.byte == "high" else first & 0xFF
    if spec.type == "bool":
        return 1 if first else 0
    return combine(words, spec.word_order)


def decode_spec(spec: ValueSpec, words: Sequence[int]) -> Decoded:
    """Decode a complete value from its words (16-bit, address order)."""
    info = TYPES[spec.type]
    unit = f" {spec.unit}" if spec.unit else ""
    if spec.type == "str":
        data = b"".join(word.to_bytes(2, "big") for word in ordered_words(words, spec.word_order))
        text = device_string(data)
        return Decoded(text, text, None)
    raw = raw_integer(spec, words)
    if info.kind == "float":
        packed = raw.to_bytes(info.bits // 8, "big")
        real = struct.unpack(">f" if info.bits == 32 else ">d", packed)[0]
        value, text = scaled(spec, real, is_float=True)
        return Decoded(value, f"{text}{unit}", value)
    qualifiers: list[str] = []
    if spec.sign_bit is not None or spec.flag_bits:
        mask = 0
        for bit, qualifier in spec.flag_bits.items():
            mask |= 1 << bit
            word = qualifier.set if (raw >> bit) & 1 else qualifier.clear
            if word:
                qualifiers.append(word)
        negative = False
        if spec.sign_bit is not None:
            mask |= 1 << spec.sign_bit
            negative = bool((raw >> spec.sign_bit) & 1)
        magnitude = raw & ~mask
        number = -magnitude if negative else magnitude
    elif info.signed and spec.bit is None:
        number = to_signed(raw, info.bits)
    else:
        number = raw
    tail = "".join(f" {word}" for word in qualifiers)
    is_flag = spec.type == "bool" and (spec.bit is None or spec.width == 1)
    if spec.bits:
        names = [spec.bits.get(bit, f"bit {bit}") for bit in range(info.bits) if (raw >> bit) & 1]
        return Decoded(number, ", ".join(names) if names else "none", None)
    if is_flag:
        state = "on" if number else "off"
        name = spec.enum.get(number)
        if name is not None:
            return Decoded(name, name, None)
        if spec.enum:
            return Decoded(bool(number), f"{state} (undocumented)", None, undocumented=number)
        return Decoded(bool(number), state, None)
    special = spec.special.get(number)
    if special is not None:
        return Decoded(special, f"{special}{tail}", None)
    value, text = scaled(spec, number, is_float=False)
    name = spec.enum.get(number)
    if name is not None:
        return Decoded(name, f"{name}{tail}", value)
    if spec.enum:
        return Decoded(value, f"{text}{unit} (undocumented){tail}", value, undocumented=number)
    return Decoded(value, f"{text}{unit}{tail}", value)


def range_problems(spec: ValueSpec, decoded: Decoded, write: bool) -> list[str]:
    """What is outside the documentation: range, enum, access."""
    problems: list[str] = []
    lead = "written value" if write else "value"
    unit = f" {spec.unit}" if spec.unit else ""
    number = decoded.number
    if decoded.undocumented is not None:
        problems.append(f"{lead} {decoded.undocumented} is not one of the documented values")
    if isinstance(number, (int, float)) and not (isinstance(number, float) and math.isnan(number)):
        value = decoded.value if isinstance(decoded.value, (int, float)) else number
        shown = number_text(value)
        if spec.max is not None and number > spec.max:
            maximum = number_text(spec.max)
            problems.append(f"{lead} {shown}{unit} above the documented maximum {maximum}{unit}")
        if spec.min is not None and number < spec.min:
            minimum = number_text(spec.min)
            problems.append(f"{lead} {shown}{unit} below the documented minimum {minimum}{unit}")
    if write and spec.access == "r":
        problems.append("written to a read-only entry")
    if not write and spec.access == "w":
        problems.append("read from a write-only entry")
    return problems


def partial_string(spec: ValueSpec, present: Sequence[int], first: int) -> str | None:
    """The characters a frame holds of a `str` it holds only part of (None for others)."""
    if spec.type != "str":
        return None
    data = b"".join(word.to_bytes(2, "big") for word in ordered_words(present, spec.word_order))
    chars = plain(data.split(b"\x00", 1)[0].decode("latin-1"))
    before = "…" if first > 0 else ""
    after = "…" if first + len(present) < spec.size else ""
    return f"{before}{chars}{after}"


def decode_entry(entry: Entry, words: Sequence[int], first: int, write: bool) -> RegisterValue:
    """Decode `entry` from `words`: the part of it present, starting at element `first`."""
    spec = entry.spec
    raw = tuple(words)
    if first == 0 and len(words) >= spec.size:
        decoded = decode_spec(spec, words[: spec.size])
        problems = tuple(range_problems(spec, decoded, write))
        text = f"{entry.name} = {decoded.shown}"
        return RegisterValue(
            entry.table,
            entry.address,
            entry.name,
            decoded.value,
            spec.unit,
            text,
            raw,
            False,
            problems,
        )
    value = partial_string(spec, words, first)
    shown = "?" if value is None else value
    noun = "register" if spec.size == 1 else "registers"
    text = f"{entry.name} = {shown} (only {len(words)} of {spec.size} {noun} in this frame)"
    return RegisterValue(entry.table, entry.address, entry.name, value, spec.unit, text, raw, True)


def decode_flag(entry: Entry, bit: bool, write: bool) -> RegisterValue:
    """Decode a coil or discrete input entry from its bit."""
    decoded = decode_spec(entry.spec, [1 if bit else 0])
    problems = tuple(range_problems(entry.spec, decoded, write))
    text = f"{entry.name} = {decoded.shown}"
    raw = (1 if bit else 0,)
    return RegisterValue(
        entry.table,
        entry.address,
        entry.name,
        decoded.value,
        entry.spec.unit,
        text,
        raw,
        False,
        problems,
    )
