"""Provides SunSpec recognition: a unit the master reads the `SunS` marker and model chain
from is named and annotated from the SunSpec model definitions, with no dictionary.

The tracker follows the capture in order (the annotator calls `follow` for each answer
to a read of registers, FC 3 or FC 4). A unit becomes a candidate when an answer shows
the marker 0x5375 0x6E53 at one of the usual base addresses: PDU 40000 (the "40001" of
the SunSpec documents), 50000 or 0, and PDU 40001, 50001 or 1 for devices and masters that
took the 1-based number as the address. From then on the registers the master reads with
that function code are kept (SunSpec's registers are holding registers, FC 3; devices
that serve the same map as input registers are read with FC 4, and the tracker keeps
to the table the marker was found in), and the chain is walked from the base: model id,
length, the model's registers, the next id, ..., up to the end marker 0xFFFF. A model
whose header was never read ends the chain known so far; it grows as the master reads on.

One rule picks the reads, whatever carries them: the answer's function code is one of
`READS`, its check is good, it is paired, and its request's PDU (function code, start,
count) names the registers read. The request's PDU is found by its envelope: after the
unit byte of an RTU frame (serial, or RTU over TCP/UDP), after the MBAP header and unit
byte of a Modbus TCP frame, in the decoded hex of an ASCII frame. The compiled first look
(sniffer/_core.c: sunspec_rows) is given these numbers (`_READS_MASK`, `_FRAMES`) at
each call rather than keeping its own.

Values are scaled by their model's scale-factor registers (`_SF` points): the value in
the same frame when the frame carries it, else the last value the capture showed before
that frame. The scale factors' values are kept as they change, so a frame is decoded
with the scale factors in force when it was sent, whenever it is shown.
"""

from __future__ import annotations

import bisect
from array import array
from collections.abc import Container, Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from itertools import compress
from typing import Any

from dissectors import mbap
from dissectors.dictionary import RegisterValue
from dissectors.dictionary.sunspec import (
    END_ID,
    HOLDING,
    MARKER,
    ModelDef,
    ModelLibrary,
    PointDef,
    decode_point,
    default_library,
)
from dissectors.envelope import ascii_body
from dissectors.values import Dissection
from sniffer import core
from sniffer.framing.columns import marking
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.vocab import Flag

BASES = (40000, 50000, 0, 40001, 50001, 1)  # PDU addresses of the marker, likeliest first
_SORTED_BASES = tuple(sorted(BASES))
_BASES_ARRAY = array("q", _SORTED_BASES)
MAX_MODELS = 64  # a longer chain is not believed
READ_HOLDING = 3
READ_INPUT = 4
READS = (READ_HOLDING, READ_INPUT)  # the reads that may show a SunSpec device
TABLES = {READ_HOLDING: HOLDING, READ_INPUT: "input_registers"}  # what each reads
_READS_MASK = marking(READS)  # function byte -> 0/1
# Where a request's PDU lies in its row's bytes, by envelope: (bytes before the function
# code, bytes after the PDU). RTU (on a serial line, or over TCP/UDP): unit byte, PDU,
# CRC. Modbus TCP: the MBAP header (its seven bytes end with the unit), PDU, nothing after.
# ASCII rows are decoded first (their body is unit byte and PDU).
_RTU_FRAME = (1, 2)
_MBAP_FRAME = (mbap.HEADER_SIZE, 0)
_READ_PDU = 5  # function code, first register, count
_FRAMES = array("q", (*_RTU_FRAME, *_MBAP_FRAME, _READ_PDU))  # the same, for the core
_CHECK_BAD, _ASCII, _MBAP = int(Flag.CHECK_BAD), int(Flag.ASCII), int(Flag.MBAP)
INSTALL_HINT = "install modscope[sunspec] (pysunspec2) to name its values"


@dataclass(frozen=True, slots=True)
class ModelInstance:
    """One model of a device's chain: its id, first register (the ID) and length."""

    id: int
    start: int
    length: int
    definition: ModelDef | None

    @property
    def end(self) -> int:
        """One past the model's last register."""
        return self.start + 2 + self.length

    @property
    def title(self) -> str:
        d = self.definition
        label = (d.label or d.name) if d is not None else "unknown model"
        return f"model {self.id} ({label})"


@dataclass
class _History:
    """A register's values as they changed: the row of each change and the value."""

    rows: list[int] = field(default_factory=list)
    values: list[int] = field(default_factory=list)

    def add(self, row: int, value: int) -> None:
        if not self.values or self.values[-1] != value:
            self.rows.append(row)
            self.values.append(value)

    def at(self, row: int) -> int | None:
        k = bisect.bisect_right(self.rows, row)
        return self.values[k - 1] if k else None


@dataclass
class SunSpecUnit:
    """What is known of one SunSpec device (`function`: the read that showed its marker,
    FC 3 or 4; the device's registers are that read's table)."""

    unit: int
    base: int
    image: dict[int, int] = field(default_factory=dict)  # register -> last value read
    models: tuple[ModelInstance, ...] = ()
    complete: bool = False  # the chain's end marker was read
    layouts: dict[int, tuple[PointDef, ...]] = field(default_factory=dict)  # by start
    scale: dict[int, _History] = field(default_factory=dict)  # sf register -> history
    function: int = READ_HOLDING

    @property
    def table(self) -> str:
        return TABLES[self.function]

    def model_at(self, address: int) -> ModelInstance | None:
        for m in self.models:
            if m.start <= address < m.end:
                return m
        return None

    def describe(self) -> str:
        ids = ", ".join(str(m.id) for m in self.models) or "no model read yet"
        end = "" if self.complete else ", chain not read to its end"
        return f"SunSpec at {self.base}: models {ids}{end}"


class SunSpecTracker:
    """Finds SunSpec devices among the units with no dictionary and decodes their reads."""

    def __init__(self, library: ModelLibrary | None = None, skip: Container[int] = ()) -> None:
        self.library = library if library is not None else default_library()
        self.skip = skip
        self.units: dict[int, SunSpecUnit] = {}
        # rows are recorded as row `base + i` of the capture (see Annotator.base)
        self.base = 0

    # -- following the capture -------------------------------------------------------

    def follow(self, store: FrameStore, i: int) -> None:
        """Take in row `i` if it answers a read of registers (FC 3 or 4)."""
        self.follow_rows(store, (i,))

    def follow_rows(self, store: FrameStore, rows: Iterable[int]) -> None:
        """Take in those of `rows` (in order) that answer a read of registers (`READS`),
        in any envelope. Cheap for the reads of other units: the request's range is looked
        at first, in one loop over the rows with ints, not flags, rather than a call a
        row: a capture may hold hundreds of thousands of such answers."""
        fast = core.FAST
        if fast is not None:
            self._follow_fast(fast, store, array("q", rows))
            return
        self._follow(store, rows)

    def follow_mask(self, store: FrameStore, start: int, mask: bytes) -> None:
        """`follow_rows` of rows `start + k` of `store` for each k where `mask[k]` is 1
        (the annotator's picks): with the compiled core, no Python step a row."""
        fast = core.FAST
        if fast is not None:
            todo = array("q")
            todo.frombytes(fast.mask_rows(mask, start))
            self._follow_fast(fast, store, todo)
            return
        self._follow(store, compress(range(start, start + len(mask)), mask))

    def _follow_fast(self, fast: Any, store: FrameStore, todo: array[int]) -> None:
        """`follow_rows` of the rows `todo` (int64) with its first tests in the compiled
        core (sniffer/_core.c: sunspec_rows), which hands on only the rows the loop of
        `_follow` may take; a unit found on the way (its marker read) makes the rest be
        picked again, now with all its reads. Most rows fail the first tests, so they
        never reach Python."""
        skip = bytes(u in self.skip for u in range(256))
        at = 0
        while at < len(todo):
            known = bytes(u in self.units for u in range(256))
            picked = array("q")
            picked.frombytes(
                fast.sunspec_rows(store, todo, at, known, skip, _BASES_ARRAY, _READS_MASK, _FRAMES)
            )
            found: list[int] = []
            self._follow(store, _until_a_new_unit(self.units, todo, picked, found))
            at = found[0] if found else len(todo)  # picked again: the new unit's reads count

    def _follow(self, store: FrameStore, rows: Iterable[int]) -> None:
        """`follow_rows` in Python, the reference of the compiled filter."""
        fc, flags, partner, unit_of = store.fc, store.flags, store.partner, store.unit
        offset, length, channel, streams = store.offset, store.length, store.channel, store.streams
        skip, units, reads = self.skip, self.units, _READS_MASK
        for i in rows:
            function = fc[i]
            if not reads[function] or flags[i] & _CHECK_BAD:
                continue
            req = partner[i]
            if req == NO_PARTNER:
                continue
            unit = unit_of[i]
            if unit in skip:
                continue
            request: bytes | bytearray
            if flags[req] & _ASCII:
                request = _body(store, req)[1 : 1 + _READ_PDU]
                if len(request) < _READ_PDU:
                    continue
            else:
                head, tail = _MBAP_FRAME if flags[req] & _MBAP else _RTU_FRAME
                if length[req] < head + _READ_PDU + tail:
                    continue
                # the PDU's first bytes, not the whole frame: most answers are not SunSpec's
                at = offset[req] + head
                request = streams[channel[req]][at : at + _READ_PDU]
            start = (request[1] << 8) | request[2]
            count = (request[3] << 8) | request[4]
            found = units.get(unit)
            if found is None:
                k = bisect.bisect_left(_SORTED_BASES, start)
                if k == len(_SORTED_BASES) or _SORTED_BASES[k] + 2 > start + count:
                    continue  # no marker can be in this read
            elif found.function != function:
                continue  # the other table: not the registers the marker was read from
            answer = _body(store, i)
            if len(answer) < 3:
                continue
            data = answer[3 : 3 + answer[2]]
            if len(data) != 2 * count:
                continue
            words = [int.from_bytes(data[k : k + 2], "big") for k in range(0, len(data), 2)]
            self.take(unit, self.base + i, start, words, function)

    def take(
        self, unit: int, row: int, start: int, words: Sequence[int], function: int = READ_HOLDING
    ) -> None:
        """Registers `start`.. of `unit` as row `row` read them with `function` (FC 3 or
        4); a read of the other table than the marker's is left out."""
        found = self.units.get(unit)
        if found is None:
            base = _marker_in(start, words)
            if base is None:
                return
            found = self.units[unit] = SunSpecUnit(unit, base, function=function)
        elif found.function != function:
            return
        image = found.image
        for k, w in enumerate(words):
            image[start + k] = w
        for address, history in found.scale.items():
            if start <= address < start + len(words):
                history.add(row, words[address - start])
        if not found.complete:
            self._walk(found, row, start, words)

    def _walk(self, su: SunSpecUnit, row: int, start: int, words: Sequence[int]) -> None:
        image = su.image
        if (image.get(su.base), image.get(su.base + 1)) != MARKER:
            return
        models: list[ModelInstance] = []
        at = su.base + 2
        complete = False
        while len(models) < MAX_MODELS and at + 1 <= 0xFFFF:
            model_id, length = image.get(at), image.get(at + 1)
            if model_id is None or length is None:
                break
            if model_id == END_ID:
                complete = True
                break
            if at + 2 + length > 0x10000:
                break
            models.append(ModelInstance(model_id, at, length, self.library.get(model_id)))
            at += 2 + length
        if len(models) == len(su.models) and complete == su.complete:
            return
        su.models = tuple(models)
        su.complete = complete
        for m in models:
            if m.start in su.layouts or m.definition is None:
                continue
            layout = m.definition.layout(m.length)
            su.layouts[m.start] = layout
            names = {p.name: p for p in layout if p.type == "sunssf" and not p.group}
            for p in layout:
                if isinstance(p.sf, str) and p.sf in names:
                    address = m.start + names[p.sf].offset
                    if address not in su.scale:
                        history = su.scale[address] = _History()
                        # a scale factor read before the chain was known (this frame too)
                        if address in image:
                            history.add(row, image[address])

    def _name(self, su: SunSpecUnit) -> str:
        common = next((m for m in su.models if m.id == 1), None)
        if common is None:
            return "SunSpec device"
        words = [su.image.get(common.start + k, 0) for k in range(2, 34)]
        text = b"".join(w.to_bytes(2, "big") for w in words)
        maker = text[:32].rstrip(b"\x00").decode("latin-1").strip()
        model = text[32:64].rstrip(b"\x00").decode("latin-1").strip()
        return " ".join(x for x in ("SunSpec", maker, model) if x)

    # -- on demand ---------------------------------------------------------------------

    def label(self, unit: int) -> str:
        found = self.units.get(unit)
        if found is None or not found.models:
            return ""
        return self._name(found)

    def registers(self, unit: int, row: int, dissection: Dissection) -> list[RegisterValue]:
        """Named values of a frame of a recognised SunSpec unit (empty for others): the
        registers of the table its marker was read from (holding, or input for a device
        read with FC 4)."""
        su = self.units.get(unit)
        if su is None:
            return []
        out: list[RegisterValue] = []
        table = su.table
        for data in dissection.data:
            if data.table != table or data.address is None or not data.values:
                continue
            values = self.decode(su, row, data.address, data.values, write=data.write)
            if table != HOLDING:  # the model definitions name holding registers
                values = [replace(v, table=table) for v in values]
            out.extend(values)
        return out

    def decode(
        self, su: SunSpecUnit, row: int, start: int, words: Sequence[int], *, write: bool = False
    ) -> list[RegisterValue]:
        end = start + len(words)
        out: list[RegisterValue] = []
        if start < su.base + 2 and end > su.base:
            raw = tuple(words[max(0, su.base - start) : su.base + 2 - start])
            shown = "SunS" if raw == MARKER else " ".join(f"0x{w:04X}" for w in raw)
            text = f"SunSpec marker = {shown}"
            problems = () if raw == MARKER or len(raw) < 2 else ("not the SunS marker",)
            out.append(
                RegisterValue(
                    HOLDING, su.base, "SunSpec marker", shown, "", text, raw, len(raw) < 2, problems
                )
            )
        for m in su.models:
            if m.end <= start or m.start >= end:
                continue
            out.extend(self._model_values(su, m, row, start, words, write))
        last = su.models[-1].end if su.models else su.base + 2
        if su.complete and start <= last + 1 and end > last:
            raw = tuple(words[max(0, last - start) : last + 2 - start])
            out.append(
                RegisterValue(HOLDING, last, "SunSpec end", None, "", "SunSpec end of models", raw)
            )
        return out

    def _model_values(
        self,
        su: SunSpecUnit,
        m: ModelInstance,
        row: int,
        start: int,
        words: Sequence[int],
        write: bool,
    ) -> list[RegisterValue]:
        end = start + len(words)
        out: list[RegisterValue] = []
        if start <= m.start < end:
            text = f"Model ID = {m.title}"
            raw = (words[m.start - start],)
            out.append(RegisterValue(HOLDING, m.start, "Model ID", m.id, "", text, raw))
        if start <= m.start + 1 < end:
            raw = (words[m.start + 1 - start],)
            text = f"Model length = {raw[0]} registers"
            out.append(RegisterValue(HOLDING, m.start + 1, "Model length", raw[0], "", text, raw))
        layout = su.layouts.get(m.start)
        if layout is None:
            lo, hi = max(start, m.start + 2), min(end, m.end)
            if lo < hi:
                why = INSTALL_HINT if not self.library.available else "no definition known"
                text = f"{m.title}: {hi - lo} registers ({why})"
                body = tuple(words[lo - start : hi - start])
                out.append(RegisterValue(HOLDING, lo, m.title, None, "", text, body))
            return out
        sf_points = {p.name: p for p in layout if p.type == "sunssf" and not p.group}
        for p in layout:
            if p.offset < 2 or p.type == "pad":
                continue  # ID and L are shown above; padding carries nothing
            address = m.start + p.offset
            if address + p.size <= start or address >= end:
                continue
            lo, hi = max(address, start), min(address + p.size, end)
            part = words[lo - start : hi - start]
            sf, known = self._scale(su, m, p, sf_points, row, start, words)
            out.append(decode_point(p, lo, part, sf, write=write, sf_known=known))
        return out

    def _scale(
        self,
        su: SunSpecUnit,
        m: ModelInstance,
        p: PointDef,
        sf_points: dict[str, PointDef],
        row: int,
        start: int,
        words: Sequence[int],
    ) -> tuple[int | None, bool]:
        if p.sf is None:
            return None, True
        if isinstance(p.sf, int):
            return p.sf, True
        sfp = sf_points.get(p.sf)
        if sfp is None:
            return None, False
        address = m.start + sfp.offset
        if start <= address < start + len(words):
            raw = words[address - start]
        else:
            history = su.scale.get(address)
            seen = history.at(row) if history is not None else None
            if seen is None:
                return None, False
            raw = seen
        value = raw - 0x10000 if raw >= 0x8000 else raw
        if raw == 0x8000 or not -10 <= value <= 10:
            return None, False  # not implemented, or no believable power of ten
        return value, True


def _body(store: FrameStore, i: int) -> bytes:
    """Unit byte and PDU of a frame row, without its check or header (as FrameView.body)."""
    raw = store.raw(i)
    flags = store.flags[i]
    if flags & _ASCII:
        decoded = ascii_body(raw)
        return decoded[:-1] if decoded else b""
    if flags & _MBAP:
        return mbap.body(raw)
    return raw[:-2]


def _until_a_new_unit(
    units: dict[int, SunSpecUnit], todo: array[int], picked: array[int], found: list[int]
) -> Iterator[int]:
    """The rows at the positions `picked` of `todo`, up to the first that makes a unit
    known (each is taken in before the next is asked for); `found` gets the position
    after that one."""
    before = len(units)
    for k in picked:
        yield todo[k]
        if len(units) != before:
            found.append(k + 1)
            return


def _marker_in(start: int, words: Sequence[int]) -> int | None:
    """The base address of a SunS marker these registers hold, or None."""
    for base in BASES:
        k = base - start
        if k >= 0 and k + 1 < len(words) and (words[k], words[k + 1]) == MARKER:
            return base
    return None
