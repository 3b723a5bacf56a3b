"""Provides per-unit statistics, kept up to date as frames are indexed."""

from __future__ import annotations

from array import array
from collections import Counter, deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from functools import partial
from itertools import compress, islice, repeat
from math import ceil, isnan
from operator import lt, ne, not_, sub
from typing import Any

from sniffer import core
from sniffer.framing.columns import flag_mask, marking
from sniffer.framing.pairing import (
    INF,
    RESOLVED,
    TIMING_WORDS,
    UNRESOLVED,
    Latency,
    StampClock,
    duration,
    judge,
    shown_step,
    timing_note,
)
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.model import Stamp
from sniffer.vocab import BAD_CHECK, Flag, Kind, Status

# what a spill is handed (see `Stats.bound`): a unit's latencies or its request times
LATENCIES, REQUEST_TIMES = 0, 1
Spill = Callable[[int, int, Sequence[float]], None]

RECENT = 1024  # newest latencies and request times a bounded unit keeps (the MQTT status)


def latency_figure(ms: float) -> float:
    """A latency in ms as the table prints it: to 0.1 ms, or to the microsecond under
    0.1 ms (a server on the capturing host answers in tens of µs; never 0.0)."""
    return round(ms, 1) if abs(ms) >= 0.1 else round(ms, 3)


def latency_text(ms: float) -> str:
    """`latency_figure(ms)` as the table prints it. Equal for a value and its figure
    (rounding twice to the same places changes nothing), which the tallies rely on."""
    figure = latency_figure(ms)
    return f"{figure:.1f}" if abs(figure) >= 0.1 else f"{figure:.3f}"


class Tallies:
    """A unit's latencies and request times in a bounded form, for a live capture that
    runs for days (`Stats.bound`): the printed figures, counted, instead of every value.

    The table prints latencies in ms to 0.1 (under 0.1 ms to 0.001) and the poll period
    in ms to 1, both as the nearest-rank quantile of the values. Rounding is monotonic,
    so the value at a rank, rounded, is the rounded value at that rank: counting how
    many values round to each printed figure (`latency_ms`: `latency_figure(ms)`,
    `gap_ms`: `round(gap * 1000)`, exactly what `latency_text` and `{:.0f}` print) gives
    the very figures the whole arrays give, in memory that grows with the number of
    distinct figures, not of frames. The newest
    RECENT values of each are kept as they are, for the MQTT unit status (its own
    window of exact values). Latencies are never NaN live (stamps from the clock); one
    that were would be left out."""

    __slots__ = (
        "gap_ms",
        "last_request",
        "latencies",
        "latency_ms",
        "recent_latencies",
        "recent_requests",
        "requests",
        "spill",
    )

    def __init__(self) -> None:
        self.latency_ms: Counter[float] = Counter()  # latency_figure(ms) -> how many
        self.gap_ms: Counter[int] = Counter()  # round(gap s * 1000) -> how many
        self.latencies = 0  # latencies counted
        self.requests = 0  # request times seen
        self.last_request: float | None = None
        self.recent_latencies: deque[float] = deque(maxlen=RECENT)
        self.recent_requests: deque[float] = deque(maxlen=RECENT)
        # where every value is handed as it is counted, if anywhere (a sidecar being
        # written keeps them on disk: `Stats.bound`): (LATENCIES or REQUEST_TIMES, values)
        self.spill: Callable[[int, Sequence[float]], None] | None = None

    def add_latencies(self, values: Sequence[float]) -> None:
        """Count latencies (seconds)."""
        if self.spill is not None and len(values):
            self.spill(LATENCIES, values)
        fast = core.FAST
        if fast is not None and isinstance(values, array) and values.typecode == "d":
            # the counting in C (sniffer/_core.c: tally_latencies), the figures rounded
            # exactly as latency_figure(x * 1000) rounds them
            kept = fast.tally_latencies(self.latency_ms, values)
            self.latencies += kept
            if kept < len(values):  # NaN among them
                values = [x for x in values if not isnan(x)]
            self.recent_latencies.extend(_tail(values))
            return
        values = [x for x in values if not isnan(x)]
        self.latencies += len(values)
        self.recent_latencies.extend(_tail(values))
        self.latency_ms.update(latency_figure(x * 1000) for x in values)

    def add_requests(self, times: Sequence[float]) -> None:
        """Count request times (seconds, in the order they came): their gaps."""
        if not times:
            return
        if self.spill is not None:
            self.spill(REQUEST_TIMES, times)
        self.requests += len(times)
        self.recent_requests.extend(_tail(times))
        last = self.last_request
        start = 0
        if last is None:
            last, start = times[0], 1
        fast = core.FAST
        if fast is not None and isinstance(times, array) and times.typecode == "d":
            # the counting in C (sniffer/_core.c: tally_gaps), rounded as round() rounds
            self.last_request = fast.tally_gaps(self.gap_ms, times, start, last)
            return
        gaps = self.gap_ms
        for t in islice(times, start, None):
            gaps[round((t - last) * 1000)] += 1  # as median_gap: b - a
            last = t
        self.last_request = last


def _tail(values: Sequence[float]) -> Iterable[float]:
    """The newest RECENT of `values`: what a deque of that length keeps of them all."""
    return islice(values, max(0, len(values) - RECENT), None)


def _tally_ranked(tally: Counter[Any], q: float) -> Any:
    """The q-quantile (0..1) of a tally's values (at least one), nearest rank."""
    n = tally.total()
    rank = min(n - 1, max(0, round(q * (n - 1))))
    seen = 0
    for key in sorted(tally):
        seen += tally[key]
        if seen > rank:
            return key
    raise AssertionError("a rank within the tally")


@dataclass
class UnitStats:
    unit: int
    requests: int = 0
    responses: int = 0
    exceptions: Counter[int] = field(default_factory=Counter)
    timeouts: int = 0
    check_errors: int = 0
    latencies: array[float] = field(default_factory=lambda: array("d"))  # seconds
    request_times: array[float] = field(default_factory=lambda: array("d"))
    last_seen: float = 0.0
    below_resolution: int = 0  # answers faster than the timing resolves
    unmeasured: int = 0  # answers whose latency the timing cannot give at all
    # bounded (a long live capture, `Stats.bound`): the latencies and request times
    # are counted here, and the two arrays above stay empty
    tallies: Tallies | None = None

    @property
    def exception_count(self) -> int:
        return sum(self.exceptions.values())

    def latency_ms(self, q: float) -> float | None:
        """The q-quantile (0..1) of answer latency in ms, nearest rank (bounded: to the
        0.1 ms the table prints)."""
        return self.latencies_ms(q)[0]

    def latencies_ms(self, *qs: float) -> list[float | None]:
        """`latency_ms` of each of `qs`, the latencies sorted once."""
        tallies = self.tallies
        if tallies is not None:
            tally = tallies.latency_ms
            return [_tally_ranked(tally, q) if tally else None for q in qs]
        values = self.latencies
        if not values:
            return [None for _ in qs]
        picked = _select(values, qs)
        if picked is None:
            ordered = sorted(values)
            picked = [_ranked(ordered, q) for q in qs]
        return [x * 1000 for x in picked]

    def polling_period(self) -> float | None:
        """Median seconds between two requests to this unit (bounded: to the 1 ms the
        table prints)."""
        tallies = self.tallies
        if tallies is not None:
            gaps = tallies.gap_ms
            return _tally_ranked(gaps, 0.5) / 1000 if gaps else None
        return median_gap(self.request_times)

    def period(self, resolution: float) -> Latency | None:
        """The polling period as stamps of `resolution` can vouch for it
        (`resolved_period`)."""
        median = self.polling_period()
        if median is not None and self.tallies is None and median == median:
            median = round(median * 1000) / 1000  # to the 1 ms the tallies count, as they
        return resolved_period(median, resolution)

    @property
    def latency_count(self) -> int:
        """Latencies measured so far."""
        return len(self.latencies) if self.tallies is None else self.tallies.latencies

    @property
    def request_count(self) -> int:
        """Request times seen so far (the requests with a good check)."""
        return len(self.request_times) if self.tallies is None else self.tallies.requests

    def newest_latencies(self, k: int) -> list[float]:
        """The newest `k` latencies (fewer if there are not as many; bounded, at most
        RECENT)."""
        return _newest(self.latencies if self.tallies is None else self.tallies.recent_latencies, k)

    def newest_requests(self, k: int) -> list[float]:
        """The newest `k` request times (as `newest_latencies`)."""
        return _newest(
            self.request_times if self.tallies is None else self.tallies.recent_requests, k
        )

    def bound(self, spill: Spill | None = None) -> None:
        """Count latencies and request times in `Tallies` from now on (those so far
        included) instead of keeping them all; each value also handed to `spill`
        (with the unit), if given."""
        if self.tallies is not None:
            return
        self.tallies = Tallies()
        if spill is not None:
            self.tallies.spill = partial(spill, self.unit)
        self.tallies.add_latencies(self.latencies)
        self.tallies.add_requests(self.request_times)
        self.latencies, self.request_times = array("d"), array("d")


def _newest(values: Iterable[float], k: int) -> list[float]:
    if k <= 0:
        return []
    if isinstance(values, array):
        return list(values[-k:])
    return list(values)[-k:]


def nearest_rank(values: Sequence[float], q: float) -> float | None:
    """The q-quantile (0..1) of `values`, nearest rank (what --stats, the poll cycle and
    the MQTT unit status all report); None for no values."""
    if not values:
        return None
    picked = _select(values, (q,))
    return _ranked(sorted(values), q) if picked is None else picked[0]


def _ranked(ordered: Sequence[float], q: float) -> float:
    """The q-quantile of values already sorted (at least one), nearest rank."""
    return ordered[min(len(ordered) - 1, max(0, round(q * (len(ordered) - 1))))]


def resolved_period(median: float | None, resolution: float) -> Latency | None:
    """A period (the median wait between sendings) as stamps good to `resolution` can
    vouch for it, as a latency is (`pairing.judge`): the median when it is at least
    RESOLVED resolutions long; else at most the median plus one resolution (each end of
    a wait may be off by that much: a poll every 250 ms logged by a 1 s clock is `<2s`);
    None when there is none or the stamps bound nothing."""
    if median is None or not resolution < INF:
        return None
    step = shown_step(resolution)
    if median != median:  # (a NaN, from stamps that had none, as it is)
        return Latency(median, False, step, median)
    if not median < max(RESOLVED * resolution, UNRESOLVED):
        return Latency(_to_step(median, resolution), False, step, median)
    if resolution > 0 and median + resolution > 0:
        return Latency(ceil((median + resolution) / step - 1e-9) * step, True, step, median)
    return None


def _to_step(seconds: float, resolution: float) -> float:
    """A period rounded to whole seconds where the stamps hold no more (`shown_step`);
    finer ones are printed to the millisecond as they are (the bounded tallies count
    them so, and a second rounding would differ from theirs)."""
    step = shown_step(resolution)
    return round(seconds / step) * step if step >= 1.0 else seconds


def median_gap(times: Sequence[float]) -> float | None:
    """The median gap between consecutive `times` (a polling period); None for fewer
    than two."""
    if len(times) < 2:
        return None
    picked = _select(times, (0.5,), gaps=True)
    if picked is not None:
        return picked[0]
    return nearest_rank(list(map(sub, islice(times, 1, None), times)), 0.5)  # b - a


def _select(values: Sequence[float], qs: Sequence[float], gaps: bool = False) -> list[float] | None:
    """The nearest-rank q-quantiles of `values` (at least one; with `gaps`, of the
    differences of consecutive values, b - a, at least two values) from the compiled
    core, by selection instead of a sort: the values sorted() would put at those ranks
    (sniffer/_core.c: ranked). None where it cannot say (no compiled core, values not
    an array of floats, a NaN or a negative zero among them): then sort. Selection
    needs no sorted copy of each unit's values."""
    fast = core.FAST
    if fast is None or not isinstance(values, array) or values.typecode != "d":
        return None
    n = len(values) - 1 if gaps else len(values)
    ranks = [min(n - 1, max(0, round(q * (n - 1)))) for q in qs]
    order = sorted(range(len(ranks)), key=ranks.__getitem__)
    found = fast.ranked(values, tuple(ranks[k] for k in order), gaps)
    if found is None:
        return None
    picked = [0.0] * len(ranks)
    for k, x in zip(order, found, strict=True):
        picked[k] = x
    return picked


NOISE, REQUEST, RESPONSE = int(Kind.NOISE), int(Kind.REQUEST), int(Kind.RESPONSE)
EXCEPTION, EVENT = int(Kind.EXCEPTION), int(Kind.EVENT)
TIMEOUT, OPEN = int(Status.TIMEOUT), int(Status.OPEN)


# A row's class, one byte: its kind, plus 8 for a frame with a bad check.
BAD = 8
_IS_NOISE = marking((NOISE,))
_IS_FRAME = marking(c for c in range(16) if c & 7 not in (NOISE, EVENT))
_IS_BAD_FRAME = marking(c | BAD for c in range(8) if c not in (NOISE, EVENT))
_IS_REQUEST = marking((REQUEST,))  # with a good check
_IS_ANSWER = marking((RESPONSE, EXCEPTION))  # with a good check
_IS_OPEN = marking((OPEN,))
_IS_TIMEOUT = marking((TIMEOUT,))
_HAS_EXCEPTION_BIT = marking(range(0x80, 0x100))


class Stats:
    """Per-unit counts over a store; call `update()` as rows arrive."""

    def __init__(self, store: FrameStore) -> None:
        self.store = store
        self.units: dict[int, UnitStats] = {}
        self.next = 0
        self.noise_bytes = 0
        self.noise_spans = 0
        self.events = 0
        self._timed_out: set[int] = set()
        self._open: set[int] = set()
        self.bounded = False  # see `bound`
        self.spill: Spill | None = None
        # what the table's timing line says besides the store's stamps and resolution:
        # the response timeout and what the resolution was measured from (the session's)
        self.timeout: float | None = None
        self.clock: StampClock | None = None
        # answers counted while the clock still learnt the stamps' resolution (live: the
        # first reads), each (unit, its wait, its request's length in time): whether the
        # wait is a latency, a bound or neither is told once the resolution is
        # (`_judge_waiting`), as a replay, which measures it first, tells every answer's
        self._unjudged: list[tuple[int, float, float]] = []

    def bound(self, spill: Spill | None = None) -> None:
        """Keep each unit's latencies and request times in the bounded form (`Tallies`)
        from now on: what a headless live capture does, so that its statistics do not
        grow with every frame. The table prints the same; the arrays stay empty.

        `spill(unit, LATENCIES or REQUEST_TIMES, values)`: given every value as it is
        counted, those so far first, in the order the arrays would have them (a sidecar
        being written keeps them on disk: `sniffer.session.index.Spill`)."""
        self.bounded = True
        self.spill = spill
        for unit in self.units.values():
            unit.bound(spill)

    def unit(self, u: int) -> UnitStats:
        found = self.units.get(u)
        if found is None:
            found = self.units[u] = UnitStats(u)
            if self.bounded:
                found.bound(self.spill)
        return found

    def update(self) -> None:
        """Count the rows added since the last update.

        Column by column, not row by row: the new rows are sorted out with C-level scans
        (`bytes.translate`, `itertools.compress`, `collections.Counter`) and only the times
        that are kept (requests, latencies) are handed to their unit one by one, so the
        interpreter never steps through the rows that count only as a number."""
        s = self.store
        s.sync()
        # requests still open last time may have timed out since
        for i in list(self._open):
            if s.status[i] != OPEN:
                self._open.discard(i)
                if s.status[i] == TIMEOUT:
                    self.unit(s.unit[i]).timeouts += 1
        learning = self.clock is not None and self.clock.learning
        if self._unjudged and not learning:
            self._judge_waiting()
        start, n = self.next, len(s)
        if start >= n:
            return
        fast = core.FAST
        if fast is not None and s.stamps is not Stamp.PRINT and not learning:
            # (print times: each latency's bound depends on its request's length too,
            # which the compiled scan does not look at; logs are short)
            self._fast_update(fast, start, n)
            return
        kinds = s.kind[start:n].tobytes()
        self.events += kinds.count(EVENT)
        spans = kinds.count(NOISE)
        if spans:
            self.noise_spans += spans
            self.noise_bytes += sum(compress(s.length[start:n], kinds.translate(_IS_NOISE)))
        classes = kinds
        bad = flag_mask(s.flags, BAD_CHECK, start, n)
        if 1 in bad:  # the flag bytes are 0 or 1: shifted by 3 bits, each stays in its byte
            both = int.from_bytes(kinds, "big") | int.from_bytes(bad, "big") << 3
            classes = both.to_bytes(len(kinds), "big")
        units = s.unit[start:n].tobytes()
        frames = classes.translate(_IS_FRAME)
        framed = bytes(compress(units, frames))
        if not framed:
            self.next = n
            return
        for u in sorted(set(framed), key=framed.find):  # in order of first appearance
            last = units.rfind(u)
            while not frames[last]:  # a noise span or event with that unit byte
                last = units.rfind(u, 0, last)
            (self.units.get(u) or self.unit(u)).last_seen = s.t_end[start + last]
        if 1 in bad:
            for u, count in Counter(compress(units, classes.translate(_IS_BAD_FRAME))).items():
                self.units[u].check_errors += count
        self._requests(start, n, units, classes.translate(_IS_REQUEST))
        self._answers(start, n, units, classes.translate(_IS_ANSWER), learning)
        self.next = n

    def _fast_update(self, fast: Any, start: int, n: int) -> None:
        """The counts of `update` from the compiled core (sniffer/_core.c: stats_scan), one
        pass over the rows in C; what it hands back is added here as `update` adds it,
        unit by unit in the order of their first frames. The per-row work is then a
        step of a C loop, not of the interpreter."""
        s = self.store
        resolution = s.resolution
        mode = 0 if s.stamps == Stamp.NONE or not resolution < INF else 2
        below = mode and resolution > 0
        spans, noise_bytes, events, units, exceptions, still_open = fast.stats_scan(
            s, start, n, mode, max(RESOLVED * resolution, UNRESOLVED)
        )
        self.events += events
        self.noise_spans += spans
        self.noise_bytes += noise_bytes
        for u, last_seen, check_errors, asked, timeouts, answers, left_out, times, lat in units:
            st = self.units.get(u) or self.unit(u)
            st.last_seen = last_seen
            st.check_errors += check_errors
            st.requests += asked
            st.timeouts += timeouts
            st.responses += answers
            if below:
                st.below_resolution += left_out
            else:
                st.unmeasured += left_out
            if st.tallies is not None:
                if times:
                    st.tallies.add_requests(array("d", times))
                if lat:
                    st.tallies.add_latencies(array("d", lat))
            else:
                st.request_times.frombytes(times)
                st.latencies.frombytes(lat)
        if exceptions:
            for i in array("q", exceptions):
                self.units[s.unit[i]].exceptions[_exception_code(s, i)] += 1
        if still_open:
            self._open.update(array("q", still_open))
        self.next = n

    def _requests(self, start: int, n: int, units: bytes, mask: bytes) -> None:
        """Count the requests with a good check among rows `start`..`n` (`mask`)."""
        s = self.store
        asked = bytes(compress(units, mask))
        if not asked:
            return
        stats = self.units
        for u, count in Counter(asked).items():
            stats[u].requests += count
        if self.bounded:
            _hand_out(stats, asked, compress(s.t[start:n], mask), Tallies.add_requests)
        else:
            append = {u: stats[u].request_times.append for u in set(asked)}
            for u, t in zip(asked, compress(s.t[start:n], mask), strict=True):
                append[u](t)
        states = bytes(compress(s.status[start:n], mask))
        if TIMEOUT in states:
            for u, count in Counter(compress(asked, states.translate(_IS_TIMEOUT))).items():
                stats[u].timeouts += count
        if OPEN in states:
            rows = compress(range(start, n), mask)
            self._open.update(compress(rows, states.translate(_IS_OPEN)))

    def _answers(
        self, start: int, n: int, units: bytes, mask: bytes, learning: bool = False
    ) -> None:
        """Count the answers with a good check among rows `start`..`n` (`mask`), their
        exceptions and latencies (`learning`: their waits kept to be judged later)."""
        s = self.store
        answering = bytes(compress(units, mask))
        if not answering:
            return
        stats = self.units
        for u, count in Counter(answering).items():
            stats[u].responses += count
        exceptions = bytes(compress(s.fc[start:n], mask)).translate(_HAS_EXCEPTION_BIT)
        if 1 in exceptions:
            for i in compress(compress(range(start, n), mask), exceptions):
                stats[s.unit[i]].exceptions[_exception_code(s, i)] += 1
        partners = list(compress(s.partner[start:n], mask))
        times = list(compress(s.t[start:n], mask))
        if NO_PARTNER in partners:
            answered = list(map(ne, partners, repeat(NO_PARTNER)))
            partners = list(compress(partners, answered))
            times = list(compress(times, answered))
            answering = bytes(compress(answering, answered))
        # row i answers row j: t[i] - t_end[j], as pairing.latency; then sorted out as
        # pairing.measure does: a value (kept), or not (a bound or unknown)
        raw = list(map(sub, times, map(s.t_end.__getitem__, partners)))
        lengths = (
            [s.t_end[j] - s.t[j] for j in partners] if learning or s.stamps is Stamp.PRINT else []
        )
        if learning:
            self._unjudged.extend(zip(answering, raw, lengths, strict=True))
            return
        self._judge(answering, raw, lengths)

    def _judge_waiting(self) -> None:
        """Judge the waits of the answers counted while the clock learnt, in order."""
        waiting, self._unjudged = self._unjudged, []
        units = bytes(u for u, _, _ in waiting)
        self._judge(units, [x for _, x, _ in waiting], [d for _, _, d in waiting])

    def _judge(self, answering: bytes, raw: list[float], lengths: list[float]) -> None:
        """Each answer's wait (`raw`, unit by unit in `answering`), with the store's
        resolution: a latency kept, or a bound, or unknown (`lengths`: the requests'
        lengths in time, for print times)."""
        s = self.store
        stats = self.units
        resolution = s.resolution
        if s.stamps in (Stamp.NONE, Stamp.PRINT) or not resolution < INF:
            kept = [False] * len(raw)
        else:
            threshold = max(RESOLVED * resolution, UNRESOLVED)
            kept = list(map(not_, map(lt, raw, repeat(threshold))))  # NaN: kept
        if s.stamps is Stamp.PRINT and resolution < INF:
            # a print time's latency is a bound, unless the prints came too close
            for u, length, x in zip(answering, lengths, raw, strict=True):
                told = judge(x, resolution, Stamp.PRINT, length)
                if told is None:
                    stats[u].unmeasured += 1
                else:
                    stats[u].below_resolution += 1
            return
        below = s.stamps != Stamp.NONE and 0 < resolution < INF
        for u, count in Counter(compress(answering, map(not_, kept))).items():
            if below:
                stats[u].below_resolution += count
            else:
                stats[u].unmeasured += count
        if self.bounded:
            _hand_out(stats, compress(answering, kept), compress(raw, kept), Tallies.add_latencies)
            return
        append = {u: stats[u].latencies.append for u in set(answering)}
        for u, latency in zip(compress(answering, kept), compress(raw, kept), strict=True):
            append[u](latency)

    def table(self, labels: dict[int, str] | None = None) -> str:
        """The per-unit table, as `modscope replay --stats` prints it."""
        labels = labels or {}
        head = (
            f"{'unit':>4}  {'device':<16} {'req':>7} {'resp':>7} {'exc':>5} {'t/o':>5} "
            f"{'chk':>5} {'lat min':>8} {'median':>8} {'p95':>8} {'max':>8} {'period':>8}"
        )
        lines = [head, "-" * len(head)]

        resolution = self.store.resolution
        step_ms = shown_step(resolution) * 1000

        def ms(x: float | None) -> str:
            # a latency no finer than the stamps give it (0.1 ms at the finest)
            if x is None:
                return "-"
            if x != x:  # (a NaN as it is)
                return f"{x:.1f}"
            if step_ms < 1:  # below 0.1 ms to the microsecond, as listings: never 0.0
                return latency_text(x)
            return f"{round(x / step_ms) * step_ms:.0f}"

        for u in sorted(self.units):
            st = self.units[u]
            period = st.period(resolution) if self.store.stamps != Stamp.NONE else None
            least, median, p95, most = st.latencies_ms(0, 0.5, 0.95, 1)
            lines.append(
                f"{u:>4}  {labels.get(u, '')[:16]:<16} {st.requests:>7} {st.responses:>7} "
                f"{st.exception_count:>5} {st.timeouts:>5} {st.check_errors:>5} "
                f"{ms(least):>8} {ms(median):>8} {ms(p95):>8} {ms(most):>8} "
                f"{'-' if period is None else _period_text(period):>8}"
            )
            if st.exceptions:
                # in hex, as the listing and the specification write them (0B, not 11)
                codes = ", ".join(f"{c:02X} x{n}" for c, n in sorted(st.exceptions.items()))
                lines.append(f"{'':>4}  exceptions by code: {codes}")
        lines.append(
            f"noise: {self.noise_spans} spans, {self.noise_bytes} bytes; events: {self.events}"
        )
        lines.append(self.timing_line())
        return "\n".join(lines)

    def timing_line(self) -> str:
        """What the latencies and periods above are worth, given the source's stamps:
        `pairing.timing_note`, and how many answers' latencies are left out of the
        columns (bounded, or not measurable at all)."""
        s = self.store
        below = sum(u.below_resolution for u in self.units.values())
        unmeasured = sum(u.unmeasured for u in self.units.values())
        if s.stamps == Stamp.NONE:
            return timing_note(s.stamps, s.resolution)
        # why stamps bound nothing is the source's (a sidecar read back says it alike);
        # what a resolution was measured from is said once in the session's notes
        clock = self.clock
        why = clock.why() if clock is not None and not s.resolution < INF else ""
        text = timing_note(s.stamps, s.resolution, self.timeout, why)
        if not text:
            text = f"timing: {TIMING_WORDS[s.stamps]}"
            if s.resolution > 0:
                text += f", resolution {duration(s.resolution)}"
        if below:
            shown = "faster than that" if s.stamps is not Stamp.PRINT else "logged"
            text += f"; {below} answer(s) {shown}, only bounded (<x)"
        if unmeasured:
            text += f"; {unmeasured} latency(ies) the stamps cannot give"
        if below or unmeasured:
            text += ", left out of the latency columns"
        if self._unjudged:
            text += (
                f"; {len(self._unjudged)} answer(s) wait until the stamps' resolution is "
                "measured, to be shown as latencies or bounds"
            )
        return text


def _period_text(period: Latency) -> str:
    """A poll period as the table prints it: `250ms` (whole milliseconds, as the bounded
    tallies count them), `<2s`, `3s` (whole seconds, where the stamps hold no more)."""
    if period.step >= 1.0:
        return period.text()
    shown = f"{period.seconds * 1000:.0f}ms"
    return "<" + shown if period.bound else shown


def _hand_out(
    stats: dict[int, UnitStats],
    units: Iterable[int],
    values: Iterable[float],
    add: Callable[[Tallies, Sequence[float]], None],
) -> None:
    """Each value to its unit's tallies (bounded statistics), in order, with `add`."""
    per: dict[int, list[float]] = {}
    for u, x in zip(units, values, strict=True):
        got = per.get(u)
        if got is None:
            got = per[u] = []
        got.append(x)
    for u, xs in per.items():
        tallies = stats[u].tallies
        assert tallies is not None
        add(tallies, xs)


_FRAMED_APART = int(Flag.ASCII | Flag.MBAP)  # rows whose body is not their bytes less the CRC


def _exception_code(s: FrameStore, i: int) -> int:
    """The exception code of answer row `i` (0 when the frame is too short for one): the
    third byte of its body (`FrameView.body`), read in place for a plain RTU frame."""
    if s.flags[i] & _FRAMED_APART:
        body = s.view(i).body()
        return body[2] if len(body) > 2 else 0
    return s.streams[s.channel[i]][s.offset[i] + 2] if s.length[i] > 4 else 0
