"""Provides the pipeline: chunks from any source in, framed and paired frames in a store out.

One framer per channel (a port or probe per direction is framed on its own); rows of
several channels are merged by time before they reach the store. The same pipeline
serves replay and live capture, so a recording frames exactly as the line did.

What a source knows besides its bytes comes with it (`SourceInfo`):
- `labels`: only CERTAIN labels (a port or probe per direction) narrow what a channel's
  framer looks for. Any other label (a logger's sends and receives, EPB flags, dump
  markers) is a hint: the channel is framed as a passive tap would frame it, and each
  frame's direction follows from its content and order. Frames whose content contradicts
  their label are counted and reported once (`source_notes`), never refused.
- `stamps`: frame-start stamps are turned into chunk start times here; every row time
  then means what it does for any source. The store is told the stamps' meaning and
  resolution, so that latencies are shown only as far as they can be measured
  (`pairing.measure`). Stamps that leave the bytes less time than the line speed needs
  (print times, a wrong baud rate) are counted and reported once.
"""

from __future__ import annotations

from array import array
from bisect import bisect_right
from collections.abc import Iterable
from dataclasses import dataclass, field
from itertools import repeat
from operator import add

from dissectors.functions import FUNCTIONS, Registry
from sniffer import core
from sniffer.framing.pairing import (
    INF,
    Pairer,
    StampClock,
    default_timeout,
    timing_note,
)
from sniffer.framing.serial import AsciiFramer, Framer, RtuFramer, looks_ascii
from sniffer.framing.store import FrameStore
from sniffer.model import Chunk, Direction, Labels, LineSettings, Stamp
from sniffer.sources.reads import Reads
from sniffer.vocab import Flag, Kind

CAPTURE_COMPLETE = "capture complete"  # a source's last word: when the capture ended
BYTE_ERRORS = ("framing error", "parity error")  # events about the byte before them
MERGE_SLACK = 1.0  # seconds a channel's rows are held back so that others can catch up
LIVE_MERGE_SLACK = 0.05  # live ports share one clock: a little is enough
# Batches of reads (a reader's, at most MAX_BATCH_SPAN each) held and framed together,
# up to this many bytes: the framer's cost per call, paid once for many (what is left
# per batch is the reader's)
HOLD_BYTES = 1 << 19
# ... and while a windowed replay waits for a settled moment to drop its rows at
# (`sniffer.session.session.Session.ingest`), this many: see `Pipeline.hold_bytes`
SETTLING_HOLD_BYTES = 1 << 15


@dataclass
class _Channel:
    number: int
    direction: Direction
    framer: Framer | None = None
    staging: FrameStore | None = None  # rows waiting to be merged (several channels)
    read: int = 0  # next staging row to merge
    held: list[Chunk] | None = None  # chunks kept while the mode is being detected
    last_t: float = float("-inf")
    # the direction labels of a hinted channel: stream offsets where the label changes
    hint_at: list[int] | None = None
    hint_dir: list[Direction] | None = None
    fed: int = 0  # stream offset after the bytes fed so far (held ones included)
    # for each staging row, the number of the chunk fed when it appeared: rows of one
    # time on several channels are merged in that order, the order of the source
    born: list[int] = field(default_factory=list)
    # a source's events that came while the framer held bytes undecided, each with the
    # framer's stream length then: stored once the bytes before it are rows, after them
    # (a log's error line after the frame it is about)
    events: list[tuple[Chunk, int]] = field(default_factory=list)


class Pipeline:
    """Feeds chunks through framing, merging and pairing into `store`."""

    def __init__(
        self,
        line: LineSettings,
        store: FrameStore | None = None,
        *,
        exact_timing: bool = False,
        timeout: float | None = None,
        registry: Registry | None = None,
        merge_slack: float = MERGE_SLACK,
        labels: Labels = Labels.CERTAIN,
        stamps: Stamp = Stamp.READ_END,
        resolution: float = 0.0,
    ) -> None:
        self.line = line
        self.labels = labels
        self.stamps = stamps
        self.merge_slack = merge_slack
        self.store = store if store is not None else FrameStore()
        # what the stamps are worth, measured from the first of them as they come
        # (sniffer.framing.pairing.StampClock); the store keeps the resolution
        self.clock = StampClock(stamps, resolution)
        self.store.stamps = stamps
        self.store.resolution = self.clock.resolution
        self._frame_starts = stamps == Stamp.FRAME_START
        self.contradictions = 0  # frames whose content contradicts their label
        self.first_contradiction = -1  # the row of the first
        self._hint_checked = 0  # rows of the store checked against their labels
        self.exact_timing = exact_timing
        # the public registry, or one with the vendor codes of the devices on this bus
        self.registry: Registry = registry if registry is not None else FUNCTIONS
        if timeout is None:
            timeout = default_timeout(line)
        if stamps == Stamp.NONE:
            timeout = float("inf")  # no time to measure a wait by: only order counts
        # (a clock of resolution r puts up to r between stamps of one instant: only a wait
        # longer than the timeout by r shows a timeout, `Pairer.judged`, as the framer's
        # wait for an echo; the timeout itself stays what the master waits, which the
        # timing line, the doctor and `replay --mqtt` name)
        self.pairer = Pairer(self.store, timeout, self.registry.answered_broadcasts)
        self.mode: str | None = None if line.mode == "auto" else line.mode
        self.channels: dict[int, _Channel] = {}
        self._sample = bytearray()
        self._bus_end: float | None = None  # end of the last frame merged, any channel
        # batches of reads of one channel not yet handed to its framer (see HOLD_BYTES);
        # whatever looks at the framers or the store frames them first (`_frame_held`)
        self._held: list[Reads] = []
        self._held_bytes = 0
        # how many bytes are held before they are framed (None: HOLD_BYTES). A store
        # is dropped only where the framers stand settled at the end of what they were
        # given (`Session.settled`): a held 512 KiB ends wherever its last read ends,
        # mid-frame as often as not in 16 ms reads of a slow line, so the replay that
        # waits for a settled moment looks at the end of smaller holds
        self.hold_bytes: int | None = None
        self._chunks_fed = 0  # chunks fed so far: the order rows of one time merge in

    @property
    def multi(self) -> bool:
        return len(self.channels) > 1

    # -- input ---------------------------------------------------------------------------

    def feed(self, chunk: Chunk) -> None:
        self._chunks_fed += 1
        if isinstance(chunk, Reads):
            self._feed_reads(chunk)
            return
        if self._held:
            self._frame_held()
        if self.clock.learning:
            self.note_stamps(chunk)
        if self._frame_starts and chunk.data and chunk.t_start is None:
            # the stamp is when the frame began: it ends when its bytes are through
            end = chunk.t_end + len(chunk.data) * self.line.char_time
            chunk = Chunk(chunk.data, end, chunk.t_end, chunk.channel, chunk.direction)
        ch = self.channels.get(chunk.channel)
        if ch is None:
            ch = self._add_channel(chunk.channel, chunk.direction)
        if chunk.event == CAPTURE_COMPLETE and not chunk.data:
            # the recorder stopped here: requests still open by then have timed out
            self.pairer.end_time = max(self.pairer.end_time, chunk.t_end)
            return
        if chunk.event and not chunk.data:
            if ch.framer is None and ch.held:
                # the bytes before it wait for the mode to be known: so does the event,
                # to keep its place after them (a log's error line after its frame)
                ch.held.append(chunk)
                return
            self._event(ch, chunk)
            self._release(final=False)
            return
        hints = ch.hint_dir
        if hints is not None and ch.hint_at is not None and hints[-1:] != [chunk.direction]:
            ch.hint_at.append(ch.fed)
            hints.append(chunk.direction)
        ch.fed += len(chunk.data)
        if ch.framer is None and not self._detect(ch, chunk):
            return
        assert ch.framer is not None
        ch.framer.feed(chunk)
        ch.last_t = chunk.t_end
        if ch.events:
            self._settle_events(ch)
        if self.multi:
            self._release(final=False)

    def _event(self, ch: _Channel, chunk: Chunk) -> None:
        """A source's event (no bytes) on channel `ch`: stored now, or once the bytes fed
        before it are rows (`_settle_events`), so that it comes after them as it came
        after them from the source, whatever the framer needed to decide them."""
        if chunk.event in BYTE_ERRORS and self.exact_timing and ch.framer is not None:
            ch.framer.line_error()  # exact sources report it right after its byte
        framer = ch.framer
        if ch.events or (framer is not None and framer.undecided()):
            ch.events.append((chunk, 0 if framer is None else len(framer.stream)))
        else:
            self._add_event(ch, chunk)

    def _settle_events(self, ch: _Channel) -> None:
        """Store the events waiting on `ch` whose bytes before them are all decided."""
        events, framer = ch.events, ch.framer
        decided = framer.decided() if framer is not None else 0
        done = 0
        while done < len(events) and (framer is None or events[done][1] <= decided):
            self._add_event(ch, events[done][0])
            done += 1
        del events[:done]

    def _add_event(self, ch: _Channel, chunk: Chunk) -> None:
        if ch.framer is not None:
            # the framer's rows first: what it tells of them (the units it saw, its
            # pairs) before the event's row completes them in the store
            ch.framer.flush()
        text = chunk.event + (f": {chunk.note}" if chunk.note else "")
        (ch.staging if ch.staging is not None else self.store).add_event(
            chunk.t_end, text, chunk.channel
        )
        ch.last_t = max(ch.last_t, chunk.t_end)

    def _feed_reads(self, reads: Reads) -> None:
        """A batch of reads of one channel (see `sniffer.sources.reads`): handed to the
        framer in one call where that frames it as the reads one by one would; else read
        by read."""
        ch = self.channels.get(reads.channel)
        if (
            ch is None
            or ch.framer is None
            or self.multi
            or self._frame_starts
            or (ch.hint_dir is not None and ch.hint_dir[-1:] != [reads.direction])
        ):
            if self._held:
                self._frame_held()
            for chunk in reads.split():
                self.feed(chunk)
            return
        if self.clock.learning:
            self.note_stamps(reads)
        ch.fed += len(reads.data)
        ch.last_t = reads.t_end
        # framed with the batches before it: the framer frames a batch read by read,
        # so the rows are the same however the reads are cut into batches
        self._held.append(reads)
        self._held_bytes += len(reads.data)
        hold = self.hold_bytes
        if self._held_bytes >= (HOLD_BYTES if hold is None else hold):
            self._frame_held()

    def _frame_held(self) -> None:
        """Hand the batches held to their channel's framer, as one batch."""
        held = self._held
        if not held:
            return
        self._held = []
        self._held_bytes = 0
        ch = self.channels[held[0].channel]
        assert ch.framer is not None
        ch.framer.feed_reads(held[0] if len(held) == 1 else _joined(held))
        if ch.events:
            self._settle_events(ch)

    def note_stamps(self, chunk: Chunk) -> None:
        """The clock notes the chunk's stamp (each read's, for a batch: as it would read
        by read) while it learns, and measures again when that is due."""
        clock = self.clock
        if isinstance(chunk, Reads):
            for t in chunk.t_ends:
                clock.note(t)
                if not clock.learning:
                    break  # measured enough here, as it would be read by read
        elif chunk.data and clock.learning:
            clock.note(chunk.t_end)
        if clock.due:
            self.measure_stamps()

    def feed_all(self, chunks: Iterable[Chunk]) -> None:
        for chunk in chunks:
            self.feed(chunk)

    @property
    def holding(self) -> bool:
        """Batches of reads wait to be framed (`sync` frames them)."""
        return bool(self._held)

    def sync(self) -> None:
        """Bring the store up to date: complete the framers' rows, merge channels, pair.
        Readers of the store call this (Session.refresh does) before they look."""
        self._frame_held()
        self._release(final=False)
        self.measure_stamps()
        self.pairer.update()
        self._check_hints()

    def idle(self, now: float) -> None:
        """Live sources call this when the line has been quiet: bytes buffered in the
        framers are decided, and overdue requests time out."""
        self._frame_held()
        for ch in self.channels.values():
            if ch.framer is not None and now - ch.last_t >= self.line.t35:
                ch.framer.idle()
        self._release(final=False, now=now)
        self.pairer.tick(now)

    def finish(self) -> None:
        self._frame_held()
        for ch in self.channels.values():
            if ch.framer is None:
                self.mode = self.mode or "rtu"
                self._start_framer(ch)
            assert ch.framer is not None
            ch.framer.finish()
        self._release(final=True)
        self.measure_stamps()
        self.pairer.finish()
        self._check_hints()

    # -- what the source's labels and stamps turned out to be worth ----------------------

    def measure_stamps(self) -> None:
        """The stamps' resolution, measured again from those seen since (the clock's
        step, the host reads' rhythm and lateness), into the store."""
        if self.clock.update():
            self.store.resolution = self.clock.resolution
            for ch in self.channels.values():
                if isinstance(ch.framer, (RtuFramer, AsciiFramer)):  # (a serial framer)
                    self._time_framer(ch.framer)

    def _time_framer(self, framer: Framer) -> None:
        """What a serial framer takes from the stamps' resolution (the store's): stamps
        that coarse are not too close, and the wait for an answer is the timeout plus it
        (the wait the row times show as overdue), its last stretch told by an echo's
        bytes."""
        resolution = self.store.resolution
        framer.timeline.slack = max(framer.timeline.slack, resolution)
        framer.timeout = self.pairer.judged
        framer.echo_band = resolution

    def read_stamps_as(self, stamps: Stamp, reading: str) -> None:
        """Per-frame stamps turned out to mark the other end of each frame (before any
        chunk was fed): `reading` says how that was told."""
        self.stamps = self.store.stamps = self.clock.stamps = stamps
        self.clock.reading = reading
        self._frame_starts = stamps == Stamp.FRAME_START

    def _check_hints(self) -> None:
        """Compare each new frame's kind with the label of the bytes it starts in."""
        store = self.store
        n = len(store)
        if self.labels != Labels.HINT or not any(
            d != Direction.UNKNOWN for ch in self.channels.values() for d in ch.hint_dir or ()
        ):
            # nothing to check against: a passive tap labels every byte inbound (UNKNOWN),
            # and a walk over every new row for nothing would be a large share of indexing
            self._hint_checked = n
            return
        kind, channel, offset = store.kind, store.channel, store.offset
        for i in range(self._hint_checked, n):
            k = kind[i]
            if k not in (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION):
                continue
            ch = self.channels.get(channel[i])
            if ch is None or not ch.hint_at or ch.hint_dir is None:
                continue
            label = ch.hint_dir[max(0, bisect_right(ch.hint_at, offset[i]) - 1)]
            if label == Direction.UNKNOWN:
                continue
            if (label == Direction.MASTER) != (k == Kind.REQUEST):
                self.contradictions += 1
                if self.first_contradiction < 0:
                    self.first_contradiction = i
        self._hint_checked = n

    def too_fast(self) -> tuple[int, float | None]:
        """How many chunks came sooner than the line speed allows, and the first's time."""
        self._frame_held()
        count, first = 0, None
        for ch in self.channels.values():
            if ch.framer is not None:
                tl = ch.framer.timeline
                count += tl.too_fast
                if tl.first_too_fast is not None and (first is None or tl.first_too_fast < first):
                    first = tl.first_too_fast
        return count, first

    def source_notes(self) -> list[str]:
        """Warnings: what the source's labels and timestamps turned out to be worth."""
        notes: list[str] = []
        if self.contradictions:
            notes.append(
                f"direction labels: {self.contradictions} frame(s) are labelled against "
                f"their content (the first is row {self.first_contradiction}); each was "
                "taken for what its length, check and order say it is"
            )
        count, first = self.too_fast()
        if count:
            notes.append(
                f"timestamps: {count} read(s) or line(s) came sooner than "
                f"{self.line.baud} baud can carry their bytes (the first at {first:.6f}); "
                "the stamps are print times or the baud rate is wrong: latencies that "
                "depend on them are shown as unknown"
            )
        return notes

    def timing_notes(self) -> list[str]:
        """What the user should know about the times shown (not a fault of the source)."""
        if self.stamps == Stamp.NONE:
            return [
                "timing: the source has no timestamps; times are synthetic (one character "
                "time per byte) and no latency or poll period is measured"
            ]
        # coarse times are said where they are shown (a listing's first line, --stats);
        # here, once, what was measured from the stamps to say so: stamps that bound
        # nothing, a resolution coarser than the source declared, frame stamps read the
        # other way round than their format says
        clock = self.clock
        if self.store.resolution < INF and not clock.reading and not clock.measured_coarser:
            return []
        return [timing_note(self.stamps, self.store.resolution, self.pairer.timeout, clock.why())]

    # -- internals -----------------------------------------------------------------------

    def _add_channel(self, number: int, direction: Direction) -> _Channel:
        if self.labels != Labels.CERTAIN:
            # a hint never narrows framing; it is checked against the frames instead
            ch = _Channel(number, Direction.UNKNOWN)
            if self.labels == Labels.HINT:
                ch.hint_at, ch.hint_dir = [], []
        else:
            ch = _Channel(number, direction)
        ch.fed = len(self.store.streams.get(number, b""))
        self.channels[number] = ch
        if len(self.channels) == 2:
            # from now on every channel's rows wait in staging to be merged by time
            for other in self.channels.values():
                other.staging = FrameStore(self.store.streams)
                if other.framer is not None:
                    # complete the rows its fast path left in the store (their channel
                    # column) before the framer writes elsewhere
                    other.framer.flush()
                    other.framer.out = other.staging
                    other.framer.pair_inline = False
        elif len(self.channels) > 2:
            ch.staging = FrameStore(self.store.streams)
        return ch

    def _detect(self, ch: _Channel, chunk: Chunk) -> bool:
        """Start the channel's framer, once the mode is known. False while still unsure."""
        if self.mode is None:
            if ch.held is None:
                ch.held = []
            ch.held.append(chunk)
            self._sample += chunk.data
            verdict = looks_ascii(bytes(self._sample[:512]))
            if verdict is None and len(self._sample) < 64:
                return False
            self.mode = "ascii" if verdict else "rtu"
            self._start_framer(ch)
            return False
        self._start_framer(ch)
        return True

    def _start_framer(self, ch: _Channel) -> None:
        cls = AsciiFramer if self.mode == "ascii" else RtuFramer
        ch.framer = cls(
            self.line,
            ch.staging if ch.staging is not None else self.store,
            channel=ch.number,
            direction=ch.direction,
            exact_timing=self.exact_timing,
            functions=self.registry,
        )
        if isinstance(ch.framer, RtuFramer):
            ch.framer.pair_inline = ch.staging is None
        self._time_framer(ch.framer)
        held, ch.held = ch.held or [], None
        for old in held:
            if old.event and not old.data:
                self._event(ch, old)
                continue
            ch.framer.feed(old)
            ch.last_t = old.t_end
        for other in self.channels.values():
            if other is not ch and other.held:
                self._start_framer(other)

    def _release(self, final: bool, now: float | None = None) -> None:
        """Complete framed rows and, with several channels, merge those whose time has
        come. Pairing waits for sync(), idle() or finish()."""
        for ch in self.channels.values():
            if ch.framer is not None:
                ch.framer.flush()
            if ch.events:
                self._settle_events(ch)
            if ch.staging is not None and len(ch.born) < len(ch.staging):
                ch.born.extend([self._chunks_fed] * (len(ch.staging) - len(ch.born)))
        if self.multi:
            if final:
                watermark = float("inf")
            else:
                watermark = min(c.last_t for c in self.channels.values()) - self.merge_slack
                if now is not None:
                    watermark = max(watermark, now - self.merge_slack)
            self._merge(watermark)

    def _merge(self, watermark: float) -> None:
        store = self.store
        staged = [c for c in self.channels.values() if c.staging is not None]
        while True:
            best: _Channel | None = None
            best_key = (watermark, float("inf"))
            for c in staged:
                st = c.staging
                assert st is not None
                # rows of one time go in the order they appeared: a log printing whole
                # seconds gives a request and its answer one time, on two channels
                if c.read < len(st):
                    key = (st.t[c.read], c.born[c.read] if c.read < len(c.born) else 0)
                    if key[0] <= watermark and key < best_key:
                        best, best_key = c, key
            if best is None:
                break
            assert best.staging is not None
            store.copy_row(best.staging, best.read)
            best.read += 1
            if self.exact_timing:
                self._bus_silence(len(store) - 1)
        for c in staged:
            st = c.staging
            assert st is not None
            if c.read and c.read == len(st):
                c.staging = FrameStore(store.streams)
                c.born = []
                if c.framer is not None:
                    c.framer.out = c.staging
                c.read = 0

    def _bus_silence(self, row: int) -> None:
        """With one channel per direction, the silence that matters is the bus's: the
        time since the last frame on any channel (a slave answering inside t3.5)."""
        store = self.store
        kind = store.kind[row]
        if kind == Kind.NOISE or kind == Kind.EVENT:
            return
        flags = store.flags[row] & ~Flag.SHORT_SILENCE
        if self._bus_end is not None and store.t[row] - self._bus_end < self.line.t35:
            flags |= Flag.SHORT_SILENCE
        store.flags[row] = flags
        self._bus_end = store.t_end[row]


def frame_capture(
    chunks: Iterable[Chunk],
    line: LineSettings,
    *,
    exact_timing: bool = False,
    timeout: float | None = None,
) -> FrameStore:
    """Frame and pair a whole capture."""
    pipeline = Pipeline(line, exact_timing=exact_timing, timeout=timeout)
    pipeline.feed_all(chunks)
    pipeline.finish()
    return pipeline.store


__all__ = ["Pipeline", "frame_capture"]


def _joined(batches: list[Reads]) -> Reads:
    """Consecutive batches of reads of one channel as one batch (each read's end offset
    moved by the bytes of the batches before it)."""
    first, last = batches[0], batches[-1]
    ends: array[int] = array("q")
    t_starts: array[float] = array("d")
    t_ends: array[float] = array("d")
    fast = core.FAST
    if fast is not None:  # the compiled copy of the loop below: 3 C calls a batch less
        data, moved, starts, times = fast.join_reads(batches)
        ends.frombytes(moved)
        t_starts.frombytes(starts)
        t_ends.frombytes(times)
    else:
        before = 0
        for b in batches:
            ends.extend(map(add, b.ends, repeat(before)) if before else b.ends)
            t_starts.extend(b.t_starts)
            t_ends.extend(b.t_ends)
            before += len(b.data)
        data = b"".join([b.data for b in batches])
    return Reads(
        data,
        last.t_end,
        first.t_start,
        first.channel,
        first.direction,
        ends=ends,
        t_starts=t_starts,
        t_ends=t_ends,
    )
