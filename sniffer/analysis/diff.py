"""Provides the capture diff: what changed on a bus between two captures of it.

Units and repeating requests that appeared or vanished, poll periods and answer
latencies that moved, and registers whose values in the second capture left the range
they kept in the first.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sniffer.analysis.draft import observe
from sniffer.analysis.pollcycle import Poll, poll_cycles
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.vocab import Kind

PERIOD_CHANGE = 0.2  # a period that moved by more than 20 % is reported
LATENCY_CHANGE = 0.5  # a median latency that moved by more than 50 % (and 2 ms)
LATENCY_FLOOR = 0.002
TABLE_WORDS = {
    "holding_registers": "holding",
    "input_registers": "input",
    "coils": "coil",
    "discrete_inputs": "input bit",
}


@dataclass(frozen=True, slots=True)
class Moved:
    """A register whose values in B left the range it kept in A."""

    unit: int
    table: str
    address: int
    a_low: int
    a_high: int
    b_low: int
    b_high: int
    outside: int  # readings in B outside A's range
    readings: int  # readings in B


@dataclass
class CaptureDiff:
    """Everything that differs, unit by unit."""

    a: str
    b: str
    units_new: list[int] = field(default_factory=list)
    units_gone: list[int] = field(default_factory=list)
    requests_new: list[Poll] = field(default_factory=list)
    requests_gone: list[Poll] = field(default_factory=list)
    periods: list[tuple[Poll, Poll]] = field(default_factory=list)
    latencies: list[tuple[int, float, float]] = field(default_factory=list)  # unit, a, b
    moved: list[Moved] = field(default_factory=list)

    @property
    def same(self) -> bool:
        return not (
            self.units_new
            or self.units_gone
            or self.requests_new
            or self.requests_gone
            or self.periods
            or self.latencies
            or self.moved
        )

    def text(self) -> str:
        out = [f"A: {self.a}", f"B: {self.b}"]
        if self.same:
            out.append("no difference in units, polls, latencies or register ranges")
            return "\n".join(out)
        for u in self.units_new:
            out.append(f"unit {u}: new in B")
        for u in self.units_gone:
            out.append(f"unit {u}: gone in B (seen in A, not in B)")
        for p in self.requests_new:
            out.append(f"unit {p.unit}: new poll in B: {p.what} every {_ms(p.period)}")
        for p in self.requests_gone:
            out.append(f"unit {p.unit}: poll gone in B: {p.what} (every {_ms(p.period)} in A)")
        for pa, pb in self.periods:
            out.append(
                f"unit {pa.unit}: {pa.what} every {_ms(pa.period)} in A, {_ms(pb.period)} in B"
            )
        for unit, la, lb in self.latencies:
            out.append(f"unit {unit}: median answer time {_ms(la)} in A, {_ms(lb)} in B")
        for m in self.moved:
            where = f"{TABLE_WORDS.get(m.table, m.table)} {m.address}"
            out.append(
                f"unit {m.unit}: {where} left its range: {m.a_low}..{m.a_high} in A, "
                f"{m.b_low}..{m.b_high} in B ({m.outside} of {m.readings} readings outside)"
            )
        return "\n".join(out)


def _ms(seconds: float) -> str:
    return f"{seconds * 1000:.1f}ms" if seconds < 10 else f"{seconds:.1f}s"


def _latencies(store: FrameStore) -> dict[int, float]:
    found: dict[int, list[float]] = {}
    for i in range(len(store)):
        if store.kind[i] != Kind.REQUEST or store.partner[i] == NO_PARTNER:
            continue
        j = store.partner[i]
        found.setdefault(store.unit[i], []).append(store.t[j] - store.t_end[i])
    return {u: sorted(v)[len(v) // 2] for u, v in found.items()}


def _units(store: FrameStore) -> set[int]:
    return {
        store.unit[i]
        for i in range(len(store))
        if store.kind[i] in (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION)
    }


def diff_stores(a: FrameStore, b: FrameStore, name_a: str = "A", name_b: str = "B") -> CaptureDiff:
    """Compare two framed captures of one bus."""
    a.sync()
    b.sync()
    out = CaptureDiff(name_a, name_b)
    units_a, units_b = _units(a), _units(b)
    out.units_new = sorted(units_b - units_a)
    out.units_gone = sorted(units_a - units_b)
    cycles_a, cycles_b = poll_cycles(a), poll_cycles(b)
    for unit in sorted(units_a & units_b):
        polls_a = {p.what: p for p in cycles_a[unit].polls} if unit in cycles_a else {}
        polls_b = {p.what: p for p in cycles_b[unit].polls} if unit in cycles_b else {}
        out.requests_new += [polls_b[w] for w in sorted(polls_b.keys() - polls_a.keys())]
        out.requests_gone += [polls_a[w] for w in sorted(polls_a.keys() - polls_b.keys())]
        for what in sorted(polls_a.keys() & polls_b.keys()):
            pa, pb = polls_a[what], polls_b[what]
            if abs(pb.period - pa.period) > PERIOD_CHANGE * pa.period:
                out.periods.append((pa, pb))
    lat_a, lat_b = _latencies(a), _latencies(b)
    for unit in sorted(lat_a.keys() & lat_b.keys()):
        la, lb = lat_a[unit], lat_b[unit]
        if abs(lb - la) > max(LATENCY_CHANGE * la, LATENCY_FLOOR):
            out.latencies.append((unit, la, lb))
    for unit in sorted(units_a & units_b):
        seen_a, seen_b = observe(a, unit), observe(b, unit)
        for key, place_b in sorted(seen_b.places.items()):
            place_a = seen_a.places.get(key)
            if place_a is None or not place_a.reads or not place_b.reads:
                continue
            va = [v for _t, v in place_a.reads]
            vb = [v for _t, v in place_b.reads]
            low, high = min(va), max(va)
            outside = sum(1 for v in vb if not low <= v <= high)
            if outside:
                out.moved.append(
                    Moved(unit, key[0], key[1], low, high, min(vb), max(vb), outside, len(vb))
                )
    return out
