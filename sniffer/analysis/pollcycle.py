"""Provides the poll cycle: per unit, which requests the master repeats, how often, how
steadily, and where the cycle stalled.

A request repeats when the same poll (`sniffer.analysis.polls`: unit, function, address,
quantity; written values left out) is sent again. Its period is the median time between
two sendings, its jitter the spread of those times (95th minus 5th percentile), and a
gap is a wait of more than twice the period: the master stopped polling, or the unit was
skipped.
"""

from __future__ import annotations

from array import array
from collections.abc import Mapping
from dataclasses import dataclass, field
from itertools import compress, repeat
from math import ceil
from operator import add, lt, sub
from typing import Any, cast

from sniffer import core
from sniffer.analysis.polls import FRAMED_APART, core_rules, frame_body, poll_identity
from sniffer.analysis.stats import resolved_period
from sniffer.framing.columns import both, but_not, flag_mask, marking
from sniffer.framing.pairing import RESOLVED, shown_step, span_words
from sniffer.framing.store import FrameStore
from sniffer.vocab import BAD_CHECK, Flag, Kind

GAP_FACTOR = 2.0  # a wait longer than this many periods is a gap
MIN_REPEATS = 3  # sendings before a request counts as part of the cycle


@dataclass(frozen=True, slots=True)
class Gap:
    """A wait of more than GAP_FACTOR periods between two sendings of a request."""

    start: float  # when the request was last sent before the gap
    length: float  # seconds until it was sent again


@dataclass(frozen=True, slots=True)
class Poll:
    """One repeating request."""

    unit: int
    function: int
    what: str  # "holding 3200-3211", "coil 16", "FC 8"
    count: int  # times sent
    period: float  # median seconds between sendings
    jitter: float  # p95 - p5 of those seconds
    gaps: tuple[Gap, ...]
    first: float
    last: float
    retries: int = 0  # sendings that repeated one left unanswered (counted in `count`)
    # stamps too coarse for the waits (see `sniffer.framing.pairing.judge`): the period
    # and the jitter are then upper bounds (at most), and `resolution` says how coarse
    period_bound: bool = False
    jitter_bound: bool = False
    resolution: float = 0.0

    def period_text(self) -> str:
        """`250ms`, `<2s`: the period no finer than the stamps hold."""
        return _shown(self.period, self.period_bound, self.resolution)

    def jitter_text(self) -> str:
        return _shown(self.jitter, self.jitter_bound, self.resolution)


@dataclass
class UnitCycle:
    """The repeating requests of one unit and the unit's whole cycle."""

    unit: int
    polls: list[Poll] = field(default_factory=list)
    once: int = 0  # requests sent fewer than MIN_REPEATS times

    @property
    def period(self) -> float | None:
        """The longest period of its repeating requests: the time for a whole cycle."""
        return max((p.period for p in self.polls), default=None)

    @property
    def gaps(self) -> list[Gap]:
        return sorted({g for p in self.polls for g in p.gaps}, key=lambda g: g.start)


_IS_REQUEST = marking((Kind.REQUEST,))  # kind byte -> 0/1
_CORE_RULES = core_rules()  # the same-poll rule of writes, as the compiled core takes it
_RETRY = int(Flag.RETRY)


# rows looked at a block at a time: what a block's keys hold is freed before the next,
# so the memory the poll cycle takes beyond the times it keeps does not grow with the
# capture (a day's capture keyed at once would hold every request's bytes at once)
BLOCK = 1 << 16
# keys the compiled table keeps from one `add` to the next: past this many it starts
# again, so that requests that never repeat (Modbus TCP's transaction ids make each
# request's bytes differ) do not make it grow with the capture
TABLE_KEYS = 1 << 16


@dataclass(slots=True)
class _Sent:
    """The sendings of one request (one identity of one unit): their times in the order
    of their rows, and how many were retries."""

    what: str
    fc: int
    times: array[float] = field(default_factory=lambda: array("d"))
    retries: int = 0


class PollCycles:
    """The poll cycle counted over rows given in parts (`add`): a whole store, or the
    segments of a windowed session one after the other (`sniffer.session.session.Session.window`),
    whose rows are then gone. What it keeps of each request with a good check is its time
    (8 bytes): the period, jitter and gaps are quantiles and comparisons of the exact
    waits, so nothing coarser gives the same table. `cycles()` gives what `poll_cycles`
    of one store holding every row gives."""

    def __init__(self) -> None:
        # unit -> identity -> sendings, each in order of its first sending
        self.sendings: dict[int, dict[tuple[object, ...], _Sent]] = {}
        # the compiled core's table of the keys met (see _fast_add), kept from one `add`
        # to the next, with the _Sent of each group it gives and the keys in it
        self._table: object = None
        self._groups: list[_Sent] = []
        self._number: dict[int, int] = {}  # id of a _Sent (held in _groups) -> its group
        self._keys = 0
        self.resolution = 0.0  # what the stamps of the rows added are worth

    def add(self, store: FrameStore, start: int = 0) -> None:
        """Count the requests among the rows of `store` from `start` on."""
        store.sync()
        self.resolution = store.resolution  # as measured so far: the newest rows' store
        n = len(store)
        if start >= n:
            return
        fast = core.FAST
        if fast is not None:
            self._fast_add(fast, store, start, n)
            return
        # the requests with a good check, picked out of the columns in C
        requests = but_not(
            store.kind[start:n].tobytes().translate(_IS_REQUEST),
            flag_mask(store.flags, BAD_CHECK, start, n),
        )
        # a polling master sends the same requests all day: each distinct request (its
        # bytes) is taken apart once a call, not once a row
        found: dict[object, _Sent] = {}
        t = store.t
        for lo in range(start, n, BLOCK):
            hi = min(lo + BLOCK, n)
            mask = requests[lo - start : hi - start]
            if 1 not in mask:
                continue
            keys = _keys(store, lo, mask)
            for key, i, when in zip(
                keys, compress(range(lo, hi), mask), compress(t[lo:hi], mask), strict=True
            ):
                sent = found.get(key)
                if sent is None:
                    sent = found[key] = self._sent(store, key, i)
                sent.times.append(when)
            retried = both(mask, flag_mask(store.flags, _RETRY, lo, hi))
            if 1 in retried:
                for key, retry in zip(keys, compress(retried, mask), strict=True):
                    if retry:
                        found[key].retries += 1

    def _fast_add(self, fast: Any, store: FrameStore, start: int, n: int) -> None:
        """`add` with the compiled core (sniffer/_core.c: poll_block): the rows picked,
        keyed and grouped in C a block at a time, each group one _Sent (several keys
        may share one: writes of other values), so Python touches only a key met for
        the first time (`_sent`, as `add` does) and each group once a block: its times
        appended in the order of their rows, its retries counted."""
        if self._table is None or self._keys > TABLE_KEYS:
            # the keys met, as `add`'s `found`, kept for the segments that follow, so
            # that a windowed replay does not hand the same requests to Python again
            # at each segment; the rule says which writes share a key
            self._table = fast.poll_table(_CORE_RULES)
            self._groups = []
            self._number = {}
            self._keys = 0
        table, groups, number = self._table, self._groups, self._number

        def resolve(key: object, i: int) -> int:
            self._keys += 1
            sent = self._sent(store, key, i)
            group = number.get(id(sent))
            if group is None:
                group = number[id(sent)] = len(groups)
                groups.append(sent)
            return group

        request = int(Kind.REQUEST)
        for lo in range(start, n, BLOCK):
            hi = min(lo + BLOCK, n)
            for group, times, retries in fast.poll_block(
                table, store, lo, hi, resolve, request, BAD_CHECK, _RETRY, FRAMED_APART
            ):
                sent = groups[group]
                sent.times.frombytes(times)
                sent.retries += retries

    def _sent(self, store: FrameStore, key: object, i: int) -> _Sent:
        """Where the sendings of row `i`'s request (`key`: its bytes, with its framing
        where it has any) are counted."""
        if isinstance(key, bytes):
            framing, raw = 0, key
        else:
            framing, raw = cast(tuple[int, bytes], key)
        # writes with other values: the same identity
        identity, what = poll_identity(frame_body(raw, framing))
        requests = self.sendings.setdefault(store.unit[i], {})
        sent = requests.get(identity)
        if sent is None:
            sent = requests[identity] = _Sent(what, store.fc[i])
        return sent

    def cycles(self, more: FrameStore | None = None) -> dict[int, UnitCycle]:
        """Every unit's poll cycle, from the requests added so far and those of `more`
        (not added: a live window's rows, counted again when the next summary comes)."""
        if more is None:
            return _cycles(self.sendings, self.resolution)
        both = PollCycles()
        both.sendings = {
            unit: {key: _Sent(s.what, s.fc, array("d", s.times), s.retries) for key, s in r.items()}
            for unit, r in self.sendings.items()
        }
        both.add(more)
        return _cycles(both.sendings, both.resolution)


def poll_cycles(store: FrameStore) -> dict[int, UnitCycle]:
    """Every unit's poll cycle, from the requests in `store`."""
    found = PollCycles()
    found.add(store)
    return found.cycles()


def _keys(store: FrameStore, lo: int, rows: bytes) -> list[object]:
    """What tells one request from another, for each of `rows` (a mask of the rows from
    `lo`): its bytes. The rows of ASCII and Modbus TCP frames have their framing added (a
    tuple), so a key fixes the row's unit and body (plain frames: the unit byte first,
    the CRC last)."""
    hi = lo + len(rows)
    starts = list(compress(store.offset[lo:hi], rows))
    lengths = list(compress(store.length[lo:hi], rows))
    keys: list[object]
    if len(store.streams) == 1:
        # the bytes these rows lie in, copied once, then sliced by a comprehension (a
        # map of slice objects costs a call more a row)
        (data,) = store.streams.values()
        first = min(starts)
        seg = bytes(data[first : max(map(add, starts, lengths))])
        keys = [
            seg[at - first : at - first + size] for at, size in zip(starts, lengths, strict=True)
        ]
    else:
        streams = store.streams
        channels = compress(store.channel[lo:hi], rows)
        keys = [
            bytes(streams[ch][at : at + size])
            for ch, at, size in zip(channels, starts, lengths, strict=True)
        ]
    apart = both(rows, flag_mask(store.flags, FRAMED_APART, lo, hi))
    if 1 in apart:
        framing = compress(store.flags[lo:hi], rows)
        keys = [
            (how & FRAMED_APART, key) if odd else key
            for odd, how, key in zip(compress(apart, rows), framing, keys, strict=True)
        ]
    return keys


def _cycles(
    sendings: dict[int, dict[tuple[object, ...], _Sent]], resolution: float = 0.0
) -> dict[int, UnitCycle]:
    """The cycles of the requests sent (the times of each), with stamps good to
    `resolution`: each wait may be off by one resolution either way, so a period or a
    jitter too short for it is an upper bound (`resolved_period`), and a wait is a gap
    only when even its shortest reading is one."""
    out: dict[int, UnitCycle] = {}
    for unit, requests in sorted(sendings.items()):
        cycle = out[unit] = UnitCycle(unit)
        for sent in requests.values():
            if len(sent.times) < MIN_REPEATS:
                cycle.once += 1
                continue
            times = sent.times
            picked = _picked_waits(times)
            waits: list[float] | None = None
            if picked is None:
                waits = list(map(sub, times[1:], times[:-1]))
                ordered = sorted(waits)  # once for the three quantiles (as nearest_rank)
                low, period, high = (_rank(ordered, q) for q in (0.05, 0.5, 0.95))
            else:
                low, period, high, longest = picked
            period, period_bound, jitter, jitter_bound = resolved_cycle(
                period, high - low, resolution
            )
            limit = GAP_FACTOR * period + resolution
            gaps: tuple[Gap, ...] = ()
            if waits is None and longest > limit:
                waits = list(map(sub, times[1:], times[:-1]))
            if waits is not None:
                gaps = tuple(
                    Gap(times[k], waits[k])
                    for k in compress(range(len(waits)), map(lt, repeat(limit), waits))
                )
            cycle.polls.append(
                Poll(
                    unit,
                    sent.fc,
                    sent.what,
                    len(times),
                    period,
                    jitter,
                    gaps,
                    times[0],
                    times[-1],
                    sent.retries,
                    period_bound,
                    jitter_bound,
                    resolution,
                )
            )
        cycle.polls.sort(key=lambda p: (p.period, p.what))
    return out


def resolved_cycle(
    period: float, jitter: float, resolution: float
) -> tuple[float, bool, float, bool]:
    """A poll's period and jitter (the median wait and the p95 - p5 spread of the waits)
    as stamps good to `resolution` vouch for them: (period, whether it is only an upper
    bound, jitter, likewise). The period is `resolved_period`'s (infinite where the
    stamps bound nothing); each end of a wait may be off by a resolution, so a spread
    shorter than RESOLVED times both is at most the spread plus both."""
    if resolution <= 0:
        return period, False, jitter, False
    told = resolved_period(period, resolution)
    if told is None:  # repeated, but how often the stamps cannot say
        return float("inf"), True, float("inf"), True
    if jitter < RESOLVED * 2 * resolution:
        return told.seconds, told.bound, jitter + 2 * resolution, True
    return told.seconds, told.bound, jitter, False


def _picked_waits(times: array[float]) -> tuple[float, float, float, float] | None:
    """The 5th, 50th and 95th percentile (nearest rank) and the longest of the waits
    between `times` (at least three), from the compiled core: the values sorted() would
    put at those ranks, found by selection (sniffer/_core.c: ranked). None where only a
    sort says (no compiled core, a NaN or a negative zero among the waits). Selection
    rather than a sort: a busy poll's waits are many, and only four ranks are asked."""
    fast = core.FAST
    if fast is None:
        return None
    n = len(times) - 1
    ranks = tuple(min(n - 1, max(0, round(q * (n - 1)))) for q in (0.05, 0.5, 0.95, 1.0))
    found: tuple[float, float, float, float] | None = fast.ranked(times, ranks, True)
    return found


def _rank(ordered: list[float], q: float) -> float:
    """`sniffer.analysis.stats.nearest_rank` of values already sorted."""
    return ordered[min(len(ordered) - 1, max(0, round(q * (len(ordered) - 1))))]


def _ms(seconds: float, resolution: float = 0.0) -> str:
    """A wait as the table prints it, no finer than the stamps hold."""
    return _shown(seconds, False, resolution)


def _shown(seconds: float, bound: bool, resolution: float) -> str:
    """A period, jitter or gap in words: to 1 ms (0.1 s past 10 s); stamps coarser than
    a second round it (a bound up) to whole seconds (`pairing.shown_step`)."""
    if not seconds < float("inf"):
        return "?"  # stamps that bound nothing
    if resolution >= 1.0:
        step = shown_step(resolution)
        value = ceil(seconds / step - 1e-9) * step if bound else round(seconds / step) * step
        text = span_words(value * 1000)
    else:
        text = f"{seconds * 1000:.0f}ms" if seconds < 10 else f"{seconds:.1f}s"
    return "<" + text if bound else text


def cycle_table(
    cycles: Mapping[int, UnitCycle], labels: Mapping[int, str] | None = None, origin: float = 0.0
) -> str:
    """The poll cycle as text for `--stats`; gaps are placed in seconds from `origin` (the
    listing's first row, as the listing shows times), not as epoch seconds."""
    labels = labels or {}
    rows = [
        "poll cycle",
        "unit  request                       sent   period   jitter  gaps  retries",
    ]
    for unit, cycle in cycles.items():
        label = labels.get(unit, "")
        for n, p in enumerate(cycle.polls):
            head = f"{unit:>4}  " if n == 0 else "      "
            gaps = str(len(p.gaps)) if p.gaps else "-"
            retries = str(p.retries) if p.retries else "-"
            rows.append(
                f"{head}{p.what:<28} {p.count:>6} {p.period_text():>8} {p.jitter_text():>8}  "
                f"{gaps:>4}  {retries:>7}"
            )
        if not cycle.polls:
            rows.append(f"{unit:>4}  (no request repeated {MIN_REPEATS} times)")
        if label and cycle.polls:
            rows[-len(cycle.polls)] += f"  {label}"
        shown = max((p.resolution for p in cycle.polls), default=0.0)
        for g in cycle.gaps[:3]:
            at = g.start - origin
            rows.append(f"      gap at {at:.3f}s: {_ms(g.length, shown)} without polls")
        if len(cycle.gaps) > 3:
            rows.append(f"      ... {len(cycle.gaps) - 3} more gaps")
    return "\n".join(rows)
