"""Provides the capture diff: what changed on a bus between two captures of it.

Units that went silent or answer again, repeating requests that began failing or
recovered, then units and repeating requests that appeared or vanished, poll periods and
answer latencies that moved, and registers whose values in the second capture left the
range they kept in the first: a unit that stopped answering matters more than a value
that moved, so it comes first.

A request counts for its unit's answers when the capture says what became of it: an
answer, an exception answer, an answer with a wrong check, or none before the timeout.
Requests that are themselves damaged (a wrong CRC or LRC: the slave must ignore them),
broadcasts, and a request the capture ended on are left out.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field
from typing import Any

from sniffer.analysis.draft import observe
from sniffer.analysis.pollcycle import Poll, PollCycles
from sniffer.analysis.polls import FRAMED_APART, frame_body, poll_identity
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.vocab import BAD_CHECK, Kind, Status

PERIOD_CHANGE = 0.2  # a period that moved by more than 20 % is reported
LATENCY_CHANGE = 0.5  # a median latency that moved by more than 50 % (and 2 ms)
LATENCY_FLOOR = 0.002
FAIL_CHANGE = 0.2  # a poll whose share of failed sendings moved by 20 points or more
FAIL_FLOOR = 2  # ... with at least this many failed in the capture where it fails more
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


@dataclass(frozen=True, slots=True)
class Fared:
    """What became of the requests of a unit (or of one of its polls) in one capture."""

    answered: int = 0  # normal answers
    exceptions: int = 0  # exception answers
    bad: int = 0  # answers with a wrong CRC or LRC
    timeouts: int = 0  # no answer

    @property
    def sent(self) -> int:
        return self.answered + self.exceptions + self.bad + self.timeouts

    @property
    def replied(self) -> int:
        """Requests the unit answered somehow: it was alive."""
        return self.answered + self.exceptions + self.bad

    @property
    def failed(self) -> int:
        """Requests that did not bring their values."""
        return self.exceptions + self.bad + self.timeouts

    def add(self, status: int) -> Fared:
        return Fared(
            self.answered + (status == Status.OK),
            self.exceptions + (status == Status.EXCEPTION),
            self.bad + (status == Status.BAD_ANSWER),
            self.timeouts + (status == Status.TIMEOUT),
        )

    def plus(self, other: Fared) -> Fared:
        return Fared(
            self.answered + other.answered,
            self.exceptions + other.exceptions,
            self.bad + other.bad,
            self.timeouts + other.timeouts,
        )

    def why(self) -> str:
        """The failures by kind: `8 timeouts, 2 exceptions`."""
        parts = [
            _count(n, word)
            for n, word in (
                (self.timeouts, "timeout"),
                (self.exceptions, "exception"),
                (self.bad, "bad answer"),
            )
            if n
        ]
        return ", ".join(parts)


@dataclass(frozen=True, slots=True)
class Change:
    """A unit (`what` empty) or one of its polls whose answers changed from A to B."""

    unit: int
    what: str
    a: Fared
    b: Fared

    @property
    def moved(self) -> float:
        """How far the share of failed sendings moved (B minus A)."""
        return _share(self.b.failed, self.b.sent) - _share(self.a.failed, self.a.sent)


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
    silent: list[Change] = field(default_factory=list)  # answered in A, never in B
    back: list[Change] = field(default_factory=list)  # never answered in A, does in B
    failing: list[Change] = field(default_factory=list)  # polls that began failing in B
    recovered: list[Change] = field(default_factory=list)  # polls that failed less in B

    @property
    def same(self) -> bool:
        return not (
            self.silent
            or self.back
            or self.failing
            or self.recovered
            or self.units_new
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
            out.append("no difference in units, answers, polls, latencies or register ranges")
            return "\n".join(out)
        for u in self.units_new:
            out.append(f"unit {u}: new in B")
        for u in self.units_gone:
            out.append(f"unit {u}: gone in B (seen in A, not in B)")
        for c in self.silent:
            out.append(
                f"unit {c.unit}: silent in B: none of {c.b.sent} requests answered "
                f"({c.b.why()}); {_answered(c.a)} in A"
            )
        for c in self.back:
            out.append(
                f"unit {c.unit}: answers again in B: {_answered(c.b)}; none of {c.a.sent} "
                f"in A ({c.a.why()})"
            )
        for c in self.failing:
            out.append(
                f"unit {c.unit}: {c.what} began failing in B: {_failed(c.b)}; "
                f"{_failed(c.a, 'in A')}"
            )
        for c in self.recovered:
            out.append(
                f"unit {c.unit}: {c.what} recovered in B: {_failed(c.b)}; {_failed(c.a, 'in A')}"
            )
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


def _count(n: int, word: str) -> str:
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def _share(part: int, whole: int) -> float:
    return part / whole if whole else 0.0


def _percent(part: int, whole: int) -> str:
    return f"{100 * _share(part, whole):.0f} %"


def _answered(f: Fared) -> str:
    """`20 of 24 requests answered (83 %)`."""
    return f"{f.replied} of {f.sent} requests answered ({_percent(f.replied, f.sent)})"


def _failed(f: Fared, where: str = "failed") -> str:
    """`10 of 20 failed (50 %: 8 timeouts, 2 exceptions)`."""
    why = f.why()
    share = _percent(f.failed, f.sent) + (f": {why}" if why else "")
    return f"{f.failed} of {f.sent} {where} ({share})"


def _ms(seconds: float) -> str:
    return f"{seconds * 1000:.1f}ms" if seconds < 10 else f"{seconds:.1f}s"


def _waits(store: FrameStore) -> dict[int, list[float]]:
    """Each unit's answer times (an answer's first byte less its request's last)."""
    found: dict[int, list[float]] = {}
    for i in range(len(store)):
        if store.kind[i] != Kind.REQUEST or store.partner[i] == NO_PARTNER:
            continue
        j = store.partner[i]
        found.setdefault(store.unit[i], []).append(store.t[j] - store.t_end[i])
    return found


def _medians(waits: dict[int, array[float]]) -> dict[int, float]:
    """Each unit's median answer time (the upper of the two middle ones)."""
    return {u: sorted(v)[len(v) // 2] for u, v in waits.items() if v}


def _units(store: FrameStore) -> set[int]:
    return {
        store.unit[i]
        for i in range(len(store))
        if store.kind[i] in (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION)
    }


_DECIDED = (Status.OK, Status.EXCEPTION, Status.BAD_ANSWER, Status.TIMEOUT)


def fared(store: FrameStore) -> tuple[dict[int, Fared], dict[tuple[int, str], Fared]]:
    """What became of the requests of each unit, and of each of its polls (by the
    poll cycle's `what`), over the requests whose fate the capture shows."""
    units: dict[int, Fared] = {}
    polls: dict[tuple[int, str], Fared] = {}
    named: dict[tuple[bytes, int], str] = {}  # a polling master repeats its requests
    for i in range(len(store)):
        status = store.status[i]
        if store.kind[i] != Kind.REQUEST or status not in _DECIDED:
            continue
        flags = store.flags[i]
        if flags & BAD_CHECK:
            continue
        unit = store.unit[i]
        key = (store.raw(i), flags & FRAMED_APART)
        what = named.get(key)
        if what is None:
            what = named[key] = poll_identity(frame_body(*key))[1]
        units[unit] = units.get(unit, Fared()).add(status)
        polls[unit, what] = polls.get((unit, what), Fared()).add(status)
    return units, polls


def _answers(
    out: CaptureDiff,
    a: Side,
    b: Side,
    polls_in_both: set[tuple[int, str]],
) -> None:
    """Units gone silent or back, polls that began failing or recovered."""
    units_a, polls_a = a.fared_units, a.fared_polls
    units_b, polls_b = b.fared_units, b.fared_polls
    for unit in sorted(units_a.keys() & units_b.keys()):
        fa, fb = units_a[unit], units_b[unit]
        if fa.replied and not fb.replied:
            out.silent.append(Change(unit, "", fa, fb))
        elif fb.replied and not fa.replied:
            out.back.append(Change(unit, "", fa, fb))
    whole = {c.unit for c in out.silent + out.back}  # their polls all changed with them
    for unit, what in sorted(polls_in_both & polls_a.keys() & polls_b.keys()):
        if unit in whole:
            continue
        change = Change(unit, what, polls_a[unit, what], polls_b[unit, what])
        if change.moved >= FAIL_CHANGE and change.b.failed >= FAIL_FLOOR:
            out.failing.append(change)
        elif -change.moved >= FAIL_CHANGE and change.a.failed >= FAIL_FLOOR:
            out.recovered.append(change)
    out.failing.sort(key=lambda c: -c.moved)
    out.recovered.sort(key=lambda c: c.moved)


@dataclass(slots=True)
class _Range:
    """The values read at one place of one unit: their range and count, and (in B) how
    many lay outside the range A kept there."""

    low: int
    high: int
    readings: int = 0
    outside: int = 0


class Side:
    """What `diff` keeps of one capture, counted a segment of rows at a time (`add`, the
    `segment` of a windowed `sniffer.session.session.Session.ingest`), so that two days of
    a bus compare in memory that does not grow with their rows: the units seen, what
    became of each unit's and each poll's requests, the poll cycle (bounded, as
    `--stats` counts it), each answer's latency (8 bytes a transaction: the median is
    that of every value) and each register's range of values read. `before`: A's side,
    complete, when this is B's: a value read in B is counted outside A's range as it is
    met. A segment holds each of its requests' answers (segments end where no request
    waits), so what a pair says is counted whole."""

    def __init__(self, before: Side | None = None) -> None:
        self.before = before
        self.units: set[int] = set()
        self.fared_units: dict[int, Fared] = {}
        self.fared_polls: dict[tuple[int, str], Fared] = {}
        self.cycles = PollCycles()
        self.latencies: dict[int, array[float]] = {}
        self.ranges: dict[tuple[int, str, int], _Range] = {}  # (unit, table, address)

    def __call__(self, session: Any) -> None:  # (a Session: analysis does not import it)
        self.add(session.store)

    def add(self, store: FrameStore) -> None:
        """Count the rows of `store` (a whole capture, or one segment after another)."""
        store.sync()
        units = _units(store)
        self.units |= units
        fared_units, fared_polls = fared(store)
        for unit, f in fared_units.items():
            self.fared_units[unit] = self.fared_units.get(unit, Fared()).plus(f)
        for key, f in fared_polls.items():
            self.fared_polls[key] = self.fared_polls.get(key, Fared()).plus(f)
        self.cycles.add(store)
        for unit, waits in _waits(store).items():
            self.latencies.setdefault(unit, array("d")).extend(waits)
        earlier = self.before.ranges if self.before is not None else None
        for unit in sorted(units):
            for (table, address), place in observe(store, unit).places.items():
                if not place.reads:
                    continue
                values = [v for _t, v in place.reads]
                where = (unit, table, address)
                kept = self.ranges.get(where)
                if kept is None:
                    kept = self.ranges[where] = _Range(min(values), max(values))
                kept.low, kept.high = min(kept.low, *values), max(kept.high, *values)
                kept.readings += len(values)
                a = earlier.get(where) if earlier is not None else None
                if a is not None:
                    kept.outside += sum(1 for v in values if not a.low <= v <= a.high)


def diff_stores(a: FrameStore, b: FrameStore, name_a: str = "A", name_b: str = "B") -> CaptureDiff:
    """Compare two framed captures of one bus."""
    side_a = Side()
    side_a.add(a)
    side_b = Side(before=side_a)
    side_b.add(b)
    return diff_sides(side_a, side_b, name_a, name_b)


def diff_sides(a: Side, b: Side, name_a: str = "A", name_b: str = "B") -> CaptureDiff:
    """Compare two captures of one bus from what was counted of each (`Side`; B's
    counted with A's as its `before`)."""
    out = CaptureDiff(name_a, name_b)
    units_a, units_b = a.units, b.units
    out.units_new = sorted(units_b - units_a)
    out.units_gone = sorted(units_a - units_b)
    cycles_a, cycles_b = a.cycles.cycles(), b.cycles.cycles()
    repeating = {
        (unit, p.what)
        for cycles in (cycles_a, cycles_b)
        for unit, cycle in cycles.items()
        for p in cycle.polls
    }
    _answers(out, a, b, repeating)
    for unit in sorted(units_a & units_b):
        polls_a = {p.what: p for p in cycles_a[unit].polls} if unit in cycles_a else {}
        polls_b = {p.what: p for p in cycles_b[unit].polls} if unit in cycles_b else {}
        out.requests_new += [polls_b[w] for w in sorted(polls_b.keys() - polls_a.keys())]
        out.requests_gone += [polls_a[w] for w in sorted(polls_a.keys() - polls_b.keys())]
        for what in sorted(polls_a.keys() & polls_b.keys()):
            pa, pb = polls_a[what], polls_b[what]
            if abs(pb.period - pa.period) > PERIOD_CHANGE * pa.period:
                out.periods.append((pa, pb))
    lat_a, lat_b = _medians(a.latencies), _medians(b.latencies)
    for unit in sorted(lat_a.keys() & lat_b.keys()):
        la, lb = lat_a[unit], lat_b[unit]
        if abs(lb - la) > max(LATENCY_CHANGE * la, LATENCY_FLOOR):
            out.latencies.append((unit, la, lb))
    both = units_a & units_b
    for key in sorted(k for k in b.ranges if k[0] in both):
        kept_a, kept_b = a.ranges.get(key), b.ranges[key]
        if kept_a is None or not kept_b.outside:
            continue
        unit, table, address = key
        out.moved.append(
            Moved(
                unit,
                table,
                address,
                kept_a.low,
                kept_a.high,
                kept_b.low,
                kept_b.high,
                kept_b.outside,
                kept_b.readings,
            )
        )
    return out
