"""Provides the dictionary builder: parsed TOML-shaped data checked into a DeviceDictionary.

Every problem becomes a DictionaryError naming the line and the fix. Problems in one
entry do not stop the others from being checked; all of them ride on the first error.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import partial
from types import MappingProxyType
from typing import TypeVar

from .device import DeviceDictionary, Window
from .errors import DictionaryError, nearest
from .model import BIT_TABLES, MODEL_PATTERN, Entry, Parameter, Space, Timing
from .places import Places
from .reader import Source, Table, kind
from .tomlpos import KeyPath
from .values import VALUE_KEYS, ValueReader, names, parse_key_number, table_name, word_order_name
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
DEVICE_KEYS = ("model", "name", "manual", "word_order", "default_space", "unit", "notes")
TIMING_KEYS = (
    "response_ms",
    "long_response_ms",
    "long_response_functions",
    "quiet_after_write_ms",
    "quiet_after_functions",
)
SPACE_KEYS = ("table", "prefix", "suffix", "radix", "first", "pdu", "bit_first", "width")
PLACE_KEYS = ("ref", "address", "space", "pdu", "table")
ENTRY_KEYS = PLACE_KEYS + VALUE_KEYS
PARAMETER_KEYS = ("number", *VALUE_KEYS)
WINDOW_KEYS = ("name", "select", "value", "parameter", "description", "notes")
FUNCTION_KEYS = ("code", "name", "broadcast", "request", "response", "description", "notes")
FIELD_KEYS = ("name", "type", "length", "enum", "description")
REPORT_KEYS = ("fields", "description", "notes")
STANDARD_FUNCTIONS = frozenset({1, 2, 3, 4, 5, 6, 7, 8, 11, 12, 15, 16, 17, 20, 21, 22, 23, 24, 43})
OVERLAP_FIX = (
    "give each register, or each bit of one, to one entry: check the refs and sizes "
    "(32-bit types take 2 registers, 64-bit 4, str its length)"
)


@dataclass(frozen=True, slots=True)
class DeviceHead:
    """What [device] says."""

    model: str
    name: str
    manual: str
    notes: tuple[str, ...]
    unit: int | None = None  # the slave address this dictionary was made for (a draft)


@dataclass(frozen=True, slots=True)
class Repeat:
    """How an entry expands: `count` copies, `stride` elements apart, numbered from `first`."""

    count: int
    stride: int
    first: int

    def name(self, name: str, k: int) -> str:
        return name.replace("{n}", str(self.first + k)) if "{n}" in name else name


class Builder:
    """Checks one parsed file and builds its DeviceDictionary."""

    def __init__(self, src: Source, *, drop_overlaps: bool = False) -> None:
        self.src = src
        self.drop_overlaps = drop_overlaps  # imports: leave clashing entries out, with a note
        self.errors: list[DictionaryError] = []
        self.notes: list[str] = []
        self.spaces: dict[str, Space] = {}
        self.places = Places({}, None)
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
        self.places = Places(self.spaces, self.default_space)

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
            model=device.model,
            name=device.name,
            path=self.src.path,
            entries=tuple(entries),
            manual=device.manual,
            word_order=self.word_order,
            default_space=self.default_space,
            notes=(*device.notes, *self.notes),
            timing=timing,
            spaces=MappingProxyType(dict(self.spaces)),
            functions=MappingProxyType(functions or {}),
            exceptions=MappingProxyType(exceptions or {}),
            windows=tuple(windows),
            report_server_id=report,
            unit_hint=unit_hint if unit_hint is not None else device.unit,
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

    def device(self, top: Table) -> DeviceHead:
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
        name = table.label("name") or model
        manual = table.text("manual")
        order = table.opt_text("word_order")
        if order is not None:
            self.word_order = word_order_name(table, order)
        self.default_space = table.opt_text("default_space")
        unit = table.integer("unit", 1, 247)
        return DeviceHead(model, name, manual, table.texts("notes"), unit)

    def check_default_space(self, top: Table) -> None:
        if self.default_space is not None and self.default_space not in self.spaces:
            table = Table(self.src, ("device",), top.get("device"), "[device]", DEVICE_KEYS)
            raise table.error(
                "default_space",
                f"default_space '{self.default_space}' is not a declared space",
                Places(self.spaces, None).space_fix(self.default_space),
            )

    def read_spaces(self, top: Table) -> None:
        raw = top.subtable("spaces")
        for name, body in (raw or {}).items():
            table = Table(self.src, ("spaces", name), body, f"[spaces.{name}]", SPACE_KEYS)
            target = table_name(table, "table")
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

    # -- entries --------------------------------------------------------------------------

    def entry(self, index: int, raw: object) -> list[Entry]:
        at: KeyPath = ("entry", index)
        what = f"entry #{index + 1}"
        if isinstance(raw, dict) and isinstance(raw.get("name"), str) and raw["name"].strip():
            what = f"entry '{raw['name']}'"
        table = Table(self.src, at, raw, what, ENTRY_KEYS)
        name = table.need_text("name", 'name = "as the manual calls it"')
        where = self.places.place(table)
        spec = ValueReader(table, where.table, where.bit, self.word_order).read()
        line = self.src.lines.line(at)
        repeat = self.repeat(table, spec.size, name)
        made: list[Entry] = []
        for k in range(repeat.count):
            address = where.address + k * repeat.stride
            if address + spec.size - 1 > 65535:
                raise table.error(
                    "repeat" if k else None,
                    f"{what} runs past PDU address 65535",
                    "check the place, size and repeat",
                )
            copy = spec
            if "{n}" in spec.description:
                copy = replace(spec, description=repeat.name(spec.description, k))
            ref = where.ref_at(address) if k else where.ref
            made.append(Entry(where.table, address, repeat.name(name, k), copy, ref, line))
        return made

    def repeat(self, table: Table, size: int, name: str) -> Repeat:
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
            return Repeat(1, size, 1)
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
        return Repeat(count, stride, 1 if first_n is None else first_n)

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
                        f"entry '{entry.name}'{_line(entry.line)} overlaps entry "
                        f"'{other.name}'{_line(other.line)} at {where}",
                        OVERLAP_FIX,
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
        select = self.places.register(table, "select")
        value = self.places.register(table, "value")
        parameters: dict[int, Parameter] = {}
        for number, item in enumerate(table.tables("parameter", "[[window.parameter]]")):
            for parameter in self.parameter((*at, "parameter", number), item, name):
                before = parameters.get(parameter.number)
                if before is not None:
                    raise self.src.error(
                        (*at, "parameter", number, "number"),
                        f"window '{name}': parameter {parameter.number} '{parameter.name}'"
                        f"{_line(parameter.line)} repeats parameter '{before.name}'"
                        f"{_line(before.line)}",
                        "give each parameter its own number",
                    )
                parameters[parameter.number] = parameter
        table.texts("notes")
        return Window(
            name=name,
            select=select.address,
            value=value.address,
            parameters=MappingProxyType(parameters),
            select_ref=select.ref,
            value_ref=value.ref,
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
        spec = ValueReader(table, "holding_registers", None, self.word_order).read()
        repeat = self.repeat(table, 1, name)
        line = self.src.lines.line(at)
        out: list[Parameter] = []
        for k in range(repeat.count):
            copy = repeat.name(name, k)
            numbered = number + k * repeat.stride
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
                enum = names(field, "enum", 0, top, f"a {type_name}")
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
                    f"{what}: code {code} is already '{out[code].name}'{_line(out[code].line)}",
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


def _line(line: int | None) -> str:
    return "" if line is None else f" (line {line})"


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
