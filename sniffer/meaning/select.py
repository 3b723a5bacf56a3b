"""Provides the filter matcher: the rows of a store that a query (and the list's options) select.

A filter scans the store's columns, not dissected frames: each column term becomes a
mask of 0/1 bytes made with `bytes.translate` over the column's bytes, masks are
combined as big integers, and `itertools.compress` turns the result into row numbers,
all at C speed. Only register-name and free-text terms dissect rows, and only the
candidates the column terms leave, a slice at a time so that matches arrive
incrementally. The TUI's frame list (`sniffer.tui.rows`) and the command line's
`--filter` both use it, so a query means the same in both; nothing here imports Textual.
"""

from __future__ import annotations

import sys
import time as _time
from array import array
from bisect import bisect_left
from collections.abc import Callable, Iterable, Sequence
from datetime import datetime
from itertools import compress

from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.meaning.annotate import Annotator
from sniffer.meaning.describe import Describer, FrameDetail
from sniffer.meaning.query import Query, TimePoint
from sniffer.vocab import BAD_CHECK, PROBLEM_MASK, STATUS_NAMES, Kind, Status

BLOCK = 1 << 18  # rows per column scan step
_LITTLE = sys.byteorder == "little"
_NOT = bytes([1, 0]) + bytes(254)  # 0 -> 1, 1 -> 0
_PAIRED = b"\x01" * 255 + b"\x00"  # a partner's top byte: 0xFF only for -1
_STATUS_CODES = {name: code for code, name in enumerate(STATUS_NAMES) if name}
_PROBLEM_STATUS = (Status.EXCEPTION, Status.TIMEOUT, Status.ORPHAN)
_OPEN_LOOKBACK = 64


# -- masks ---------------------------------------------------------------------------------


def _table(selected: Iterable[int]) -> bytes:
    """A `bytes.translate` table giving 1 for the selected byte values, 0 otherwise."""
    t = bytearray(256)
    for v in selected:
        t[v] = 1
    return bytes(t)


def _bits_table(mask: int) -> bytes:
    return bytes(1 if v & mask else 0 for v in range(256))


def _and(a: bytes, b: bytes) -> bytes:
    n = len(a)
    return (int.from_bytes(a, "little") & int.from_bytes(b, "little")).to_bytes(n, "little")


def _or(a: bytes, b: bytes) -> bytes:
    n = len(a)
    return (int.from_bytes(a, "little") | int.from_bytes(b, "little")).to_bytes(n, "little")


def _bytes_mask(col: array[int], lo: int, hi: int, selected: Iterable[int]) -> bytes:
    return col[lo:hi].tobytes().translate(_table(selected))


def flag_mask(store: FrameStore, lo: int, hi: int, bits: int) -> bytes:
    """1 where `flags & bits` is not zero."""
    raw = store.flags[lo:hi].tobytes()
    size = store.flags.itemsize
    out: bytes | None = None
    for k in range(size):
        part = (bits >> (8 * k)) & 0xFF
        if not part:
            continue
        column = raw[k::size] if _LITTLE else raw[size - 1 - k :: size]
        m = column.translate(_bits_table(part))
        out = m if out is None else _or(out, m)
    return out if out is not None else bytes(hi - lo)


def paired_mask(store: FrameStore, lo: int, hi: int) -> bytes:
    """1 where the row has a partner: `partner != -1`, read from the top byte of each
    signed entry (0xFF only for -1, since row numbers stay far below the type's limit)."""
    raw = store.partner[lo:hi].tobytes()
    size = store.partner.itemsize
    top = raw[size - 1 :: size] if _LITTLE else raw[0::size]
    return top.translate(_PAIRED)


def problem_mask(store: FrameStore, lo: int, hi: int) -> bytes:
    """1 for rows with something wrong: noise, events, exceptions, timeouts, orphans, and
    every framing, check, pairing and device-timing flag."""
    m = _bytes_mask(store.kind, lo, hi, (Kind.NOISE, Kind.EVENT))
    m = _or(m, _bytes_mask(store.status, lo, hi, _PROBLEM_STATUS))
    return _or(m, flag_mask(store, lo, hi, int(PROBLEM_MASK)))


def answer_mask(store: FrameStore, lo: int, hi: int) -> bytes:
    """1 for answers paired with their request (hidden when showing transactions)."""
    answers = _bytes_mask(store.kind, lo, hi, (Kind.RESPONSE, Kind.EXCEPTION))
    return _and(answers, paired_mask(store, lo, hi))


def status_mask(store: FrameStore, lo: int, hi: int, names: Iterable[str]) -> bytes:
    out = bytes(hi - lo)
    codes = [_STATUS_CODES[n] for n in names if n in _STATUS_CODES]
    if codes:
        out = _or(out, _bytes_mask(store.status, lo, hi, codes))
    names = set(names)
    if "check" in names:
        out = _or(out, flag_mask(store, lo, hi, BAD_CHECK))
    if "noise" in names:
        out = _or(out, _bytes_mask(store.kind, lo, hi, (Kind.NOISE,)))
    if "event" in names:
        out = _or(out, _bytes_mask(store.kind, lo, hi, (Kind.EVENT,)))
    if "problem" in names:
        out = _or(out, problem_mask(store, lo, hi))
    return out


def function_codes(functions: Iterable[int]) -> list[int]:
    """The function byte values that mean these functions (the exception bit set or not)."""
    out = []
    for f in functions:
        out += [f, f | 0x80]
    return out


class Options:
    """What the list shows besides a query: transactions, only problems, bound units."""

    def __init__(
        self, *, transactions: bool = False, problems_only: bool = False, bound: Iterable[int] = ()
    ) -> None:
        self.transactions = transactions
        self.problems_only = problems_only
        self.bound = frozenset(bound)


def column_mask(store: FrameStore, lo: int, hi: int, query: Query, options: Options) -> bytes:
    """1 for rows of [lo, hi) that pass every column term of `query` and the options."""
    n = hi - lo
    mask: bytes | None = None

    def keep(m: bytes) -> None:
        nonlocal mask
        mask = m if mask is None else _and(mask, m)

    def drop(m: bytes) -> None:
        keep(m.translate(_NOT))

    frames = (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION, Kind.UNKNOWN)
    if query.units or query.functions:
        keep(_bytes_mask(store.kind, lo, hi, frames))
    if query.units:
        keep(_bytes_mask(store.unit, lo, hi, query.units))
    if query.not_units:
        units = _bytes_mask(store.unit, lo, hi, query.not_units)
        drop(_and(units, _bytes_mask(store.kind, lo, hi, frames)))
    if query.functions:
        keep(_bytes_mask(store.fc, lo, hi, function_codes(query.functions)))
    if query.not_functions:
        fcs = _bytes_mask(store.fc, lo, hi, function_codes(query.not_functions))
        drop(_and(fcs, _bytes_mask(store.kind, lo, hi, frames)))
    if query.kinds:
        keep(_bytes_mask(store.kind, lo, hi, query.kinds))
    if query.not_kinds:
        drop(_bytes_mask(store.kind, lo, hi, query.not_kinds))
    if query.statuses:
        keep(status_mask(store, lo, hi, query.statuses))
    if query.not_statuses:
        drop(status_mask(store, lo, hi, query.not_statuses))
    if query.registers:
        # only bound units carry named registers, in requests (writes) and answers (reads)
        keep(_bytes_mask(store.unit, lo, hi, options.bound))
        keep(_bytes_mask(store.kind, lo, hi, (Kind.REQUEST, Kind.RESPONSE)))
    if options.problems_only:
        problems = problem_mask(store, lo, hi)
        if options.transactions:
            problems = _lift_answers(store, lo, problems)
        keep(problems)
    if options.transactions:
        drop(answer_mask(store, lo, hi))
    return mask if mask is not None else b"\x01" * n


def _lift_answers(store: FrameStore, lo: int, problems: bytes) -> bytes:
    """Mark a request as a problem when its paired answer is one (for transaction rows)."""
    out = bytearray(problems)
    n = len(out)
    kind, partner = store.kind, store.partner
    start = 0
    while True:
        k = problems.find(1, start)
        if k < 0:
            break
        start = k + 1
        i = lo + k
        if kind[i] in (Kind.RESPONSE, Kind.EXCEPTION):
            j = partner[i]
            if j != NO_PARTNER and lo <= j < lo + n:
                out[j - lo] = 1
    return bytes(out)


def resolve_time(point: TimePoint, origin: float) -> float:
    """A query's time point as a store time (seconds, same clock as the store)."""
    if not point.clock:
        return origin + point.seconds
    day = datetime.fromtimestamp(origin).astimezone()
    midnight = day.replace(hour=0, minute=0, second=0, microsecond=0)
    return midnight.timestamp() + point.seconds


def time_bounds(store: FrameStore, query: Query, origin: float, count: int) -> tuple[int, int]:
    """The rows [lo, hi) a query's time span allows (all `count` rows without one)."""
    if query.time is None or count == 0:
        return 0, count
    lo, hi = 0, count
    if query.time.start is not None:
        lo = bisect_left(store.t, resolve_time(query.time.start, origin), 0, count)
    if query.time.end is not None:
        hi = bisect_left(store.t, resolve_time(query.time.end, origin), 0, count)
    return lo, max(lo, hi)


# -- details ---------------------------------------------------------------------------------


def row_words(d: FrameDetail) -> str:
    """What free text is matched against: name, summary, device, problems, register texts."""
    parts = [
        d.name,
        d.summary,
        d.label,
        d.direction,
        *d.problem_texts,
        *(r.text for r in d.registers),
    ]
    return "\n".join(parts).lower()


def detail_matches(query: Query, details: Sequence[FrameDetail]) -> bool:
    if query.registers:
        names = [r.name.lower() for d in details for r in d.registers]
        if not any(part in name for part in query.registers for name in names):
            return False
    if query.words:
        text = "\n".join(row_words(d) for d in details)
        if not all(w in text for w in query.words):
            return False
    return True


# -- the job ---------------------------------------------------------------------------------


class FilterJob:
    """The rows matching a query (and the options), found incrementally.

    `advance(upto)` scans rows up to `upto` (the count the ingest thread published) for a
    while and returns whether work is left. Matches are appended to `rows` in row order;
    the UI may read `rows` at any time. Rows near the end whose request is still open are
    scanned again later, since their status can still change.
    """

    def __init__(
        self,
        store: FrameStore,
        query: Query,
        options: Options,
        annotator: Annotator,
        origin: float,
    ) -> None:
        self.store = store
        self.query = query
        self.options = options
        self.origin = origin
        self.annotator = annotator
        self.describer = Describer(store, annotator, size=512)
        # 4 bytes a match (rows below 2**32: a store that size would not fit in memory):
        # the transactions view of a 30M-row day holds 15M matches: 60 MB, half of "Q"
        self.rows: array[int] = array("I")
        self.scanned = 0  # rows whose columns were tested
        self.candidates: array[int] = array("I")  # rows waiting for a detail test
        self.checked = 0  # candidates tested
        self.upto = 0
        self.start = -1  # the first row the time span allows, once known

    @property
    def progress(self) -> float:
        """0..1: how far the scan got (1 when caught up)."""
        start = max(0, self.start)
        done = (self.scanned - start) / max(1, self.upto - start)
        if self.query.needs_detail and self.candidates:
            done = min(done, self.checked / len(self.candidates))
        return max(0.0, min(1.0, done))

    @property
    def caught_up(self) -> bool:
        return self.scanned >= self.upto and self.checked >= len(self.candidates)

    def advance(
        self,
        upto: int,
        should_stop: Callable[[], bool] | None = None,
        budget: float = 0.05,
        *,
        final: bool = False,
    ) -> bool:
        """Work for about `budget` seconds on rows below `upto`; True if work is left.
        `final`: no row will change any more (the capture is indexed), so open requests
        at the end are taken as they are."""
        self.upto = upto
        store = self.store
        span = self.query.time
        if span is not None and span.start is not None:
            first = resolve_time(span.start, self.origin)
            self.scanned = bisect_left(store.t, first, self.scanned, upto)
        if self.start < 0 and upto:
            self.start = self.scanned
        limit = upto
        if span is not None and span.end is not None:
            end = resolve_time(span.end, self.origin)
            limit = bisect_left(store.t, end, self.scanned, upto)
        deadline = _time.monotonic() + budget
        options = self._options()
        while self.scanned < limit:
            if should_stop is not None and should_stop():
                return True
            hi = min(limit, self.scanned + BLOCK)
            if hi == upto and not final:
                hi = self._stable(self.scanned, hi)
                if hi <= self.scanned:
                    break
            mask = column_mask(store, self.scanned, hi, self.query, options)
            found = compress(range(self.scanned, hi), mask)
            if self.query.needs_detail:
                self.candidates.extend(found)
            else:
                self.rows.extend(found)
            self.scanned = hi
            if _time.monotonic() > deadline:
                return True
        if self.query.needs_detail:
            cands = self.candidates
            while self.checked < len(cands):
                if should_stop is not None and should_stop():
                    return True
                stop = min(len(cands), self.checked + 64)
                for k in range(self.checked, stop):
                    i = cands[k]
                    if detail_matches(self.query, self._details(i)):
                        self.rows.append(i)
                self.checked = stop
                if _time.monotonic() > deadline:
                    return True
        return False

    def _options(self) -> Options:
        """The options, with the units recognised as SunSpec devices so far counted as
        bound: they carry named registers with no dictionary."""
        found = self.annotator.sunspec.units.keys() - self.options.bound
        if not found:
            return self.options
        o = self.options
        return Options(
            transactions=o.transactions, problems_only=o.problems_only, bound=o.bound | found
        )

    def _details(self, i: int) -> list[FrameDetail]:
        d = self.describer.detail(i)
        out = [d]
        if self.options.transactions and d.view.kind == Kind.REQUEST:
            j = d.view.partner
            if j != NO_PARTNER and j < self.upto:
                out.append(self.describer.detail(j))
        return out

    def _stable(self, lo: int, hi: int) -> int:
        """`hi`, or the first of the last rows whose request is still open."""
        status = self.store.status
        first = hi
        for i in range(hi - 1, max(lo, hi - _OPEN_LOOKBACK) - 1, -1):
            if status[i] == Status.OPEN:
                first = i
        return first
