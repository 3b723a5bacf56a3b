"""Provides the units panel: per-unit state, requests, answers, exceptions, timeouts, check
errors, latency median and p95, the time since its last answer and its last frame, and
the poll cycle (period, jitter, gaps of the unit's main poll); units that stopped
answering stand out. The state and the ages are measured against a clock
(`sniffer.analysis.liveness`): live, the port's, so they age while no frame comes."""

from __future__ import annotations

import operator
import time
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from itertools import compress
from typing import ClassVar

from rich.style import Style
from rich.text import Text
from textual.widgets import DataTable

from dissectors import mbap
from sniffer.analysis.liveness import UnitState, age_text, unit_liveness
from sniffer.analysis.pollcycle import GAP_FACTOR, MIN_REPEATS, resolved_cycle
from sniffer.analysis.polls import FRAMED_APART, Identity, frame_body, poll_identity
from sniffer.analysis.stats import UnitStats
from sniffer.framing.columns import marking
from sniffer.framing.pairing import Latency
from sniffer.framing.store import FrameStore
from sniffer.text import plain
from sniffer.tui.render import fit_columns
from sniffer.vocab import BAD_CHECK, Flag, Kind

# fixed widths: columns that grew with whatever was shown first would jump about
COLUMNS = (
    ("unit", 4),
    ("device", 16),
    ("state", 6),
    ("req", 7),
    ("ans", 7),
    ("exc", 5),
    ("t/o", 5),
    ("chk", 5),
    ("median", 7),
    ("p95", 7),
    ("period", 6),
    ("jitter", 6),
    ("gaps", 4),
    ("answer", 10),
    ("frame", 10),
)
# what stays when the pane is narrow, most important first
PRIORITY = (
    "unit",
    "state",
    "answer",
    "exc",
    "t/o",
    "chk",
    "median",
    "p95",
    "period",
    "ans",
    "req",
    "device",
    "frame",
    "gaps",
    "jitter",
)
STATE_WORDS = {
    UnitState.OK: "ok",
    UnitState.SILENT: "SILENT",
    UnitState.UNKNOWN: "?",  # quiet a while, its period unknown: not judged
    UnitState.NOT_ASKED: "-",
    UnitState.BROADCAST: "bcast",  # unit 0: nobody answers it
}


@dataclass(frozen=True, slots=True)
class UnitRow:
    unit: int
    label: str
    requests: int
    answers: int
    exceptions: int
    timeouts: int
    check_errors: int
    median_ms: float | None
    p95_ms: float | None
    last_seen: float
    last_answer: float | None
    silent: bool
    state: UnitState = UnitState.OK
    since_answer: float | None = None  # seconds from the clock's now (None: never)
    since_frame: float | None = None
    resolution: float = 0.0  # the stamps': an age under it is a bound (`age_text`)
    period: float | None = None  # seconds between sendings of the unit's main poll
    jitter: float | None = None  # p95 - p5 of those seconds
    gaps: int = 0  # waits of more than GAP_FACTOR periods, over all its polls
    # stamps too coarse for them: the period or jitter is an upper bound (`<`)
    period_bound: bool = False
    jitter_bound: bool = False


Cache = dict[tuple[int, str], tuple[int, float | None, float | None]]


def latency_quantiles(st: UnitStats, cache: Cache) -> tuple[float | None, float | None]:
    """Median and p95 latency in ms (one sort, redone only when there are new answers)."""
    n = len(st.latencies)
    found = cache.get((st.unit, "latency"))
    if found is not None and found[0] == n:
        return found[1], found[2]
    median = p95 = None
    if n:
        ordered = sorted(st.latencies)
        median = ordered[min(n - 1, round(0.5 * (n - 1)))] * 1000
        p95 = ordered[min(n - 1, round(0.95 * (n - 1)))] * 1000
    cache[(st.unit, "latency")] = (n, median, p95)
    return median, p95


def polling_period(st: UnitStats, cache: Cache, resolution: float = 0.0) -> Latency | None:
    """Median seconds between requests as the stamps vouch for it (`UnitStats.period`;
    redone only when there are new requests)."""
    n = st.request_count
    found = cache.get((st.unit, "period"))
    if found is not None and found[0] == n:
        return None if found[1] is None else Latency(found[1], bool(found[2]))
    period = st.period(resolution)
    cache[(st.unit, "period")] = (
        n,
        None if period is None else period.seconds,
        None if period is None else float(period.bound),
    )
    return period


def unit_rows(
    units: list[UnitStats],
    labels: dict[int, str],
    last_answer: dict[int, float],
    now: float,
    cache: Cache | None = None,
    resolution: float = 0.0,
) -> list[UnitRow]:
    """The panel's rows at `now` (live: the port's clock; a replay: the end of the
    capture). A unit's state is `sniffer.analysis.liveness.unit_liveness`: silent once
    its last answer is older than SILENT_AFTER of its own poll periods (and SILENT_MIN
    seconds), or asked and never answered; `?` where its period is unknown."""
    out = []
    cache = cache if cache is not None else {}
    for st in sorted(units, key=lambda s: s.unit):
        median, p95 = latency_quantiles(st, cache)
        answered = last_answer.get(st.unit)
        measured = polling_period(st, cache, resolution)
        requests = st.newest_requests(1)
        alive = unit_liveness(
            st.unit,
            now,
            asked=st.requests > 0,
            last_frame=st.last_seen or None,
            last_answer=answered,
            last_request=requests[-1] if requests else None,
            period=measured.seconds if measured is not None else None,
            period_bound=measured.bound if measured is not None else False,
        )
        out.append(
            UnitRow(
                st.unit,
                labels.get(st.unit, ""),
                st.requests,
                st.responses,
                st.exception_count,
                st.timeouts,
                st.check_errors,
                median,
                p95,
                st.last_seen,
                answered,
                alive.state is UnitState.SILENT,
                state=alive.state,
                since_answer=alive.since_answer,
                since_frame=alive.since_frame,
                resolution=resolution,
            )
        )
    return out


# -- the poll cycle, followed as rows arrive ------------------------------------------------

WINDOW = 512  # the latest waits a period and jitter are measured over
REMEASURE = 32  # sendings between two measurements of a long-running poll


def _quantile(ordered: list[float], q: float) -> float:
    return ordered[min(len(ordered) - 1, max(0, round(q * (len(ordered) - 1))))]


@dataclass
class _Poll:
    """One repeating request: its latest waits, period and jitter, and gaps so far."""

    count: int = 0
    last: float | None = None
    waits: deque[float] = field(default_factory=lambda: deque(maxlen=WINDOW))
    period: float | None = None
    jitter: float | None = None
    measured_at: int = 0  # `count` when period and jitter were last measured
    gaps: int = 0

    def send(self, t: float) -> None:
        self.count += 1
        if self.last is not None:
            wait = t - self.last
            if self.period is not None and wait > GAP_FACTOR * self.period:
                self.gaps += 1
            self.waits.append(wait)
            if self.count < 2 * REMEASURE or self.count - self.measured_at >= REMEASURE:
                self.measure()
        self.last = t

    def measure(self) -> None:
        if self.count < MIN_REPEATS:
            return
        ordered = sorted(self.waits)
        self.period = _quantile(ordered, 0.5)
        self.jitter = _quantile(ordered, 0.95) - _quantile(ordered, 0.05)
        self.measured_at = self.count


@dataclass(frozen=True, slots=True)
class CycleSummary:
    """A unit's poll cycle as the pane shows it."""

    period: float | None
    jitter: float | None
    gaps: int
    period_bound: bool = False
    jitter_bound: bool = False


# rows a PollWatch takes in at a time, and request frames it remembers the poll of
CHUNK = 4096
SEEN = 1 << 16
# the pane's share of the UI thread while it follows a big capture: at most this long a
# call, then again after a pause for keys
FOLLOW_BUDGET = 0.04
FOLLOW_AGAIN = 0.04
# ...and while a capture is indexed, a smaller share: the index first, which the pane
# following at half the thread would slow several times over
FOLLOW_AGAIN_INDEXING = 0.25
_SKIPPED = int(BAD_CHECK)  # the requests the poll cycle leaves out
_REQUESTS = marking((int(Kind.REQUEST),))
_MBAP = int(Flag.MBAP)
# a request as sent: unit and bytes, or, framed otherwise than RTU, unit, framing and
# bytes (a Modbus TCP frame's without its header, whose transaction id differs each time)
_Sending = tuple[int, bytes] | tuple[int, int, bytes]


class PollWatch:
    """Each unit's repeating requests, followed incrementally over a store.

    The same polls as `sniffer.analysis.pollcycle.poll_cycles` (which the --stats table
    uses): the same requests (a good check), told apart by the same rule
    (`sniffer.analysis.polls`), but measured over each poll's latest WINDOW waits so the
    pane stays cheap on a long capture; a gap is a wait of more than GAP_FACTOR times the
    period known when it ended.
    """

    def __init__(self) -> None:
        self.store: FrameStore | None = None
        self.next = 0
        self.polls: dict[int, dict[Identity, _Poll]] = {}
        # each request as sent -> its poll: a polling master sends the same bytes all
        # day, so most rows skip the rule (up to SEEN of them)
        self._seen: dict[_Sending, _Poll] = {}

    def update(self, store: FrameStore, upto: int, budget: float | None = None) -> bool:
        """Take in rows below `upto` (rows another thread has finished writing), in
        chunks of `CHUNK` rows, for about `budget` seconds at most (None: all of them);
        True if rows are left for the next call. A bounded call keeps the UI thread
        answering keys while a day's capture is indexed (30M rows, 15M requests)."""
        if store is not self.store or upto < self.next:
            self.store, self.next, self.polls = store, 0, {}
            self._seen = {}
        deadline = None if budget is None else time.monotonic() + budget
        while self.next < upto:
            hi = min(upto, self.next + CHUNK)
            self._chunk(store, self.next, hi)
            self.next = hi
            if deadline is not None and time.monotonic() >= deadline:
                break
        return self.next < upto

    def _chunk(self, store: FrameStore, lo: int, hi: int) -> None:
        """The requests among rows `lo`..`hi`: each column read once for the chunk (a
        slice: an array, or a paged store's block), the bytes of each channel once."""
        mask = store.kind[lo:hi].tobytes().translate(_REQUESTS)
        if 1 not in mask:
            return
        flags, unit, times = store.flags[lo:hi], store.unit[lo:hi], store.t[lo:hi]
        offsets, lengths, channels = store.offset[lo:hi], store.length[lo:hi], store.channel[lo:hi]
        spans: dict[int, tuple[int, bytes]] = {}
        present = channels.tobytes()
        for ch in set(present):
            picked = present.translate(marking((ch,)))
            first = min(compress(offsets, picked))
            end = max(compress(map(operator.add, offsets, lengths), picked))
            spans[ch] = (first, bytes(store.streams[ch][first:end]))
        seen = self._seen
        for k in compress(range(hi - lo), mask):
            f = flags[k]
            if f & _SKIPPED:
                continue
            first, data = spans[channels[k]]
            at = offsets[k] - first
            raw = data[at : at + lengths[k]]
            u = unit[k]
            framing = f & FRAMED_APART
            sent: _Sending = (
                (u, framing, mbap.body(raw) if framing & _MBAP else raw) if framing else (u, raw)
            )
            poll = seen.get(sent)
            if poll is None:
                mine = self.polls.setdefault(u, {})
                identity, _ = poll_identity(frame_body(raw, framing))
                poll = mine.get(identity)
                if poll is None:
                    poll = mine[identity] = _Poll()
                if len(seen) < SEEN:  # (a write of ever new values is not worth keeping)
                    seen[sent] = poll
            poll.send(times[k])

    def summary(self, unit: int) -> CycleSummary:
        """The unit's main poll (the request sent most often) and all its polls' gaps."""
        repeating = [p for p in self.polls.get(unit, {}).values() if p.count >= MIN_REPEATS]
        if not repeating:
            return CycleSummary(None, None, 0)
        main = max(repeating, key=lambda p: (p.count, -(p.period or 0.0)))
        if main.measured_at != main.count:
            main.measure()  # up to date when shown, however seldom it is re-measured
        gaps = sum(p.gaps for p in repeating)
        resolution = self.store.resolution if self.store is not None else 0.0
        if main.period is None or main.jitter is None:
            return CycleSummary(main.period, main.jitter, gaps)
        # no finer than the stamps hold, as the --stats poll cycle says it
        period, period_bound, jitter, jitter_bound = resolved_cycle(
            main.period, main.jitter, resolution
        )
        return CycleSummary(period, jitter, gaps, period_bound, jitter_bound)

    def summaries(self) -> dict[int, CycleSummary]:
        return {unit: self.summary(unit) for unit in self.polls}


def with_cycles(rows: list[UnitRow], cycles: Mapping[int, CycleSummary]) -> list[UnitRow]:
    """The rows with each unit's poll cycle filled in."""
    out = []
    for r in rows:
        c = cycles.get(r.unit)
        out.append(
            r
            if c is None
            else replace(
                r,
                period=c.period,
                jitter=c.jitter,
                gaps=c.gaps,
                period_bound=c.period_bound,
                jitter_bound=c.jitter_bound,
            )
        )
    return out


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v:.1f}"


def _span(seconds: float | None, bound: bool = False) -> str:
    """A period or jitter in at most 6 cells: 250ms, 2501ms, 11.3s, 1.2h; `<250ms` where
    the stamps only bound it, `?` where they cannot tell."""
    if seconds is None:
        return "-"
    if not seconds < float("inf"):
        return "?"
    if bound:
        return "<" + _span(seconds)
    if seconds < 10:
        return f"{seconds * 1000:.0f}ms"
    if seconds < 3600:
        return f"{seconds:.1f}s" if seconds < 1000 else f"{seconds / 60:.0f}m"
    return f"{seconds / 3600:.1f}h"


class UnitsPanel(DataTable[Text]):
    """The per-unit table (refreshed by the app while it is shown)."""

    COMPONENT_CLASSES: ClassVar[set[str]] = {"units-panel--silent", "units-panel--bad"}

    def on_mount(self) -> None:
        self.cursor_type = "row"
        self.zebra_stripes = True
        self.shown: list[str] = []
        self.last: tuple[list[UnitRow], float] = ([], 0.0)
        self.polls = PollWatch()
        self._again = False  # a call to catch up with the rows is due
        self._columns(fit_columns(COLUMNS, PRIORITY, 200))

    def _columns(self, names: list[str]) -> None:
        self.clear(columns=True)
        self.shown = names
        widths = dict(COLUMNS)
        for name in names:
            self.add_column(
                Text(name, justify="left" if name in ("device", "state") else "right"),
                key=name,
                width=widths[name],
            )

    def on_resize(self) -> None:
        names = fit_columns(COLUMNS, PRIORITY, self.size.width - 1)
        if names != self.shown:
            self._columns(names)
            self._fill(*self.last)

    def _follow(self, rows: list[UnitRow]) -> list[UnitRow]:
        """The rows with the poll cycle, followed over the rows the app has published
        (the pane reads the store itself, so the app hands it only the counts)."""
        model = getattr(self.app, "model", None)
        reader = getattr(model, "reader", None)
        upto = getattr(model, "published", None)
        if not isinstance(reader, FrameStore) or not isinstance(upto, int):
            return rows
        if self.polls.update(reader, upto, budget=FOLLOW_BUDGET) and not self._again:
            # rows left (a big capture): on again soon, between keys, not at the next tick
            self._again = True
            indexing = not getattr(model, "done", True)  # a capture's first indexing
            self.set_timer(FOLLOW_AGAIN_INDEXING if indexing else FOLLOW_AGAIN, self._catch_up)
        return with_cycles(rows, self.polls.summaries())

    def _catch_up(self) -> None:
        self._again = False
        rows, now = self.last
        if self.is_mounted:
            self._fill(self._follow(rows), now)

    def show(self, rows: list[UnitRow], now: float) -> None:
        self._fill(self._follow(rows), now)

    def _fill(self, rows: list[UnitRow], now: float) -> None:
        self.last = (rows, now)
        silent = self.get_component_rich_style("units-panel--silent", partial=True)
        bad = self.get_component_rich_style("units-panel--bad", partial=True)
        keys = [str(r.unit) for r in rows]
        current = [str(k.value) for k in self.rows]
        names = [name for name, _ in COLUMNS]
        if keys != current:
            self.clear()
            for r in rows:
                cells = dict(zip(names, self._cells(r, now, silent, bad), strict=True))
                self.add_row(*(cells[n] for n in self.shown), key=str(r.unit))
            return
        for r in rows:
            for name, cell in zip(names, self._cells(r, now, silent, bad), strict=True):
                if name in self.shown:
                    self.update_cell(str(r.unit), name, cell)

    def _cells(self, r: UnitRow, now: float, silent: Style, bad: Style) -> list[Text]:
        def cell(value: str, style: Style | None = None, right: bool = True) -> Text:
            return Text(value, style=style or "", justify="right" if right else "left")

        row_style = silent if r.silent else None
        res = r.resolution
        answer = "never" if r.since_answer is None else age_text(r.since_answer, res) + " ago"
        frame = "-" if r.since_frame is None else age_text(r.since_frame, res) + " ago"
        return [
            cell(str(r.unit), row_style),
            cell(plain(r.label, 16), row_style, right=False),
            cell(STATE_WORDS[r.state], silent if r.silent else None, right=False),
            cell(str(r.requests)),
            cell(str(r.answers)),
            cell(str(r.exceptions), bad if r.exceptions else None),
            cell(str(r.timeouts), bad if r.timeouts else None),
            cell(str(r.check_errors), bad if r.check_errors else None),
            cell(_ms(r.median_ms)),
            cell(_ms(r.p95_ms)),
            cell(_span(r.period, r.period_bound)),
            cell(_span(r.jitter, r.jitter_bound)),
            cell(str(r.gaps) if r.gaps else "-", bad if r.gaps else None),
            cell(answer, row_style),
            cell(frame),
        ]
