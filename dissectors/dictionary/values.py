"""Provides the checks of an entry's value keys (type, bit, scale, enum, range, ...)."""

from __future__ import annotations

import re
from collections.abc import Mapping
from types import MappingProxyType

from .errors import DictionaryError, nearest
from .limits import MAX_DIGITS
from .model import (
    ACCESS,
    BIT_TABLES,
    INPUT_TABLES,
    TABLE_NAMES,
    TABLES,
    TYPES,
    WORD_ORDERS,
    FlagBit,
    TypeInfo,
    ValueSpec,
)
from .reader import Table, kind

VALUE_KEYS = (
    "name",
    "description",
    "type",
    "byte",
    "bit",
    "width",
    "length",
    "word_order",
    "scale",
    "offset",
    "precision",
    "unit",
    "sign_bit",
    "flag_bits",
    "enum",
    "special",
    "bits",
    "min",
    "max",
    "default",
    "access",
    "notes",
    "repeat",
    "stride",
    "n_first",
)
NOT_FOR_BITS = (
    "byte",
    "bit",
    "width",
    "length",
    "word_order",
    "scale",
    "offset",
    "precision",
    "sign_bit",
    "flag_bits",
    "bits",
    "special",
    "min",
    "max",
)
NOT_FOR_FIELDS = ("byte", "length", "word_order", "sign_bit", "flag_bits", "bits")
NOT_WITH_BITS = (
    "enum",
    "special",
    "scale",
    "offset",
    "precision",
    "sign_bit",
    "flag_bits",
    "min",
    "max",
)
UNSIGNED = ("u8", "u16", "u32", "u64")
TYPE_ALIASES: Mapping[str, str] = MappingProxyType(
    {
        "uint8": "u8",
        "int8": "s8",
        "i8": "s8",
        "uint16": "u16",
        "int16": "s16",
        "i16": "s16",
        "word": "u16",
        "uint": "u16",
        "int": "s16",
        "uint32": "u32",
        "int32": "s32",
        "i32": "s32",
        "dword": "u32",
        "uint64": "u64",
        "int64": "s64",
        "i64": "s64",
        "float": "f32",
        "float32": "f32",
        "real": "f32",
        "float64": "f64",
        "double": "f64",
        "string": "str",
        "text": "str",
        "boolean": "bool",
        "bit": "bool",
    }
)
_DECIMAL = re.compile(r"[+-]?[0-9]+\Z")
_HEX = re.compile(r"0[xX][0-9a-fA-F]+\Z")


def parse_key_number(text: str) -> int | None:
    """An enum, bits or exception key: decimal ("10", "-1") or hex ("0x0A"); None for
    anything else, a number of more than MAX_DIGITS digits included (int() refuses over
    4300 decimal digits, and no key needs more than a few)."""
    text = text.strip()
    if len(text) > MAX_DIGITS:
        return None
    if _DECIMAL.match(text):
        return int(text)
    if _HEX.match(text):
        return int(text, 16)
    return None


def table_name(table: Table, key: str) -> str | None:
    """The long name of the Modbus table given at `key`, if any."""
    given = table.opt_text(key)
    if given is None:
        return None
    found = TABLE_NAMES.get(given)
    if found is None:
        close = nearest(given, TABLE_NAMES)
        fix = (
            f"write '{close}' instead of '{given}'" if close else f"use one of {', '.join(TABLES)}"
        )
        raise table.error(key, f"{table.what}: unknown table '{given}'", fix)
    return found


def word_order_name(table: Table, given: str) -> str:
    """The long name of a word order written either way (`low_first` or `CDAB`)."""
    found = WORD_ORDERS.get(given) or WORD_ORDERS.get(given.upper())
    if found is None:
        close = nearest(given, WORD_ORDERS)
        fix = (
            f"write '{close}' instead of '{given}'"
            if close
            else "use high_first (ABCD), low_first (CDAB), high_first_swapped (BADC) "
            "or low_first_swapped (DCBA)"
        )
        raise table.error("word_order", f"{table.what}: unknown word_order '{given}'", fix)
    return found


def names(table: Table, key: str, low: int, high: int, what: str) -> dict[int, str]:
    """An enum or bits table: number keys (checked against low..high) -> names."""
    raw = table.subtable(key)
    out: dict[int, str] = {}
    written: dict[int, str] = {}
    for text, name in (raw or {}).items():
        number = parse_key_number(text)
        at = (*table.at, key, text)
        if number is None:
            raise table.src.error(
                at,
                f"{table.what}: {key} key '{text}' is not a number",
                'write keys as decimal ("10") or hex ("0x0A") strings',
            )
        if not low <= number <= high:
            raise table.src.error(
                at,
                f"{table.what}: {key} key '{text}' is outside {what} ({low} to {high})",
                f"use keys from {low} to {high}",
            )
        if number in written:
            raise table.src.error(
                at,
                f"{table.what}: {key} keys '{written[number]}' and '{text}' are the same number",
                "keep one of them",
            )
        if not isinstance(name, str) or not name.strip() or not name.isprintable():
            raise table.src.error(
                at,
                f"{table.what}: {key} '{text}' must name something on one line, not {kind(name)}",
                f'write "{text}" = "a name"',
            )
        written[number] = text
        out[number] = name
    return out


class ValueReader:
    """Checks the value keys of one entry or parameter and makes its ValueSpec.

    `where` is the table the value sits in, `ref_bit` the bit its ref selected, and
    `word_order` the device's default for 32/64-bit types.
    """

    def __init__(self, table: Table, where: str, ref_bit: int | None, word_order: str) -> None:
        self.table = table
        self.what = table.what
        self.where = where
        self.device_order = word_order
        self.bit = self.read_bit(ref_bit)
        self.type = self.read_type()
        self.info: TypeInfo = TYPES[self.type]
        self.width = 1

    def fail(self, key: str | None, message: str, fix: str) -> DictionaryError:
        return self.table.error(key, f"{self.what}: {message}", fix)

    def refuse(self, keys: tuple[str, ...], why: str) -> None:
        """An error for the first of `keys` present: it does not apply here."""
        for key in keys:
            if self.table.has(key):
                raise self.fail(key, f"'{key}' does not apply to {why}", f"remove {key}")

    def read(self) -> ValueSpec:
        table = self.table
        if self.where in BIT_TABLES:
            self.refuse(NOT_FOR_BITS, f"{self.where} (single bits)")
        self.read_width()
        byte = self.read_byte()
        length = self.read_length()
        order = self.read_word_order()
        scale, offset, precision = self.read_scaling()
        sign_bit, flag_bits = self.read_sign_and_flags()
        enum = self.read_enum(sign_bit, bool(flag_bits))
        special = self.read_special(sign_bit, bool(flag_bits), enum)
        bits = self.read_bits()
        low, high = self.read_limits()
        return ValueSpec(
            type=self.type,
            byte=byte,
            bit=self.bit,
            width=self.width,
            length=length,
            word_order=order,
            scale=1 if scale is None else scale,
            offset=0 if offset is None else offset,
            precision=precision,
            unit=table.label("unit") or "",
            sign_bit=sign_bit,
            flag_bits=MappingProxyType(flag_bits),
            enum=MappingProxyType(enum),
            special=MappingProxyType(special),
            bits=MappingProxyType(bits),
            min=low,
            max=high,
            default=self.read_default({**enum, **special}, low, high),
            access=self.read_access(),
            description=table.text("description"),
            notes=table.texts("notes"),
        )

    def read_bit(self, ref_bit: int | None) -> int | None:
        bit = self.table.integer("bit")
        if ref_bit is not None:
            if bit is not None:
                raise self.fail(
                    "bit",
                    f"the bit is given twice, in the ref and as bit = {bit}",
                    "remove bit (the ref's .N sets it)",
                )
            return ref_bit
        return bit

    def read_type(self) -> str:
        given = self.table.opt_text("type")
        if self.where in BIT_TABLES:
            if given not in (None, "bool"):
                raise self.fail(
                    "type",
                    f"type '{given}' in {self.where}, which hold single bits",
                    'remove type, or write type = "bool"',
                )
            return "bool"
        if given is None:
            width = self.table.get("width")
            return "bool" if self.bit is not None and width in (None, 1) else "u16"
        if given not in TYPES:
            close = TYPE_ALIASES.get(given.lower()) or nearest(given, TYPES)
            fix = (
                f"write '{close}' instead of '{given}'"
                if close
                else f"use one of {', '.join(TYPES)}"
            )
            raise self.fail("type", f"unknown type '{given}'", fix)
        return given

    def read_width(self) -> None:
        width = self.table.integer("width")
        bit = self.bit
        if bit is None:
            if width is not None:
                raise self.fail(
                    "width",
                    "width without bit",
                    "add bit = N (the lowest bit of the field), or remove width",
                )
            return
        if self.type not in ("bool", "u16"):
            raise self.fail(
                "bit",
                f"bit with type '{self.type}'",
                'a bit is type "bool", a field of width bits is "u16" (or leave type out); '
                "for named bits of a wider value use bits = { ... }",
            )
        if not 0 <= bit <= 15:
            raise self.fail(
                "bit",
                f"bit {bit} is outside the register",
                "use a bit from 0 (least significant) to 15",
            )
        self.width = 1 if width is None else width
        if self.width < 1 or bit + self.width > 16:
            raise self.fail(
                "width",
                f"a field of {self.width} bits from bit {bit} does not fit a register",
                f"use a width from 1 to {16 - bit}",
            )
        if self.type == "bool" and self.width != 1:
            raise self.fail(
                "width",
                f"a field of {self.width} bits is a number, not a bool",
                'write type = "u16" or leave type out',
            )
        self.refuse(NOT_FOR_FIELDS, "a bit or bit field")

    def read_byte(self) -> str | None:
        byte = self.table.opt_text("byte")
        if self.type in ("u8", "s8"):
            if byte is None:
                raise self.fail(
                    "type",
                    f"{self.type} does not say which byte",
                    'add byte = "high" or byte = "low"',
                )
            if byte not in ("high", "low"):
                raise self.fail("byte", f"byte = '{byte}'", 'write byte = "high" or byte = "low"')
        elif byte is not None:
            raise self.fail(
                "byte",
                f"byte applies to u8 and s8, not {self.type}",
                "remove byte, or change the type",
            )
        return byte

    def read_length(self) -> int:
        length = self.table.integer("length")
        if self.type != "str":
            if length is not None:
                raise self.fail(
                    "length", f"length applies to str, not {self.type}", "remove length"
                )
            return 0
        if length is None:
            raise self.fail(
                "type", "str without length", "add length = N (registers, two characters each)"
            )
        if not 1 <= length <= 256:
            raise self.fail("length", f"length = {length}", "use 1 to 256 registers")
        return length

    def read_word_order(self) -> str:
        given = self.table.opt_text("word_order")
        if given is None:
            return self.device_order if self.info.words > 1 else "high_first"
        order = word_order_name(self.table, given)
        if self.type in ("bool", "u8", "s8") or self.bit is not None:
            raise self.fail(
                "word_order", f"word_order does not apply to {self.type}", "remove word_order"
            )
        one_word = self.info.words == 1 or self.type == "str"
        if one_word and order not in ("high_first", "high_first_swapped"):
            raise self.fail(
                "word_order",
                f"{self.type} has a byte order but no word order",
                'use "high_first" or "high_first_swapped" (bytes swapped), or remove it',
            )
        return order

    def read_scaling(self) -> tuple[int | float | None, int | float | None, int | None]:
        table = self.table
        scale = table.number("scale")
        offset = table.number("offset")
        precision = table.integer("precision", 0, 10)
        is_number = self.info.kind in ("int", "float") and not (
            self.bit is not None and self.width == 1
        )
        if not is_number:
            self.refuse(("scale", "offset", "precision"), f"a {self.type}")
        if scale == 0:
            raise self.fail("scale", "scale = 0", "use a non-zero scale")
        return scale, offset, precision

    def read_sign_and_flags(self) -> tuple[int | None, dict[int, FlagBit]]:
        table = self.table
        sign_bit = table.integer("sign_bit")
        if sign_bit is None and not table.has("flag_bits"):
            return None, {}
        key = "sign_bit" if sign_bit is not None else "flag_bits"
        if self.type not in UNSIGNED:
            raise self.fail(
                key,
                f"{key} needs an unsigned type, not {self.type}",
                'write type = "u16" or "u32" (the raw value, sign and flags included)',
            )
        bits = self.info.bits
        if sign_bit is not None and not 0 <= sign_bit < bits:
            raise self.fail(
                "sign_bit",
                f"sign_bit {sign_bit} is outside a {self.type}",
                f"use a bit from 0 to {bits - 1}",
            )
        flags = self.read_flags(bits)
        if sign_bit is not None and sign_bit in flags:
            raise table.src.error(
                (*table.at, "flag_bits", str(sign_bit)),
                f"{self.what}: bit {sign_bit} is both the sign_bit and a flag bit",
                "give the sign and each flag a bit of its own",
            )
        return sign_bit, flags

    def read_flags(self, bits: int) -> dict[int, FlagBit]:
        table = self.table
        out: dict[int, FlagBit] = {}
        for text, body in (table.subtable("flag_bits") or {}).items():
            at = (*table.at, "flag_bits", text)
            number = parse_key_number(text)
            if number is None or not 0 <= number < bits:
                raise table.src.error(
                    at,
                    f"{self.what}: flag_bits key '{text}' is not a bit of the value (0-{bits - 1})",
                    f"use a bit number from 0 to {bits - 1}",
                )
            if number in out:
                raise table.src.error(
                    at, f"{self.what}: flag bit {number} is given twice", "keep one of them"
                )
            flag = Table(table.src, at, body, f"{self.what}: flag bit {number}", ("clear", "set"))
            clear, set_ = flag.label("clear") or "", flag.label("set") or ""
            if not clear and not set_:
                raise flag.error(
                    None,
                    f"{flag.what} has no words to show",
                    'write { clear = "inductive", set = "capacitive" }',
                )
            out[number] = FlagBit(clear=clear, set=set_)
        return out

    def read_special(
        self, sign_bit: int | None, flagged: bool, enum: Mapping[int, str]
    ) -> dict[int, str]:
        """Named raw values of a number that is otherwise scaled (raw 1 = "off")."""
        if not self.table.has("special"):
            return {}
        if enum:
            raise self.fail(
                "special",
                "special names raw values of a number; with an enum every value is named",
                "move the special values into the enum, or remove the enum",
            )
        return self.read_enum(sign_bit, flagged, "special")

    def read_enum(self, sign_bit: int | None, flagged: bool, key: str = "enum") -> dict[int, str]:
        if not self.table.has(key):
            return {}
        if self.info.kind in ("float", "str"):
            raise self.fail(key, f"{key} does not apply to {self.type}", f"remove {key}")
        bits = self.info.bits
        if self.bit is not None:
            low, high = 0, (1 << self.width) - 1
        elif sign_bit is not None or flagged:
            high = (1 << bits) - 1
            low = -high if sign_bit is not None else 0
        elif self.info.signed:
            low, high = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
        else:
            low, high = 0, (1 << bits) - 1
        return names(self.table, key, low, high, f"a {self.type}")

    def read_bits(self) -> dict[int, str]:
        if not self.table.has("bits"):
            return {}
        if self.type not in UNSIGNED:
            raise self.fail(
                "bits",
                f"bits needs an unsigned type, not {self.type}",
                'write type = "u16" (or u32 for a 32-bit bit field)',
            )
        for key in NOT_WITH_BITS:
            if self.table.has(key):
                raise self.fail(
                    key,
                    f"'{key}' does not go with bits (a register of named bits)",
                    f"remove {key}, or split the entry",
                )
        return names(self.table, "bits", 0, self.info.bits - 1, f"the bits of a {self.type}")

    def read_limits(self) -> tuple[int | float | None, int | float | None]:
        low = self.table.number("min")
        high = self.table.number("max")
        if self.info.kind in ("str", "bool"):
            self.refuse(("min", "max"), f"a {self.type}")
        if low is not None and high is not None and low > high:
            raise self.fail(
                "min", f"min {low} is greater than max {high}", "swap them, or check the manual"
            )
        return low, high

    def read_default(
        self, enum: Mapping[int, str], low: int | float | None, high: int | float | None
    ) -> int | float | str | bool | None:
        table = self.table
        value = table.get("default")
        if value is None:
            return None
        kind_name = self.info.kind
        if isinstance(value, str):
            if kind_name == "str" or value in enum.values():
                return value
            if enum:
                listed = ", ".join(f'"{name}"' for name in enum.values())
                raise self.fail(
                    "default",
                    f"default '{value}' is not one of the enum names",
                    f"use one of {listed}, or the number",
                )
            raise table.wrong("default", "a number", "default = 300 (no quotes)")
        if isinstance(value, bool):
            if kind_name != "bool":
                raise table.wrong("default", "a number", "default = 1")
            return value
        if not isinstance(value, (int, float)):
            raise table.wrong("default", "a number or a string", "default = 300")
        if kind_name == "str":
            raise table.wrong("default", "a string", 'default = "..."')
        if kind_name == "bool" and value not in (0, 1):
            raise self.fail("default", f"default {value} for a bool", "use true or false")
        if (low is not None and value < low) or (high is not None and value > high):
            raise self.fail(
                "default",
                f"default {value} is outside min {low} .. max {high}",
                "check the manual: fix the default or the range",
            )
        return value

    def read_access(self) -> str:
        access = self.table.opt_text("access")
        if access is None:
            return "r" if self.where in INPUT_TABLES else "rw"
        if access not in ACCESS:
            close = nearest(access, ACCESS)
            fix = f"write '{close}' instead of '{access}'" if close else 'use "r", "w" or "rw"'
            raise self.fail("access", f"access = '{access}'", fix)
        if self.where in INPUT_TABLES and access != "r":
            raise self.fail(
                "access",
                f"access '{access}' but {self.where} cannot be written",
                'write access = "r" or remove it',
            )
        return access
