"""Provides the poll cycle: per unit, which requests the master repeats, how often, how
steadily, and where the cycle stalled.

A request repeats when the same poll (`sniffer.analysis.polls`: unit, function, address,
quantity; written values left out) is sent again. Its period is the median time between
two sendings, its jitter the spread of those times (95th minus 5th percentile), and a
gap is a wait of more than twice the period: the master stopped polling, or the unit was
skipped.

What is kept of each request does not grow with the capture (issue 29: a day's `--stats`
in bounded memory). Its waits are counted, each distinct wait once (`_Sent.waits`), so
that a steady poll keeps a few hundred numbers however long it runs, and the quantiles
and the gaps are those of every wait. Only where a request's waits take more than
BUCKETS distinct values (or all requests together more than BUDGET) are they counted in
buckets of a power-of-two width (`_Sent.quantum`): with stamps of epoch seconds the
waits are whole multiples of 2**-22 s (the spacing of doubles between 2004 and 2038), so
buckets up to that width still hold each wait exactly, and the table is the same. Wider
buckets make the period good to half a bucket and the jitter to a bucket, which the
table marks (`≈`) only where that error reaches half the printed step. The gaps need the
period before they are known: each request keeps, in order, the waits that fewer than
RECORDS_TOP earlier waits were as long as (`_Sent.records`, at most RECORDS of them), so
that whatever the period, its first gaps are among them; how many gaps there are comes
from the counted waits. At most MAX_REQUESTS requests are followed; the sendings of
others are counted per unit, and the table says so.
"""

from __future__ import annotations

from array import array
from bisect import bisect_left, bisect_right
from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from heapq import heappush, heapreplace
from itertools import accumulate, compress, repeat
from math import ceil, floor
from operator import add, and_, gt, lt, mul, ne, rshift, sub
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

# sendings of a request whose times are kept (8 bytes each): up to this many its period,
# jitter and gaps are those of its exact waits, as they ever were
EXACT = 1 << 15
# beyond, its waits are counted in BUCKETS buckets (4 bytes each) and up to FAR more
# counted apart (about 100 bytes each; past that many the buckets are made twice as wide)
BUCKETS = 1 << 16
FAR = 1 << 10
# distinct waits counted apart (each in a bucket of _FINEST: exact) before the buckets
SPARSE = 1 << 11
# times all requests together keep: past this, those that keep most are bucketed (into
# as many buckets as they had sendings, at least MIN_BUCKETS)
TIMES_BUDGET = 1 << 22
MIN_BUCKETS = 1 << 10
# requests followed (each identity of each unit); the sendings of any other are counted
# per unit, not followed (a bus of random addresses would otherwise grow the table all day)
MAX_REQUESTS = 1 << 15
# a wait is kept with its time when fewer than RECORDS_TOP earlier waits of its request
# were as long: then every gap of a request with at most RECORDS_TOP gaps is kept, and
# the first three of any; at most RECORDS such waits a request (steady waits make about
# RECORDS_TOP * ln(sendings / RECORDS_TOP) of them: some 160 in a day of a 250 ms poll)
RECORDS_TOP = 16
RECORDS = 256
# the narrowest bucket: stamps of epoch seconds (2004-2038) are whole multiples of 2**-22
_FINEST = 2.0**-30


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
    # bounded (see the module's doc): gaps counted beyond those in `gaps`; waits that may
    # or may not be gaps (bucketed too coarsely to say); the width of the buckets its
    # waits were counted in, 0.0 where each wait was counted exactly (then the period is
    # good to half of it and the jitter to all of it); whether its first gaps may lie
    # beyond the waits it kept
    more_gaps: int = 0
    unsure_gaps: int = 0
    quantum: float = 0.0
    gaps_cut: bool = False

    @property
    def gap_count(self) -> int:
        """Its gaps (those that surely are, where `unsure_gaps`)."""
        return len(self.gaps) + self.more_gaps

    def period_text(self) -> str:
        """`250ms`, `<2s`: the period no finer than the stamps hold (`≈250ms` where the
        buckets' error reaches half the printed step)."""
        return _shown(self.period, self.period_bound, self.resolution, self.quantum / 2)

    def jitter_text(self) -> str:
        return _shown(self.jitter, self.jitter_bound, self.resolution, self.quantum)

    def gaps_text(self) -> str:
        """The gap count as the table prints it: `-` for none, `≥3` where waits too
        close to the limit may be gaps too."""
        n = self.gap_count
        if self.unsure_gaps:
            return f"≥{n}"
        return str(n) if n else "-"


@dataclass
class UnitCycle:
    """The repeating requests of one unit and the unit's whole cycle."""

    unit: int
    polls: list[Poll] = field(default_factory=list)
    once: int = 0  # requests sent fewer than MIN_REPEATS times
    unfollowed: int = 0  # sendings of requests past MAX_REQUESTS, counted only

    @property
    def period(self) -> float | None:
        """The longest period of its repeating requests: the time for a whole cycle."""
        return max((p.period for p in self.polls), default=None)

    @property
    def gaps(self) -> list[Gap]:
        """The gaps its polls list (every gap of a poll with few; the first of any)."""
        return sorted({g for p in self.polls for g in p.gaps}, key=lambda g: g.start)

    @property
    def gap_count(self) -> int:
        """Its gaps: those listed (one gap of two polls counted once) and those counted."""
        return len(self.gaps) + sum(p.more_gaps for p in self.polls)


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


@dataclass(slots=True, eq=False)
class _Sent:
    """The sendings of one request (one identity of one unit): how many, the first and
    the last, its retries, and their times (`times`) while they are few; past EXACT of
    them (or when all requests together keep more than TIMES_BUDGET times) its waits
    counted instead (`waits`). A sink (`sink`) only counts: the sendings of requests
    past MAX_REQUESTS."""

    what: str
    fc: int
    retries: int = 0
    times: array[float] | None = field(default_factory=lambda: array("d"))
    count: int = 0
    first: float = 0.0
    last: float = 0.0
    waits: _Waits | None = None
    sink: bool = False

    def feed(self, times: array[float]) -> None:
        """Count sendings at `times` (in order, after those fed before)."""
        n = len(times)
        if not n:
            return
        if self.sink:
            self.count += n
            return
        if not self.count:
            self.first = times[0]
        self.count += n
        kept = self.times
        if kept is not None:
            kept.extend(times)
            self.last = times[-1]
            if len(kept) > EXACT:
                self.bucket(BUCKETS)
            return
        seq = array("d", (self.last,))
        seq.extend(times)
        self.last = times[-1]
        assert self.waits is not None
        self.waits.count(seq)

    def bucket(self, span: int, dense: bool = False) -> None:
        """Count its waits (`_Waits`) from now on, those so far included, into `span`
        buckets where they are many (at once with `dense`); its times are let go."""
        times = self.times
        assert times is not None
        self.times = None
        waits = self.waits = _Waits(span=span)
        if len(times) > 1:
            waits.count(times)
        if dense:
            waits.densify()

    def copy(self) -> _Sent:
        return _Sent(
            self.what,
            self.fc,
            self.retries,
            None if self.times is None else array("d", self.times),
            self.count,
            self.first,
            self.last,
            None if self.waits is None else self.waits.copy(),
            self.sink,
        )


@dataclass(slots=True, eq=False)
class _Waits:
    """The waits between a request's sendings, counted in buckets a power of two of
    seconds wide (`quantum`): the waits from k * quantum up to (k + 1) * quantum in
    dense[k] (0 <= k < len(dense)) or far[k] (any other k: long gaps, waits of a clock
    set back). First every wait goes to `far` in buckets of _FINEST (which hold each
    wait of epoch stamps exactly); past SPARSE distinct ones they are counted in `span`
    buckets from zero (`densify`), as wide as puts twice the 99th percentile of the
    waits so far within them, and twice as wide again whenever more than FAR lie
    beyond (`coarsen`). Also the waits its first gaps are among (`starts`, `lengths`)."""

    span: int  # the buckets it takes where the distinct waits are too many
    quantum: float = _FINEST
    dense: array[int] = field(default_factory=lambda: array("I"))
    far: Counter[int] = field(default_factory=Counter)
    exact: bool = True  # every wait counted is a whole number of quanta (then exact)
    unknown: int = 0  # waits that are NaN (stamps that hold no time)
    # the RECORDS_TOP longest waits so far (a heap, shortest first), and the waits kept:
    # when each began, and how long it was, in order
    top: list[float] = field(default_factory=list)
    starts: array[float] = field(default_factory=lambda: array("d"))
    lengths: array[float] = field(default_factory=lambda: array("d"))
    cut: bool = False  # RECORDS were kept and a later wait would have been too

    def densify(self) -> None:
        """Count the waits kept apart (`far`) in `span` buckets from zero instead.

        Its steps over the keys run in C where they can (the 99th percentile's key by
        bisecting the running counts, the test of exactness by `any`): a request whose
        waits are first counted when it has been sent EXACT times, with stamps exact
        enough to tell each wait apart, brings some 32k keys here, and a Python step a
        key in each was 3.7 of the 8.1 s of `replay --stats` of 5M frames one per packet
        under cProfile (58 requests, 2026-12-07). All of them run in C where the keys
        and counts fit in 61 bits (`sniffer._core.waits_densify`; this is its
        reference): keys of about a second's wait (2 ** 30 quanta) are compared as long
        ints by `sorted`, and a Python step a key after that took 0.5 of the 2.9 s of
        5M frames of mix738335539 under cProfile (61 requests, 2026-12-07)."""
        fast = core.FAST
        if fast is not None:
            dense = array("I", bytes(4 * self.span))
            wider: Counter[int] = Counter()
            got = fast.waits_densify(self.far, self.span, dense, wider, self.exact)
            if got is not None:
                shift, self.exact = got
                self.quantum *= 1 << shift
                self.dense, self.far = dense, wider
                if len(wider) > FAR:
                    self.coarsen()
                return
        far = self.far
        keys = sorted(far)
        counts = list(map(far.__getitem__, keys))
        running = list(accumulate(counts))
        rank = (running[-1] if running else 0) * 99 // 100
        at = bisect_right(running, rank)  # the first key the count passes the rank at
        high = max(1, 2 * keys[at]) if at < len(keys) else 1
        shift = 0
        while (self.span << shift) < high:
            shift += 1
        self.quantum *= 1 << shift
        span = self.span
        dense = array("I", bytes(4 * span))
        kept: Counter[int] = Counter()
        low = (1 << shift) - 1
        if low and any(map(and_, keys, repeat(low))):
            self.exact = False
        # the keys are sorted: those of the dense buckets are one run of them
        lo, hi = bisect_left(keys, 0), bisect_left(keys, span << shift)
        for k, c in zip(map(rshift, keys[lo:hi], repeat(shift)), counts[lo:hi], strict=True):
            dense[k] += c
        for k, c in zip(keys[:lo] + keys[hi:], counts[:lo] + counts[hi:], strict=True):
            kept[k >> shift] += c
        self.dense, self.far = dense, kept
        if len(kept) > FAR:
            self.coarsen()

    def count(self, seq: array[float]) -> None:
        """Count the waits between consecutive `seq` (at least two) in the buckets."""
        fast, quantum = core.FAST, self.quantum
        got = None
        if fast is not None:  # (the compiled core: 9 of a day's 23 s in Python, 2026-12-07)
            got = fast.waits_count(seq, 1 / quantum, quantum, self.dense, self.far, self.exact)
        if got is not None:
            high, self.exact = got
        else:
            high = self._count(seq)
            if high is None:
                return
        if not self.dense and len(self.far) > SPARSE:
            self.densify()
        elif len(self.far) > FAR:
            self.coarsen()
        top = self.top
        if self.cut:
            return
        if len(top) < RECORDS_TOP or (high + 1) * quantum > top[0]:
            self._records(seq, list(map(sub, seq[1:], seq[:-1])))

    def _count(self, seq: array[float]) -> int | None:
        """`count`'s counting in Python (the reference of the compiled `waits_count`): the
        greatest bucket met, None when no wait is a time."""
        later, earlier = seq[1:], seq[:-1]
        quantum = self.quantum
        known: list[float] | None = None
        try:  # each wait's bucket, b - a as the gaps were ever taken, all in C
            keys = list(map(floor, map(mul, map(sub, later, earlier), repeat(1 / quantum))))
        except (ValueError, OverflowError):  # NaN (or infinite) stamps among them
            known = self._known(later, earlier)
            keys = list(map(floor, map(mul, known, repeat(1 / quantum))))
        if self.exact and any(
            map(
                ne,
                map(mul, keys, repeat(quantum)),
                map(sub, later, earlier) if known is None else known,
            )
        ):
            self.exact = False
        dense, far, span = self.dense, self.far, len(self.dense)
        if not span:
            far.update(keys)  # (counted in C)
        else:
            # counted in C first: stamps of a host's reads give waits of a few values
            for k, c in Counter(keys).items():
                if 0 <= k < span:
                    dense[k] += c
                else:
                    far[k] += c
        return max(keys) if keys else None

    def _known(self, later: array[float], earlier: array[float]) -> list[float]:
        """The waits that are a time; those that are not (NaN, infinite) counted apart."""
        known = [w for w in map(sub, later, earlier) if abs(w) < float("inf")]
        self.unknown += len(later) - len(known)
        return known

    def _records(self, seq: array[float], waits: list[float]) -> None:
        """Keep the waits fewer than RECORDS_TOP earlier ones were as long as."""
        top, starts, lengths = self.top, self.starts, self.lengths
        at: Iterable[int] = range(len(waits))
        if len(top) >= RECORDS_TOP:
            # only a wait longer than the shortest of the top can be kept, and the
            # shortest only grows: the others are passed over in C (NaN among them)
            at = compress(at, map(gt, waits, repeat(top[0])))
        for k in at:
            w = waits[k]
            if w != w:
                continue
            if len(top) < RECORDS_TOP:
                heappush(top, w)
            elif w > top[0]:
                heapreplace(top, w)
            else:
                continue
            if len(lengths) == RECORDS:
                self.cut = True
                return
            starts.append(seq[k])
            lengths.append(w)

    def coarsen(self) -> None:
        """Buckets twice as wide, until at most FAR // 2 lie beyond the dense ones."""
        while len(self.far) > FAR // 2:
            dense, span = self.dense, len(self.dense)
            if self.exact and (any(dense[1::2]) or any(k & 1 and c for k, c in self.far.items())):
                self.exact = False
            halved = array("I", map(add, dense[0::2], dense[1::2]))
            halved.extend(bytes(4 * (span - len(halved))))
            far: Counter[int] = Counter()
            for k, c in self.far.items():
                k >>= 1
                if 0 <= k < span:
                    halved[k] += c
                else:
                    far[k] += c
            self.dense, self.far = halved, far
            self.quantum *= 2

    def copy(self) -> _Waits:
        return _Waits(
            self.span,
            self.quantum,
            array("I", self.dense),
            Counter(self.far),
            self.exact,
            self.unknown,
            list(self.top),
            array("d", self.starts),
            array("d", self.lengths),
            self.cut,
        )


class PollCycles:
    """The poll cycle counted over rows given in parts (`add`): a whole store, or the
    segments of a windowed session one after the other (`sniffer.session.session.Session.window`),
    whose rows are then gone. What it keeps does not grow with the rows (see the
    module's doc: the distinct waits of each request, bucketed past BUCKETS, at most
    MAX_REQUESTS requests); `cycles()` gives what `poll_cycles` of one store holding
    every row gives, the same table while no request's waits had to be bucketed more
    coarsely than its stamps."""

    def __init__(self) -> None:
        # unit -> identity -> sendings, each in order of its first sending
        self.sendings: dict[int, dict[tuple[object, ...], _Sent]] = {}
        # unit -> the sendings of requests not followed (past MAX_REQUESTS)
        self.unfollowed: dict[int, _Sent] = {}
        self.followed = 0  # requests in `sendings`
        self.timed = 0  # the times they keep (`_Sent.times`), all together
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
        else:
            self._slow_add(store, start, n)
        if self.timed > TIMES_BUDGET:
            self._rebudget()

    def _slow_add(self, store: FrameStore, start: int, n: int) -> None:
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
            block: dict[_Sent, array[float]] = {}
            for key, i, when in zip(
                keys, compress(range(lo, hi), mask), compress(t[lo:hi], mask), strict=True
            ):
                sent = found.get(key)
                if sent is None:
                    sent = found[key] = self._sent(store, key, i)
                times = block.get(sent)
                if times is None:
                    times = block[sent] = array("d")
                times.append(when)
            for sent, times in block.items():
                self._feed(sent, times)
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
        counted in the order of their rows, its retries counted."""
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
                found = array("d")
                found.frombytes(times)
                self._feed(sent, found)
                sent.retries += retries

    def _feed(self, sent: _Sent, times: array[float]) -> None:
        kept = sent.times
        if kept is None:
            sent.feed(times)
            return
        before = len(kept)
        sent.feed(times)
        self.timed += (0 if sent.times is None else len(kept)) - before

    def _sent(self, store: FrameStore, key: object, i: int) -> _Sent:
        """Where the sendings of row `i`'s request (`key`: its bytes, with its framing
        where it has any) are counted."""
        if isinstance(key, bytes):
            framing, raw = 0, key
        else:
            framing, raw = cast(tuple[int, bytes], key)
        # writes with other values: the same identity
        identity, what = poll_identity(frame_body(raw, framing))
        unit = store.unit[i]
        requests = self.sendings.setdefault(unit, {})
        sent = requests.get(identity)
        if sent is None:
            if self.followed >= MAX_REQUESTS:  # counted, not followed
                sent = self.unfollowed.get(unit)
                if sent is None:
                    sent = self.unfollowed[unit] = _Sent("", 0, sink=True)
                return sent
            sent = requests[identity] = _Sent(what, store.fc[i])
            self.followed += 1
        return sent

    def _rebudget(self) -> None:
        """Bucket the waits of the requests that keep most times, until all keep at most
        three quarters of TIMES_BUDGET: each into as many buckets as it has times (a
        power of two, MIN_BUCKETS to BUCKETS), which take no more than its times did."""
        timed = sorted(
            (s for r in self.sendings.values() for s in r.values() if s.times is not None),
            key=lambda s: len(s.times or ()),
            reverse=True,
        )
        for sent in timed:
            if self.timed <= TIMES_BUDGET * 3 // 4:
                return
            n = len(sent.times or ())
            span = MIN_BUCKETS
            while span < min(n, BUCKETS):
                span *= 2
            sent.bucket(span, dense=True)
            self.timed -= n

    def cycles(self, more: FrameStore | None = None) -> dict[int, UnitCycle]:
        """Every unit's poll cycle, from the requests added so far and those of `more`
        (not added: a live window's rows, counted again when the next summary comes)."""
        if more is None:
            return _cycles(self.sendings, self.resolution, self.unfollowed)
        both = PollCycles()
        both.sendings = {
            unit: {key: s.copy() for key, s in r.items()} for unit, r in self.sendings.items()
        }
        both.unfollowed = {unit: s.copy() for unit, s in self.unfollowed.items()}
        both.followed, both.timed = self.followed, self.timed
        both.add(more)
        return _cycles(both.sendings, both.resolution, both.unfollowed)


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
    sendings: dict[int, dict[tuple[object, ...], _Sent]],
    resolution: float = 0.0,
    unfollowed: Mapping[int, _Sent] | None = None,
) -> dict[int, UnitCycle]:
    """The cycles of the requests sent (the waits of each), with stamps good to
    `resolution`: each wait may be off by one resolution either way, so a period or a
    jitter too short for it is an upper bound (`resolved_period`), and a wait is a gap
    only when even its shortest reading is one."""
    unfollowed = unfollowed or {}
    out: dict[int, UnitCycle] = {}
    for unit in sorted(sendings.keys() | unfollowed.keys()):
        cycle = out[unit] = UnitCycle(unit)
        sink = unfollowed.get(unit)
        cycle.unfollowed = sink.count if sink is not None else 0
        for sent in sendings.get(unit, {}).values():
            if sent.count < MIN_REPEATS:
                cycle.once += 1
                continue
            cycle.polls.append(_poll(unit, sent, resolution))
        cycle.polls.sort(key=lambda p: (p.period, p.what))
    return out


def _poll(unit: int, sent: _Sent, resolution: float) -> Poll:
    """One repeating request's line of the table: from its times while it keeps them,
    else from its waits counted in buckets."""
    times, waits = sent.times, sent.waits
    if times is not None or waits is None:
        return _timed_poll(unit, sent, times or array("d"), resolution)
    exact = waits.exact
    quantum = waits.quantum
    error = 0.0 if exact else quantum
    counted = _Counted(waits)
    if waits.unknown or not counted.n:  # stamps that hold no time: nothing to say
        low = period = high = float("nan")
    else:
        low, period, high = (counted.ranked(q) for q in (0.05, 0.5, 0.95))
    period, period_bound, jitter, jitter_bound = resolved_cycle(period, high - low, resolution)
    limit = GAP_FACTOR * period + resolution
    # a wait is a gap past the limit; bucketed, the limit is off by as much as twice the
    # period's error (half a bucket), and a wait by its bucket
    sure = counted.above(limit + error)
    maybe = sure if exact else counted.above(limit - 2 * quantum)
    # the waits kept with their times: surely gaps past the limit and its error
    kept = zip(waits.starts, waits.lengths, strict=True)
    gaps = tuple(Gap(at, length) for at, length in kept if length > limit + error)
    found = max(sure, len(gaps))  # at least these many; at most `maybe`
    return Poll(
        unit,
        sent.fc,
        sent.what,
        sent.count,
        period,
        jitter,
        gaps,
        sent.first,
        sent.last,
        sent.retries,
        period_bound,
        jitter_bound,
        resolution,
        more_gaps=found - len(gaps),
        unsure_gaps=maybe - found,
        quantum=error,
        gaps_cut=waits.cut and len(gaps) < min(3, found),
    )


class _Counted:
    """The waits of a request counted in buckets, as quantiles and counts: a bucket
    stands for its lowest wait where every wait counted is a whole number of quanta
    (then it is the wait), else for its middle (off by at most half a bucket)."""

    def __init__(self, waits: _Waits) -> None:
        self.quantum = waits.quantum
        self.exact = waits.exact
        below = sorted((k, c) for k, c in waits.far.items() if k < 0)
        above = sorted((k, c) for k, c in waits.far.items() if k >= 0)
        # the buckets in order, as (first key, how many up to and with it)
        self.keys: list[int] = [k for k, _ in below]
        self.cum: list[int] = list(accumulate(c for _, c in below))
        dense = waits.dense
        seen = self.cum[-1] if self.cum else 0
        self.dense_cum = list(accumulate(dense, initial=seen))[1:]
        seen = self.dense_cum[-1] if self.dense_cum else seen
        self.above_keys = [k for k, _ in above]
        self.above_cum = list(accumulate((c for _, c in above), initial=seen))[1:]
        self.n = self.above_cum[-1] if self.above_cum else seen

    def _key(self, rank: int) -> int:
        """The bucket of the wait at `rank` (0-based, ascending)."""
        at = bisect_right(self.cum, rank)
        if at < len(self.cum):
            return self.keys[at]
        at = bisect_right(self.dense_cum, rank)
        if at < len(self.dense_cum):
            return at
        return self.above_keys[bisect_right(self.above_cum, rank)]

    def value(self, key: int) -> float:
        if self.exact:
            return float(key * self.quantum)
        return float((key + 0.5) * self.quantum)

    def ranked(self, q: float) -> float:
        """The nearest-rank q-quantile (`sniffer.analysis.stats.nearest_rank`)."""
        n = self.n
        return self.value(self._key(min(n - 1, max(0, round(q * (n - 1))))))

    def above(self, limit: float) -> int:
        """How many waits lie in buckets wholly above `limit` (exact: the waits above it)."""
        if limit != limit:
            return 0
        first = floor(limit / self.quantum) + 1  # the first bucket whose lowest is above
        while first * self.quantum <= limit:
            first += 1
        while (first - 1) * self.quantum > limit:
            first -= 1
        return self.n - self._before(first)

    def _before(self, key: int) -> int:
        """How many waits lie in buckets below `key`."""
        at = bisect_left(self.keys, key)
        if at < len(self.keys):
            return self.cum[at - 1] if at else 0
        seen = self.cum[-1] if self.cum else 0
        if key <= 0:
            return seen
        if key <= len(self.dense_cum):
            return self.dense_cum[key - 1]
        seen = self.dense_cum[-1] if self.dense_cum else seen
        at = bisect_left(self.above_keys, key)
        return self.above_cum[at - 1] if at else seen


def _timed_poll(unit: int, sent: _Sent, times: array[float], resolution: float) -> Poll:
    """One repeating request's line from every time it was sent (as it ever was)."""
    picked = _picked_waits(times)
    if picked is None:
        ordered = sorted(map(sub, times[1:], times[:-1]))  # for the quantiles (nearest_rank)
        low, period, high = (_rank(ordered, q) for q in (0.05, 0.5, 0.95))
        longest = float("inf")  # (NaN may have left the order anyhow: every wait looked at)
    else:
        low, period, high, longest = picked
    period, period_bound, jitter, jitter_bound = resolved_cycle(period, high - low, resolution)
    limit = GAP_FACTOR * period + resolution
    gaps: tuple[Gap, ...] = ()
    if not longest <= limit:  # (a NaN among the waits: looked at one by one, as ever)
        # the waits past the limit picked out in C, a Gap made only for each of those
        later, earlier = times[1:], times[:-1]
        past = map(lt, repeat(limit), map(sub, later, earlier))
        gaps = tuple(Gap(times[k], later[k] - times[k]) for k in compress(range(len(later)), past))
    return Poll(
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


def _ms(seconds: float, resolution: float = 0.0) -> str:
    """A wait as the table prints it, no finer than the stamps hold."""
    return _shown(seconds, False, resolution)


def _shown(seconds: float, bound: bool, resolution: float, error: float = 0.0) -> str:
    """A period, jitter or gap in words: to 1 ms (0.1 s past 10 s); stamps coarser than
    a second round it (a bound up) to whole seconds (`pairing.shown_step`). `≈` before
    it where it may be off by `error` seconds (waits bucketed) and that reaches half the
    step it is printed to: a smaller error changes the figure at most to its neighbour,
    and only where the exact value lies that close to the middle between two."""
    if not seconds < float("inf"):
        return "?"  # stamps that bound nothing
    if resolution >= 1.0:
        step = shown_step(resolution)
        value = ceil(seconds / step - 1e-9) * step if bound else round(seconds / step) * step
        text = span_words(value * 1000)
    else:
        step = 0.001 if seconds < 10 else 0.1
        text = f"{seconds * 1000:.0f}ms" if seconds < 10 else f"{seconds:.1f}s"
    if error and error >= step / 2:
        text = "≈" + text
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
            gaps = p.gaps_text()
            retries = str(p.retries) if p.retries else "-"
            rows.append(
                f"{head}{p.what:<28} {p.count:>6} {p.period_text():>8} {p.jitter_text():>8}  "
                f"{gaps:>4}  {retries:>7}"
            )
        if not cycle.polls:
            rows.append(f"{unit:>4}  (no request repeated {MIN_REPEATS} times)")
        if cycle.unfollowed:
            rows.append(
                f"      {cycle.unfollowed} sendings of other requests counted, not followed "
                f"(past {MAX_REQUESTS} requests in all)"
            )
        if label and cycle.polls:
            rows[-len(cycle.polls)] += f"  {label}"
        shown = max((p.resolution for p in cycle.polls), default=0.0)
        for g in cycle.gaps[:3]:
            at = g.start - origin
            rows.append(f"      gap at {at:.3f}s: {_ms(g.length, shown)} without polls")
        total = cycle.gap_count
        if total > 3:
            rows.append(f"      ... {total - 3} more gaps")
        if any(p.gaps_cut for p in cycle.polls):
            rows.append("      (the first gaps of some polls were not kept: those above may not be")
            rows.append("      the first)")
    return "\n".join(rows)
