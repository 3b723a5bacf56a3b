"""Provides DeviceDictionary and Window: a loaded device model and its decoding."""

from __future__ import annotations

import bisect
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

from .decode import decode_entry, decode_flag, decode_spec, range_problems
from .model import (
    BIT_TABLES,
    Entry,
    Parameter,
    RegisterValue,
    Space,
    Timing,
    canonical_table,
)
from .vendor import ReportServerId, VendorFunction


@dataclass(frozen=True, slots=True)
class Window:
    """A stateful parameter window: a number written to `select` picks what `value` holds.

    `select` and `value` are PDU addresses; they apply whether the master uses holding
    registers (FC 3/6/16) or input registers (FC 4) to reach them.
    """

    name: str
    select: int
    value: int
    parameters: Mapping[int, Parameter]
    select_ref: str = ""
    value_ref: str = ""
    description: str = ""
    line: int | None = None

    def parameter_name(self, number: int) -> str:
        found = self.parameters.get(number)
        return found.name if found is not None else f"{self.name} {number}"

    def decode_select(
        self, number: int, *, table: str = "holding_registers", write: bool = True
    ) -> RegisterValue:
        """The select register holding `number`: names the parameter it picks."""
        number &= 0xFFFF
        found = self.parameters.get(number)
        if found is not None:
            text = f"{self.name} = {found.name} ({number})"
            value: str | int = found.name
        else:
            text = f"{self.name} = {number} (not in the dictionary)"
            value = number
        return RegisterValue(
            canonical_table(table), self.select, self.name, value, "", text, (number,)
        )

    def decode(
        self,
        number: int,
        words: Sequence[int],
        *,
        write: bool = False,
        table: str = "holding_registers",
    ) -> RegisterValue:
        """The value registers as read or written while parameter `number` is selected."""
        table = canonical_table(table)
        clean = [word & 0xFFFF for word in words]
        raw = tuple(clean)
        found = self.parameters.get(number & 0xFFFF)
        if found is None:
            name = f"{self.name} {number}"
            shown = " ".join(f"0x{word:04X}" for word in clean) or "(no registers)"
            text = f"{name} = {shown} (parameter not in the dictionary)"
            value = clean[0] if len(clean) == 1 else None
            return RegisterValue(table, self.value, name, value, "", text, raw)
        spec = found.spec
        if len(clean) < spec.size:
            noun = "register" if spec.size == 1 else "registers"
            text = f"{found.name} = ? (only {len(clean)} of {spec.size} {noun} in this frame)"
            return RegisterValue(table, self.value, found.name, None, spec.unit, text, raw, True)
        decoded = decode_spec(spec, clean[: spec.size])
        problems = range_problems(spec, decoded, write)
        if len(clean) > spec.size:
            problems.append(f"{len(clean)} registers for a {spec.size}-register parameter")
        text = f"{found.name} = {decoded.shown}"
        return RegisterValue(
            table,
            self.value,
            found.name,
            decoded.value,
            spec.unit,
            text,
            raw,
            False,
            tuple(problems),
        )


@dataclass(frozen=True, slots=True)
class _TableIndex:
    starts: tuple[int, ...]
    entries: tuple[Entry, ...]
    longest: int


def _index(entries: Sequence[Entry]) -> Mapping[str, _TableIndex]:
    out: dict[str, _TableIndex] = {}
    for table in ("coils", "discrete_inputs", "input_registers", "holding_registers"):
        mine = sorted(
            (e for e in entries if e.table == table),
            key=lambda e: (e.address, e.spec.bit if e.spec.bit is not None else -1),
        )
        longest = max((e.size for e in mine), default=1)
        out[table] = _TableIndex(tuple(e.address for e in mine), tuple(mine), longest)
    return MappingProxyType(out)


@dataclass(frozen=True, slots=True)
class DeviceDictionary:
    """Everything modscope knows about one device model. Immutable once loaded."""

    model: str
    name: str
    path: str
    entries: tuple[Entry, ...] = ()
    manual: str = ""
    word_order: str = "high_first"
    default_space: str | None = None
    notes: tuple[str, ...] = ()
    timing: Timing | None = None
    spaces: Mapping[str, Space] = field(default_factory=lambda: MappingProxyType({}))
    functions: Mapping[int, VendorFunction] = field(default_factory=lambda: MappingProxyType({}))
    exceptions: Mapping[int, str] = field(default_factory=lambda: MappingProxyType({}))
    windows: tuple[Window, ...] = ()
    report_server_id: ReportServerId | None = None
    unit_hint: int | None = None  # imports: the slave address the source file used
    _tables: Mapping[str, _TableIndex] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_tables", _index(self.entries))

    def _touching(self, table: str, start: int, end: int) -> Iterator[Entry]:
        index = self._tables[table]
        at = bisect.bisect_left(index.starts, start - index.longest + 1)
        while at < len(index.entries) and index.starts[at] < end:
            entry = index.entries[at]
            if entry.end > start:
                yield entry
            at += 1

    def entries_in(self, table: str) -> tuple[Entry, ...]:
        """The entries of one table in address order."""
        return self._tables[canonical_table(table)].entries

    def entries_at(self, table: str, address: int) -> tuple[Entry, ...]:
        """Every entry holding `address` (several when a register holds bit fields)."""
        return tuple(self._touching(canonical_table(table), address, address + 1))

    def lookup(self, table: str, address: int) -> Entry | None:
        """The entry holding `address` (the lowest bit field when there are several)."""
        found = self.entries_at(table, address)
        return found[0] if found else None

    def decode(
        self, table: str, start: int, words: Sequence[int], *, write: bool = False
    ) -> list[RegisterValue]:
        """Registers `start`.. as read or written: one value per entry they touch.

        Entries cut by the range come back `partial`. In the bit tables a nonzero word is
        an ON bit (0xFF00 as FC 5 writes it).
        """
        table = canonical_table(table)
        if table in BIT_TABLES:
            return self.decode_bits(table, start, [bool(word) for word in words], write=write)
        clean = [word & 0xFFFF for word in words]
        end = start + len(clean)
        out: list[RegisterValue] = []
        for entry in self._touching(table, start, end):
            low = max(entry.address, start)
            high = min(entry.end, end)
            out.append(
                decode_entry(entry, clean[low - start : high - start], low - entry.address, write)
            )
        return out

    def decode_bits(
        self, table: str, start: int, bits: Sequence[bool], *, write: bool = False
    ) -> list[RegisterValue]:
        """Coils or discrete inputs `start`.. as read or written: one value per entry."""
        table = canonical_table(table)
        if table not in BIT_TABLES:
            raise ValueError(f"decode_bits reads coils and discrete inputs, not {table}")
        end = start + len(bits)
        return [
            decode_flag(entry, bool(bits[entry.address - start]), write)
            for entry in self._touching(table, start, end)
        ]

    def window_at(self, address: int) -> Window | None:
        """The window whose select or value register is at `address`."""
        for window in self.windows:
            if address in (window.select, window.value):
                return window
        return None
