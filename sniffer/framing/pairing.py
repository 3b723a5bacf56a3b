"""Provides request/response pairing over a frame store: transactions, timeouts, retries.

A sniffer does not know who sent what; the framer already told requests from answers by
their layouts and by order. Pairing then walks the frames in time order with one open
request per bus (Modbus RTU has one transaction in flight at a time) and decides what
became of each: answered, exception, timeout, orphan answer, broadcast, retry.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass
from math import ceil, floor, log10, ulp

from sniffer import core
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.model import Chunk, Labels, LineSettings, SourceInfo, Stamp
from sniffer.vocab import BAD_CHECK, Flag, Kind, Status


def default_timeout(line: LineSettings) -> float:
    """Response timeout when none is given: 200 ms plus the time of a longest frame."""
    return 0.2 + 256 * line.char_time


class Pairer:
    """Pairs the frames of a store incrementally: call `update()` after frames arrive,
    `tick(now)` while live so that silent slaves time out, `finish()` at the end."""

    def __init__(
        self, store: FrameStore, timeout: float, answered_broadcasts: frozenset[int] = frozenset()
    ) -> None:
        self.store = store
        self.timeout = timeout
        # vendor function codes whose broadcasts do get an answer (VED903B 0x41)
        self.answered_broadcasts = answered_broadcasts
        self.end_time = float("-inf")  # when the capture ended, if the source said so
        self.next = 0
        self.open = -1  # index of the request waiting for its answer
        self.last_timed_out = b""  # raw bytes of the last request that got no answer
        # the same as 256 bytes, for the compiled loop (made again if the set is replaced)
        self._answered_of = answered_broadcasts
        self._answered = bytes(fc in answered_broadcasts for fc in range(256))

    @property
    def judged(self) -> float:
        """The wait past which the row times show an answer overdue: the response timeout
        plus the stamps' resolution, since each end of the wait may be off by that much (a
        1 s clock cannot show a 200 ms timeout; infinite when the stamps bound nothing)."""
        return self.timeout + self.store.resolution

    def settled(self) -> bool:
        """No request waits for its answer: no row to come pairs with a row so far."""
        return self.open < 0

    def rebase(self, store: FrameStore) -> None:
        """A settled pairer goes on in `store`, empty, numbering rows from 0 again
        (`sniffer.session.session.Session.new_segment`)."""
        self.store = store
        self.next = 0

    def update(self) -> None:
        s = self.store
        s.sync()
        n = len(s)
        fast = core.FAST
        if fast is not None and self.next < n:
            if self._answered_of is not self.answered_broadcasts:
                self._answered_of = self.answered_broadcasts
                self._answered = bytes(fc in self._answered_of for fc in range(256))
            # the compiled copy of the loop below (sniffer/_core.c: pair_update): the loop
            # does little for each row, so in Python its cost is mostly the interpreter's
            self.open, last = fast.pair_update(
                s, self.next, self.open, self.judged, self._answered, self.last_timed_out
            )
            if last != -2:
                self.last_timed_out = b"" if last == -1 else s.raw(last)
            self.next = n
            return
        kind, unit, fc, partner = s.kind, s.unit, s.fc, s.partner
        t, t_end, timeout = s.t, s.t_end, self.judged
        for i in range(self.next, n):
            k = kind[i]
            if k == 0 or k == 5:  # noise, events
                continue
            op = self.open
            j = partner[i]
            # the wait is over (the open request timed out) unless this row is its
            # answer: an answer however late, with nothing between, is still its answer
            # (flagged LATE), as the framer's fast path pairs it, so that how the reads
            # cut the frames changes nothing (tests/framing/test_read_shapes.py)
            if (
                op >= 0
                and t[i] - t_end[op] > timeout
                and (j >= 0 or k == 1 or unit[op] not in (unit[i], 0) or fc[op] != fc[i] & 0x7F)
            ):
                self._time_out(op)
                op = -1
            if j >= 0:
                # paired as it was framed (the answer its request predicted)
                if j < i:  # the answer
                    if op == j:
                        self.open = -1
                    if t[i] - t_end[j] > timeout:
                        s.flags[i] |= Flag.LATE
                else:  # the request
                    if op >= 0:
                        self._time_out(op)
                    if self.last_timed_out:
                        self._check_retry(i)
                continue
            if k == 1:  # Kind.REQUEST
                self._request(i)
                continue
            u = unit[i]
            if op >= 0 and unit[op] in (u, 0) and fc[op] == fc[i] & 0x7F:
                self._pair(op, i)
            elif k != Kind.UNKNOWN:
                s.status[i] = Status.ORPHAN
                if u == 0:
                    s.flags[i] |= Flag.ANSWERED_BROADCAST
        self.next = n

    def _check_retry(self, i: int) -> None:
        if self.store.raw(i) == self.last_timed_out:
            self.store.flags[i] |= Flag.RETRY
        self.last_timed_out = b""

    def _request(self, i: int) -> None:
        s = self.store
        if self.open >= 0:
            self._time_out(self.open)
        if s.unit[i] == 0 and s.fc[i] not in self.answered_broadcasts:
            s.status[i] = Status.BROADCAST
            self.open = -1
        else:
            s.status[i] = Status.OPEN
            self.open = i
        if self.last_timed_out:
            self._check_retry(i)

    def _pair(self, req: int, resp: int) -> None:
        s = self.store
        s.partner[req] = resp
        s.partner[resp] = req
        if s.flags[resp] & BAD_CHECK:
            status = Status.BAD_ANSWER
        elif s.fc[resp] & 0x80:
            status = Status.EXCEPTION
        else:
            status = Status.OK
        s.status[req] = status
        s.status[resp] = status
        if s.t[resp] - s.t_end[req] > self.judged:
            s.flags[resp] |= Flag.LATE
        self.open = -1

    def _time_out(self, req: int) -> None:
        s = self.store
        self.open = -1
        if s.partner[req] != NO_PARTNER:
            return  # answered after all (paired as it was framed)
        s.status[req] = Status.TIMEOUT
        self.last_timed_out = s.raw(req)
        self.open = -1

    def tick(self, now: float) -> None:
        """Time out the open request if its answer is overdue at time `now`."""
        self.update()
        if self.open >= 0 and now - self.store.t_end[self.open] > self.judged:
            self._time_out(self.open)

    def finish(self) -> None:
        """At the end of a capture an open request stays open: the capture, not the
        slave, may have stopped first (unless the capture went on past the timeout)."""
        self.update()
        s = self.store
        if self.open >= 0:
            end = max(s.t_end[len(s) - 1], self.end_time)
            if end - s.t_end[self.open] > self.judged:
                self._time_out(self.open)


def latency(store: FrameStore, i: int) -> float | None:
    """Seconds from the end of a request to the start of its answer (either side's index),
    as the row times say; `measure` says what of it the timing can vouch for."""
    j = store.partner[i]
    if j == NO_PARTNER:
        return None
    req, resp = (i, j) if store.kind[i] == Kind.REQUEST else (j, i)
    return store.t[resp] - store.t_end[req]


_REQUEST = int(Kind.REQUEST)

# Below this, an answer's start and its request's end are the same instant to the row
# times: the framer placed both inside one read (or one print stamp) by the line speed.
UNRESOLVED = 1e-6
# A time is shown as a value only when it is at least this many resolutions long: its
# value is then known to within half of itself; anything shorter is a bound (`<x`).
RESOLVED = 2.0
INF = float("inf")


def shown_step(resolution: float) -> float:
    """The finest step a time measured with stamps of `resolution` seconds is shown to:
    the resolution's decade below a millisecond (1 µs at the finest), whole milliseconds
    up to a second, whole seconds beyond. A bound is rounded up to it, a value to the
    nearest."""
    if not resolution > UNRESOLVED:
        return UNRESOLVED
    if resolution >= 1.0:
        return 1.0
    if resolution >= 1e-3:
        return 1e-3
    return 10.0 ** floor(log10(resolution) + 1e-9)


def _up(x: float, step: float) -> float:
    """`x` rounded up to a whole `step` (a bound is never made smaller)."""
    return ceil(x / step - 1e-9) * step


@dataclass(frozen=True, slots=True)
class Latency:
    """A latency as far as the timing can vouch for it: `seconds` is what every view shows,
    a value rounded to `step` (`shown_step` of the resolution) or, when `bound`, an upper
    bound rounded up to it (the latency is below it). `raw` is the difference of the row
    times it was made from."""

    seconds: float
    bound: bool = False
    step: float = UNRESOLVED
    raw: float = 0.0

    @property
    def ms(self) -> float:
        """`seconds` in milliseconds, to the step (what JSONL, CSV and Parquet carry)."""
        return round(self.seconds * 1000, max(0, -round(log10(self.step * 1000) - 1e-9)))

    def text(self) -> str:
        """`12.3ms`, `<16ms`, `<2s`: a listing's words for it (`latency_words`)."""
        shown = span_words(self.ms)
        return "<" + shown if self.bound else shown


def span_words(ms: float) -> str:
    """A latency or period in ms, in a listing's words, no finer than `measure` rounded
    it (to the stamps' resolution): `12.3ms`; `16ms` (whole milliseconds drop their
    zero, as stamps of a millisecond or coarser give them); `2s` (whole seconds);
    `0.025ms` (below 0.1 ms); `?` for a NaN (times that were none)."""
    if ms != ms:
        return "?"
    whole = round(ms)
    if abs(ms - whole) < 1e-6 and whole and whole % 1000 == 0:
        return f"{whole // 1000}s"
    text = f"{ms:.1f}" if ms >= 0.1 else f"{ms:.3f}"
    return (text[:-2] if text.endswith(".0") else text) + "ms"


def latency_words(ms: float | None, max_ms: float | None) -> str:
    """A row's latency pair (JSONL `latency_ms`, `latency_max_ms`) as every listing and
    the TUI write it: the value (`12.3ms`), the bound (`<16ms`), or nothing (unknown)."""
    if ms is not None:
        return span_words(round(ms, 3))  # (to the microsecond, as JSONL gives it)
    if max_ms is not None:
        return "<" + span_words(round(max_ms, 3))
    return ""


def judge(
    raw: float, resolution: float, stamps: Stamp, wire: float = 0.0, shown: float | None = None
) -> Latency | None:
    """What a difference `raw` of row times (an answer's start less its request's end)
    says, with stamps of `stamps` meaning good to `resolution` seconds (see `measure`);
    `wire` is the request's own time on the line. None: the timing cannot say.

    Each stamp may be off by up to the resolution, so the latency is `raw` give or take
    one resolution: a value when `raw` is at least RESOLVED resolutions long, else at
    most `raw` plus one resolution (a bound). Print times are always bounds: a program
    prints a request as it hands it to the port and an answer once it has it, so the
    latency is at most the time between the two prints (give or take the clock), and
    may be any amount less; prints closer than the request's own bytes need on the line
    break that rule, and say nothing. `shown`: the difference of the row times as they
    are shown (to the microsecond), which a value is rounded from (by default `raw`)."""
    if stamps is Stamp.NONE or not resolution < INF:
        return None
    step = shown_step(resolution)
    if stamps is Stamp.PRINT:
        if raw < wire - resolution or not raw + resolution > 0:
            return None
        return Latency(_up(raw + resolution, step), True, step, raw)
    if not raw < max(RESOLVED * resolution, UNRESOLVED):  # (a NaN stays a value, as the
        # statistics' compiled scan keeps it)
        value = raw if shown is None else shown
        if value == value:  # (a NaN is kept as it is)
            value = round(value / step) * step
        return Latency(value, False, step, raw)
    if resolution > 0 and raw + resolution > 0:
        return Latency(_up(raw + resolution, step), True, step, raw)
    return None


def measure(store: FrameStore, i: int) -> Latency | None:
    """The latency of row `i`'s transaction as far as the store's timing can measure it
    (`judge` with the store's stamps and resolution); None when it cannot (no
    timestamps, stamps that bound nothing, or stamps that put the answer's bytes on the
    wire before the line speed allows). Every view shows this, and only this."""
    j = store.partner[i]
    stamps = store.stamps
    if j == NO_PARTNER or stamps is Stamp.NONE:
        return None
    req, resp = (j, i) if store.kind[i] != _REQUEST else (i, j)
    t, end = store.t[resp], store.t_end[req]
    # a value is the difference of the times as listings show them (to the microsecond,
    # as recordings keep them), so a live listing and the replay of its recording agree
    return judge(t - end, store.resolution, stamps, end - store.t[req], round(t, 6) - round(end, 6))


# -- what a source's stamps are worth, measured from the stamps ----------------------------

READ_IDLE = 0.1  # a wait between host reads longer than this is a pause of the line
READ_GAPS = 64  # waits between host reads the read resolution is measured from
READ_NOTES = 4096  # host reads looked at at most (a slow line gives few waits)
MIN_READ_GAPS = 16
READ_DELAY_RANK = 0.999  # the late reads a bound allows for: all but the latest 0.1 %
READ_BUSY = 4.0  # waits up to this many medians may be late reads rather than pauses
CLOCK_STAMPS = 64  # stamps the clock's step is measured from
CLOCK_NOTES = 65_536  # stamps looked at at most for them (a clock that never moves)
MIN_CLOCK_STAMPS = 8
# steps a clock may print to (what a time's fraction digits give): the coarsest that
# every stamp is a whole multiple of is the clock's
DECIMAL_STEPS = (1.0, 0.1, 0.01, 1e-3, 1e-4, 1e-5, 1e-6)
TOLD_APART = 2.0**42  # a float this many steps long still tells a step's multiples apart
# log formats whose program prints what it sent only later: ESPHome's uart_debug holds
# sent bytes until the answer's first byte comes in (or its timeout ends)
PRINTS_SENDS_LATE = frozenset({"esphome"})


def clock_step(stamps: Sequence[float]) -> float:
    """The coarsest decimal step (1 s, 0.1 s, ... 1 µs) every one of `stamps` is a whole
    multiple of: what the clock's fraction digits really hold (a log printing
    `12:34:56.000` has a 1 s clock). 0 when it cannot be told (too few stamps, or finer
    than a float of their size keeps)."""
    seen = set(stamps)
    if len(seen) < MIN_CLOCK_STAMPS:
        return 0.0
    top = max(abs(x) for x in seen)
    # a whole multiple to within what a float of the stamps' size keeps (a few of its
    # last bits), never to a share of the step: 30 µs past a tenth of a second is not a
    # tenth, however small a share of one it is
    near = 4 * ulp(max(top, 1.0))  # (6.2 µs at epoch times once, 26 ulps: 994 µs read as 1 ms)
    for step in DECIMAL_STEPS:
        if top / step > TOLD_APART:
            break
        if all(abs(x - round(x / step) * step) <= near for x in seen):
            return step
    return 0.0


def read_interval(gaps: Sequence[float]) -> tuple[float, float]:
    """The host reads' rhythm from the waits between reads: the median wait (a USB
    adapter's latency timer shows as reads 16 ms apart) and how late a read may come
    beyond it (a loaded machine wakes its reader late, and the bytes wait for it). The
    lateness is measured from the spread of the waits around the median: a read that
    came late makes its wait longer and the next one shorter, so waits shorter than the
    median show it as well as longer ones (which pauses of the line lengthen too, so
    only those up to twice the median count); the larger of the two spreads, each to
    all but the outermost READ_DELAY_RANK."""
    ordered = sorted(gaps)
    n = len(ordered)
    median = ordered[n // 2]
    early = ordered[int((1 - READ_DELAY_RANK) * (n - 1))]
    busy = bisect_right(ordered, READ_BUSY * median)
    late = ordered[min(busy - 1, ceil(READ_DELAY_RANK * (busy - 1)))]
    return median, max(0.0, median - early, late - median)


class StampClock:
    """What a source's stamps are worth, measured from the stamps themselves as they
    come (the first CLOCK_STAMPS for the clock's step, the first READ_GAPS waits between
    host reads for their rhythm) on top of what the reader declared.

    `resolution`: how far a row time may be from when its bytes were on the line: the
    largest of the declared resolution, the clock's step, and, for host reads, the read
    interval plus the reads' lateness (bytes may have waited that long for the read that
    stamped them). Infinite when the stamps bound nothing (a program that prints what it
    sent only later)."""

    def __init__(self, stamps: Stamp, declared: float = 0.0, basis: str = "") -> None:
        self.stamps = stamps
        self.declared = declared
        self.basis = basis  # why the declared resolution is what it is, if it says more
        self.step = 0.0  # the clock's step, from the stamps
        self.read_quantum = 0.0  # host reads: the median wait between reads
        self.read_delay = 0.0  # host reads: how much later the late ones came
        self.reading = ""  # frame stamps: which end they mark, when the line speed told
        self.resolution = 0.0 if declared != declared else declared
        self.learning = stamps is not Stamp.NONE and declared < INF
        # host reads are timed from their rhythm unless the source said what they are
        # worth (a modscope export of a capture: the resolution that capture had)
        self._reads = stamps is Stamp.READ_END and declared <= UNRESOLVED
        self._seen: list[float] = []
        self._gaps: list[float] = []
        self._last: float | None = None
        self._noted = 0
        self._stamps = 0  # stamps noted, repeated ones too
        self._measured = (0, 0)
        self.due = False  # stamps enough for a new measurement (see `note`)

    def note(self, t: float) -> None:
        """One stamp of the source (a host read's end, a line's print time), in order."""
        seen = self._seen
        self._stamps += 1
        # distinct stamps only: a clock of 1 s gives a busy line's packets one stamp for
        # many, and the first CLOCK_STAMPS of them may hold fewer instants than the step
        # is told from (then taken as the declared microsecond: a request and its answer
        # 0 µs apart, a poll every `<0ms`)
        if len(seen) < CLOCK_STAMPS and (not seen or t != seen[-1]):
            seen.append(t)
            # measure the clock's step early, and again as stamps double: the framer's
            # leeway for stamps too close for the line speed follows it
            n = len(seen)
            self.due = self.due or (n >= MIN_CLOCK_STAMPS and n & (n - 1) == 0)
        if self._reads:
            last = self._last
            if last is not None:
                gap = t - last
                if 0 < gap < READ_IDLE:
                    self._gaps.append(gap)
            self._last = t
            self._noted += 1
            enough = len(self._gaps) >= READ_GAPS and len(seen) >= CLOCK_STAMPS
            if enough or self._noted >= READ_NOTES:
                self.learning = False
        elif len(seen) >= CLOCK_STAMPS or self._stamps >= CLOCK_NOTES:
            self.learning = False
        # measured once more with all it learnt, at this stamp, not at whatever moment
        # a reader next looks (a live view's refresh): what is framed next is the same
        self.due = self.due or not self.learning

    def update(self) -> bool:
        """Measure again from the stamps noted since the last time; whether the
        resolution changed."""
        self.due = False
        key = (len(self._seen), len(self._gaps))
        if key == self._measured:
            return False
        self._measured = key
        self.step = clock_step(self._seen)
        if len(self._gaps) >= MIN_READ_GAPS:
            self.read_quantum, self.read_delay = read_interval(self._gaps)
        before = self.resolution
        if not self.declared < INF:
            self.resolution = INF
        else:
            self.resolution = max(self.declared, self.step, self.read_quantum + self.read_delay)
        return self.resolution != before

    @property
    def measured_coarser(self) -> bool:
        """Whether the stamps turned out coarser than the source declared (a clock step,
        host reads' interval) by enough to change what is shown (NOTEWORTHY)."""
        return self.resolution >= NOTEWORTHY and self.resolution > self.declared

    def why(self) -> str:
        """What the resolution was measured from, in a few words (empty: as declared)."""
        if not self.resolution < INF:
            return self.basis
        parts = []
        u = self.resolution
        if self.read_quantum and self.read_quantum + self.read_delay >= u:
            part = f"host reads about {duration(self.read_quantum)} apart"
            if self.read_delay:
                part += f", the late ones up to {duration(self.read_delay)} later"
            parts.append(part)
        elif self.step and self.step >= u and self.step > self.declared:
            parts.append(f"every stamp is a whole multiple of {duration(self.step)}")
        elif self.basis:
            parts.append(self.basis)
        if self.reading:
            parts.append(self.reading)
        return "; ".join(parts)


def declared_resolution(info: SourceInfo) -> tuple[float, str]:
    """The resolution a reader's stamps are worth before any is seen, and why when that
    is not just their digits: print times of a program that prints what it sent only
    later, or of one that only listens (it prints what it read some time after), bound
    no latency or poll period (infinite)."""
    if info.stamps is Stamp.PRINT:
        if info.format in PRINTS_SENDS_LATE:
            return INF, (
                "ESPHome prints what it sent only once the answer starts coming in, or when "
                "its debug timeout ends, so these times bound nothing on the line"
            )
        # a program's own sends and receives (TX/RX labels, or a connection's two
        # directions, which are certain) are a party's; a log without them a listener's
        if info.labels is Labels.NONE:
            return INF, (
                "a listening program's print times: when it printed what it read, an "
                "unknown time after the bytes were on the line"
            )
    return info.resolution, ""


def frame_overlaps(chunks: Sequence[Chunk], char_time: float, starts: bool, slack: float) -> int:
    """How many of `chunks` (one frame each) would overlap the one before on their
    channel if their stamps marked frame starts (`starts`) or frame ends: the bytes
    then need longer on the line than the stamps leave them."""
    last: dict[int, tuple[float, int]] = {}
    overlaps = 0
    for c in chunks:
        if not c.data:
            continue
        before = last.get(c.channel)
        if before is not None:
            t, n = before
            if starts:
                overlaps += c.t_end < t + n * char_time - slack
            else:
                overlaps += c.t_end - len(c.data) * char_time < t - slack
        last[c.channel] = (c.t_end, len(c.data))
    return overlaps


def frame_reading(
    chunks: Sequence[Chunk], declared: Stamp, char_time: float, slack: float
) -> tuple[Stamp, str]:
    """Whether per-frame stamps mark frame starts or frame ends: the reading under which
    the bytes fit the line speed (fewer frames overlapping), the declared one when both
    fit alike; and, when that is not the declared one, a few words on why."""
    as_starts = frame_overlaps(chunks, char_time, True, slack)
    as_ends = frame_overlaps(chunks, char_time, False, slack)
    chosen = Stamp.FRAME_START if as_starts < as_ends else Stamp.FRAME_END
    if as_starts == as_ends or chosen is declared:
        return declared, ""
    other = max(as_starts, as_ends)
    said = "starts" if chosen is Stamp.FRAME_START else "ends"
    not_said = "ends" if chosen is Stamp.FRAME_START else "starts"
    return chosen, (
        f"stamps read as frame {said}: as frame {not_said}, {other} of the first "
        f"{len(chunks)} frames would overlap the one before"
    )


def duration(seconds: float) -> str:
    """`1 s`, `16 ms`, `0.5 ms`, `1 µs`: a resolution or a timeout in words."""
    if seconds >= 0.9995:
        return f"{seconds:.3g} s"
    if seconds >= 0.9995e-3:
        return f"{seconds * 1000:.3g} ms"
    return f"{seconds * 1e6:.3g} µs"


TIMING_WORDS = {
    Stamp.EXACT: "exact (per character)",
    Stamp.READ_END: "end of each host read",
    Stamp.FRAME_START: "start of each frame",
    Stamp.FRAME_END: "end of each frame",
    Stamp.PRINT: "when each line was logged",
    Stamp.NONE: "synthetic",
}


NOTEWORTHY = 1e-3  # a resolution from which on what it bounds is said (`coarse`)


def coarse(stamps: Stamp, resolution: float) -> bool:
    """Whether the times shown are coarse enough to say so once (`timing_note`): print
    times, stamps that bound nothing, or a resolution of a millisecond or more."""
    return stamps is Stamp.PRINT or not resolution < NOTEWORTHY


def timing_note(
    stamps: Stamp, resolution: float, timeout: float | None = None, why: str = ""
) -> str:
    """The one sentence that says what the times shown are worth (`timing: ...`): the
    stamps, their resolution and what it was measured from, and what is shown as a bound
    or not at all because of it. Empty when there is nothing to say (exact times)."""
    if stamps is Stamp.NONE:
        return (
            "timing: synthetic (the source has no timestamps): no latency, timeout or "
            "poll period is measured"
        )
    words = TIMING_WORDS[stamps]
    if not resolution < INF:
        reason = f"; {why}" if why else ""
        return (
            f"timing: {words}{reason}: latencies, late answers, timeouts told by the clock "
            "and poll periods are unknown"
        )
    if resolution <= UNRESOLVED and stamps is not Stamp.PRINT:
        if stamps is Stamp.READ_END:
            return f"timing: {words}, resolution not known (too few reads to tell)"
        return ""
    text = f"timing: {words}, resolution {duration(resolution)}"
    if why:
        text += f" ({why})"
    if stamps is Stamp.PRINT:
        text += "; every latency is a bound (<x: at most the time between the prints)"
    else:
        text += (
            f"; latencies and poll periods under {duration(RESOLVED * resolution)} are "
            "shown as bounds (<x)"
        )
    if timeout is not None and timeout < INF and resolution >= 0.1 * timeout:
        text += (
            f"; an answer is called late, or a request timed out by the clock, only past "
            f"{duration(timeout + resolution)} (the {duration(timeout)} response timeout "
            "plus the resolution): nearer the timeout it cannot be told"
        )
    return text
