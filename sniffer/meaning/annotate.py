"""Provides annotation: register names, values and units for units bound to device models.

Most of it happens on demand, when a frame is shown. Two things need every frame in
order and are kept up to date as frames are indexed: which parameter a device's
parameter window has selected (a later read of the window's value is named after it),
and the device's own timing rules (answer time, quiet time after writes).
"""

from __future__ import annotations

import bisect
import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from itertools import compress
from pathlib import Path

from dissectors.dictionary import (
    DeviceDictionary,
    DictionaryError,
    RegisterValue,
    UnitBinding,
    load_bus,
    load_dictionaries,
    load_model,
    parse_unit_binding,
)
from dissectors.dictionary.device import Window
from dissectors.dissect import dissect
from dissectors.functions import FUNCTIONS, Registry
from dissectors.values import Dissection, RegisterData, Role
from sniffer.framing.columns import both, but_not, marking
from sniffer.framing.pairing import measure
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.meaning.sunspec import READS, SunSpecTracker
from sniffer.vocab import Flag, Kind

REGISTER_TABLES = ("holding_registers", "input_registers")


@dataclass(frozen=True, slots=True)
class Binding:
    """A slave address bound to a device model."""

    address: int
    label: str
    dictionary: DeviceDictionary


@dataclass
class _WindowTrack:
    window: Window
    rows: list[int] = field(default_factory=list)  # rows that wrote the select register
    numbers: list[int] = field(default_factory=list)  # the parameter each selected


def load_bindings(
    bus_file: str | Path | None = None,
    units: Sequence[str] = (),
    extra_dicts: Sequence[str | Path] = (),
) -> dict[int, Binding]:
    """Bindings from a bus file and `--unit 3=rvs-dn[:label]` options (which win).

    Dictionary files (TOML, Home Assistant YAML, CSV) come from `extra_dicts` and the bus
    file's `dictionaries`; one that says its slave address (an import, a draft) binds
    there unless the bus file or --unit binds that address.
    """
    bus = load_bus(bus_file) if bus_file is not None else None
    extra = [Path(p) for p in extra_dicts] + list(bus.dictionaries if bus else ())
    own: dict[str, DeviceDictionary] = {}
    for path in extra:
        for d in load_dictionaries(path):
            own.setdefault(d.model, d)

    found: list[tuple[UnitBinding, str | None]] = []
    if bus is not None:
        found.extend((b, bus.path) for b in bus.units.values())
    for text in units:
        try:
            found.append((parse_unit_binding(text), None))
        except ValueError as exc:
            raise DictionaryError("--unit", None, str(exc), "write --unit ADDRESS=MODEL") from exc
    out: dict[int, Binding] = {}
    for d in own.values():
        if d.unit_hint is not None and 1 <= d.unit_hint <= 247:
            out.setdefault(d.unit_hint, Binding(d.unit_hint, d.name, d))
    for b, named_in in found:
        d = own.get(b.model) or load_model(b.model, extra, named_in=named_in, line=b.line)
        out[b.address] = Binding(b.address, b.label or d.name, d)
    return out


def surely_over(store: FrameStore, i: int, ms: float) -> bool:
    """Whether answer row `i` came more than `ms` milliseconds after its request for
    whatever times its stamps allow: a latency the timing measures (not a bound, not
    unknown: `sniffer.framing.pairing.measure`) and longer than `ms` by more than one
    resolution, since each stamp may be off by that much. A 1 s clock's answer a second
    after its request is not slow against a 40 ms response time: it may have taken 0 s."""
    measured = measure(store, i)
    if measured is None or measured.bound:
        return False
    return (measured.raw - store.resolution) * 1000 > ms


class Annotator:
    """Names what bound units read and write. `update(store)` follows new frames."""

    def __init__(self, bindings: Mapping[int, Binding]) -> None:
        self.bindings = dict(bindings)
        self.registry = registry_of(self.bindings)  # what frames and dissects this bus
        self.next = 0
        # the rows it records (selections, scale factors) are numbered `base + i`, `i` a
        # row of the store it follows: 0, unless a windowed session that keeps them for
        # good (`Session.forget_annotation` with `keep_rows`) moves it on each segment, so
        # that they are numbered in the whole capture (the TUI's paged rows)
        self.base = 0
        self.keep_rows = False
        self.tracks: dict[tuple[int, int], _WindowTrack] = {}
        self.last_write: dict[int, tuple[float, int]] = {}  # unit -> (time, fc) of a write
        self.windows_of: dict[int, list[_WindowTrack]] = {}
        # units with no dictionary that show the SunSpec marker annotate themselves
        self.sunspec = SunSpecTracker(skip=self.bindings)
        for unit, b in self.bindings.items():
            for n, window in enumerate(b.dictionary.windows):
                track = self.tracks[(unit, n)] = _WindowTrack(window)
                self.windows_of.setdefault(unit, []).append(track)

    def label(self, unit: int) -> str:
        b = self.bindings.get(unit)
        return b.label if b is not None else self.sunspec.label(unit)

    # -- following the capture -----------------------------------------------------------

    def update(self, store: FrameStore) -> None:
        store.sync()
        start, n = self.next, len(store)
        if start >= n:
            return
        # Only two sorts of row need a look, picked out with C-level scans of the columns:
        # the rows of bound units, and answers to reads of registers (FC 3 or 4) of the
        # others (reads that may show a SunSpec device). Every other row is skipped
        # without a Python step of its own.
        bound = self.bindings
        units = store.unit[start:n].tobytes()
        answers = store.kind[start:n].tobytes().translate(_IS_RESPONSE)
        reads = store.fc[start:n].tobytes().translate(_IS_SUNSPEC_READ)
        of_bound = units.translate(marking(bound))
        follow = but_not(both(answers, reads), of_bound)
        if 1 in follow:
            self.sunspec.follow_mask(store, start, follow)
        if 1 in of_bound:
            kind = store.kind
            for i in compress(range(start, n), of_bound):
                k = kind[i]
                if k == Kind.REQUEST:
                    self._request(store, i, store.unit[i])
                elif k in (Kind.RESPONSE, Kind.EXCEPTION):
                    self._answer(store, i, store.unit[i])
        self.next = n

    def _request(self, store: FrameStore, i: int, unit: int) -> None:
        timing = self.bindings[unit].dictionary.timing
        if timing is not None and timing.quiet_after_write_ms is not None:
            last = self.last_write.get(unit)
            if last is not None and store.t[i] - last[0] < timing.quiet_after_write_ms / 1000:
                store.flags[i] |= Flag.QUIET_VIOLATED
        tracks = self.windows_of.get(unit)
        if tracks and not store.flags[i] & Flag.CHECK_BAD:
            # what the request writes, as the dissector reads it (FC 6, 16, 23)
            for data in dissect(store.view(i).body(), Role.REQUEST, registry=self.registry).data:
                if not data.write or data.address is None or data.table != "holding_registers":
                    continue
                for track in tracks:
                    k = track.window.select - data.address
                    if 0 <= k < len(data.values):
                        track.rows.append(self.base + i)
                        track.numbers.append(data.values[k])

    def _answer(self, store: FrameStore, i: int, unit: int) -> None:
        timing = self.bindings[unit].dictionary.timing
        req = store.partner[i]
        if timing is None or req == NO_PARTNER:
            return
        fc = store.fc[req]
        if timing.response_ms is not None and surely_over(store, i, timing.response_ms):
            store.flags[i] |= Flag.DEVICE_SLOW
        if fc in timing.quiet_after_functions and not store.fc[i] & 0x80:
            self.last_write[unit] = (store.t_end[i], fc)

    def knowing(self, whole: Annotator) -> Annotator:
        """This annotator, following a capture a segment at a time (a windowed pass), as
        one that saw every row describes the rows: with what `whole` (the same bindings,
        after every row of the capture) found of SunSpec devices (which units, their
        models, the names they gave), and this one's own state for what depends on the
        row (the parameter a window had selected, a scale factor's value): those count
        only the rows before it, which this one has seen. Shares this one's state (it
        goes on as this one follows more rows); make it anew for each segment."""
        made = copy.copy(self)
        tracker = made.sunspec = copy.copy(whole.sunspec)
        mine = self.sunspec.units
        tracker.units = {
            unit: replace(found, scale=mine[unit].scale if unit in mine else {})
            for unit, found in whole.sunspec.units.items()
        }
        return made

    def selected(self, unit: int, window_index: int, row: int) -> int | None:
        """The parameter a window had selected when `row` was sent."""
        track = self.tracks.get((unit, window_index))
        if track is None:
            return None
        k = bisect.bisect_left(track.rows, row)
        return track.numbers[k - 1] if k else None

    # -- on demand -----------------------------------------------------------------------

    def registers(self, unit: int, row: int, dissection: Dissection) -> list[RegisterValue]:
        """Named values a frame carries, for a bound unit (empty for others)."""
        b = self.bindings.get(unit)
        if b is None:
            return self.sunspec.registers(unit, row, dissection)
        out: list[RegisterValue] = []
        for data in dissection.data:
            if data.address is None or not data.values:
                continue
            out.extend(self._decode(b, unit, row, data))
        return out

    def _decode(self, b: Binding, unit: int, row: int, data: RegisterData) -> list[RegisterValue]:
        d = b.dictionary
        if data.table in REGISTER_TABLES:
            assert data.address is not None
            values = list(data.values)
            start = data.address
            out: list[RegisterValue] = []
            for n, window in enumerate(d.windows):
                if not _covers(start, len(values), window.value):
                    continue
                number = self.selected(unit, n, row)
                if number is None:
                    continue
                tail = values[window.value - start :]
                out.append(window.decode(number, tail, write=data.write, table=data.table))
                values = values[: window.value - start]
                break
            decoded = d.decode(data.table, start, values, write=data.write) if values else []
            return decoded + out
        assert data.address is not None
        return d.decode_bits(
            data.table, data.address, [bool(v) for v in data.values], write=data.write
        )

    def windows_read(self, unit: int, dissection: Dissection | None) -> tuple[int, ...]:
        """The parameter windows of `unit` whose value register the dissection's register
        data covers: their selection when the row was sent names what it carries (see
        `_decode`)."""
        b = self.bindings.get(unit)
        if dissection is None or b is None or not b.dictionary.windows:
            return ()
        found: list[int] = []
        for data in dissection.data:
            if data.address is None or not data.values or data.table not in REGISTER_TABLES:
                continue
            for n, window in enumerate(b.dictionary.windows):
                if _covers(data.address, len(data.values), window.value) and n not in found:
                    found.append(n)
        return tuple(found)

    def exception_meaning(self, unit: int, code: int) -> str:
        b = self.bindings.get(unit)
        return b.dictionary.exceptions.get(code, "") if b is not None else ""


def registry_of(bindings: Mapping[int, Binding]) -> Registry:
    """The public function codes plus the vendor codes of the bound devices, compiled into
    specs like the public ones (a code two devices define is the first one's)."""
    registry = FUNCTIONS
    for b in bindings.values():
        new = {code: f for code, f in b.dictionary.functions.items() if code not in registry}
        registry = registry.with_vendor(new)
    return registry


def _covers(start: int, count: int, address: int) -> bool:
    return start <= address < start + count


_IS_RESPONSE = marking((Kind.RESPONSE,))  # kind byte -> 0/1
_IS_SUNSPEC_READ = marking(READS)  # function byte -> 0/1: a read SunSpec's tracker takes
