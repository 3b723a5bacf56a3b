"""Provides the dictionary builder: parsed TOML-shaped data checked into a DeviceDictionary.

Every problem becomes a DictionaryError naming the line and the fix. Problems in one
entry do not stop the others from being checked; all of them ride on the first error.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import partial
from types import MappingProxyType
from typing import TypeVar

from .device import DeviceDictionary, Window
from .errors import DictionaryError, nearest
from .model import (
    ACCESS,
    BIT_TABLES,
    INPUT_TABLES,
    MODEL_PATTERN,
    REGISTER_TABLES,
    TABLE_NAMES,
    TABLES,
    TYPES,
    WORD_ORDERS,
    Entry,
    FlagBit,
    Parameter,
    RefMatch,
    Space,
    Timing,
    ValueSpec,
)
from .reader import Source, Table, kind
from .tomlpos import KeyPath
from .vendor import FIELD_SIZES, ReportServerId, VendorField, VendorFunction

T = TypeVar("T")

FORMAT = 1
TOP_KEYS = (
    "format",
    "device",
    "timing",
    "spaces",
    "entry",
    "window",
    "function",
    "report_server_id",
    "exceptions",
)
DEVICE_KEYS = ("model", "name", "manual", "word_order", "default_space", "notes")
TIMING_KEYS = (
    "response_ms",
    "long_response_ms",
    "long_response_functions",
    "quiet_after_write_ms",
    "quiet_after_functions",
)
SPACE_KEYS = ("table", "prefix", "suffix", "radix", "first", "pdu", "bit_first", "width")
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
PLACE_KEYS = ("ref", "address", "space", "pdu", "table")
ENTRY_KEYS = PLACE_KEYS + VALUE_KEYS
PARAMETER_KEYS = ("number", *VALUE_KEYS)
WINDOW_KEYS = ("name", "select", "value", "parameter", "description", "notes")
FUNCTION_KEYS = ("code", "name", "broadcast", "request", "response", "description", "notes")
FIELD_KEYS = ("name", "type", "length", "enum", "description")
REPORT_KEYS = ("fields", "description", "notes")
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
    "min",
    "max",
)
NOT_FOR_FIELDS = ("byte", "length", "word_order", "sign_bit", "flag_bits", "bits")
UNSIGNED = ("u8", "u16", "u32", "u64")
STANDARD_FUNCTIONS = frozenset({1, 2, 3, 4, 5, 6, 7, 8, 11, 12, 15, 16, 17, 20, 21, 22, 23, 24, 43})
TYPE_ALIASES: Mapping[str, str] = {
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
_DECIMAL = re.compile(r"[+-]?[0-9]+\Z")
_HEX = re.compile(r"0[xX][0-9a-fA-F]+\Z")


def parse_key_number(text: str) -> int | None:
    """An enum, bits or exception key: decimal ("10", "-1") or hex ("0x0A")."""
    text = text.strip()
    if _DECIMAL.match(text):
        return int(text)
    if _HEX.match(text):
        return int(text, 16)
    return None


@dataclass(frozen=True, slots=True)
class _Place:
    table: str
    address: int
    bit: int | None
    ref: str
    space: Space | None


class Builder:
    """Checks one parsed file and builds its DeviceDictionary."""

    def __init__(self, src: Source, *, drop_overlaps: bool = False) -> None:
        self.src = src
        self.drop_overlaps = drop_overlaps  # imports: leave clashing entries out, with a note
        self.errors: list[DictionaryError] = []
        self.notes: list[str] = []
        self.spaces: dict[str, Space] = {}
        self.default_space: str | None = None
        self.word_order = "high_first"

    # -- plumbing -------------------------------------------------------------------

    def attempt(self, step: Callable[[], T]) -> T | None:
        """Run one check; keep its error and carry on with the next."""
        try:
            return step()
        except DictionaryError as error:
            self.errors.append(error)
            return None

    def fail(self) -> None:
        if self.errors:
            ordered = sorted(self.errors, key=lambda e: (e.line is None, e.line or 0))
            first = ordered[0]
            first.more = tuple(ordered[1:])
            raise first

    # -- the file -------------------------------------------------------------------

    def build(self, data: Mapping[str, object], unit_hint: int | None = None) -> DeviceDictionary:
        top = Table(self.src, (), dict(data), "the file", TOP_KEYS)
        self.attempt(lambda: self.format(top))
        device = self.attempt(lambda: self.device(top))
        self.attempt(lambda: self.read_spaces(top))
        if device is not None:
            self.attempt(lambda: self.check_default_space(top))
        timing = self.attempt(lambda: self.timing(top))
        self.fail()
        assert device is not None
        model, name, manual, notes = device

        entries: list[Entry] = []
        for index, raw in enumerate(self.attempt(lambda: top.tables("entry", "[[entry]]")) or []):
            made = self.attempt(partial(self.entry, index, raw))
            entries.extend(made or [])
        entries = self.check_overlaps(entries)
        windows: list[Window] = []
        for index, raw in enumerate(self.attempt(lambda: top.tables("window", "[[window]]")) or []):
            window = self.attempt(partial(self.window, index, raw))
            if window is not None:
                windows.append(window)
        functions = self.attempt(lambda: self.functions(top))
        exceptions = self.attempt(lambda: self.exceptions(top))
        report = self.attempt(lambda: self.report_server_id(top))
        self.fail()
        return DeviceDictionary(
            model=model,
            name=name,
            path=self.src.path,
            entries=tuple(entries),
            manual=manual,
            word_order=self.word_order,
            default_space=self.default_space,
            notes=(*notes, *self.notes),
            timing=timing,
            spaces=MappingProxyType(dict(self.spaces)),
            functions=MappingProxyType(functions or {}),
            exceptions=MappingProxyType(exceptions or {}),
            windows=tuple(windows),
            report_server_id=report,
            unit_hint=unit_hint,
        )

    def format(self, top: Table) -> None:
        found = top.integer("format")
        if found is None:
            raise top.error(
                None, "the file does not say its format", f"add format = {FORMAT} as the first line"
            )
        if found != FORMAT:
            raise top.error(
                "format",
                f"format = {found} is not a format this modscope reads",
                f"write format = {FORMAT} and follow docs/dictionaries.md",
            )

    def device(self, top: Table) -> tuple[str, str, str, tuple[str, ...]]:
        raw = top.get("device")
        if raw is None:
            raise top.error(
                None, "the file has no [device] table", 'add [device] with model = "..."'
            )
        table = Table(self.src, ("device",), raw, "[device]", DEVICE_KEYS)
        model = table.need_text("model", 'model = "my-device"')
        if not MODEL_PATTERN.match(model):
            raise table.error(
                "model",
                f"model '{model}' has characters bus files cannot name",
                "use letters, digits and . _ + - only, starting with a letter or digit",
            )
        name = table.text("name") or model
        manual = table.text("manual")
        order = table.opt_text("word_order")
        if order is not None:
            self.word_order = self.word_order_name(table, order)
        self.default_space = table.opt_text("default_space")
        return model, name, manual, table.texts("notes")

    def check_default_space(self, top: Table) -> None:
        if self.default_space is not None and self.default_space not in self.spaces:
            table = Table(self.src, ("device",), top.get("device"), "[device]", DEVICE_KEYS)
            raise table.error(
                "default_space",
                f"default_space '{self.default_space}' is not a declared space",
                self.space_fix(self.default_space),
            )

    def space_fix(self, name: str) -> str:
        if not self.spaces:
            return f"declare it: [spaces.{name}] with table = ..., or remove the reference"
        close = nearest(name, self.spaces)
        if close is not None:
            return f"write '{close}' instead of '{name}'"
        return f"use one of the declared spaces: {', '.join(self.spaces)}"

    def word_order_name(self, table: Table, given: str) -> str:
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

    def table_name(self, table: Table, key: str) -> str | None:
        given = table.opt_text(key)
        if given is None:
            return None
        found = TABLE_NAMES.get(given)
        if found is None:
            close = nearest(given, TABLE_NAMES)
            fix = (
                f"write '{close}' instead of '{given}'"
                if close
                else f"use one of {', '.join(TABLES)}"
            )
            raise table.error(key, f"{table.what}: unknown table '{given}'", fix)
        return found

    def read_spaces(self, top: Table) -> None:
        raw = top.subtable("spaces")
        for name, body in (raw or {}).items():
            table = Table(self.src, ("spaces", name), body, f"[spaces.{name}]", SPACE_KEYS)
            target = self.table_name(table, "table")
            if target is None:
                raise table.missing("table", 'table = "holding" (or coils, discrete_inputs, input)')
            radix = table.integer("radix")
            if radix is not None and radix not in (10, 16):
                raise table.error("radix", f"{table.what}: radix = {radix}", "use radix = 10 or 16")
            bit_first = table.integer("bit_first")
            if bit_first is not None and bit_first not in (0, 1):
                raise table.error(
                    "bit_first", f"{table.what}: bit_first = {bit_first}", "use bit_first = 0 or 1"
                )
            self.spaces[name] = Space(
                name=name,
                table=target,
                prefix=table.text("prefix"),
                suffix=table.text("suffix"),
                radix=radix or 10,
                first=table.integer("first", 0) or 0,
                pdu=table.integer("pdu", 0, 65535) or 0,
                bit_first=bit_first or 0,
                width=table.integer("width", 1, 10),
            )

    def timing(self, top: Table) -> Timing | None:
        raw = top.get("timing")
        if raw is None:
            return None
        table = Table(self.src, ("timing",), raw, "[timing]", TIMING_KEYS)

        def ms(key: str) -> int | float | None:
            value = table.number(key)
            if value is not None and value < 0:
                raise table.error(key, f"[timing]: {key} = {value} is negative", "use 0 or more ms")
            return value

        def codes(key: str) -> tuple[int, ...]:
            value = table.get(key)
            if value is None:
                return ()
            if not isinstance(value, list) or not all(
                isinstance(code, int) and not isinstance(code, bool) and 1 <= code <= 127
                for code in value
            ):
                raise table.error(
                    key,
                    f"[timing]: {key} must be an array of function codes 1-127",
                    f"write {key} = [6, 16]",
                )
            return tuple(int(code) for code in value)

        return Timing(
            response_ms=ms("response_ms"),
            long_response_ms=ms("long_response_ms"),
            long_response_functions=codes("long_response_functions"),
            quiet_after_write_ms=ms("quiet_after_write_ms"),
            quiet_after_functions=codes("quiet_after_functions"),
        )

    # -- places -----------------------------------------------------------------------

    def match_ref(self, table: Table, key: str, ref: str, only: str | None) -> RefMatch:
        if not self.spaces:
            raise table.error(
                key,
                f"{table.what}: ref '{ref}' but the file declares no spaces",
                'declare how the manual numbers registers, e.g. [spaces.4x] table = "holding", '
                'prefix = "4", width = 4, first = 1; or use pdu = N with table = "..."',
            )
        if only is not None:
            if only not in self.spaces:
                raise table.error(
                    "space", f"{table.what}: unknown space '{only}'", self.space_fix(only)
                )
            candidates = [self.spaces[only]]
        else:
            candidates = list(self.spaces.values())
        matches = [m for m in (space.match(ref) for space in candidates) if m is not None]
        if not matches:
            examples = ", ".join(f"{s.name} ({s.example()})" for s in candidates)
            raise table.error(
                key,
                f"{table.what}: no space reads the ref '{ref}'",
                f"write it the way a space does: {examples}; or declare a [spaces.NAME] for it",
            )
        best = max((m.prefix_length, m.suffix_length) for m in matches)
        top = [m for m in matches if (m.prefix_length, m.suffix_length) == best]
        if len(top) > 1:
            names = " and ".join(f"'{m.space.name}'" for m in top)
            raise table.error(
                key,
                f"{table.what}: ref '{ref}' is read equally well by spaces {names}",
                f'add space = "{top[0].space.name}" to choose one, or give the spaces '
                "distinct prefixes or suffixes",
            )
        found = top[0]
        if not 0 <= found.address <= 65535:
            raise table.error(
                key,
                f"{table.what}: ref '{ref}' is PDU address {found.address} in space "
                f"'{found.space.name}', outside 0-65535",
                f"check the number, and first/pdu of [spaces.{found.space.name}]",
            )
        return found

    def place(self, table: Table) -> _Place:
        given = [key for key in ("ref", "address", "pdu") if table.has(key)]
        if not given:
            raise table.error(
                None,
                f"{table.what} does not say where it is",
                'add ref = "..." as the manual prints it, address = N (with space), '
                'or pdu = N with table = "..."',
            )
        if len(given) > 1:
            raise table.error(
                given[1],
                f"{table.what} gives both {given[0]} and {given[1]}",
                f"keep one of {' / '.join(given)}",
            )
        declared = self.table_name(table, "table")
        if given[0] == "ref":
            ref = table.need_text("ref", 'ref = "40001"')
            found = self.match_ref(table, "ref", ref, table.opt_text("space"))
            result = _Place(found.space.table, found.address, found.bit, ref.strip(), found.space)
            if found.bit is not None:
                if result.table in BIT_TABLES:
                    raise table.error(
                        "ref",
                        f"{table.what}: ref '{ref}' selects a bit of a coil or input",
                        "coils and discrete inputs are single bits: drop the .N",
                    )
                if not 0 <= found.bit <= 15:
                    first = found.space.bit_first
                    raise table.error(
                        "ref",
                        f"{table.what}: bit {found.bit + first} of ref '{ref}' "
                        "is outside the register",
                        f"space '{found.space.name}' numbers bits {first}-{15 + first}",
                    )
        elif given[0] == "address":
            number = table.integer("address")
            if number is None:
                raise table.missing("address", "address = N")
            name = table.opt_text("space") or self.default_space
            if name is None:
                raise table.error(
                    "address",
                    f"{table.what}: address = {number} but no space says how to count it",
                    'add space = "NAME", or default_space = "NAME" in [device]; '
                    'or write pdu = N with table = "..."',
                )
            if name not in self.spaces:
                key = "space" if table.has("space") else "address"
                raise table.error(
                    key, f"{table.what}: unknown space '{name}'", self.space_fix(name)
                )
            space = self.spaces[name]
            address = space.pdu + number - space.first
            if not 0 <= address <= 65535:
                raise table.error(
                    "address",
                    f"{table.what}: address {number} is PDU address {address} in space "
                    f"'{name}', outside 0-65535",
                    f"check the number, and first/pdu of [spaces.{name}]",
                )
            result = _Place(space.table, address, None, space.format(address), space)
        else:
            address = table.need_integer("pdu", 0, 65535)
            if declared is None:
                raise table.error(
                    "pdu",
                    f"{table.what}: pdu = {address} without a table",
                    'add table = "holding" (or coils, discrete_inputs, input_registers)',
                )
            if table.has("space"):
                raise table.error(
                    "space",
                    f"{table.what}: space is used with address, not pdu",
                    "remove space, or write address = N instead of pdu",
                )
            return _Place(declared, address, None, f"pdu {address}", None)
        if declared is not None and declared != result.table:
            raise table.error(
                "table",
                f"{table.what}: table = '{declared}' but its place is in {result.table}",
                "remove table (the space decides it), or fix the ref",
            )
        return result

    def register_place(self, table: Table, key: str) -> tuple[int, str]:
        """A window's select or value register: a ref, or an address in the default space."""
        value = table.get(key)
        if value is None:
            raise table.missing(key, f'{key} = "..." (a ref, as the manual prints it)')
        if isinstance(value, str):
            found = self.match_ref(table, key, value, None)
            if found.space.table not in REGISTER_TABLES or found.bit is not None:
                raise table.error(
                    key,
                    f"{table.what}: {key} '{value}' is not a whole register",
                    "give the ref of a holding or input register, without .N",
                )
            return found.address, value.strip()
        number = table.integer(key)
        assert number is not None
        if self.default_space is None:
            raise table.error(
                key,
                f"{table.what}: {key} = {number} but no default_space says how to count it",
                f'write it as a ref string, e.g. {key} = "5002h"',
            )
        space = self.spaces[self.default_space]
        address = space.pdu + number - space.first
        if not 0 <= address <= 65535:
            raise table.error(key, f"{table.what}: {key} is outside 0-65535", "check the number")
        return address, space.format(address)

    # -- values -------------------------------------------------------------------------

    def value_type(self, table: Table, where: str, bit: int | None) -> str:
        given = table.opt_text("type")
        if where in BIT_TABLES:
            for key in NOT_FOR_BITS:
                if table.has(key):
                    raise table.error(
                        key,
                        f"{table.what}: '{key}' does not apply to {where} (single bits)",
                        f"remove {key}",
                    )
            if given not in (None, "bool"):
                raise table.error(
                    "type",
                    f"{table.what}: type '{given}' in {where}, which hold single bits",
                    'remove type, or write type = "bool"',
                )
            return "bool"
        if given is None:
            width = table.get("width")
            return "bool" if bit is not None and width in (None, 1) else "u16"
        if given not in TYPES:
            alias = TYPE_ALIASES.get(given.lower())
            close = alias or nearest(given, TYPES)
            fix = (
                f"write '{close}' instead of '{given}'"
                if close
                else f"use one of {', '.join(TYPES)}"
            )
            raise table.error("type", f"{table.what}: unknown type '{given}'", fix)
        return given

    def names(self, table: Table, key: str, low: int, high: int, what: str) -> dict[int, str]:
        """An enum or bits table: number keys (checked against low..high) -> names."""
        raw = table.subtable(key)
        out: dict[int, str] = {}
        written: dict[int, str] = {}
        for text, name in (raw or {}).items():
            number = parse_key_number(text)
            at = (*table.at, key, text)
            if number is None:
                raise self.src.error(
                    at,
                    f"{table.what}: {key} key '{text}' is not a number",
                    'write keys as decimal ("10") or hex ("0x0A") strings',
                )
            if not low <= number <= high:
                raise self.src.error(
                    at,
                    f"{table.what}: {key} key '{text}' is outside {what} ({low} to {high})",
                    f"use keys from {low} to {high}",
                )
            if number in written:
                raise self.src.error(
                    at,
                    f"{table.what}: {key} keys '{written[number]}' and '{text}' "
                    "are the same number",
                    "keep one of them",
                )
            if not isinstance(name, str) or not name.strip():
                raise self.src.error(
                    at,
                    f"{table.what}: {key} '{text}' must name something, not {kind(name)}",
                    f'write "{text}" = "a name"',
                )
            written[number] = text
            out[number] = name
        return out

    def flags(self, table: Table, bits: int) -> dict[int, FlagBit]:
        raw = table.subtable("flag_bits")
        out: dict[int, FlagBit] = {}
        for text, body in (raw or {}).items():
            at = (*table.at, "flag_bits", text)
            number = parse_key_number(text)
            if number is None or not 0 <= number < bits:
                raise self.src.error(
                    at,
                    f"{table.what}: flag_bits key '{text}' is not a bit of the value "
                    f"(0-{bits - 1})",
                    f"use a bit number from 0 to {bits - 1}",
                )
            if number in out:
                raise self.src.error(
                    at, f"{table.what}: flag bit {number} is given twice", "keep one of them"
                )
            flag = Table(self.src, at, body, f"{table.what}: flag bit {number}", ("clear", "set"))
            clear, set_ = flag.text("clear"), flag.text("set")
            if not clear and not set_:
                raise flag.error(
                    None,
                    f"{flag.what} has no words to show",
                    'write { clear = "inductive", set = "capacitive" }',
                )
            out[number] = FlagBit(clear=clear, set=set_)
        return out

    def spec(self, table: Table, where: str, ref_bit: int | None) -> ValueSpec:
        """The value keys of an entry or parameter in table `where`."""
        bit = table.integer("bit")
        if ref_bit is not None:
            if bit is not None:
                raise table.error(
                    "bit",
                    f"{table.what}: the bit is given twice, in the ref and as bit = {bit}",
                    "remove bit (the ref's .N sets it)",
                )
            bit = ref_bit
        type_name = self.value_type(table, where, bit)
        info = TYPES[type_name]
        width = 1
        given_width = table.integer("width")
        if bit is not None:
            if type_name not in ("bool", "u16"):
                raise table.error(
                    "bit",
                    f"{table.what}: bit with type '{type_name}'",
                    'a bit is type "bool", a field of width bits is "u16" (or leave type out); '
                    "for named bits of a wider value use bits = { ... }",
                )
            if not 0 <= bit <= 15:
                raise table.error(
                    "bit",
                    f"{table.what}: bit {bit} is outside the register",
                    "use a bit from 0 (least significant) to 15",
                )
            width = 1 if given_width is None else given_width
            if width < 1 or bit + width > 16:
                raise table.error(
                    "width",
                    f"{table.what}: a field of {width} bits from bit {bit} does not fit a register",
                    f"use a width from 1 to {16 - bit}",
                )
            if type_name == "bool" and width != 1:
                raise table.error(
                    "width",
                    f"{table.what}: a field of {width} bits is a number, not a bool",
                    'write type = "u16" or leave type out',
                )
            for key in NOT_FOR_FIELDS:
                if table.has(key):
                    raise table.error(
                        key,
                        f"{table.what}: '{key}' does not apply to a bit or bit field",
                        f"remove {key}",
                    )
        elif given_width is not None:
            raise table.error(
                "width",
                f"{table.what}: width without bit",
                "add bit = N (the lowest bit of the field), or remove width",
            )

        byte = table.opt_text("byte")
        if type_name in ("u8", "s8"):
            if byte is None:
                raise table.error(
                    "type",
                    f"{table.what}: {type_name} does not say which byte",
                    'add byte = "high" or byte = "low"',
                )
            if byte not in ("high", "low"):
                raise table.error(
                    "byte", f"{table.what}: byte = '{byte}'", 'write byte = "high" or byte = "low"'
                )
        elif byte is not None:
            raise table.error(
                "byte",
                f"{table.what}: byte applies to u8 and s8, not {type_name}",
                "remove byte, or change the type",
            )

        length = table.integer("length")
        if type_name == "str":
            if length is None:
                raise table.error(
                    "type",
                    f"{table.what}: str without length",
                    "add length = N (registers, two characters each)",
                )
            if not 1 <= length <= 256:
                raise table.error(
                    "length", f"{table.what}: length = {length}", "use 1 to 256 registers"
                )
        elif length is not None:
            raise table.error(
                "length",
                f"{table.what}: length applies to str, not {type_name}",
                "remove length",
            )
        else:
            length = 0

        order_given = table.opt_text("word_order")
        if order_given is not None:
            order = self.word_order_name(table, order_given)
            if type_name in ("bool", "u8", "s8") or bit is not None:
                raise table.error(
                    "word_order",
                    f"{table.what}: word_order does not apply to {type_name}",
                    "remove word_order",
                )
            if (info.words == 1 or type_name == "str") and order not in (
                "high_first",
                "high_first_swapped",
            ):
                raise table.error(
                    "word_order",
                    f"{table.what}: {type_name} has a byte order but no word order",
                    'use "high_first" or "high_first_swapped" (bytes swapped), or remove it',
                )
        else:
            order = self.word_order if info.words > 1 else "high_first"

        is_number = info.kind in ("int", "float") and not (bit is not None and width == 1)
        scale = table.number("scale")
        offset = table.number("offset")
        precision = table.integer("precision", 0, 10)
        for key in ("scale", "offset", "precision"):
            if table.has(key) and not is_number:
                raise table.error(
                    key,
                    f"{table.what}: {key} does not apply to a {type_name}",
                    f"remove {key}",
                )
        if scale == 0:
            raise table.error("scale", f"{table.what}: scale = 0", "use a non-zero scale")

        sign_bit = table.integer("sign_bit")
        flag_bits: dict[int, FlagBit] = {}
        if sign_bit is not None or table.has("flag_bits"):
            key = "sign_bit" if sign_bit is not None else "flag_bits"
            if type_name not in UNSIGNED:
                raise table.error(
                    key,
                    f"{table.what}: {key} needs an unsigned type, not {type_name}",
                    'write type = "u16" or "u32" (the raw value, sign and flags included)',
                )
            if sign_bit is not None and not 0 <= sign_bit < info.bits:
                raise table.error(
                    "sign_bit",
                    f"{table.what}: sign_bit {sign_bit} is outside a {type_name}",
                    f"use a bit from 0 to {info.bits - 1}",
                )
            flag_bits = self.flags(table, info.bits)
            if sign_bit is not None and sign_bit in flag_bits:
                raise self.src.error(
                    (*table.at, "flag_bits", str(sign_bit)),
                    f"{table.what}: bit {sign_bit} is both the sign_bit and a flag bit",
                    "give the sign and each flag a bit of its own",
                )

        enum: dict[int, str] = {}
        if table.has("enum"):
            if info.kind in ("float", "str"):
                raise table.error(
                    "enum", f"{table.what}: enum does not apply to {type_name}", "remove enum"
                )
            if bit is not None:
                low, high = 0, (1 << width) - 1
            elif sign_bit is not None or flag_bits:
                high = (1 << info.bits) - 1
                low = -high if sign_bit is not None else 0
            elif info.signed:
                low, high = -(1 << (info.bits - 1)), (1 << (info.bits - 1)) - 1
            else:
                low, high = 0, (1 << info.bits) - 1
            enum = self.names(table, "enum", low, high, f"a {type_name}")

        bits: dict[int, str] = {}
        if table.has("bits"):
            if type_name not in UNSIGNED:
                raise table.error(
                    "bits",
                    f"{table.what}: bits needs an unsigned type, not {type_name}",
                    'write type = "u16" (or u32 for a 32-bit bit field)',
                )
            for key in (
                "enum",
                "scale",
                "offset",
                "precision",
                "sign_bit",
                "flag_bits",
                "min",
                "max",
            ):
                if table.has(key):
                    raise table.error(
                        key,
                        f"{table.what}: '{key}' does not go with bits (a register of named bits)",
                        f"remove {key}, or split the entry",
                    )
            bits = self.names(table, "bits", 0, info.bits - 1, f"the bits of a {type_name}")

        low_limit = table.number("min")
        high_limit = table.number("max")
        for key in ("min", "max"):
            if table.has(key) and info.kind in ("str", "bool"):
                raise table.error(
                    key, f"{table.what}: {key} does not apply to a {type_name}", f"remove {key}"
                )
        if low_limit is not None and high_limit is not None and low_limit > high_limit:
            raise table.error(
                "min",
                f"{table.what}: min {low_limit} is greater than max {high_limit}",
                "swap them, or check the manual",
            )
        default = self.default(table, type_name, enum, low_limit, high_limit)

        access = table.opt_text("access")
        if access is None:
            access = "r" if where in INPUT_TABLES else "rw"
        elif access not in ACCESS:
            close = nearest(access, ACCESS)
            fix = f"write '{close}' instead of '{access}'" if close else 'use "r", "w" or "rw"'
            raise table.error("access", f"{table.what}: access = '{access}'", fix)
        if where in INPUT_TABLES and access != "r":
            raise table.error(
                "access",
                f"{table.what}: access '{access}' but {where} cannot be written",
                'write access = "r" or remove it',
            )

        return ValueSpec(
            type=type_name,
            byte=byte,
            bit=bit,
            width=width,
            length=length,
            word_order=order,
            scale=1 if scale is None else scale,
            offset=0 if offset is None else offset,
            precision=precision,
            unit=table.text("unit"),
            sign_bit=sign_bit,
            flag_bits=MappingProxyType(flag_bits),
            enum=MappingProxyType(enum),
            bits=MappingProxyType(bits),
            min=low_limit,
            max=high_limit,
            default=default,
            access=access,
            description=table.text("description"),
            notes=table.texts("notes"),
        )

    def default(
        self,
        table: Table,
        type_name: str,
        enum: Mapping[int, str],
        low: int | float | None,
        high: int | float | None,
    ) -> int | float | str | bool | None:
        value = table.get("default")
        if value is None:
            return None
        kind_name = TYPES[type_name].kind
        if isinstance(value, str):
            if kind_name == "str" or value in enum.values():
                return value
            if enum:
                names = ", ".join(f'"{name}"' for name in enum.values())
                raise table.error(
                    "default",
                    f"{table.what}: default '{value}' is not one of the enum names",
                    f"use one of {names}, or the number",
                )
            raise table.wrong("default", "a number", "default = 300 (no quotes)")
        if isinstance(value, bool):
            if kind_name != "bool":
                raise table.wrong("default", "a number", "default = 1")
            return value
        if isinstance(value, (int, float)):
            if kind_name == "str":
                raise table.wrong("default", "a string", 'default = "..."')
            if kind_name == "bool" and value not in (0, 1):
                raise table.error(
                    "default", f"{table.what}: default {value} for a bool", "use true or false"
                )
            if (low is not None and value < low) or (high is not None and value > high):
                raise table.error(
                    "default",
                    f"{table.what}: default {value} is outside min {low} .. max {high}",
                    "check the manual: fix the default or the range",
                )
            return value
        raise table.wrong("default", "a number or a string", "default = 300")

    # -- entries --------------------------------------------------------------------------

    def entry(self, index: int, raw: object) -> list[Entry]:
        at: KeyPath = ("entry", index)
        what = f"entry #{index + 1}"
        if isinstance(raw, dict) and isinstance(raw.get("name"), str) and raw["name"].strip():
            what = f"entry '{raw['name']}'"
        table = Table(self.src, at, raw, what, ENTRY_KEYS)
        name = table.need_text("name", 'name = "as the manual calls it"')
        where = self.place(table)
        spec = self.spec(table, where.table, where.bit)
        line = self.src.lines.line(at)
        count, stride, first_n = self.repeat(table, spec.size, name)
        made: list[Entry] = []
        for k in range(count):
            address = where.address + k * stride
            if address + spec.size - 1 > 65535:
                raise table.error(
                    "repeat" if k else None,
                    f"{what} runs past PDU address 65535",
                    "check the place, size and repeat",
                )
            copy_spec = spec
            copy_name = name
            if count > 1 or "{n}" in name:
                n = str(first_n + k)
                copy_name = name.replace("{n}", n)
                if "{n}" in spec.description:
                    copy_spec = replace(spec, description=spec.description.replace("{n}", n))
            ref = where.ref
            if k:
                ref = (
                    where.space.format(address, where.bit)
                    if where.space is not None
                    else f"pdu {address}"
                )
            made.append(Entry(where.table, address, copy_name, copy_spec, ref, line))
        return made

    def repeat(self, table: Table, size: int, name: str) -> tuple[int, int, int]:
        count = table.integer("repeat", 1, 65536)
        stride = table.integer("stride", 1, 65535)
        first_n = table.integer("n_first")
        if count is None:
            for key in ("stride", "n_first"):
                if table.has(key):
                    raise table.error(
                        key,
                        f"{table.what}: {key} without repeat",
                        f"add repeat = N, or remove {key}",
                    )
            if "{n}" in name:
                raise table.error(
                    "name",
                    f"{table.what}: the name has {{n}} but the entry has no repeat",
                    "add repeat = N, or remove {n} from the name",
                )
            return 1, size, 1
        if count > 1 and "{n}" not in name:
            raise table.error(
                "name",
                f"{table.what}: repeat = {count} but the name has no {{n}}",
                'put {n} where the copy number goes, e.g. name = "Step {n} power"',
            )
        if stride is None:
            stride = size
        elif stride < size:
            raise table.error(
                "stride",
                f"{table.what}: stride {stride} is smaller than the entry's {size} elements",
                f"use a stride of at least {size}",
            )
        return count, stride, 1 if first_n is None else first_n

    def check_overlaps(self, entries: Sequence[Entry]) -> list[Entry]:
        taken: dict[tuple[str, int], list[tuple[int, Entry]]] = {}
        kept: list[Entry] = []
        for entry in entries:
            mask = _mask(entry)
            clash: tuple[int, Entry] | None = None
            for address in range(entry.address, entry.end):
                for other_mask, other in taken.get((entry.table, address), ()):
                    if other_mask & mask:
                        clash = (address, other)
                        break
                if clash is not None:
                    break
            if clash is not None:
                address, other = clash
                where = f"{entry.table} PDU address {address}"
                if self.drop_overlaps:
                    self.notes.append(
                        f"'{entry.name}' left out: it shares {where} with '{other.name}'"
                    )
                    continue
                self.errors.append(
                    DictionaryError(
                        self.src.path,
                        entry.line,
                        f"entry '{entry.name}' (line {entry.line}) overlaps entry "
                        f"'{other.name}' (line {other.line}) at {where}",
                        "give each register, or each bit of one, to one entry: check the refs "
                        "and sizes (32-bit types take 2 registers, 64-bit 4, str its length)",
                    )
                )
                continue
            for address in range(entry.address, entry.end):
                taken.setdefault((entry.table, address), []).append((mask, entry))
            kept.append(entry)
        return kept

    # -- windows, functions, exceptions ---------------------------------------------------

    def window(self, index: int, raw: object) -> Window:
        at: KeyPath = ("window", index)
        what = f"window #{index + 1}"
        if isinstance(raw, dict) and isinstance(raw.get("name"), str):
            what = f"window '{raw['name']}'"
        table = Table(self.src, at, raw, what, WINDOW_KEYS)
        name = table.need_text("name", 'name = "Setup parameter"')
        select, select_ref = self.register_place(table, "select")
        value, value_ref = self.register_place(table, "value")
        parameters: dict[int, Parameter] = {}
        for number, item in enumerate(table.tables("parameter", "[[window.parameter]]")):
            for parameter in self.parameter((*at, "parameter", number), item, name):
                before = parameters.get(parameter.number)
                if before is not None:
                    raise self.src.error(
                        (*at, "parameter", number, "number"),
                        f"window '{name}': parameter {parameter.number} '{parameter.name}' "
                        f"(line {parameter.line}) repeats parameter '{before.name}' "
                        f"(line {before.line})",
                        "give each parameter its own number",
                    )
                parameters[parameter.number] = parameter
        table.texts("notes")
        return Window(
            name=name,
            select=select,
            value=value,
            parameters=MappingProxyType(parameters),
            select_ref=select_ref,
            value_ref=value_ref,
            description=table.text("description"),
            line=self.src.lines.line(at),
        )

    def parameter(self, at: KeyPath, raw: object, window: str) -> list[Parameter]:
        what = f"window '{window}' parameter"
        if isinstance(raw, dict) and isinstance(raw.get("name"), str):
            what = f"{what} '{raw['name']}'"
        table = Table(self.src, at, raw, what, PARAMETER_KEYS)
        number = table.need_integer("number", 0, 65535)
        name = table.need_text("name", 'name = "P.01 ..."')
        spec = self.spec(table, "holding_registers", None)
        count, stride, first_n = self.repeat(table, 1, name)
        line = self.src.lines.line(at)
        out: list[Parameter] = []
        for k in range(count):
            copy = name.replace("{n}", str(first_n + k)) if count > 1 else name
            numbered = number + k * stride
            if numbered > 65535:
                raise table.error("repeat", f"{what}: numbers run past 65535", "check repeat")
            out.append(Parameter(numbered, copy, spec, line))
        return out

    def fields(self, table: Table, key: str, what: str) -> tuple[VendorField, ...]:
        items = table.get(key)
        if items is None:
            return ()
        if not isinstance(items, list):
            raise table.wrong(
                key, "an array of fields", f'{key} = [ {{ name = "...", type = "u8" }} ]'
            )
        out: list[VendorField] = []
        for index, item in enumerate(items):
            at = (*table.at, key, index)
            label = f"{what} {key} field #{index + 1}"
            if isinstance(item, dict) and isinstance(item.get("name"), str):
                label = f"{what} {key} field '{item['name']}'"
            field = Table(self.src, at, item, label, FIELD_KEYS)
            name = field.need_text("name", 'name = "..."')
            type_name = field.opt_text("type")
            if type_name is None:
                raise field.missing("type", 'type = "u8" (or u16, u32, bytes)')
            if type_name not in FIELD_SIZES:
                close = nearest(type_name, FIELD_SIZES)
                fix = (
                    f"write '{close}' instead of '{type_name}'"
                    if close
                    else "use u8, u16, u32 or bytes"
                )
                raise field.error("type", f"{label}: unknown type '{type_name}'", fix)
            length = field.integer("length", 1, 252)
            if length is not None and type_name != "bytes":
                raise field.error("length", f"{label}: length applies to bytes", "remove length")
            if type_name == "bytes" and length is None and index != len(items) - 1:
                raise field.error(
                    "type",
                    f"{label}: bytes without length before the last field",
                    "add length = N (only the last field may take the rest of the frame)",
                )
            enum: dict[int, str] = {}
            if field.has("enum"):
                if type_name == "bytes":
                    raise field.error("enum", f"{label}: enum on bytes", "remove enum")
                top = (1 << (8 * FIELD_SIZES[type_name])) - 1
                enum = self.names(field, "enum", 0, top, f"a {type_name}")
            out.append(
                VendorField(
                    name, type_name, length, MappingProxyType(enum), field.text("description")
                )
            )
        return tuple(out)

    def functions(self, top: Table) -> dict[int, VendorFunction]:
        out: dict[int, VendorFunction] = {}
        for index, raw in enumerate(top.tables("function", "[[function]]")):
            at: KeyPath = ("function", index)
            what = f"function #{index + 1}"
            if isinstance(raw, dict) and isinstance(raw.get("name"), str):
                what = f"function '{raw['name']}'"
            table = Table(self.src, at, raw, what, FUNCTION_KEYS)
            code = table.integer("code", 1, 127)
            if code is None:
                raise table.missing("code", "code = 0x41")
            if code in STANDARD_FUNCTIONS:
                raise table.error(
                    "code",
                    f"{what}: code {code} is a standard Modbus function",
                    "modscope dissects standard codes itself; vendor codes are usually 65-72 "
                    "or 100-110",
                )
            if code in out:
                raise table.error(
                    "code",
                    f"{what}: code {code} is already '{out[code].name}' (line {out[code].line})",
                    "give each function code one [[function]]",
                )
            table.texts("notes")
            out[code] = VendorFunction(
                code=code,
                name=table.need_text("name", 'name = "..."'),
                request=self.fields(table, "request", what),
                response=self.fields(table, "response", what),
                broadcast=bool(table.flag("broadcast")),
                description=table.text("description"),
                line=self.src.lines.line(at),
            )
        return out

    def exceptions(self, top: Table) -> dict[int, str]:
        raw = top.subtable("exceptions")
        out: dict[int, str] = {}
        for text, meaning in (raw or {}).items():
            at: KeyPath = ("exceptions", text)
            code = parse_key_number(text)
            if code is None or not 1 <= code <= 255:
                raise self.src.error(
                    at,
                    f"[exceptions]: key '{text}' is not an exception code 1-255",
                    'write codes as decimal ("3") or hex ("0x03") strings',
                )
            if not isinstance(meaning, str) or not meaning.strip():
                raise self.src.error(
                    at,
                    f"[exceptions]: code {code} must have a meaning, not {kind(meaning)}",
                    f'write "{text}" = "what it means on this device"',
                )
            out[code] = meaning
        return out

    def report_server_id(self, top: Table) -> ReportServerId | None:
        raw = top.get("report_server_id")
        if raw is None:
            return None
        table = Table(self.src, ("report_server_id",), raw, "[report_server_id]", REPORT_KEYS)
        table.texts("notes")
        return ReportServerId(
            self.fields(table, "fields", "[report_server_id]"),
            self.src.lines.line(("report_server_id",)),
        )


def _mask(entry: Entry) -> int:
    """The bits of each register an entry claims."""
    spec = entry.spec
    if entry.table in BIT_TABLES:
        return 1
    if spec.bit is not None:
        return ((1 << spec.width) - 1) << spec.bit
    if spec.byte == "high":
        return 0xFF00
    if spec.byte == "low":
        return 0x00FF
    return 0xFFFF
