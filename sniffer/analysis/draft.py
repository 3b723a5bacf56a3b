"""Provides dictionary drafting: a TOML dictionary for an unknown unit, from what the master
read and wrote in a capture.

Every address range the master touched becomes entries. A type, a word order or a scale
is proposed only where the values give evidence for it, and the evidence is written
beside it; everything else is said to be unknown, with what was seen:

- a string: a run of registers whose bytes are printable ASCII (NUL padding after it)
  that holds still;
- f32: two registers whose float reading is a plausible number at every sample while the
  exponent word moves too (a constant beside a 16-bit register moves only the low word,
  which is how false floats are made); a constant pair only where proven floats of the
  same word order sit in the same table and it reads as a round number;
- u32/s32: a counter whose low word wraps as the high word counts, a high word that is
  the exact sign extension of the low one, a pair that is smooth as one number where its
  low word alone jumps, or a counter beside a small constant high word (weak);
- s16: values that cross zero smoothly, or hold just below 0x10000; u16: values above
  0x7FFF that are smooth unsigned, or a counter; otherwise a 16-bit register's sign is
  unknown (u16 and s16 read values below 0x8000 alike) and no type is written;
- enum: few small values it steps between; bit field: few values made of few bits,
  changing a bit or two at a time;
- scale: a SunSpec-style scale factor register (a constant -1 to -6 after the values it
  scales, where the table has such a pattern), a register that tracks another value
  times a power of ten, or a mains frequency or voltage range (weak).

The draft is a start for the engineer, not a finding: it passes `dict check` and
annotates the capture as soon as it is bound.
"""

from __future__ import annotations

import bisect
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
FEW_VALUES = 8  # at most this many distinct values suggest an enum or a bit field
ENUM_MAX = 64  # enum values are small numbers
MIN_SAMPLES = 4  # fewer readings than this make every guess weak
ORDERS = ("ABCD", "CDAB")  # word orders tried for 32-bit values
FLOAT_RANGE = (1e-4, 1e8)  # magnitudes a measured float plausibly has (0 aside)
MATCH_SECONDS = 0.5  # readings of two registers this close in time saw the same value
SF_RANGE = range(-6, 0)  # SunSpec scale factors that make a scale: 10^-6 .. 10^-1


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


# -- numbers -----------------------------------------------------------------------------


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


def _num(v: float) -> str:
    if isinstance(v, float) and not v.is_integer():
        return f"{v:.6g}"
    return str(int(v))


def _span(values: Sequence[float]) -> str:
    low, high = min(values), max(values)
    return _num(low) if low == high else f"{_num(low)}..{_num(high)}"


def _seen_text(values: Sequence[float]) -> str:
    distinct = sorted(set(values))
    shown = ", ".join(_num(v) for v in distinct[:6]) + (", ..." if len(distinct) > 6 else "")
    return f"{len(values)} readings, {len(distinct)} distinct ({shown})"


def _round_float(value: float) -> bool:
    """A number a person would set: few significant digits (10.0, 0.9, 415.5)."""
    if value == 0:
        return False
    text = f"{value:.7g}".lstrip("-")
    digits = text.split("e")[0].replace(".", "").strip("0")
    return 1e-3 <= abs(value) <= 1e6 and len(digits) <= 4


def _plausible_float(value: float) -> bool:
    return math.isfinite(value) and (value == 0 or FLOAT_RANGE[0] <= abs(value) <= FLOAT_RANGE[1])


def _f32(hi: int, lo: int) -> float:
    value: float = struct.unpack(">f", struct.pack(">HH", hi, lo))[0]
    return value


def _scale_text(scale: float) -> str:
    return f"{scale:g}"


# -- guesses -----------------------------------------------------------------------------


@dataclass
class Guess:
    """A drafted entry: what is proposed (an empty type is unknown), why, and the decoded
    series (time, value) the scale pass compares with other entries."""

    table: str
    address: int
    type: str = ""
    length: int = 1  # registers
    word_order: str = ""
    scale: float | None = None
    kind: str = ""  # constant, counter, enum, bits, measure, string, scale factor, unread
    evidence: list[str] = field(default_factory=list)
    unknown: list[str] = field(default_factory=list)
    weak: list[str] = field(default_factory=list)
    enum: dict[int, str] = field(default_factory=dict)
    bits: dict[int, str] = field(default_factory=dict)
    access: str = "r"
    series: list[tuple[float, float]] = field(default_factory=list)
    strength: int = 0  # how strong a 32-bit reading is, to choose between overlapping ones

    @property
    def size(self) -> int:
        return self.length

    @property
    def varying(self) -> bool:
        return len({v for _t, v in self.series}) > 1

    def claims(self) -> str:
        """What the guess proposes, in a few words (type, order, scale)."""
        parts = [self.type or "unknown"]
        if self.type == "str":
            parts[0] = f"str[{self.length}]"
        if self.word_order:
            parts.append(self.word_order)
        if self.scale is not None:
            parts.append(f"x{_scale_text(self.scale)}")
        return " ".join(parts)


def _pairs(first: Place, second: Place) -> list[tuple[float, int, int]]:
    """(time, first word, second word) read together at two neighbouring addresses."""
    other = dict(second.reads)
    return [(t, v, other[t]) for t, v in first.reads if t in other]


# what device strings (names, models, serial numbers, versions) are made of; the bytes
# of floats and counters land on other printable characters too ('?', '@', '^', ...)
TEXT_CHARACTERS = frozenset(
    "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789 .-_/:,()+#"
)


def _printable(word: int) -> tuple[bool, int]:
    """Whether both bytes are printable ASCII or NUL, and how many are printable."""
    count = 0
    for byte in (word >> 8, word & 0xFF):
        if 0x20 <= byte <= 0x7E:
            count += 1
        elif byte != 0:
            return False, 0
    return True, count


def find_strings(seen: Observed, table: str, addresses: Sequence[int]) -> list[Guess]:
    """Runs of constant registers whose bytes are characters of device text (names,
    models, serials, versions): at least four, two of them letters, a NUL only at the
    end. The zero registers that may follow are left out: NUL padding and an empty
    field after it read alike."""
    out: list[Guess] = []
    present = set(addresses)
    for start in sorted(addresses):
        if out and start < out[-1].address + out[-1].length:
            continue
        run: list[int] = []
        address = start
        while address in present:
            values = {v for _t, v in seen.places[(table, address)].reads}
            if len(values) != 1:
                break
            word = next(iter(values))
            if not _printable(word)[0] or word >> 8 == 0:
                break  # a NUL in the high byte ends the text (or never began it)
            run.append(word)
            address += 1
            if word & 0xFF == 0:
                break  # the text ended in the low byte
        text = b"".join(w.to_bytes(2, "big") for w in run).rstrip(b"\0")
        letters = sum(1 for c in text if chr(c).isalpha())
        wordy = all(chr(c) in TEXT_CHARACTERS for c in text)
        if len(text) < 4 or letters < 2 or len(run) < 2 or not wordy:
            continue
        zeros = 0
        while _constant_zero(seen, table, start + len(run) + zeros):
            zeros += 1
        reads = len(seen.places[(table, start)].reads)
        g = Guess(table, start, "str", len(run), kind="string")
        g.evidence.append(
            f"str: printable ASCII {text.decode('ascii')!r} in {len(run)} registers, the "
            f"same in {reads} readings"
        )
        if zeros:
            g.unknown.append(
                f"length: {zeros} zero registers follow (NUL padding of this string, or "
                "another field)"
            )
        if reads < 2:
            g.weak.append("read once")
        out.append(g)
    return out


def _constant_zero(seen: Observed, table: str, address: int) -> bool:
    place = seen.places.get((table, address))
    return place is not None and bool(place.reads) and {v for _t, v in place.reads} == {0}


def _aligned(seen: Observed, table: str, address: int) -> bool:
    """Whether `address` is an even offset from the start of some read range holding it
    and its neighbour (32-bit values sit at even offsets in the blocks masters read)."""
    return any(
        t == table
        and start <= address
        and address + 1 <= start + count - 1
        and (address - start) % 2 == 0
        for t, start, count in seen.ranges
    )


def guess_pair(first: Place, second: Place) -> Guess | None:
    """A 32-bit value over two registers, where the values give evidence for one (see
    the module doc); None where they do not."""
    rows = _pairs(first, second)
    if len(rows) < 2:
        return None
    found: list[Guess] = []
    for order in ORDERS:
        hi = [a if order == "ABCD" else b for _t, a, b in rows]
        lo = [b if order == "ABCD" else a for _t, a, b in rows]
        times = [t for t, _a, _b in rows]
        for make in (_as_float, _as_counter, _as_sign_extended, _as_smooth_int):
            g = make(first, order, times, hi, lo)
            if g is not None:
                found.append(g)
                break
    if not found:
        return None
    found.sort(key=lambda g: -g.strength)
    best = found[0]
    if len(found) > 1 and found[1].strength == best.strength:
        other = found[1]
        best.weak.append(f"{other.type} {other.word_order} fits as well")
        best.word_order = ""
        best.unknown.append("word order: both read alike")
    if len(rows) < MIN_SAMPLES:
        best.weak.append(f"only {len(rows)} readings")
    return best


def _as_float(
    first: Place, order: str, times: list[float], hi: list[int], lo: list[int]
) -> Guess | None:
    floats = [_f32(h, low) for h, low in zip(hi, lo, strict=True)]
    if not all(_plausible_float(v) for v in floats):
        return None
    moving = {h for h, v in zip(hi, floats, strict=True) if v != 0}
    if len(set(floats)) < 3 or len(moving) < 2:
        return None  # the exponent word must move: a constant beside a u16 reads alike
    if len(set(lo)) * 4 < len(set(floats)):
        return None  # a float's low word is mantissa: as varied as the value
    g = Guess(first.table, first.address, "f32", 2, order, kind="measure", strength=3)
    g.series = list(zip(times, floats, strict=True))
    g.evidence.append(
        f"f32 {order}: a plausible float at every reading ({_span(floats)}, "
        f"{len(set(floats))} distinct in {len(floats)}); the high word moves within "
        f"0x{min(moving):04X}-0x{max(moving):04X} with the value"
    )
    return g


def _as_counter(
    first: Place, order: str, times: list[float], hi: list[int], lo: list[int]
) -> Guess | None:
    series = [h << 16 | low for h, low in zip(hi, lo, strict=True)]
    steps = [b - a for a, b in pairwise(series)]
    if len(set(series)) < 3 or sum(1 for d in steps if d < 0) > 1:  # one reset at most
        return None
    carries = 0
    for (h0, l0), (h1, l1) in pairwise(zip(hi, lo, strict=True)):
        if h1 == h0:
            continue
        if h1 != h0 + 1 or l0 - l1 < 0x8000:
            return None  # the high word moved without the low word wrapping over
        carries += 1
    g = Guess(first.table, first.address, "u32", 2, order, kind="counter")
    g.series = list(zip(times, [float(v) for v in series], strict=True))
    if carries:  # the low word fell from its top half to its bottom as the high counted
        g.strength = 3
        g.evidence.append(
            f"u32 {order} counter: the low word wraps {carries} times as the high word "
            f"counts up; {_span(series)} in {len(series)} readings"
        )
        return g
    return None  # without a carry, a 16-bit counter beside a constant reads the same


def _as_sign_extended(
    first: Place, order: str, times: list[float], hi: list[int], lo: list[int]
) -> Guess | None:
    """The high word is 0x0000 exactly when the low word is below 0x8000 and 0xFFFF
    otherwise, and both are seen: one signed 32-bit value near zero."""
    if set(hi) != {0x0000, 0xFFFF}:
        return None
    if any((h == 0xFFFF) != (low >= 0x8000) for h, low in zip(hi, lo, strict=True)):
        return None
    series = [_signed(h << 16 | low, 32) for h, low in zip(hi, lo, strict=True)]
    g = Guess(first.table, first.address, "s32", 2, order, kind="measure", strength=3)
    g.series = list(zip(times, [float(v) for v in series], strict=True))
    g.evidence.append(
        f"s32 {order}: the high word is the sign extension of the low one at every "
        f"reading (0x0000 or 0xFFFF); {_span(series)}"
    )
    return g


def _as_smooth_int(
    first: Place, order: str, times: list[float], hi: list[int], lo: list[int]
) -> Guess | None:
    """One number whose low word wraps: smooth as 32 bits, jumpy as the low word alone,
    with the high word stepping by one at the wraps."""
    if len(set(hi)) < 2 or len(hi) < MIN_SAMPLES or max(lo) - min(lo) < 0x8000:
        return None
    for (h0, l0), (h1, l1) in pairwise(zip(hi, lo, strict=True)):
        step = _signed((h1 - h0) & 0xFFFF, 16)
        if step == 0:
            continue
        if not ((step == 1 and l1 < l0) or (step == -1 and l1 > l0)):
            return None  # the high word moved without the low word wrapping
    signed = any(h >= 0x8000 for h in hi)
    series = [
        _signed(h << 16 | low, 32) if signed else h << 16 | low
        for h, low in zip(hi, lo, strict=True)
    ]
    whole, alone = roughness(series), roughness(lo)
    if whole is None or alone is None or not whole < alone:
        return None
    kind = "s32" if signed else "u32"
    g = Guess(first.table, first.address, kind, 2, order, kind="measure", strength=2)
    g.series = list(zip(times, [float(v) for v in series], strict=True))
    g.evidence.append(
        f"{kind} {order}: smooth as one number ({_span(series)}, roughness {whole:.3f}) "
        f"where the low word alone jumps (roughness {alone:.3f}) as it wraps"
    )
    return g


def constant_float(first: Place, second: Place, order: str) -> Guess | None:
    """A constant pair that reads as a round float in `order` (for the table's proven
    float order: a constant alone proves nothing)."""
    rows = _pairs(first, second)
    if len(rows) < 2 or len({(a, b) for _t, a, b in rows}) != 1:
        return None
    _t, a, b = rows[0]
    hi, lo = (a, b) if order == "ABCD" else (b, a)
    value = _f32(hi, lo)
    if not _plausible_float(value) or not _round_float(value):
        return None
    g = Guess(first.table, first.address, "f32", 2, order, kind="constant", strength=1)
    g.series = [(t, value) for t, _a, _b in rows]
    g.evidence.append(
        f"f32 {order} constant {_num(value)} in {len(rows)} readings (0x{a:04X} 0x{b:04X}), "
        f"aligned with the proven f32 {order} values of this table"
    )
    g.weak.append("a constant: the float reading rests on the table's other floats")
    return g


def guess_word(place: Place) -> Guess:
    """One register alone: what its values show, or unknown."""
    values = place.values
    g = Guess(place.table, place.address, access="rw" if place.writes else "r")
    if not values:
        g.kind = "unread"
        g.unknown.append("never answered: the master asked, no value came back")
        g.weak.append("never answered")
        return g
    g.series = sorted((t, float(v)) for t, v in place.reads + place.writes)
    distinct = sorted(set(values))
    if len(values) < MIN_SAMPLES:
        g.weak.append(f"only {len(values)} readings")
    signed = [_signed(v, 16) for v in values]
    if len(distinct) == 1:
        g.kind = "constant"
        g.unknown.append(
            f"type: constant {values[0]} (0x{values[0]:04X}) in {len(values)} readings; "
            "one value shows no type"
        )
        return g
    ordered = [v for _t, v in sorted(place.reads)]
    if _bit_field(g, distinct, values, ordered):
        return g
    if len(set(ordered)) >= 3 and all(b >= a for a, b in pairwise(ordered)):
        g.type, g.kind = "u16", "counter"
        g.evidence.append(
            f"u16 counter: only grows, {ordered[0]}..{ordered[-1]} in {len(ordered)} readings"
        )
        return g
    if _enum(g, distinct, values, ordered):
        return g
    g.kind = "measure"
    jump_signed, jump_unsigned = _largest_step(signed), _largest_step(values)
    if jump_signed < 0x4000 < 0xC000 < jump_unsigned:
        g.type = "s16"
        g.series = [(t, float(_signed(int(v), 16))) for t, v in g.series]
        g.evidence.append(
            f"s16: crosses zero smoothly ({_span(signed)}); read unsigned it jumps between "
            "0x0000 and 0xFFFF"
        )
    elif all(v >= 0xF000 for v in values):
        g.type = "s16"
        g.series = [(t, float(_signed(int(v), 16))) for t, v in g.series]
        g.evidence.append(
            f"s16: every value just below 0x10000 ({_span(values)}): small negatives "
            f"{_span(signed)}"
        )
    elif jump_unsigned < 0x4000 < 0xC000 < jump_signed:
        g.type = "u16"
        g.evidence.append(
            f"u16: crosses 0x8000 smoothly ({_span(values)}); read signed it jumps between "
            "the ends of the range"
        )
    else:
        g.unknown.append(
            f"type: a 16-bit number, {_seen_text(values)}; "
            + (
                "u16 and s16 read these alike"
                if max(values) < 0x8000
                else "nothing tells u16 from s16 here"
            )
        )
    return g


def _largest_step(series: Sequence[int]) -> int:
    return max((abs(b - a) for a, b in pairwise(series)), default=0)


def _bit_field(g: Guess, distinct: list[int], values: list[int], ordered: list[int]) -> bool:
    """Few values made of few bits, not a run of small numbers, whose bits nest: most
    pairs of the values seen have one's bits inside the other's (a flag that comes on
    while others stay on), where an enum's states share bits by chance. One value beside
    zero counts when it is a single high bit (a flag)."""
    if len(distinct) > FEW_VALUES or len(distinct) < 2:
        return False
    mask = 0
    for v in distinct:
        mask |= v
    if mask.bit_count() > 8:
        return False
    if distinct == list(range(distinct[0], distinct[0] + len(distinct))):
        return False  # 0, 1, 2, 3: counting, not bits
    set_ones = [v for v in distinct if v]
    if len(set_ones) == 1:
        flag = set_ones[0]
        if flag.bit_count() != 1 or flag < 16:
            return False
        why = f"one flag, bit {flag.bit_length() - 1}, on and off"
    else:
        pairs = [(a, b) for k, a in enumerate(set_ones) for b in set_ones[k + 1 :]]
        nested = sum(1 for a, b in pairs if a & b in (a, b))
        if nested * 3 < 2 * len(pairs) or max(v.bit_count() for v in set_ones) < 2:
            return False
        why = f"the bits nest in {nested} of {len(pairs)} pairs of values"
    g.type, g.kind = "u16", "bits"
    for bit in range(16):
        if mask >> bit & 1:
            g.bits[bit] = f"bit {bit}"
    g.evidence.append(
        f"bit field: {mask.bit_count()} bits ever set "
        f"({', '.join(str(b) for b in sorted(g.bits))}), {why}; {_seen_text(values)}"
    )
    return True


def _enum(g: Guess, distinct: list[int], values: list[int], ordered: list[int]) -> bool:
    """Few small values, each held for a while."""
    if len(distinct) > FEW_VALUES or max(distinct) > ENUM_MAX:
        return False
    run = distinct == list(range(distinct[0], distinct[0] + len(distinct)))
    if run and distinct[0] > 3:
        return False  # 20, 21, 22: a number that moves a little; states start low
    changes = sum(1 for a, b in pairwise(ordered) if a != b)
    if len(values) < 3 * len(distinct) or changes * 2 > len(ordered):
        return False
    if run and len(distinct) >= 4 and all(abs(b - a) <= 1 for a, b in pairwise(ordered)):
        return False  # a slowly moving number steps to its neighbours; states jump
    g.type, g.kind = "u16", "enum"
    g.enum = {v: f"value {v}" for v in distinct}
    g.evidence.append(f"enum: few small values, each held a while; {_seen_text(values)}")
    if len(distinct) == 2 and 0 in distinct:
        g.weak.append("two values: an on/off flag, or a number that rarely moves")
    return True


def guess_bit(place: Place) -> Guess:
    values = place.values
    g = Guess(place.table, place.address, "bool", access="rw" if place.writes else "r")
    g.kind = "bit"
    g.series = sorted((t, float(v)) for t, v in place.reads + place.writes)
    g.evidence.append(
        f"{len(values)} readings: {sum(1 for v in values if v)} on, "
        f"{sum(1 for v in values if not v)} off"
    )
    if len(values) < MIN_SAMPLES:
        g.weak.append(f"only {len(values)} readings")
    return g


# -- putting them together ---------------------------------------------------------------


def guesses(seen: Observed) -> list[Guess]:
    """Entries for every place seen: strings, 32-bit values where they have evidence,
    single registers for the rest, then the scales."""
    out: list[Guess] = []
    by_table: dict[str, list[int]] = {}
    for table, address in seen.places:
        by_table.setdefault(table, []).append(address)
    for table in sorted(by_table):
        addresses = sorted(by_table[table])
        if table not in REGISTER_TABLES:
            out.extend(guess_bit(seen.places[(table, a)]) for a in addresses)
            continue
        found = _table_guesses(seen, table, addresses)
        _scale_factors(seen, table, found)
        out.extend(found)
    _tracking_scales(out)
    _mains_scales(out)
    return sorted(out, key=lambda g: (g.table, g.address))


def _table_guesses(seen: Observed, table: str, addresses: list[int]) -> list[Guess]:
    found = find_strings(seen, table, addresses)
    taken = {a for g in found for a in range(g.address, g.address + g.length)}
    pairs: list[Guess] = []
    for address in addresses:
        if address in taken or address + 1 in taken:
            continue
        nxt = seen.places.get((table, address + 1))
        place = seen.places[(table, address)]
        if nxt is None or place.writes or nxt.writes:
            continue
        pair = guess_pair(place, nxt)
        if pair is not None:
            pairs.append(pair)
    # overlapping readings: the stronger, then the one aligned with its read block
    pairs.sort(key=lambda g: (-g.strength, not _aligned(seen, table, g.address), g.address))
    for pair in pairs:
        if pair.address in taken or pair.address + 1 in taken:
            continue
        found.append(pair)
        taken.update((pair.address, pair.address + 1))
    # constant pairs that read as round floats where this table has proven floats
    proven = [g for g in found if g.type == "f32" and g.kind == "measure" and g.word_order]
    orders = {g.word_order for g in proven}
    if len(orders) == 1:
        order = next(iter(orders))
        parity = {g.address % 2 for g in proven}
        for address in addresses:
            if address in taken or address + 1 in taken or address % 2 not in parity:
                continue
            nxt = seen.places.get((table, address + 1))
            if nxt is None:
                continue
            g = constant_float(seen.places[(table, address)], nxt, order)
            if g is not None:
                found.append(g)
                taken.update((address, address + 1))
    for address in addresses:
        if address not in taken:
            found.append(guess_word(seen.places[(table, address)]))
    found.sort(key=lambda g: g.address)
    _low_words(seen, table, found)
    return found


def _low_words(seen: Observed, table: str, found: list[Guess]) -> None:
    """A u16 beside a register that held still may be the low word of a 32-bit value
    whose high word did not move: a counter beside any constant (its carry not seen), a
    bit field, enum or unsigned number beside a constant 0 (32-bit values sit at odd
    offsets of read blocks too). Its 16-bit type is then unknown: its values read the
    same either way. (An s16 that went negative beside a 0 is no 32-bit low word.)"""
    by_address = {g.address: g for g in found}
    for g in found:
        if g.type != "u16":
            continue
        for side in (g.address - 1, g.address + 1):
            other = by_address.get(side)
            if other is None or other.kind != "constant" or other.length != 1:
                continue
            high = int(other.series[0][1]) if other.series else 0
            if g.kind != "counter" and high != 0:
                continue
            what = {"bits": "bit field", "counter": "counter", "enum": "enum"}.get(g.kind, "number")
            g.type = ""
            g.evidence = [e.removeprefix("u16 ").removeprefix("u16: ") for e in g.evidence]
            g.unknown.append(
                f"type: a 16-bit {what}, or the low word of a 32-bit value whose high word "
                f"{side} held 0x{high:04X}" + (" (no carry seen)" if g.kind == "counter" else "")
            )
            break


def _sf_value(g: Guess) -> int | None:
    """The scale factor a constant register holds, read as s16, if it could be one."""
    if g.kind != "constant" or not g.series:
        return None
    value = _signed(int(g.series[0][1]), 16)
    return value if value in SF_RANGE or value == 0 else None


def _scale_factors(seen: Observed, table: str, found: list[Guess]) -> None:
    """SunSpec-style scale factors: a constant 0 or -1..-6 (as s16) right after the
    numbers it scales. Taken only where the table shows the pattern: a "SunS" marker,
    or two such constants each after a run of moving numbers."""
    by_address = {g.address: g for g in found}
    marker = any(g.type == "str" and "'SunS" in g.evidence[0] for g in found)
    runs: list[tuple[Guess, list[Guess]]] = []
    for g in found:
        sf = _sf_value(g)
        if sf is None:
            continue
        scaled: list[Guess] = []
        address = g.address - 1
        while True:
            before = by_address.get(address)
            if before is None:
                # a 32-bit value ends here: step to its first register
                before = next(
                    (p for p in found if p.address < address < p.address + p.length), None
                )
            if before is None or before.kind not in ("measure", "counter") or not before.varying:
                break
            if before.type == "f32":
                break
            scaled.append(before)
            address = before.address - 1
        if scaled:
            runs.append((g, scaled))
    if not marker and sum(1 for sf, _s in runs if _sf_value(sf)) < 2:
        return
    for sf_guess, scaled in runs:
        sf = _sf_value(sf_guess)
        if sf is None:
            continue
        sf_guess.type, sf_guess.kind = "s16", "scale factor"
        sf_guess.unknown.clear()
        names = ", ".join(str(s.address) for s in sorted(scaled, key=lambda s: s.address))
        sf_guess.evidence.append(
            f"s16 scale factor: constant {sf} right after the moving numbers at {names}"
            + (" (SunSpec)" if marker else "")
        )
        if sf == 0:
            continue
        for s in scaled:
            s.scale = 10.0**sf
            s.evidence.append(
                f"scale {_scale_text(s.scale)}: the constant {sf} at {sf_guess.address} "
                "after it is a scale factor (10^sf)"
            )


def _tracking_scales(found: list[Guess]) -> None:
    """A moving integer that equals another entry's value times 10, 100 or 1000 at every
    reading they share: its scale is the inverse."""
    floats = [g for g in found if g.type == "f32" and g.varying]
    for g in found:
        if g.scale is not None or g.type in ("f32", "str") or g.kind in ("enum", "bits"):
            continue
        if not g.varying or len(g.series) < MIN_SAMPLES:
            continue
        for other in floats:
            k = _tracks(g, other)
            if k is None:
                continue
            g.scale = 10.0**-k
            g.evidence.append(
                f"scale {_scale_text(g.scale)}: {_series_name(g)} equals "
                f"{_series_name(other)} x{10**k} at every one of "
                f"{_shared(g, other)} readings they share"
            )
            break


def _series_name(g: Guess) -> str:
    return f"{TABLE_WORDS.get(g.table, g.table)} {g.address}"


def _matched(a: Guess, b: Guess) -> list[tuple[float, float]]:
    """(value of a, value of b) for readings of both close enough in time."""
    times = [t for t, _v in b.series]
    out: list[tuple[float, float]] = []
    for t, v in a.series:
        k = bisect.bisect_left(times, t)
        best = min(
            (j for j in (k - 1, k) if 0 <= j < len(times)),
            key=lambda j: abs(times[j] - t),
            default=None,
        )
        if best is not None and abs(times[best] - t) <= MATCH_SECONDS:
            out.append((v, b.series[best][1]))
    return out


def _shared(a: Guess, b: Guess) -> int:
    return len(_matched(a, b))


def _tracks(g: Guess, other: Guess) -> int | None:
    """k in 1..3 where g's values are other's times 10^k at every shared reading."""
    rows = _matched(g, other)
    if len(rows) < MIN_SAMPLES or len({b for _a, b in rows}) < 3:
        return None
    for k in (1, 2, 3):
        factor = 10**k
        if all(abs(a - b * factor) <= 1 + 0.002 * abs(a) for a, b in rows):
            return k
    return None


MAINS = (
    # (low, high, scale, what): a register that holds within one of these ranges
    (4950, 5050, 0.01, "a 50 Hz mains frequency in hundredths of a hertz"),
    (5950, 6050, 0.01, "a 60 Hz mains frequency in hundredths of a hertz"),
    (495, 505, 0.1, "a 50 Hz mains frequency in tenths of a hertz"),
    (595, 605, 0.1, "a 60 Hz mains frequency in tenths of a hertz"),
    (2070, 2530, 0.1, "a 230 V mains voltage in tenths of a volt"),
    (1080, 1320, 0.1, "a 120 V mains voltage in tenths of a volt"),
)


def _mains_scales(found: list[Guess]) -> None:
    """A moving 16-bit number that holds within a mains frequency or voltage range (in
    tenths or hundredths) at every reading: weak, a range is not a proof."""
    for g in found:
        if g.scale is not None or g.length != 1 or g.kind not in ("measure",):
            continue
        values = [v for _t, v in g.series]
        if len(values) < 10 or len(set(values)) < 3:
            continue
        for low, high, scale, what in MAINS:
            if low <= min(values) and max(values) <= high:
                g.scale = scale
                g.evidence.append(
                    f"scale {_scale_text(scale)}: every value in {_span(values)}, the range "
                    f"of {what}"
                )
                g.weak.append("the scale rests on the value range alone")
                break


# -- writing the TOML ----------------------------------------------------------------------


def _toml_string(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace('"', '\\"')
    return '"' + "".join(c if c.isprintable() else f"\\u{ord(c):04x}" for c in escaped) + '"'


def _comment(text: str) -> str:
    return "".join(c if c.isprintable() else "?" for c in text)


def _ranges_text(seen: Observed) -> list[str]:
    lines = []
    for table, start, count in sorted(seen.ranges):
        end = start + count - 1
        where = f"{start}" if count == 1 else f"{start}-{end}"
        lines.append(f"#   {TABLE_WORDS.get(table, table)} {where} ({count})")
    return lines


def _entry_name(g: Guess) -> str:
    word = TABLE_WORDS.get(g.table, g.table)
    name = f"{word.capitalize()} {g.address}"
    if g.kind in ("counter", "constant", "enum", "bits", "string", "scale factor"):
        name += f" ({g.kind})"
    return name


def draft_toml(seen: Observed, source: str, model: str | None = None) -> str:
    """The draft dictionary of one unit, as TOML text."""
    return toml_of(seen, guesses(seen), source, model)


def toml_of(seen: Observed, found: Sequence[Guess], source: str, model: str | None = None) -> str:
    model = model or f"draft-unit{seen.unit}"
    head = [
        f"# Drafted by modscope from {source}, unit {seen.unit}: {seen.requests} requests.",
        "# A type, word order or scale is written only where the values gave evidence for",
        "# it (the comment above each entry says which); an entry without a type is a",
        "# register whose type the capture does not show, read as a raw u16. Check each",
        "# against the manual, rename it, and delete the evidence when you are sure.",
        "# Address ranges the master asked for:",
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
        out.append("[[entry]]")
        out.extend(f"# {_comment(e)}" for e in g.evidence)
        out.extend(f"# unknown {_comment(u)}" for u in g.unknown)
        if g.weak:
            out.append("# weak guess: " + _comment("; ".join(g.weak)))
        out.append(f'table = "{g.table}"')
        out.append(f"pdu = {g.address}")
        out.append(f"name = {_toml_string(_entry_name(g))}")
        if g.type and g.type != "bool":
            out.append(f'type = "{g.type}"')
        if g.type == "str":
            out.append(f"length = {g.length}")
        if g.word_order:
            out.append(f'word_order = "{g.word_order}"')
        if g.scale is not None:
            out.append(f"scale = {_scale_text(g.scale)}")
        if g.enum:
            body = ", ".join(f'"{k}" = {_toml_string(v)}' for k, v in sorted(g.enum.items()))
            out.append(f"enum = {{ {body} }}")
        if g.bits:
            body = ", ".join(f'"{k}" = {_toml_string(v)}' for k, v in sorted(g.bits.items()))
            out.append(f"bits = {{ {body} }}")
        if g.access != "r" or g.table in ("holding_registers", "coils"):
            out.append(f'access = "{g.access}"')
        notes = [f"evidence: {e}" for e in g.evidence] + [f"unknown {u}" for u in g.unknown]
        notes += [f"weak: {w}" for w in g.weak]
        if notes:
            out.append("notes = [" + ", ".join(_toml_string(n) for n in notes) + "]")
        out.append("")
    return "\n".join(out)


def summary(seen: Observed, found: Sequence[Guess]) -> list[str]:
    """What the draft proposes and on what evidence, one line per entry, for the
    command's output."""
    registers = [g for g in found if g.table in REGISTER_TABLES]
    typed = [g for g in registers if g.type]
    kinds: dict[str, int] = {}
    for g in typed:
        kinds[g.type] = kinds.get(g.type, 0) + 1
    shown = ", ".join(f"{n} {t}" for t, n in sorted(kinds.items(), key=lambda kv: -kv[1]))
    orders = sum(1 for g in registers if g.word_order)
    scales = sum(1 for g in registers if g.scale is not None)
    lines = [
        f"unit {seen.unit}: {len(registers)} register entries; types proposed for "
        f"{len(typed)} ({shown or 'none'}), {orders} word orders, {scales} scales; "
        f"{len(registers) - len(typed)} types left unknown"
    ]
    bits = [g for g in found if g.table not in REGISTER_TABLES]
    for table in sorted({g.table for g in bits}):
        mine = [g for g in bits if g.table == table]
        on = sum(1 for g in mine if any(v for _t, v in g.series))
        where = f"{TABLE_WORDS.get(table, table)} {_addresses([g.address for g in mine])}"
        lines.append(f"  {where:<18} {'bool':<16} {len(mine)} single bits, {on} of them ever on")
    for g in found:
        if g.table not in REGISTER_TABLES:
            continue
        where = f"{TABLE_WORDS.get(g.table, g.table)} {g.address}"
        if g.length > 1:
            where += f"-{g.address + g.length - 1}"
        why = (g.evidence + g.unknown if g.type else g.unknown + g.evidence) or g.weak or [""]
        text = "; ".join(why)
        if g.weak and g.evidence:
            text += " (weak: " + "; ".join(g.weak) + ")"
        lines.append(f"  {where:<18} {g.claims():<16} {_comment(text)}")
    return lines


def _addresses(addresses: Sequence[int]) -> str:
    """`0-7, 12` for a sorted list of addresses."""
    runs: list[list[int]] = []
    for a in sorted(addresses):
        if runs and a == runs[-1][-1] + 1:
            runs[-1].append(a)
        else:
            runs.append([a])
    return ", ".join(str(r[0]) if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in runs)


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
