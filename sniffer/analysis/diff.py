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

Times are compared only as far as each capture's stamps back them (as `--stats` shows
them, `sniffer.framing.pairing.judge`): a median answer time is a value when at least
half of a unit's answers came later than twice the stamps' resolution (good to one
resolution either way), a bound when more than half came sooner (below twice the
resolution, plus the one each stamp may be off: `<48ms` for 16 ms reads), unknown when
the stamps measure none (a log's print times, a synthetic clock); a poll period is a
value good to its resolution, or a bound (at most). Two times are a change only where
no pair of times they allow is close: a 16 ms read clock's `<48ms` against 2.2 ms in B
is no change, against 80 ms it is; 40 ms against 62 ms, both read every 16 ms, is none
(both may be 50 ms).
"""

from __future__ import annotations

import sys
from array import array
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from math import ceil
from typing import Any

from dissectors.dissect import dissect
from dissectors.values import Role
from sniffer.analysis.draft import READ_TABLES
from sniffer.analysis.pollcycle import Poll, PollCycles
from sniffer.analysis.polls import FRAMED_APART, frame_body, poll_identity
from sniffer.framing.pairing import (
    INF,
    RESOLVED,
    TIMING_WORDS,
    UNRESOLVED,
    Latency,
    duration,
    shown_step,
)
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.model import Stamp
from sniffer.vocab import BAD_CHECK, Flag, Kind, Status

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

    def add(self, status: int, n: int = 1) -> Fared:
        """These counts and `n` requests more whose fate was `status`."""
        return Fared(
            self.answered + n * (status == Status.OK),
            self.exceptions + n * (status == Status.EXCEPTION),
            self.bad + n * (status == Status.BAD_ANSWER),
            self.timeouts + n * (status == Status.TIMEOUT),
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
    latencies: list[tuple[int, Latency, Latency]] = field(default_factory=list)  # unit, a, b
    # why answer times of units in both were not compared: one line a capture
    untimed: list[str] = field(default_factory=list)
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
            if self.untimed:  # (not "no difference in latencies": some were not compared)
                out.append(
                    "no difference in units, answers, polls, register ranges, or the "
                    "answer times both captures' stamps measure"
                )
            else:
                out.append("no difference in units, answers, polls, latencies or register ranges")
            out += self.untimed
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
            out.append(f"unit {p.unit}: new poll in B: {p.what} every {p.period_text()}")
        for p in self.requests_gone:
            out.append(f"unit {p.unit}: poll gone in B: {p.what} (every {p.period_text()} in A)")
        for pa, pb in self.periods:
            out.append(
                f"unit {pa.unit}: {pa.what} every {pa.period_text()} in A, {pb.period_text()} in B"
            )
        for unit, la, lb in self.latencies:
            out.append(f"unit {unit}: median answer time {la.text()} in A, {lb.text()} in B")
        for m in self.moved:
            where = f"{TABLE_WORDS.get(m.table, m.table)} {m.address}"
            out.append(
                f"unit {m.unit}: {where} left its range: {m.a_low}..{m.a_high} in A, "
                f"{m.b_low}..{m.b_high} in B ({m.outside} of {m.readings} readings outside)"
            )
        out += self.untimed
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


def _waits(store: FrameStore) -> dict[int, list[float]]:
    """Each unit's answer times (an answer's first byte less its request's last)."""
    found: dict[int, list[float]] = {}
    for i in range(len(store)):
        if store.kind[i] != Kind.REQUEST or store.partner[i] == NO_PARTNER:
            continue
        j = store.partner[i]
        found.setdefault(store.unit[i], []).append(store.t[j] - store.t_end[i])
    return found


Span = tuple[float, float]  # the least and the most a time may be


def _apart(a: Span, b: Span, change: Callable[[float], float]) -> bool:
    """Whether every time `b` allows differs from every time `a` allows by more than
    `change` of A's (a value allows itself give or take its error, a bound anything from
    0 to it): B above all of A by more than `change` of A's most, or below all of it by
    more than `change` of A's least (`change` grows with the time). Two bounds allow the
    same small times: never apart."""
    (a_low, a_high), (b_low, b_high) = a, b
    return b_low - a_high > change(a_high) or a_low - b_high > change(a_low)


def _latency_span(t: Latency, resolution: float) -> Span:
    """The answer times a median allows: to its bound, or its value give or take one
    resolution (each stamp of each answer may be off by that much, so may the middle
    one)."""
    if t.bound:
        return (0.0, t.raw)
    return (max(0.0, t.raw - resolution), t.raw + resolution)


def _period_span(p: Poll) -> Span:
    """The periods a poll's allows: to its bound, or its value give or take its stamps'
    resolution and half the buckets its waits were counted in."""
    if p.period_bound:
        return (0.0, p.period)
    error = p.resolution + p.quantum / 2
    return (max(0.0, p.period - error), p.period + error)


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
    kind, status, flags, unit = store.kind, store.status, store.flags, store.unit
    request, decided = int(Kind.REQUEST), {int(s) for s in _DECIDED}
    # a polling master repeats its requests: each distinct one (and its fate) counted
    # first, then named once (1M frames of the project stream: 0.8-1.1 s, 3.7-5.3 s row
    # by row)
    seen = Counter(
        (store.raw(i), flags[i] & FRAMED_APART, unit[i], status[i])
        for i in range(len(store))
        if kind[i] == request and status[i] in decided and not flags[i] & BAD_CHECK
    )
    named: dict[tuple[bytes, int], str] = {}
    for (raw, apart, u, fate), n in seen.items():
        what = named.get((raw, apart))
        if what is None:
            what = named[raw, apart] = poll_identity(frame_body(raw, apart))[1]
        units[u] = units.get(u, Fared()).add(fate, n)
        polls[u, what] = polls.get((u, what), Fared()).add(fate, n)
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
        # each unit's answer times the stamps measure; those too short for them (below
        # twice the resolution) and those they cannot tell at all, counted
        self.latencies: dict[int, array[float]] = {}
        self.below: Counter[int] = Counter()
        self.unmeasured: Counter[int] = Counter()
        self.stamps = Stamp.EXACT
        self.resolution = 0.0
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
        self.stamps, self.resolution = store.stamps, store.resolution
        threshold = self.threshold
        for unit, waits in _waits(store).items():
            if threshold is None:
                self.unmeasured[unit] += len(waits)
                continue
            timed = [w for w in waits if not w < threshold]  # (a NaN: kept, as --stats)
            self.below[unit] += len(waits) - len(timed)
            self.latencies.setdefault(unit, array("d")).extend(timed)
        earlier = self.before.ranges if self.before is not None else None
        for where, values in readings(store).items():
            low, high = min(values), max(values)
            kept = self.ranges.get(where)
            if kept is None:
                kept = self.ranges[where] = _Range(low, high)
            else:
                kept.low, kept.high = min(kept.low, low), max(kept.high, high)
            kept.readings += len(values)
            a = earlier.get(where) if earlier is not None else None
            if a is not None and not a.low <= low <= high <= a.high:  # (else none outside)
                kept.outside += sum(1 for v in values if not a.low <= v <= a.high)

    @property
    def threshold(self) -> float | None:
        """The shortest answer time the stamps measure (shorter ones are only bounded by
        it); None where they measure none (print times, a synthetic clock, stamps that
        bound nothing), as `--stats` counts them."""
        if self.stamps in (Stamp.NONE, Stamp.PRINT) or not self.resolution < INF:
            return None
        return max(RESOLVED * self.resolution, UNRESOLVED)

    def answers(self, unit: int) -> int:
        """`unit`'s answers with a request: measured, too short for the stamps, or not
        measurable."""
        return len(self.latencies.get(unit, ())) + self.below[unit] + self.unmeasured[unit]

    def median(self, unit: int) -> Latency | None:
        """`unit`'s median answer time (the upper of the two middle ones) as far as the
        stamps vouch for it: a value, a bound below the threshold when the middle
        answer came sooner than the stamps resolve, None when they cannot tell."""
        kept = self.latencies.get(unit, ())
        below = self.below[unit]
        n = self.answers(unit)
        threshold = self.threshold
        if not n or self.unmeasured[unit] or threshold is None:
            return None
        step = shown_step(self.resolution)
        rank = n // 2
        if rank < below:
            # every answer below the threshold came sooner than any kept, each by less
            # than the threshold plus the resolution its stamps may be off by
            most = threshold + self.resolution
            return Latency(ceil(most / step - 1e-9) * step, True, step, most)
        x = sorted(kept)[rank - below]
        return Latency(round(x / step) * step, False, step, x)

    def untimed(self, name: str, units: set[int]) -> str:
        """Why answer times of `units` (answered in both) were left uncompared here, or ''."""
        told = {u: self.median(u) for u in units if self.answers(u)}
        unknown = sorted(u for u, m in told.items() if m is None)
        bounded = sorted(u for u, m in told.items() if m is not None and m.bound)
        how = f"its stamps ({TIMING_WORDS.get(self.stamps, self.stamps.value)}"
        if self.resolution > 0 and self.resolution < INF:
            how += f", resolution {duration(self.resolution)}"
        how += ")"
        if unknown:
            return (
                f"{name}: answer times of {_units_text(unknown)} unknown: {how} cannot measure them"
            )
        if bounded:
            return (
                f"{name}: median answer times of {_units_text(bounded)} only bounded by {how}: "
                "compared where they still tell"
            )
        return ""


_UNREADABLE = int(Flag.CHECK_BAD | Flag.NON_HEX)


def readings(store: FrameStore) -> dict[tuple[int, str, int], Sequence[int]]:
    """Every value read in `store`, by (unit, table, address), in no particular order:
    what `sniffer.analysis.draft.observe` keeps as each place's reads, for every unit in
    one pass (the diff needs each place's range, count and how many left A's range, not
    their order). A read of registers or bits (FC 1-4) whose answer holds just what was
    asked is decoded here: the answers' data of one request kept end to end, each
    place's values then sliced out of them at once (the whole diff of 1M frames a side
    of the project's stream: 89 s through `observe` unit by unit, 27 s value by value,
    17.7 s so). Any other answer goes through the dissector as `observe` does. Held
    equal to `observe` by tests/analysis/test_diff.py."""
    store.sync()
    runs: dict[tuple[int, int, int, int], bytearray] = {}  # (unit, fc, address, count)
    found: dict[tuple[int, str, int], Sequence[int]] = {}
    others: dict[tuple[int, str, int], list[int]] = {}
    kind, flags, partner, unit_of = store.kind, store.flags, store.partner, store.unit
    request = int(Kind.REQUEST)
    for i in range(len(store)):
        if kind[i] != request or flags[i] & _UNREADABLE:
            continue
        j = partner[i]
        if j == NO_PARTNER or flags[j] & _UNREADABLE:
            continue
        unit = unit_of[i]
        asked = frame_body(store.raw(i), flags[i])
        answer = frame_body(store.raw(j), flags[j])
        fc = asked[1] if len(asked) == 6 else 0
        if fc in READ_TABLES and len(answer) >= 3 and answer[1] == fc:
            count = asked[4] << 8 | asked[5]
            size = 2 * count if fc >= 3 else (count + 7) // 8
            if count and answer[2] == size == len(answer) - 3:
                key = (unit, fc, asked[2] << 8 | asked[3], count)
                run = runs.get(key)
                if run is None:
                    runs[key] = bytearray(answer[3:])
                else:
                    run += answer[3:]
                continue
        told = dissect(answer, Role.RESPONSE, request=asked)
        if told.exception:
            continue
        for read in told.data:
            if read.address is None or read.write:
                continue
            for k, value in enumerate(read.values):
                others.setdefault((unit, read.table, read.address + k), []).append(value)
    for (unit, fc, address, count), run in runs.items():
        table = READ_TABLES[fc]
        if fc >= 3:
            words = array("H", run)
            if _LITTLE:
                words.byteswap()  # (the bus sends each register high byte first)
            for k in range(count):
                _join(found, (unit, table, address + k), words[k::count])
        else:
            stride = (count + 7) // 8
            for k in range(count):
                column = bytes(run[k >> 3 :: stride]).translate(_BIT[k & 7])
                _join(found, (unit, table, address + k), column)
    for where, values in others.items():
        _join(found, where, values)
    return found


_LITTLE = sys.byteorder == "little"
# a byte -> its bit k (0 or 1), for each k: a coil's value out of a column of data bytes
_BIT = [bytes(b >> k & 1 for b in range(256)) for k in range(8)]


def _join(
    found: dict[tuple[int, str, int], Sequence[int]],
    where: tuple[int, str, int],
    values: Sequence[int],
) -> None:
    """`values` read at `where`, after any read there already."""
    had = found.get(where)
    found[where] = values if had is None else [*had, *values]


def _units_text(units: list[int]) -> str:
    return (
        f"unit {units[0]}"
        if len(units) == 1
        else f"{len(units)} units ({', '.join(map(str, units))})"
    )


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
            if _apart(_period_span(pa), _period_span(pb), lambda x: PERIOD_CHANGE * x):
                out.periods.append((pa, pb))
    for unit in sorted(units_a & units_b):
        la, lb = a.median(unit), b.median(unit)
        if la is None or lb is None:
            continue
        if _apart(
            _latency_span(la, a.resolution),
            _latency_span(lb, b.resolution),
            lambda x: max(LATENCY_CHANGE * x, LATENCY_FLOOR),
        ):
            out.latencies.append((unit, la, lb))
    answered = {u for u in units_a & units_b if a.answers(u) and b.answers(u)}
    for name, side in (("A", a), ("B", b)):
        if why := side.untimed(name, answered):
            out.untimed.append(why)
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
