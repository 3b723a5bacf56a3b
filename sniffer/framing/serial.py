"""Provides the RTU and ASCII framers: timestamped chunks in, frames and noise spans out.

A sniffer sees both directions of a half-duplex line and cannot trust its timestamps
(a USB adapter delivers bytes in bursts), so the RTU framer does not split on gaps. At
each position it asks the function-code registry which lengths a frame starting there
could have (as a request, as a response, as the exact answer the last request predicts,
as an exception), tests those lengths shortest first, and lets the CRC decide. Silence
is used only where lengths cannot help: to frame unknown function codes, and to tell a
frame with a bad CRC from noise when the timing is exact. The framer's inline fast paths
(and their compiled copy) take the common frames; the search for the rest, and the
length tables the fast paths read, are `sniffer.framing.lengths.RtuLengths`.

Every byte fed in leaves in exactly one frame or one noise span, in order.
"""

from __future__ import annotations

import math
import re
from array import array
from bisect import bisect_left, bisect_right
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from dissectors.checks import crc16, lrc
from dissectors.envelope import ascii_body
from dissectors.envelope.ascii import START, VENDOR_STARTS
from dissectors.functions import EXCEPTION_LENGTH, FUNCTIONS, FunctionSpec
from sniffer import core
from sniffer.framing.lengths import (
    ECHO,
    FIXED,
    INF,
    MAX_RTU,
    MIN_RTU,
    WALKED,
    RtuLengths,
    compile_rules,
    echo_key,
    not_its_echo,
)
from sniffer.model import Chunk, Direction, LineSettings
from sniffer.vocab import Flag, Kind

if TYPE_CHECKING:
    from sniffer.framing.store import FrameStore
    from sniffer.sources.reads import Reads

MAX_ASCII = 513
MAX_NOISE = 256  # bytes in one noise row; longer noise is shown in pieces
# a chunk may seem this much faster than the line before its stamps count as inconsistent
# (a USB adapter hands over a read up to about a millisecond after its first bytes came)
TOO_FAST_SLACK = 0.002
# a lone chunk (not a batch of reads) shorter than this is framed by the Python fast
# path even where the compiled one is built: calling out costs about as much as framing
# a few frames in Python, so only a chunk of many frames gains by it
FAST_MIN_BYTES = 128


@dataclass(slots=True)
class _Span:
    """Times of one chunk's bytes within the framer's stream offsets."""

    start: int  # stream offset of the chunk's first byte
    end: int
    t_start: float
    t_end: float
    gap_before: float


class _Timeline:
    """Per-byte time estimates and silence boundaries for a stream of chunks."""

    def __init__(self, line: LineSettings, exact: bool) -> None:
        self.char = line.char_time
        self.t35 = line.t35
        self.t15 = line.t15
        self.exact = exact
        self.spans: list[_Span] = []  # chunks not yet forgotten, in stream order
        self.starts: list[int] = []  # their first offsets, for bisect
        self.boundaries: list[int] = []  # stream offsets preceded by silence >= t3.5
        self.line_errors: set[int] = set()
        self.last_end: float | None = None
        self.slack = TOO_FAST_SLACK  # how much too fast a chunk may seem (see add)
        self.too_fast = 0  # chunks whose stamps leave their bytes too little time
        self.first_too_fast: float | None = None
        self.offset = 0
        # the newest chunk: where it starts, when, and seconds per byte
        self.cur_start = 0
        self.cur_t0 = 0.0
        self.cur_rate = 0.0

    def add(self, chunk: Chunk) -> None:
        self.add_read(len(chunk.data), chunk.t_start, chunk.t_end)

    def add_read(self, n: int, chunk_start: float | None, chunk_end: float) -> None:
        """A read of `n` bytes that ended at `chunk_end` (first byte at `chunk_start`, if
        the source knows it)."""
        start = self.offset
        if chunk_start is not None:
            t_start = chunk_start
        else:
            t_start = chunk_end - n * self.char
            if self.last_end is not None and t_start < self.last_end:
                if t_start < self.last_end - self.slack:
                    # the bytes need longer on the wire than the stamps leave them
                    self.too_fast += 1
                    if self.first_too_fast is None:
                        self.first_too_fast = chunk_end
                t_start = self.last_end
        gap = float("inf") if self.last_end is None else t_start - self.last_end
        if t_start > chunk_end:
            t_start = chunk_end
        self.spans.append(_Span(start, start + n, t_start, chunk_end, gap))
        self.starts.append(start)
        self.cur_start = start
        self.cur_t0 = t_start
        self.cur_rate = (chunk_end - t_start) / n if n else 0.0
        if gap >= self.t35:
            self.boundaries.append(start)
        self.offset += n
        self.last_end = chunk_end

    def mark_error(self) -> None:
        """The last byte read had a framing or parity error."""
        if self.offset:
            self.line_errors.add(self.offset - 1)

    def _span(self, pos: int) -> _Span:
        k = bisect_right(self.starts, pos) - 1
        return self.spans[k if k >= 0 else 0]

    def start_time(self, pos: int) -> float:
        s = self._span(pos)
        n = s.end - s.start
        return s.t_start + (pos - s.start) * (s.t_end - s.t_start) / n if n else s.t_start

    def end_time(self, pos: int) -> float:
        """End of the byte at `pos`."""
        s = self._span(pos)
        n = s.end - s.start
        return s.t_start + (pos + 1 - s.start) * (s.t_end - s.t_start) / n if n else s.t_end

    def gap_before(self, pos: int) -> float:
        """Silence before the byte at `pos` (0 inside a chunk, unless each byte is a chunk)."""
        s = self._span(pos)
        return s.gap_before if pos == s.start else 0.0

    def is_boundary(self, pos: int) -> bool:
        b = self.boundaries
        i = bisect_left(b, pos)
        return i < len(b) and b[i] == pos

    def next_boundary(self, pos: int) -> int | None:
        b = self.boundaries
        i = bisect_right(b, pos)
        return b[i] if i < len(b) else None

    def forget_before(self, pos: int) -> None:
        """Drop what lies before stream offset `pos` (the framer will not look back)."""
        b = self.boundaries
        i = bisect_left(b, pos)
        if i:
            del b[:i]
        k = bisect_right(self.starts, pos) - 1  # keep the chunk holding `pos`
        if k > 0:
            del self.spans[:k]
            del self.starts[:k]
        if self.line_errors:
            self.line_errors.difference_update([p for p in self.line_errors if p < pos])

    def inside_gap(self, start: int, end: int) -> bool:
        """Whether silence longer than t1.5 interrupts the bytes start..end-1."""
        for span in self.spans:
            if span.start >= end:
                break
            if start < span.start < end and span.gap_before > self.t15:
                return True
        return False

    def has_line_error(self, start: int, end: int) -> bool:
        errors = self.line_errors
        if not errors:
            return False
        hit = any(p in errors for p in range(start, end))
        errors.difference_update([p for p in errors if p < end])
        return hit


class _Framer:
    """What both framers share: where their bytes go, their timing, their length rules.

    The bytes are kept in `out`'s stream for the channel; rows refer to them by offset.
    Feed chunks in order; call finish() at the end.
    """

    def __init__(
        self,
        line: LineSettings,
        out: FrameStore,
        *,
        channel: int = 0,
        direction: Direction = Direction.UNKNOWN,
        exact_timing: bool = False,
        functions: Mapping[int, FunctionSpec] = FUNCTIONS,
    ) -> None:
        self.line = line
        self.out = out
        self.stream = out.stream(channel)
        self.channel = channel
        self.direction = direction
        self.timeline = _Timeline(line, exact_timing)
        self.pos = len(self.stream)  # offset of the next undecided byte
        self.timeline.offset = self.pos
        self.rules = compile_rules(direction, functions)
        self.pair_inline = False  # rows are paired as they are framed (RTU fast path)
        self.pending_unit = -1  # the last request, awaiting its answer
        self.pending_fc = -1
        self.timeout = float("inf")  # the response timeout (the pipeline sets it)
        self.pending_echo = -1  # what its echo repeats of it (lengths.echo_key)
        # before the timeout's end, how long only a frame that repeats the request is its
        # echo: the stamps' resolution, by which a wait may be off (the pipeline sets it)
        self.echo_band = 0.0
        self._setup(functions)

    def _setup(self, functions: Mapping[int, FunctionSpec]) -> None:
        """What a framer of one mode keeps besides the shared state."""

    def feed(self, chunk: Chunk) -> None:
        if not chunk.data:
            return
        self.timeline.add(chunk)
        self.stream += chunk.data
        self._scan(final=False)

    def feed_reads(self, reads: Reads) -> None:
        """A batch of reads: framed read by read, exactly as `feed` would frame each."""
        for chunk in reads.split():
            self.feed(chunk)

    def finish(self) -> None:
        self._scan(final=True)

    def decided(self) -> int:
        """The stream offset of the first byte not yet decided (a frame not complete, or
        noise under way); the stream's length when every byte given is in a row. A
        source's event waits for the bytes before it to be decided (see Pipeline)."""
        return self.pos

    def undecided(self) -> bool:
        return self.decided() < len(self.stream)

    def settled(self) -> bool:
        """Whether every byte given has been decided and no answer it predicted is
        awaited: the next row owes nothing to the bytes before (see `rebase`). Where the
        pairer pairs the rows (several channels: `pair_inline` false), the answer a
        request predicts comes on another channel as often as not (one port or
        connection a direction), and the pairer says whether it is awaited: what the
        framer predicts of it is no offset, and carries over."""
        decided = self.pos == len(self.stream) == self.timeline.offset
        return decided and (self.pending_unit < 0 or not self.pair_inline)

    def rebase(self) -> None:
        """A settled framer's stream offsets from 0 again, its stream about to be emptied
        (a headless live capture's next segment, `sniffer.session.session.Session.new_segment`):
        what it knows of time (the last read's end, the line's resolution) stays."""
        self.pos = 0
        timeline = self.timeline
        timeline.offset = timeline.cur_start = 0
        timeline.spans.clear()
        timeline.starts.clear()
        timeline.boundaries.clear()
        timeline.line_errors.clear()

    def line_error(self) -> None:
        """The source says the last byte fed came with a framing or parity error: the
        frame or noise span that ends up holding it is flagged."""
        self.timeline.mark_error()

    def _scan(self, final: bool) -> None:
        raise NotImplementedError


def _compiled_scan(
    framer: RtuFramer,
    fast: Any,
    buf: bytearray,
    final: bool,
    end: int,
    reads: Reads | None,
    k: int,
    prev: int,
    base: int,
) -> tuple[bool, int, int, int]:
    """Run the compiled fast paths (`sniffer._core.rtu_scan`): from `framer.pos` to
    `end`, or over the reads of the batch from read `k` on (`prev`: the end of read
    k - 1 in the batch), adding each to the timeline. What they found goes into the
    store, the pairs and the framer's and timeline's state, as the loop in
    `_scan_bytes` would have left them, the noise span it may leave under way
    (`framer.noise_start`) among them. Returns whether the slow path must decide at
    `framer.pos`, the next read, the end of the last read added, and the scan's end."""
    tl = framer.timeline
    out = framer.out
    last_end = tl.last_end
    first_too_fast = tl.first_too_fast
    # the read holding the first undecided byte (noise under way, if any), when older
    # than the newest read: a frame or noise begun there is timed by it (see rtu_scan)
    first = framer.decided()
    held = tl._span(first) if tl.spans and first < tl.cur_start else _NO_SPAN
    if reads is not None:
        ends, t_starts, t_ends = reads.ends, reads.t_starts, reads.t_ends
    else:
        ends, t_starts, t_ends = _NO_READS
    (
        slow,
        pos,
        k,
        prev,
        end,
        framer.pending_unit,
        framer.pending_fc,
        framer.pending_len,
        framer.pending_deadline,
        framer.pending_row,
        _row,
        offsets,
        lengths,
        times,
        time_ends,
        kinds,
        units,
        codes,
        pairs,
        tl.cur_start,
        tl.cur_t0,
        tl.cur_rate,
        tl.offset,
        last_end,
        tl.too_fast,
        first_too_fast,
        spans,
        boundaries,
        framer.noise_start,
        noise_rows,
        unit0,
        framer.pending_echo,
    ) = fast.rtu_scan(
        buf,
        framer.lengths.table_bytes,
        framer.pos,
        end,
        final,
        reads is not None,
        framer.pending_unit,
        framer.pending_fc,
        framer.pending_len,
        framer.pending_deadline,
        framer.pending_row if framer.pair_inline else -1,
        len(out.t),
        framer.timeout,
        tl.cur_start,
        tl.cur_t0,
        tl.cur_rate,
        tl.offset,
        math.nan if last_end is None else last_end,
        tl.slack,
        tl.char,
        tl.t35,
        tl.too_fast,
        math.nan if first_too_fast is None else first_too_fast,
        ends,
        t_starts,
        t_ends,
        k,
        prev,
        base,
        not tl.line_errors,  # frames begun in an earlier read, too (see rtu_scan)
        held.start,
        held.end,
        held.t_start,
        held.t_end,
        framer.lengths.rule_bytes,
        True,  # the search where the fast paths cannot decide, and noise, too
        tl.boundaries,
        framer.noise_start,
        framer.pending_echo,
        framer.echo_band,
    )
    framer.pos = pos
    framer.scan_end = end
    tl.last_end = None if math.isnan(last_end) else last_end
    tl.first_too_fast = None if math.isnan(first_too_fast) else first_too_fast
    if spans:
        tl.spans.extend([_Span(*span) for span in spans])
        tl.starts.extend([span[0] for span in spans])
        tl.boundaries.extend(boundaries)
    keep0 = True
    if noise_rows:
        # its noise rows (unit 0 in the column) leave the units seen as _emit_noise does
        framer.flush()
        keep0 = unit0 or 0 in framer.units_seen
    if offsets:
        out.offset.frombytes(offsets)
        out.length.frombytes(lengths)
        out.t.frombytes(times)
        out.t_end.frombytes(time_ends)
        out.kind.frombytes(kinds)
        out.unit.frombytes(units)
        out.fc.frombytes(codes)
    if pairs:
        framer.pairs.frombytes(pairs)
    if not keep0:
        framer.flush()
        framer.units_seen.discard(0)
    if reads is not None and len(tl.spans) > 64:
        tl.forget_before(framer.decided())
    return slow, k, prev, end


class RtuFramer(_Framer):
    """Frames one channel of RTU bytes into `out`."""

    def _setup(self, functions: Mapping[int, FunctionSpec]) -> None:
        self.noise_start = -1  # offset where the current noise span began
        # the lengths a frame may have, and the search where the fast paths cannot decide
        self.lengths = RtuLengths(self.direction, functions, self.rules, self.timeline)
        self._appenders_of: FrameStore | None = None  # the store `_appenders` write into
        self._appenders: tuple[Callable[[Any], None], ...] = ()
        self.pending_len = 0
        self.pending_deadline = INF  # see _scan_bytes
        self.pending_row = -1  # its row in `out`, when rows are paired as they are framed
        self.pair_inline = True  # off while `out` is a staging store (several channels)
        # rows the fast path paired, flat: request, answer, ... (int64, as rtu_scan gives)
        self.pairs: array[int] = array("q")
        self.units_seen: set[int] = set()
        self.last_frame_end: float | None = None
        self.scan_end = 0  # the end of the bytes the scan in progress may see

    def idle(self) -> None:
        """The line has been silent for at least t3.5: decide everything buffered."""
        self._scan(final=True)

    def decided(self) -> int:
        return self.noise_start if self.noise_start >= 0 else self.pos

    def settled(self) -> bool:
        # no noise span under way, no row of `out` waiting for its answer, no pair unrecorded
        waiting = self.pair_inline and self.pending_row >= 0
        return super().settled() and self.noise_start < 0 and not waiting and not len(self.pairs)

    def rebase(self) -> None:
        super().rebase()
        self.scan_end = 0

    # -- the scanner ---------------------------------------------------------------------

    def feed_reads(self, reads: Reads) -> None:
        """A batch of reads, joining the stream at once, each then scanned as `feed` scans
        a chunk (seeing only the bytes read so far): the rows of the reads one by one."""
        if not reads.data:
            return
        base = len(self.stream)
        self.stream += reads.data
        self._scan_bytes(self.stream, False, reads, base)

    def _scan(self, final: bool) -> None:
        self._scan_bytes(self.stream, final)
        if len(self.timeline.spans) > 64:
            self.timeline.forget_before(self.decided())

    def _scan_bytes(
        self, buf: bytearray, final: bool, reads: Reads | None = None, base: int = 0
    ) -> None:
        """Frame from `self.pos` to the end of `buf`; or, given `reads` (a batch in `buf`
        from offset `base`), read by read, each joining the timeline and the scan stopping
        at its end as if it had been fed alone (one call spares a set-up a read)."""
        end = self.scan_end = len(buf)
        (
            request_base,
            request_count,
            answer_pos,
            answer_base,
            answer_item,
            answer_up,
            answer_byte,
        ) = self.lengths.tables
        check = crc16
        tl = self.timeline
        out = self.out
        exact = tl.exact
        # row columns, appended inline on the fast paths; whoever syncs the store next
        # (an event, a merge, a reader) completes them with this framer's channel
        out.fill_channel = self.channel
        if self._appenders_of is not out:
            self._appenders_of = out
            self._appenders = (
                out.offset.append,
                out.length.append,
                out.t.append,
                out.t_end.append,
                out.kind.append,
                out.unit.append,
                out.fc.append,
            )
        a_off, a_len, a_t, a_te, a_kind, a_unit, a_fc = self._appenders
        pairs_append = self.pairs.append
        timeout = self.timeout
        add_read = tl.add_read
        count = len(reads.ends) if reads is not None else 0
        fast = core.FAST
        k = prev = 0
        slow = True  # whether the loop below has anything to decide
        while True:  # once, or once a read of the batch
            if (
                fast is not None
                and not exact
                and (reads is not None or end - self.pos >= FAST_MIN_BYTES)
            ):
                # the compiled copy of the fast paths below, of the search where they
                # cannot decide (noise among what it finds) and, over a batch, of
                # add_read: it stops where the slow path must decide, and this loop goes
                # on from there in the current read
                if reads is not None and k == count:
                    break
                slow, k, prev, end = self._fast_scan(fast, buf, final, end, reads, k, prev, base)
                if not slow and reads is not None:
                    break  # every read is done
                # (done without a batch: the loop below has nothing more to decide, as
                # the compiled scan stopped only where it would stop too, and is skipped:
                # it would make the same search again)
            elif reads is not None:
                if k == count:
                    break
                read_end = reads.ends[k]
                t_start = reads.t_starts[k]
                add_read(read_end - prev, None if t_start != t_start else t_start, reads.t_ends[k])
                prev = read_end
                end = self.scan_end = base + read_end
                k += 1
            pos = self.pos
            # the newest chunk's timing, for the inline time estimate of frames inside it;
            # a frame begun in a read before (a read cut it) is timed as the slow path
            # times it, by the spans of the reads holding its ends, and paired as it is
            # framed all the same, unless a line error is pending (`_row` flags those)
            cur_start, cur_t0, cur_rate = tl.cur_start, tl.cur_t0, tl.cur_rate
            row = len(out.t)
            pr = self.pending_row if self.pair_inline else -1
            # rows go straight into the columns while no noise is pending and timing is
            # estimated per read (exact timing needs the slow path's checks)
            inline = self.noise_start < 0 and not exact
            # the open request, as locals: written back before every slow-path call
            pu, pf, pl = self.pending_unit, self.pending_fc, self.pending_len
            pfx = pf | 0x80
            # an echoed answer (FC 5, 6, 8, 21, 22) is the request's own bytes again: after
            # this time they are the master's retry, not the answer (inf for every other
            # code); from `band` before it, only bytes that repeat the request (`pe`) are
            # (a wait this near the timeout is told by what the frame says, not by when)
            pdl = self.pending_deadline
            pe, band = self.pending_echo, self.echo_band
            while slow and end - pos >= MIN_RTU:
                unit = buf[pos]
                fc = buf[pos + 1]
                if unit == pu and fc == pf and pdl != INF:
                    t0 = (
                        cur_t0 + (pos - cur_start) * cur_rate
                        if pos >= cur_start
                        else tl.start_time(pos)
                    )
                    if t0 > pdl or (t0 > pdl - band and not_its_echo(buf, pos, end, pe)):
                        pu = -1  # the wait is over
                # fast path 1: the answer the open request predicts, or its exception
                # (two comparisons, not `in (pf, pfx)`: that builds a tuple, which the GC counts)
                if unit == pu and (fc == pf or fc == pfx):  # noqa: SIM109
                    length = pl if fc == pf else EXCEPTION_LENGTH
                    stop = pos + length
                    if stop > end:
                        if not final:
                            break  # wait for the rest of it
                    elif (
                        inline
                        # begun in this read, or in one before it (see above)
                        and (pos >= cur_start or not tl.line_errors)
                        # a counted answer whose byte count is not the one its request
                        # asked for goes the slow way (see RtuLengths.candidates)
                        and (fc != pf or answer_pos[pf] < 0 or buf[pos + 2] == pl - 5)
                        and check(buf[pos:stop]) == 0
                    ):
                        if pos >= cur_start:
                            t0 = cur_t0 + (pos - cur_start) * cur_rate
                            t1 = t0 + length * cur_rate
                        else:
                            t0, t1 = tl.start_time(pos), tl.end_time(stop - 1)
                        a_off(pos)
                        a_len(length)
                        a_t(t0)
                        a_te(t1)
                        a_kind(2 if fc == pf else 3)  # Kind.RESPONSE, Kind.EXCEPTION
                        a_unit(unit)
                        a_fc(fc)
                        if pr >= 0:
                            pairs_append(pr)  # this row answers row pr
                            pairs_append(row)
                        pr = pu = -1
                        row += 1
                        pos = stop
                        continue
                # fast path 2: a request, when no answer is predicted for it
                elif inline:
                    length = request_base[fc]
                    if length:
                        cpos = request_count[fc]
                        if cpos:
                            if pos + cpos >= end and not final:
                                break
                            length += buf[pos + cpos] if pos + cpos < end else 0
                        stop = pos + length
                        if stop > end:
                            if not final:
                                break
                        elif (pos >= cur_start or not tl.line_errors) and check(buf[pos:stop]) == 0:
                            if pos >= cur_start:
                                rate = cur_rate
                                t0 = cur_t0 + (pos - cur_start) * rate
                                t1 = t0 + length * rate
                            else:  # begun in a read before (see above)
                                rate = tl.char
                                t0, t1 = tl.start_time(pos), tl.end_time(stop - 1)
                            a_off(pos)
                            a_len(length)
                            a_t(t0)
                            a_te(t1)
                            a_kind(1)  # Kind.REQUEST
                            a_unit(unit)
                            a_fc(fc)
                            pr = pu = -1
                            pdl = INF
                            pe = -1
                            if unit:  # a broadcast gets no answer
                                pr = row
                                ap = answer_pos[fc]
                                if ap >= 0:
                                    q = buf[pos + ap] << 8 | buf[pos + ap + 1]
                                    pl = (
                                        answer_base[fc]
                                        + (q * answer_item[fc] + answer_up[fc]) // answer_byte[fc]
                                    )
                                    pu, pf, pfx = unit, fc, fc | 0x80
                                elif ap == FIXED:
                                    pu, pf, pfx, pl = unit, fc, fc | 0x80, answer_base[fc]
                                elif ap == ECHO:
                                    pu, pf, pfx, pl = unit, fc, fc | 0x80, length
                                    pdl = t0 + length * rate + timeout
                                    pe = echo_key(buf, pos, fc)
                                elif ap == WALKED:
                                    walked = self.lengths.predict(buf, pos, length, fc)
                                    if walked is not None:
                                        pu, pf, pfx, pl = unit, fc, fc | 0x80, walked
                                if pl > MAX_RTU:
                                    pu = -1
                            row += 1
                            pos = stop
                            continue
                self.pending_unit, self.pending_fc, self.pending_len = pu, pf, pl
                self.pending_row = pr
                self.pending_deadline = pdl
                self.pending_echo = pe
                found, kind, waiting = self.lengths.candidates(
                    buf, pos, end, unit, fc, final, pu, pf, pl, pdl, band, pe
                )
                if not found and waiting:
                    break
                if not found:
                    found, kind, waiting = self.lengths.silence_framed(buf, pos, end, fc, final)
                    if waiting:
                        break
                if not found:
                    if self.noise_start < 0:
                        self.noise_start = pos
                        inline = False
                    pos += 1
                    continue
                if self.noise_start >= 0:
                    self._emit_noise(self.noise_start, pos)
                    self.noise_start = -1
                self._emit_frame(buf, pos, found, kind)
                pu, pf, pl = self.pending_unit, self.pending_fc, self.pending_len
                pfx = pf | 0x80
                pdl = self.pending_deadline
                pe = self.pending_echo
                pr = self.pending_row
                row = len(out.t)
                inline = not exact
                pos += found
            self.pending_unit, self.pending_fc, self.pending_len = pu, pf, pl
            self.pending_row = pr
            self.pending_deadline = pdl
            self.pending_echo = pe
            if final:
                if end > pos and self.noise_start < 0:
                    self.noise_start = pos
                if self.noise_start >= 0:
                    self._emit_noise(self.noise_start, end)
                    self.noise_start = -1
                pos = end
            self.pos = pos
            if reads is None:
                break
            if len(tl.spans) > 64:
                tl.forget_before(self.decided())

    # the compiled fast paths over the bytes or reads (see `_compiled_scan`)
    _fast_scan = _compiled_scan

    def flush(self) -> None:
        """Complete the rows the fast path appended and record the pairs it found."""
        out = self.out
        out.fill_channel = self.channel
        if len(out.flags) < len(out.t):
            _add_units(self.units_seen, out.unit[len(out.flags) :].tobytes())
        out.sync()
        if self.pairs:
            if self.pair_inline:
                out.pair_rows(self.pairs)
            del self.pairs[:]

    # -- output (the slow path) ----------------------------------------------------------

    def _emit_frame(self, buf: bytearray, pos: int, length: int, kind: int) -> None:
        unit = buf[pos]
        fc = buf[pos + 1] & 0x7F
        flags = 0
        if kind == Kind.UNKNOWN:
            flags |= Flag.SILENCE_FRAMED
        if kind in (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION):
            self.pending_row = -1  # pairing of slow-path rows is left to the Pairer
        if kind == Kind.REQUEST:
            self.pending_unit = -1
            self.pending_deadline = INF
            self.pending_echo = -1
            predicted = self.lengths.predict(buf, pos, length, fc) if unit != 0 else None
            if predicted is not None and MIN_RTU <= predicted <= MAX_RTU:
                self.pending_unit, self.pending_fc, self.pending_len = unit, fc, predicted
                if self.lengths.answer_pos[fc] == ECHO:  # from its start, as the fast path
                    start = self.timeline.start_time(pos)
                    self.pending_deadline = start + length * self.timeline.char + self.timeout
                    self.pending_echo = echo_key(buf, pos, fc)
        elif kind in (Kind.RESPONSE, Kind.EXCEPTION) and unit == self.pending_unit:
            self.pending_unit = -1
        self.units_seen.add(unit)
        self._row(pos, pos + length, kind, flags)

    def _emit_noise(self, start: int, end: int) -> None:
        """Bytes no frame claimed. A stretch that has the exact length of a known frame
        from a known unit is a frame whose CRC is wrong; with exact timing, silence splits
        the rest into frames with bad checks and noise."""
        self.flush()  # units the fast path saw count as known
        tl = self.timeline
        while start < end:
            stop = min(end, start + MAX_NOISE)
            if tl.exact:
                nxt = tl.next_boundary(start)
                if nxt is not None and start < nxt < stop:
                    stop = nxt
            length = stop - start
            kind = int(Kind.NOISE)
            flags = 0
            if length >= MIN_RTU and self._plausible_frame(start, length):
                kind = self._kind_of(start)
                flags = Flag.CHECK_BAD
            self._row(start, stop, kind, flags)
            start = stop

    def _plausible_frame(self, start: int, length: int) -> bool:
        buf = self.stream
        unit = buf[start]
        if unit not in self.units_seen:
            return False
        if self.timeline.exact and self.timeline.gap_before(start) >= self.line.t35:
            return True
        fc = buf[start + 1]
        predicted = EXCEPTION_LENGTH if fc & 0x80 else self.pending_len
        if unit == self.pending_unit and (fc & 0x7F) == self.pending_fc and length == predicted:
            return True
        # the bytes seen so far, as when each read came alone (see feed_reads)
        return any(rule.length(buf, start, self.scan_end) == length for rule, _ in self.rules[fc])

    def _kind_of(self, start: int) -> int:
        fc = self.stream[start + 1]
        if fc & 0x80:
            return int(Kind.EXCEPTION)
        if self.stream[start] == self.pending_unit and fc == self.pending_fc:
            return int(Kind.RESPONSE)
        kinds = {kind for _, kind in self.rules[fc]}
        if int(Kind.REQUEST) in kinds:
            return int(Kind.REQUEST)
        if kinds:
            return int(Kind.RESPONSE)
        return int(Kind.UNKNOWN)

    def _row(self, start: int, end: int, kind: int, flags: int) -> None:
        tl = self.timeline
        t0 = tl.start_time(start)
        t1 = tl.end_time(end - 1)
        if tl.exact and kind != Kind.NOISE:
            if tl.inside_gap(start, end):
                flags |= Flag.GAP_INSIDE
            if self.last_frame_end is not None and tl.gap_before(start) < tl.t35:
                flags |= Flag.SHORT_SILENCE
        if tl.has_line_error(start, end):
            flags |= Flag.LINE_ERROR
        if kind != Kind.NOISE:
            self.last_frame_end = t1
        self.flush()
        self.out.add_row(self.channel, start, end - start, t0, t1, kind, flags)


def _add_units(seen: set[int], units: bytes) -> None:
    """`seen.update(units)`, in passes over the bytes rather than a set insertion a row:
    the units already seen are struck out at once, then each new one found (a bus has
    few), so a batch of rows from known units costs one `translate`."""
    rest = units.translate(None, bytes(seen))
    while rest:
        unit = rest[0]
        seen.add(unit)
        rest = rest.translate(None, bytes((unit,)))


# the read the compiled fast paths get when no older read holds the scan's position
_NO_SPAN = _Span(0, 0, 0.0, 0.0, 0.0)
# the empty batch the compiled fast paths get when there is none
_NO_READS: tuple[array[int], array[float], array[float]] = (array("q"), array("d"), array("d"))


class AsciiFramer(_Framer):
    """Frames one channel of Modbus ASCII: ':' opens a frame (and aborts an open one),
    CR LF closes it, the LRC is checked. Everything outside frames is noise.

    A vendor's start character (`dissectors.envelope.ascii.VENDOR_STARTS`: ABL's `>`)
    opens a frame too, flagged `VENDOR_START`, but only where a frame's characters
    follow it: at least unit, function code and LRC in hex digits, then CR LF (or LF, or
    a ':' that aborts it, or the end of the capture). Anywhere else it is a byte of
    noise, so noise holding a `>` stays noise. Inside an open frame only ':' aborts, as
    the standard says."""

    def _setup(self, functions: Mapping[int, FunctionSpec]) -> None:
        self.open = -1  # offset of the ':' of an open frame
        self.answer_rules = {
            code: spec.answer for code, spec in functions.items() if spec.answer is not None
        }
        self.pending_len = -1  # the open request's answer body length (-1: not known)
        self.pending_end = 0.0  # when the open request ended

    def decided(self) -> int:
        return self.open if self.open >= 0 else self.pos  # (a frame opens before pos)

    def settled(self) -> bool:
        return super().settled() and self.open < 0  # no frame under way

    def idle(self) -> None:
        """ASCII allows 1 s between characters: idleness alone does not close a frame."""

    def flush(self) -> None:
        """Rows are complete as they are written: nothing to do."""

    def _scan(self, final: bool) -> None:
        buf = self.stream
        end = len(buf)
        pos = self.pos
        while pos < end:
            if self.open < 0:
                pos, more = self._outside(buf, pos, end, final)
                if not more:
                    break
                continue
            nl = buf.find(b"\n", pos)
            colon = buf.find(b":", pos)
            limit = self.open + MAX_ASCII
            if colon >= 0 and (nl < 0 or colon < nl) and colon <= limit:
                self._close(self.open, colon, Flag.ABORTED)
                self.open = colon
                pos = colon + 1
                continue
            if 0 <= nl < limit:
                self._close(self.open, nl + 1, Flag.NONE)
                self.open = -1
                pos = nl + 1
                continue
            if end >= limit:
                self._close(self.open, limit, Flag.TOO_LONG)
                self.open = -1
                pos = limit
                continue
            pos = end
        if final and self.open >= 0:
            self._close(self.open, end, Flag.UNTERMINATED)
            self.open = -1
        self.pos = pos
        self.timeline.forget_before(self.decided())

    def _outside(self, buf: bytearray, pos: int, end: int, final: bool) -> tuple[int, bool]:
        """The bytes from `pos`, outside any frame: noise up to the next start character
        that opens a frame, and that frame opened (':') or, a vendor's, closed. Returns
        where the scan goes on and whether it goes on now (not: it waits for more bytes,
        or has reached the end)."""
        search = pos
        while True:
            found = _STARTS.search(buf, search, end)
            if found is None:
                self._noise(pos, end)
                return end, False
            start = found.start()
            if buf[start] == START:
                self._noise(pos, start)
                self.open = start
                return start + 1, True
            verdict = self._vendor_frame(buf, start, end, final)
            if verdict is None:  # a byte of noise that happens to be a start character
                search = start + 1
                continue
            self._noise(pos, start)
            if verdict == _WAIT:
                return start, False  # decided when more bytes come
            stop, flags = verdict
            self._close(start, stop, flags)
            return stop, True

    def _vendor_frame(
        self, buf: bytearray, start: int, end: int, final: bool
    ) -> tuple[int, int] | None:
        """Whether the vendor start character at `start` opens a frame: (its end, its
        flags) when it does, None when it is noise, `_WAIT` while the bytes so far cannot
        tell. A frame is the start, an even number of hex digits (at least unit, function
        code and LRC), an optional CR, then LF; cut by ':' it is aborted, by the end of
        the capture unterminated, as a ':' frame would be."""
        limit = start + MAX_ASCII  # a frame's characters end before this, LF included
        run = _HEX_RUN.match(buf, start + 1, min(end, limit))
        digits = run.end() if run is not None else start + 1
        count = digits - start - 1
        shaped = count >= _MIN_DIGITS and count % 2 == 0
        at = digits + 1 if digits < end and buf[digits] == _CR else digits
        if at >= limit:
            return None  # longer than any frame
        if at >= end:
            if not final:
                return _WAIT
            return (end, int(Flag.UNTERMINATED)) if shaped else None
        if not shaped:
            return None
        if buf[at] == _LF:
            return at + 1, int(Flag.NONE)
        if buf[at] == START:
            return at, int(Flag.ABORTED)
        return None

    def _noise(self, start: int, end: int) -> None:
        for piece in range(start, end, MAX_NOISE):
            self._row(piece, min(end, piece + MAX_NOISE), int(Kind.NOISE), int(Flag.ASCII))

    def _close(self, start: int, end: int, flags: int) -> None:
        raw = bytes(self.stream[start:end])
        flags |= Flag.ASCII
        if raw[0] != START:
            flags |= Flag.VENDOR_START
        if raw.endswith(b"\n") and not raw.endswith(b"\r\n"):
            flags |= Flag.NO_CR
        body = ascii_body(raw)
        kind = int(Kind.UNKNOWN)
        if body is None:
            flags |= Flag.NON_HEX
        elif len(body) < 3:
            flags |= Flag.CHECK_BAD
        else:
            if lrc(body[:-1]) != body[-1]:
                flags |= Flag.CHECK_BAD
            tl = self.timeline
            kind = self._kind(body, tl.start_time(start), tl.end_time(end - 1))
        if self._long_gap(start, end):
            flags |= Flag.LONG_GAP
        self._row(start, end, kind, flags)

    def _long_gap(self, start: int, end: int) -> bool:
        for span in self.timeline.spans:
            if span.start >= end:
                break
            if start < span.start < end and span.gap_before > 1.0:
                return True
        return False

    def _kind(self, body: bytes, t0: float, t1: float) -> int:
        """Request, answer or exception, by the open request and the length rules. An
        answer must have the length its request predicts (a repeated request from the
        same master is a retry, not its answer), and the wait ends with the response
        timeout."""
        unit, fc = body[0], body[1]
        length = len(body) - 1 + 2  # as if it were an RTU frame with its CRC
        if self.pending_unit >= 0:
            waited = t0 - self.pending_end
            if waited > self.timeout or (
                waited > self.timeout - self.echo_band
                and (unit, fc) == (self.pending_unit, self.pending_fc)
                and not_its_echo(body, 0, len(body), self.pending_echo)
            ):
                self.pending_unit = -1  # the open request timed out (see RtuFramer)
        awaited = unit == self.pending_unit and (fc & 0x7F) == self.pending_fc
        if fc & 0x80:
            kind = int(Kind.EXCEPTION)
        elif awaited and self.pending_len in (-1, length):
            kind = int(Kind.RESPONSE)
        else:
            kind = int(Kind.UNKNOWN)
            matches = set()
            for rule, rkind in self.rules[fc]:
                if rule.length(body, 0, len(body)) == length:
                    matches.add(rkind)
            if int(Kind.REQUEST) in matches:
                kind = int(Kind.REQUEST)
            elif matches:
                kind = int(Kind.RESPONSE)
        if kind == Kind.REQUEST:
            self.pending_unit, self.pending_fc = (unit, fc) if unit else (-1, -1)
            self.pending_len = self._answer_length(body, fc)
            self.pending_end = t1
            self.pending_echo = echo_key(body, 0, fc)
        elif awaited:
            self.pending_unit = -1
        return kind

    def _answer_length(self, body: bytes, fc: int) -> int:
        """The RTU length of the answer a request predicts (-1 when no rule says)."""
        rule = self.answer_rules.get(fc)
        if rule is None:
            return -1
        predicted = rule.length(body[:-1] + b"\0\0")  # the request as an RTU frame
        return predicted if predicted is not None else -1

    def _row(self, start: int, end: int, kind: int, flags: int) -> None:
        tl = self.timeline
        if tl.has_line_error(start, end):
            flags |= Flag.LINE_ERROR
        t0 = tl.start_time(start)
        t1 = tl.end_time(end - 1)
        self.out.add_row(self.channel, start, end - start, t0, t1, kind, flags)


Framer = RtuFramer | AsciiFramer

# what the ASCII framer looks for: the first start character (':' or a vendor's), a run
# of hex digits, the line's end
_STARTS = re.compile(b"[" + re.escape(bytes([START, *VENDOR_STARTS])) + b"]")
_HEX_RUN = re.compile(rb"[0-9A-Fa-f]+")
_CR, _LF = 0x0D, 0x0A
_MIN_DIGITS = 6  # unit, function code and LRC: what a vendor's start must be followed by
_WAIT: tuple[int, int] = (-1, -1)  # `_vendor_frame`'s answer while the bytes cannot tell
_ASCII_CHARACTERS = frozenset(b"0123456789ABCDEFabcdef\r\n" + bytes([START, *VENDOR_STARTS]))


def looks_ascii(sample: bytes) -> bool | None:
    """Whether traffic is Modbus ASCII: True, False, or None when there is too little.
    A vendor's start counts as a ':' does (a port that hears only ABL's answers sees
    nothing but `>` frames)."""
    if len(sample) < 16:
        return None
    good = sum(1 for b in sample if b in _ASCII_CHARACTERS)
    starts = _STARTS.search(sample) is not None
    return starts and b"\n" in sample and good >= 0.95 * len(sample)
