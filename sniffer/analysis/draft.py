"""Provides dictionary drafting: a TOML dictionary for an unknown unit, from what the master
read and wrote in a capture.

Every address range the master touched becomes entries with a guessed type, the evidence
for the guess (values seen, how smooth the series is in each reading) and a comment
where the guess is weak. The draft is a start for the engineer, not a finding: it passes
`dict check` and annotates the capture as soon as it is bound.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from pathlib import Path

from dissectors.dissect import dissect
from dissectors.values import Dissection, Role
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.vocab import Flag, Kind

REGISTER_TABLES = ("holding_registers", "input_registers")
TABLE_WORDS = {
    "holding_registers": "holding",
    "input_registers": "input",
    "coils": "coil",
    "discrete_inputs": "input bit",
}
FEW_VALUES = 6  # at most this many distinct values (and repeats) suggest an enum
MIN_SAMPLES = 4  # fewer readings than this make every guess weak
ORDERS = ("ABCD", "CDAB")  # word orders tried for 32-bit values


@dataclass
class Place:
    """What was seen at one address of one table."""

    table: str
    address: int
    reads: list[tuple[float, int]] = field(default_factory=list)  # (time, value)
    writes: list[tuple[float, int]] = field(default_factory=list)

    @property
    def values(self) -> list[int]:
        return [v for _t, v in sorted(self.reads + self.writes)]


@dataclass
class Observed:
    """One unit's traffic: the places, the address ranges of each request, counts."""

    unit: int
    places: dict[tuple[str, int], Place] = field(default_factory=dict)
    ranges: set[tuple[str, int, int]] = field(default_factory=set)  # table, start, count
    requests: int = 0
    exceptions: dict[tuple[str, int, int], int] = field(default_factory=dict)

    def place(self, table: str, address: int) -> Place:
        key = (table, address)
        found = self.places.get(key)
        if found is None:
            found = self.places[key] = Place(table, address)
        return found


READ_TABLES = {1: "coils", 2: "discrete_inputs", 3: "holding_registers", 4: "input_registers"}


def _read_range(asked: Dissection) -> tuple[str, int, int] | None:
    """(table, start, count) a read request asks for (FC 1-4), else None."""
    table = READ_TABLES.get(asked.function)
    address, quantity = asked.field("address"), asked.field("quantity")
    if table is None or address is None or quantity is None:
        return None
    if not isinstance(address.value, int) or not isinstance(quantity.value, int):
        return None
    return (table, address.value, quantity.value)


def observe(store: FrameStore, unit: int) -> Observed:
    """Every value unit `unit` was read at or written to, in time order."""
    store.sync()
    seen = Observed(unit)
    for i in range(len(store)):
        if store.unit[i] != unit or store.kind[i] != Kind.REQUEST:
            continue
        if store.flags[i] & (Flag.CHECK_BAD | Flag.NON_HEX):
            continue
        seen.requests += 1
        request = store.view(i).body()
        asked = dissect(request, Role.REQUEST)
        wanted = _read_range(asked)
        if wanted is not None:
            seen.ranges.add(wanted)
        for data in asked.data:
            if data.address is None:
                continue
            wanted = (data.table, data.address, len(data.values))
            seen.ranges.add(wanted)
            for k, value in enumerate(data.values):
                seen.place(data.table, data.address + k).writes.append((store.t[i], value))
        reply = store.partner[i]
        if reply == NO_PARTNER or store.flags[reply] & (Flag.CHECK_BAD | Flag.NON_HEX):
            continue
        answer = dissect(store.view(reply).body(), Role.RESPONSE, request=request)
        if answer.exception:
            if wanted is not None:
                seen.exceptions[wanted] = seen.exceptions.get(wanted, 0) + 1
            continue
        for data in answer.data:
            if data.address is None or data.write:
                continue
            seen.ranges.add((data.table, data.address, len(data.values)))
            for k, value in enumerate(data.values):
                seen.place(data.table, data.address + k).reads.append((store.t[reply], value))
    return seen


# -- guessing ----------------------------------------------------------------------------


def roughness(series: Sequence[float]) -> float | None:
    """How jumpy a series is: mean step over the range (0 = smooth or constant, about 1
    for noise). None with fewer than three values."""
    if len(series) < 3:
        return None
    low, high = min(series), max(series)
    if high == low:
        return 0.0
    steps = [abs(b - a) for a, b in pairwise(series)]
    return sum(steps) / len(steps) / (high - low)


def _signed(v: int, bits: int) -> int:
    return v - (1 << bits) if v & (1 << (bits - 1)) else v


def _pairs(hi: Place, lo: Place) -> list[tuple[int, int]]:
    """Word pairs read together (same time) at two neighbouring addresses."""
    second = dict(lo.reads)
    return [(v, second[t]) for t, v in hi.reads if t in second]


def _as32(pairs: Sequence[tuple[int, int]], order: str, kind: str) -> list[float] | None:
    out: list[float] = []
    for a, b in pairs:
        hi, lo = (a, b) if order == "ABCD" else (b, a)
        raw = hi << 16 | lo
        if kind == "u32":
            out.append(raw)
        elif kind == "s32":
            out.append(_signed(raw, 32))
        else:
            value = struct.unpack(">f", raw.to_bytes(4, "big"))[0]
            if not math.isfinite(value) or (value != 0 and not 1e-6 <= abs(value) <= 1e9):
                return None
            out.append(value)
    return out


@dataclass
class Guess:
    """A drafted entry."""

    table: str
    address: int
    type: str
    word_order: str = ""
    evidence: list[str] = field(default_factory=list)
    weak: list[str] = field(default_factory=list)
    enum: dict[int, str] = field(default_factory=dict)
    bits: dict[int, str] = field(default_factory=dict)
    access: str = "r"
    kind: str = ""  # constant, counter, enum, bits, measure

    @property
    def size(self) -> int:
        return 2 if self.type in ("u32", "s32", "f32") else 1


def _seen_text(values: Sequence[float]) -> str:
    distinct = sorted(set(values))
    shown = ", ".join(_num(v) for v in distinct[:6]) + (", ..." if len(distinct) > 6 else "")
    return f"{len(values)} readings, {len(distinct)} distinct ({shown})"


def _num(v: float) -> str:
    if isinstance(v, float) and not v.is_integer():
        return f"{v:.6g}"
    return str(int(v))


def _round_float(value: float) -> bool:
    """A number a person would set: few significant digits (10.0, 0.9, 415.5)."""
    if value == 0:
        return False
    text = f"{value:.7g}".lstrip("-")
    digits = text.split("e")[0].replace(".", "").strip("0")
    return 1e-3 <= abs(value) <= 1e6 and len(digits) <= 4


def guess_pair(first: Place, second: Place) -> Guess | None:
    """A 32-bit value over two registers, when a 32-bit reading explains them better
    than two 16-bit ones: a float whose exponent word holds still while the other word
    moves, a float constant with few digits, or a counter carrying from one word into
    the other."""
    pairs = _pairs(first, second)
    if len(pairs) < 2:
        return None
    results: list[tuple[int, Guess]] = []  # (strength, guess)
    for order in ORDERS:
        top = [a if order == "ABCD" else b for a, b in pairs]
        low = [b if order == "ABCD" else a for a, b in pairs]
        floats = _as32(pairs, order, "f32")
        if floats is not None and any(top):
            moving_low = len(set(low)) > 1
            narrow_top = max(top) - min(top) <= 0x0800  # sign, exponent, top of mantissa
            r = roughness(floats)
            g = Guess(first.table, first.address, "f32", order, kind="measure")
            if moving_low and narrow_top:
                g.evidence.append(
                    f"f32 {order}: {_seen_text(floats)}, roughness {r or 0:.3f}; the "
                    f"exponent word stays within 0x{min(top):04X}-0x{max(top):04X} while "
                    f"the other takes {len(set(low))} values"
                )
                results.append((3, g))
            elif not moving_low and len(set(top)) == 1 and _round_float(floats[0]):
                g.kind = "constant"
                g.evidence.append(
                    f"f32 {order} constant {_num(floats[0])} in {len(pairs)} readings "
                    f"(as two u16: 0x{pairs[0][0]:04X} 0x{pairs[0][1]:04X})"
                )
                g.weak.append("a constant: the float reading rests on its round value alone")
                results.append((2, g))
        carries = sum(
            1
            for (t0, l0), (t1, l1) in pairwise(zip(top, low, strict=True))
            if t1 == t0 + 1 and l1 < l0
        )
        series = _as32(pairs, order, "u32") or []
        steps = [b - a for a, b in pairwise(series)]
        growing = sum(1 for d in steps if d < 0) <= 1  # one reset at most
        if carries and growing and len(set(top)) <= len(pairs) // 2 and max(top) < 0x0100:
            g = Guess(first.table, first.address, "u32", order, kind="counter")
            g.evidence.append(
                f"u32 {order}: the low word wraps {carries} times as the high word counts "
                f"up; {_seen_text(series)}"
            )
            results.append((3, g))
    if not results:
        return None
    results.sort(key=lambda r: -r[0])
    best = results[0][1]
    if len(pairs) < MIN_SAMPLES:
        best.weak.append(f"only {len(pairs)} readings")
    if len(results) > 1 and results[1][0] == results[0][0]:
        other = results[1][1]
        best.weak.append(f"{other.type} {other.word_order} fits as well")
    return best


def guess_word(place: Place) -> Guess:
    """One register alone: constant, counter, enum, bit field, s16 or u16."""
    values = place.values
    g = Guess(place.table, place.address, "u16", access="rw" if place.writes else "r")
    if not values:
        g.kind = "unread"
        g.weak.append("never answered: the master asked, no value came back")
        return g
    distinct = sorted(set(values))
    if len(values) < MIN_SAMPLES:
        g.weak.append(f"only {len(values)} readings")
    signed = [_signed(v, 16) for v in values]
    if len(distinct) == 1:
        g.kind = "constant"
        g.evidence.append(f"constant {values[0]} (0x{values[0]:04X}) in {len(values)} readings")
        return g
    ordered = [v for _t, v in sorted(place.reads)]
    if len(set(ordered)) >= 3 and all(b >= a for a, b in pairwise(ordered)):
        g.kind = "counter"
        g.evidence.append(f"only grows: {ordered[0]} .. {ordered[-1]} in {len(ordered)} readings")
        return g
    high_and_low = any(v >= 0x8000 for v in values) and any(v < 0x1000 for v in values)
    if high_and_low and max(abs(s) for s in signed) < 0x4000:
        g.type = "s16"
        g.kind = "measure"
        g.evidence.append(
            f"s16: {_seen_text(signed)}, roughness {roughness(signed) or 0:.3f} "
            f"(as u16 {roughness(values) or 0:.3f})"
        )
        return g
    mask = 0
    for v in distinct:
        mask |= v
    single = all(v & (v - 1) == 0 for v in distinct)
    few_bits = mask.bit_count() <= 3 or (single and mask.bit_count() <= 8)
    if len(distinct) <= 2 * FEW_VALUES and few_bits and max(distinct) >= 16:
        g.kind = "bits"
        for bit in range(16):
            if mask >> bit & 1:
                g.bits[bit] = f"bit {bit}"
        g.evidence.append(
            f"bit field: {mask.bit_count()} bits ever set "
            f"({', '.join(str(b) for b in sorted(g.bits))}); {_seen_text(values)}"
        )
        return g
    if len(distinct) <= FEW_VALUES and len(values) >= 2 * len(distinct):
        g.kind = "enum"
        g.enum = {v: f"value {v}" for v in distinct}
        g.evidence.append(f"few values: {_seen_text(values)}")
        if len(distinct) == 2 and 0 in distinct:
            g.weak.append("two values: an on/off flag, or a number that rarely moves")
        return g
    g.kind = "measure"
    g.evidence.append(f"u16: {_seen_text(values)}, roughness {roughness(values) or 0:.3f}")
    return g


def guess_bit(place: Place) -> Guess:
    values = place.values
    g = Guess(place.table, place.address, "bool", access="rw" if place.writes else "r")
    g.kind = "bit"
    g.evidence.append(
        f"{len(values)} readings: {sum(1 for v in values if v)} on, "
        f"{sum(1 for v in values if not v)} off"
    )
    if len(values) < MIN_SAMPLES:
        g.weak.append(f"only {len(values)} readings")
    return g


def guesses(seen: Observed) -> list[Guess]:
    """Entries for every place seen, 32-bit pairs taken where they read clearly better."""
    out: list[Guess] = []
    by_table: dict[str, list[int]] = {}
    for table, address in seen.places:
        by_table.setdefault(table, []).append(address)
    for table in sorted(by_table):
        addresses = sorted(by_table[table])
        taken: set[int] = set()
        for address in addresses:
            if address in taken:
                continue
            place = seen.places[(table, address)]
            if table not in REGISTER_TABLES:
                out.append(guess_bit(place))
                continue
            pair = None
            nxt = seen.places.get((table, address + 1))
            if nxt is not None and not place.writes:
                pair = guess_pair(place, nxt)
            if pair is not None:
                out.append(pair)
                taken.update((address, address + 1))
                continue
            out.append(guess_word(place))
            taken.add(address)
    return out


# -- writing the TOML ----------------------------------------------------------------------


def _toml_string(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace('"', '\\"')
    return '"' + "".join(c if c.isprintable() else f"\\u{ord(c):04x}" for c in escaped) + '"'


def _ranges_text(seen: Observed) -> list[str]:
    lines = []
    for table, start, count in sorted(seen.ranges):
        end = start + count - 1
        where = f"{start}" if count == 1 else f"{start}-{end}"
        lines.append(f"#   {TABLE_WORDS.get(table, table)} {where} ({count})")
    return lines


def draft_toml(seen: Observed, source: str, model: str | None = None) -> str:
    """The draft dictionary of one unit, as TOML text."""
    model = model or f"draft-unit{seen.unit}"
    found = guesses(seen)
    head = [
        f"# Drafted by modscope from {source}, unit {seen.unit}: {seen.requests} requests.",
        "# Every entry is a guess from the values seen; check each one against the manual,",
        "# rename it, and delete the evidence when you are sure. Address ranges the master",
        "# asked for:",
        *_ranges_text(seen),
    ]
    if seen.exceptions:
        head.append("# Requests answered with an exception (table, start, count: times):")
        for (table, start, count), n in sorted(seen.exceptions.items()):
            head.append(f"#   {TABLE_WORDS.get(table, table)} {start} ({count}): {n}")
    out = [
        *head,
        "",
        "format = 1",
        "",
        "[device]",
        f"model = {_toml_string(model)}",
        f"name = {_toml_string(f'Unit {seen.unit} (draft)')}",
        f"manual = {_toml_string(f'drafted from {Path(source).name}')}",
        f"unit = {seen.unit}",
        "",
    ]
    for g in found:
        word = TABLE_WORDS.get(g.table, g.table)
        name = f"{word.capitalize()} {g.address}"
        if g.kind in ("counter", "constant", "enum", "bits"):
            name += f" ({g.kind})"
        out.append("[[entry]]")
        if g.weak:
            out.append("# weak guess: " + "; ".join(g.weak))
        out.append(f'table = "{g.table}"')
        out.append(f"pdu = {g.address}")
        out.append(f"name = {_toml_string(name)}")
        if g.type != "bool":
            out.append(f'type = "{g.type}"')
        if g.word_order:
            out.append(f'word_order = "{g.word_order}"')
        if g.enum:
            body = ", ".join(f'"{k}" = {_toml_string(v)}' for k, v in sorted(g.enum.items()))
            out.append(f"enum = {{ {body} }}")
        if g.bits:
            body = ", ".join(f'"{k}" = {_toml_string(v)}' for k, v in sorted(g.bits.items()))
            out.append(f"bits = {{ {body} }}")
        if g.access != "r" or g.table in ("holding_registers", "coils"):
            out.append(f'access = "{g.access}"')
        notes = [f"evidence: {e}" for e in g.evidence] + [f"weak: {w}" for w in g.weak]
        if notes:
            out.append("notes = [" + ", ".join(_toml_string(n) for n in notes) + "]")
        out.append("")
    return "\n".join(out)


def draft(store: FrameStore, unit: int, source: str, model: str | None = None) -> str:
    """Observe unit `unit` in a framed capture and draft its dictionary."""
    return draft_toml(observe(store, unit), source, model)


def units_seen(store: FrameStore) -> list[int]:
    """Units that answered at least one request (candidates for a draft)."""
    store.sync()
    return sorted(
        {
            store.unit[i]
            for i in range(len(store))
            if store.kind[i] in (Kind.RESPONSE, Kind.EXCEPTION)
        }
    )
