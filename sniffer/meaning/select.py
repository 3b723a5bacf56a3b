"""Provides the filter matcher: the rows of a store that a query (and the list's options) select.

A filter scans the store's columns, not dissected frames: each column term becomes a
mask of 0/1 bytes made with `bytes.translate` over the column's bytes, and the query's
tree (`and`, `or`, `not`) combines the masks as big integers, all at C speed;
`itertools.compress` turns the result into row numbers. Only register-name and
free-text terms dissect rows, and only the candidates the column terms leave (those the
tree may select whatever the details say), a slice at a time so that matches arrive
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
from functools import lru_cache
from itertools import compress

from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.meaning.annotate import Annotator
from sniffer.meaning.describe import Describer, FrameDetail
from sniffer.meaning.query import (
    And,
    Column,
    Node,
    Not,
    Query,
    Register,
    StatusTerm,
    Text,
    Time,
    TimePoint,
    TimeSpan,
    needs_detail,
)
from sniffer.vocab import BAD_CHECK, PROBLEM_MASK, STATUS_NAMES, Kind, Status

BLOCK = 1 << 18  # rows per column scan step
_LITTLE = sys.byteorder == "little"
_PAIRED = b"\x01" * 255 + b"\x00"  # a partner's top byte: 0xFF only for -1
_STATUS_CODES = {name: code for code, name in enumerate(STATUS_NAMES) if name}
_PROBLEM_STATUS = (Status.EXCEPTION, Status.TIMEOUT, Status.ORPHAN)
_OPEN_LOOKBACK = 64
_FRAMES = (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION, Kind.UNKNOWN)  # rows with a unit, fc
_NAMED = (Kind.REQUEST, Kind.RESPONSE)  # rows that carry register values


# -- masks ---------------------------------------------------------------------------------


def _table(selected: Iterable[int]) -> bytes:
    """A `bytes.translate` table giving 1 for the selected byte values, 0 otherwise."""
    return _frozen_table(frozenset(selected))


@lru_cache(maxsize=256)
def _frozen_table(selected: frozenset[int]) -> bytes:
    # a query's terms ask for the same tables block after block and row after row
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


def column_mask(
    store: FrameStore,
    lo: int,
    hi: int,
    query: Query,
    options: Options,
    origin: float | None = None,
) -> bytes:
    """1 for rows of [lo, hi) that the query's column terms and the options let through:
    the matches, for a query without register names or words; else the candidates,
    rows the query may select depending on their details (`row_matches` decides).
    `origin`: the time `t:` counts from (the store's first row when not given)."""
    n = hi - lo
    full = _ones(n)
    _sure, maybe = _masks(query.tree, store, lo, hi, options, origin, full)
    mask = maybe & full
    if options.problems_only:
        problems = problem_mask(store, lo, hi)
        if options.transactions:
            problems = _lift_answers(store, lo, problems)
        mask &= _int(problems)
    if options.transactions:
        mask &= full ^ _int(answer_mask(store, lo, hi))
    return mask.to_bytes(n, "little")


def _int(m: bytes) -> int:
    return int.from_bytes(m, "little")


def _ones(n: int) -> int:
    return _int(b"\x01" * n)


def _atom_mask(
    node: Column | StatusTerm | Time | Register,
    store: FrameStore,
    lo: int,
    hi: int,
    options: Options,
    origin: float | None,
) -> int:
    """The rows a column term selects; for `reg:`, the rows that may carry named
    registers (requests and answers of the bound units)."""
    if isinstance(node, Column):
        if node.key == "kind":
            return _int(_bytes_mask(store.kind, lo, hi, node.values))
        frames = _int(_bytes_mask(store.kind, lo, hi, _FRAMES))
        if node.key == "unit":
            return frames & _int(_bytes_mask(store.unit, lo, hi, node.values))
        return frames & _int(_bytes_mask(store.fc, lo, hi, function_codes(node.values)))
    if isinstance(node, StatusTerm):
        return _int(status_mask(store, lo, hi, node.names))
    if isinstance(node, Time):
        a, b = _span_rows(store, node.span, lo, hi, origin)
        return _int(bytes(a - lo) + b"\x01" * (b - a) + bytes(hi - b))
    bound = _int(_bytes_mask(store.unit, lo, hi, options.bound))
    return bound & _int(_bytes_mask(store.kind, lo, hi, _NAMED))


def _span_rows(
    store: FrameStore, span: TimeSpan, lo: int, hi: int, origin: float | None
) -> tuple[int, int]:
    """The rows [a, b) of [lo, hi) that start inside `span` (rows are in time order)."""
    if origin is None:
        origin = store.t[0]
    a, b = lo, hi
    if span.start is not None:
        a = bisect_left(store.t, resolve_time(span.start, origin), lo, hi)
    if span.end is not None:
        b = bisect_left(store.t, resolve_time(span.end, origin), lo, hi)
    return a, max(a, b)


def _masks(
    node: Node,
    store: FrameStore,
    lo: int,
    hi: int,
    options: Options,
    origin: float | None,
    full: int,
) -> tuple[int, int]:
    """(sure, maybe): the rows of [lo, hi) `node` selects whatever their details say,
    and those it may select (the same for a node with no register names or words)."""
    if isinstance(node, Text):
        return 0, full
    if isinstance(node, Register):
        return 0, _atom_mask(node, store, lo, hi, options, origin)
    if isinstance(node, Column | StatusTerm | Time):
        m = _atom_mask(node, store, lo, hi, options, origin)
        return m, m
    if isinstance(node, Not):
        sure, maybe = _masks(node.part, store, lo, hi, options, origin, full)
        return full ^ maybe, full ^ sure
    if isinstance(node, And):
        sure, maybe = full, full
        for part in node.parts:
            s, m = _masks(part, store, lo, hi, options, origin, full)
            sure, maybe = sure & s, maybe & m
            if not maybe:
                break
        return sure, maybe
    sure, maybe = 0, 0
    for part in node.parts:
        s, m = _masks(part, store, lo, hi, options, origin, full)
        sure, maybe = sure | s, maybe | m
        if sure == full:
            break
    return sure, maybe


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


class _Row:
    """One row being decided: its details, found once and only when a term needs them."""

    def __init__(
        self,
        store: FrameStore,
        i: int,
        options: Options,
        origin: float | None,
        details: Callable[[int], Sequence[FrameDetail]],
    ) -> None:
        self.store, self.i, self.options, self.origin = store, i, options, origin
        self._details = details
        self._found: Sequence[FrameDetail] | None = None
        self._text: str | None = None
        self._names: list[str] | None = None

    @property
    def details(self) -> Sequence[FrameDetail]:
        if self._found is None:
            self._found = self._details(self.i)
        return self._found

    @property
    def text(self) -> str:
        if self._text is None:
            self._text = "\n".join(row_words(d) for d in self.details)
        return self._text

    @property
    def names(self) -> list[str]:
        if self._names is None:
            self._names = [r.name.lower() for d in self.details for r in d.registers]
        return self._names

    def holds_candidate(self, node: Node) -> bool:
        """`holds` for a row `column_mask` let through: it satisfies the column-only
        parts of the conjunctions the whole tree needs, so those are not tested again."""
        if not isinstance(node, And):
            return self.holds(node)
        return all(self.holds_candidate(p) for p in node.parts if needs_detail(p))

    def holds(self, node: Node) -> bool:
        if isinstance(node, Text):
            return node.word in self.text
        if isinstance(node, Column | StatusTerm | Time | Register):
            i = self.i
            if not _atom_mask(node, self.store, i, i + 1, self.options, self.origin):
                return False
            if isinstance(node, Register):
                return any(part in name for part in node.parts for name in self.names)
            return True
        if isinstance(node, Not):
            return not self.holds(node.part)
        # the terms decided from the columns first: they may spare the dissection
        parts = sorted(node.parts, key=needs_detail)
        if isinstance(node, And):
            return all(self.holds(p) for p in parts)
        return any(self.holds(p) for p in parts)


def row_matches(
    store: FrameStore,
    i: int,
    query: Query,
    options: Options,
    details: Callable[[int], Sequence[FrameDetail]],
    origin: float | None = None,
    *,
    candidate: bool = False,
) -> bool:
    """Whether `query` selects row `i` (the options aside), its details given by
    `details(i)` when a register name or a word must be looked for: the row's, and in
    the transactions view its answer's too. `candidate`: the row is one `column_mask`
    let through, so the column terms every match needs are known to hold."""
    row = _Row(store, i, options, origin, details)
    return row.holds_candidate(query.tree) if candidate else row.holds(query.tree)


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
            mask = column_mask(store, self.scanned, hi, self.query, options, self.origin)
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
                    if row_matches(
                        store, i, self.query, options, self._details, self.origin, candidate=True
                    ):
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
