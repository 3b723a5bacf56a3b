"""Provides a capture session: a source's chunks framed, paired, annotated and counted.

The CLI listing, the exports and the TUI all look at a capture through a Session. What
the work leaves behind (rows, statistics, annotation, warnings) is its `SessionState`
(`sniffer.session.state`), which the sidecar index (`sniffer.session.index`) writes and
reads back.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import replace
from functools import partial
from importlib import resources
from itertools import chain
from pathlib import Path
from typing import Any, Generic, TypeVar, overload

from sniffer.analysis.baud import estimate_line
from sniffer.analysis.stats import Stats
from sniffer.framing.pairing import declared_resolution, frame_reading
from sniffer.framing.pipeline import MERGE_SLACK, SETTLING_HOLD_BYTES, Pipeline
from sniffer.framing.store import FrameStore
from sniffer.framing.tcp import NetPipeline
from sniffer.meaning.annotate import Annotator, Binding
from sniffer.meaning.describe import Describer
from sniffer.model import Chunk, Labels, LineSettings, Stamp
from sniffer.session import index as sidecar
from sniffer.session.index import Writer
from sniffer.session.state import SessionState
from sniffer.sources import Capture, ReadOptions, open_capture
from sniffer.sources.reads import Reads, batching
from sniffer.vocab import Kind, Status


def _demo_file(name: str) -> Path:
    """A file of the bundled demo: package data (`sniffer/demo/`), so an installed wheel
    has it too, found through importlib.resources rather than the source tree."""
    return Path(str(resources.files("sniffer").joinpath("demo", name)))


DEMO_CAPTURE = _demo_file("demo.pcapng")
DEMO_BUS = _demo_file("demo-bus.toml")

Progress = Callable[[int, int], None]
"""progress(bytes_done, frames_so_far)."""

_T = TypeVar("_T")


class _Kept(Generic[_T]):
    """An attribute of a session held in its state (`Session.state`): read and set
    through the session as well."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    @overload
    def __get__(self, session: None, owner: type) -> _Kept[_T]: ...
    @overload
    def __get__(self, session: Session, owner: type) -> _T: ...
    def __get__(self, session: Session | None, owner: type) -> _T | _Kept[_T]:
        if session is None:
            return self
        value: _T = getattr(session.state, self.name)
        return value

    def __set__(self, session: Session, value: _T) -> None:
        setattr(session.state, self.name, value)


class Session:
    """One capture being looked at: store, pipeline, annotation, statistics, details.

    The rows and what was counted and learnt from them are in `state`; its attributes
    read (and set) as the session's own."""

    store = _Kept[FrameStore]()
    pipeline = _Kept[Pipeline]()
    annotator = _Kept[Annotator]()
    stats = _Kept[Stats]()
    warnings = _Kept[list[str]]()
    notes = _Kept[list[str]]()
    chunks = _Kept[int]()
    base = _Kept[int]()
    stream_base = _Kept[dict[int, int]]()
    frames_before = _Kept[int]()

    def __init__(
        self,
        line: LineSettings,
        *,
        bindings: Mapping[int, Binding] | None = None,
        exact_timing: bool = False,
        timeout: float | None = None,
        source: str = "",
        merge_slack: float = MERGE_SLACK,
        labels: Labels = Labels.CERTAIN,
        stamps: Stamp = Stamp.READ_END,
        resolution: float = 0.0,
        network: Mapping[int, str] | None = None,
    ) -> None:
        """`network`: the channel labels of a network capture (`SourceInfo.channels`),
        which is then framed by `NetPipeline` (Modbus TCP, RTU over TCP/UDP)."""
        self.line = line
        self.source = source
        store = FrameStore()
        annotator = Annotator(bindings or {})
        pipeline_class: type[Pipeline] = Pipeline
        extra: dict[str, Any] = {}
        if network is not None:
            pipeline_class = NetPipeline
            extra["channels"] = network
        pipeline = pipeline_class(
            line,
            store,
            exact_timing=exact_timing,
            timeout=timeout,
            registry=annotator.registry,
            merge_slack=merge_slack,
            labels=labels,
            stamps=stamps,
            resolution=resolution,
            **extra,
        )
        self.state = SessionState(store, pipeline, annotator, Stats(store))
        # what --stats says of the times shown: the timeout and the stamps' worth
        self.stats.timeout, self.stats.clock = pipeline.pairer.timeout, pipeline.clock
        self.describer = Describer(store, annotator)
        self._contradiction_placed = False  # pipeline.first_contradiction counts from 0
        self.batch_reads = True  # let readers pass runs of reads as one batch (ingest)
        # the sidecar index (sniffer.session.index): where it came from, or what to save it as
        self.indexed_from: Path | None = None
        self.indexed_to: Path | None = None  # the sidecar `ingest` wrote, if it wrote one
        self._sidecar: tuple[Path, Capture, str] | None = None

    @property
    def indexing(self) -> bool:
        """Whether `ingest` will read or write a sidecar index (see `open_session`)."""
        return self._sidecar is not None

    @property
    def mode(self) -> str:
        return self.pipeline.mode or self.line.mode

    def feed(self, chunk: Chunk) -> None:
        state = self.state
        state.pipeline.feed(chunk)
        state.chunks += len(chunk) if isinstance(chunk, Reads) else 1

    def refresh(self) -> None:
        """Bring pairing, annotation state and statistics up to date with the store."""
        self.pipeline.sync()
        self.annotator.update(self.store)
        self.stats.update()

    def idle(self, now: float) -> None:
        self.pipeline.idle(now)
        self.refresh()

    def finish(self) -> None:
        self.pipeline.finish()
        # every stamp there will be was seen: the answers counted while the clock learnt
        # are judged now, with what it measured (`Stats._unjudged`)
        self.pipeline.clock.learning = False
        self.refresh()
        self._place_contradiction()
        # what the source's labels and stamps turned out to be worth, said once
        self.warnings.extend(n for n in self.pipeline.source_notes() if n not in self.warnings)
        self.notes.extend(n for n in self.pipeline.timing_notes() if n not in self.notes)

    def settled(self) -> bool:
        """Whether the store may be dropped now (see `new_segment`): every byte read
        decided, no request waiting for its answer or its timeout (nor, on a network, a
        request that timed out for a late answer: `NetPairer.settled`), no row waiting to
        be merged, no source event waiting for the bytes before it; the caller brings the
        pairing up to date first (`pipeline.sync`), and the annotation and statistics
        before it drops the rows (`refresh`: see `Cutter.cut`)."""
        pipeline = self.pipeline
        store = self.store
        if not len(store) or not pipeline.pairer.settled():
            return False
        if pipeline.holding:  # bytes read but not framed yet
            return False
        for ch in pipeline.channels.values():
            framer = ch.framer
            if ch.held or ch.events or (framer is not None and not framer.settled()):
                return False  # (no framer and nothing held: a channel of events alone)
            if ch.staging is not None and ch.read < len(ch.staging):
                return False
        # the scan of every row last: a replay waiting for a settled moment tries often
        # (see ingest), and the framers say no at most tries
        return store.status.tobytes().find(bytes([Status.OPEN])) < 0

    def new_segment(self) -> bool:
        """Forget the rows framed so far and go on in an empty store, numbering rows on
        from where they were (`base`): what keeps a headless live capture's memory
        bounded, and a replay's (`ingest` with a window). Only at a settled moment
        (`settled`); False (nothing done) otherwise. The framers, the pairer, the
        annotation state and the statistics carry on as they are, so the rows that follow
        are those one store would have had, shifted by `base` (their offsets by
        `stream_base`). Callers must be done with the old rows (listed, exported,
        published, counted) and tell every consumer that numbers rows (see
        `sniffer.live.engine.LiveCapture.cut`)."""
        if not self.settled():
            return False
        pipeline = self.pipeline
        store = self.store
        store.sync()
        kinds = store.kind.tobytes()
        self.frames_before += len(kinds) - kinds.count(Kind.NOISE) - kinds.count(Kind.EVENT)
        for number, stream in store.streams.items():
            self.stream_base[number] = self.stream_base.get(number, 0) + len(stream)
        self._place_contradiction()
        rows = len(store)
        fresh = FrameStore(store.streams)  # the same bytearrays, emptied below
        fresh.stamps, fresh.resolution = store.stamps, store.resolution
        fresh.fill_channel = store.fill_channel
        fresh.peers, fresh.servers = store.peers, store.servers
        for ch in pipeline.channels.values():
            if ch.framer is not None:  # (none: a channel of events alone, no bytes)
                ch.framer.rebase()
                if ch.staging is None:
                    ch.framer.out = fresh
            ch.fed = 0
            if ch.hint_at is not None and ch.hint_dir:
                ch.hint_at, ch.hint_dir = [0], ch.hint_dir[-1:]
        for stream in store.streams.values():
            del stream[:]
        pipeline.store = fresh
        pipeline.pairer.rebase(fresh)
        pipeline._hint_checked = 0
        self.forget_annotation()
        self.stats.store = fresh
        self.stats.next = 0
        self.describer = Describer(fresh, self.annotator, self.describer.size)
        self.store = fresh
        self.base += rows
        return True

    def _place_contradiction(self) -> None:
        """The row a source warning names (the first frame labelled against its
        content), numbered in the whole capture once its segment ends."""
        pipeline = self.pipeline
        if pipeline.first_contradiction >= 0 and not self._contradiction_placed:
            pipeline.first_contradiction += self.base
            self._contradiction_placed = True

    def _timed(self) -> bool:
        """Whether the rows framed so far may be counted for good: not while the
        stamps' resolution is still being measured (`Pipeline.clock`, from the first
        stamps and host reads), since what counts as a measured latency, a bound or a
        poll period depends on it. A whole store counts its rows at the end, and a
        windowed replay must count them alike. (A replay measures the stamps before it
        frames any, `learn_stamps`; a live capture learns them as they come.)"""
        return not self.pipeline.clock.learning

    def learn_stamps(self, chunks: Iterable[Chunk]) -> Iterator[Chunk]:
        """`chunks`, once the stamps' resolution was measured from the first of them
        (`Pipeline.clock`: the clock's step, host reads' rhythm; a log printing `.000`
        has a 1 s clock), before any is framed: then the framer takes stamps that coarse
        as they are, and every wait the pairing and the statistics judge is judged
        against the resolution the whole capture gets, not against the part measured
        when a refresh happened to come (a replay's refreshes come every quarter second
        of the reader's own time: on a slower machine, earlier in the capture). Held
        at most until the clock stops learning (READ_NOTES host reads, CLOCK_NOTES
        stamps); a capture that ends first was measured from every stamp it has.

        For per-frame stamps, also whether they mark frame starts or frame ends: the
        reading under which the first READING_CHUNKS frames fit the line speed
        (`sniffer.framing.pairing.frame_reading`), which the pipeline then takes them
        as.

        `ingest` calls this; a reader that paces the chunks (a replay at the original
        speed) calls it on them first, so that the stamps are measured at the file's
        speed, not over the seconds they took on the line."""
        it = iter(chunks)
        pipeline, store = self.pipeline, self.store
        clock = pipeline.clock
        if not clock.learning:  # (measured already: a sidecar read back, a second call)
            return it
        first: list[Chunk] = []
        for chunk in it:
            first.append(chunk)
            if clock.learning:
                pipeline.note_stamps(chunk)
            if not clock.learning and len(first) >= READING_CHUNKS:
                break
        clock.learning = False  # (the capture's every stamp noted, if it ended first)
        pipeline.measure_stamps()
        if store.stamps in (Stamp.FRAME_END, Stamp.FRAME_START) and type(pipeline) is Pipeline:
            stamps, reading = frame_reading(
                [c for c in first[:READING_CHUNKS] if not isinstance(c, Reads)],
                store.stamps,
                self.line.char_time,
                max(store.resolution, READING_SLACK),
            )
            if stamps is not store.stamps:
                pipeline.read_stamps_as(stamps, reading)
        return chain(first, it)

    def forget_annotation(self) -> None:
        """See `SessionState.forget_annotation`."""
        self.state.forget_annotation()

    def ingest(
        self,
        chunks: Iterable[Chunk],
        progress: Progress | None = None,
        every: float = 0.25,
        should_stop: Callable[[], bool] | None = None,
        *,
        shown: bool = False,
        index: bool = True,
        window: int | None = None,
        segment: Callable[[Session], None] | None = None,
        written: Callable[[Session, Writer | None], None] | None = None,
        opened: Callable[[Path, int, int, dict[str, Any]], None] | None = None,
        bounded: bool = False,
    ) -> None:
        """Feed all `chunks`, refreshing and reporting progress every `every` seconds.

        Where a sidecar index fits (see `open_session`), its rows are read instead, a
        block at a time, with progress after each block. `shown`: another thread shows
        the rows reported to `progress`, so they are never taken back: a sidecar found
        damaged after some raises `sniffer.session.index.DamagedError` (else the capture is indexed
        again). `index` False: the sidecar is neither read nor written.

        `window`: rows the store may hold before they are dropped (at the next settled
        moment, `new_segment`): memory stays bounded whatever the size of the capture.
        `segment(session)` is called with each segment's rows in `session.store` (row
        `i` is row `session.base + i` of the capture) just before they are dropped, and
        with the last segment's once every row has been read: what needs every row
        (`sniffer.analysis.pollcycle.PollCycles`, `sniffer.analysis.baud.SpeedCheck`) counts
        them there.
        The statistics carry on across segments (bound them: `Stats.bound`). The
        sidecar is then written a segment at a time (`sniffer.session.index.Writer`), and read
        back a block at a time, each block a segment.

        `written(session, writer)` (with `window`): called once each segment's rows are
        in the sidecar being written (`writer`, None when none is: the rows are only in
        `session.store`), before they are dropped, and once with the last segment's.
        `opened(path, fd, start, header)`: the sidecar being read back (see
        `sniffer.session.index.load`). Both feed `sniffer.session.paged.PagedStore`.

        `bounded`: the statistics count latencies and request times in their bounded form
        (`Stats.bound`), read back from a sidecar as written to one: the sidecar being
        written is then handed every value (`sniffer.session.index.Spill`, on disk)."""
        if not index:
            self._sidecar = None
        if self._sidecar is not None and self.indexed_from is None and not len(self.store):
            # read back from the sidecar index where one fits: every row is there already
            # (here rather than in open_session: the TUI draws while this thread reads)
            path, capture, key = self._sidecar
            if bounded:
                self.stats.bound()  # (the values read back are counted as they come)
            blocks = None  # each block read back is a segment (windowed)
            if segment is not None and window is not None:
                blocks = partial(segment, self)
            self.indexed_from = sidecar.load(
                self.state,
                capture,
                path,
                key,
                progress,
                should_stop,
                shown=shown,
                segment=blocks,
                opened=opened,
            )
        if self.indexed_from is not None:
            if segment is not None:
                segment(self)  # every row, or (windowed) the last block's
            return
        if not len(self.store):
            with batching(self.batch_reads):  # (a reader tells at its first chunk)
                chunks = self.learn_stamps(chunks)
        last = time.monotonic()
        done = 0
        writer = None
        if window is not None and self._sidecar is not None:
            writer = Writer(self._sidecar[0])
        if bounded:
            self.stats.bound(
                writer.spill if writer is not None and writer.out is not None else None
            )
        cutter = Cutter(self, window) if window is not None else None

        def before_cut() -> None:
            if segment is not None:
                segment(self)
            if writer is not None:
                writer.add(self.state)
            if written is not None:
                written(self, _open(writer))

        try:
            # readers may pass runs of reads as one batch (sniffer.sources.reads): the
            # pipeline frames them read by read, so the rows are the same
            with batching(self.batch_reads):
                for chunk in chunks:
                    self.feed(chunk)
                    done += len(chunk.data)
                    now = time.monotonic()
                    if now - last >= every:
                        last = now
                        self.refresh()
                        if progress is not None:
                            progress(done, self.base + len(self.store))
                        if should_stop is not None and should_stop():
                            return
                    if cutter is not None and cutter.due():
                        cutter.cut(before_cut)
            self.finish()
            if segment is not None:
                segment(self)
            if self._sidecar is not None:
                path, capture, key = self._sidecar
                if capture.finished:  # read to its end
                    if writer is not None:
                        writer.add(self.state)
                        if written is not None:
                            written(self, _open(writer))
                            written = None
                        self.indexed_to = writer.close(self.state, capture, key)
                    else:
                        self.indexed_to = sidecar.save(self.state, capture, path, key)
                    self._sidecar = None
            if written is not None and window is not None:
                written(self, None)  # the last segment, not in a sidecar
        finally:
            if writer is not None:  # (no half-written sidecar left behind: Ctrl-C)
                writer.abandon()
        if progress is not None:
            progress(done, self.base + len(self.store))


class Cutter:
    """When a session that keeps a window of rows drops them (`Session.new_segment`): at
    the first settled moment once the store holds `window` rows (`Session.ingest`, and
    `replay --mqtt`'s publishing, `sniffer.outputs.mqtt.publish.publish_replay`)."""

    def __init__(self, session: Session, window: int) -> None:
        self.session = session
        self.window = window
        self.retry = window  # rows in the store before the next try at a new segment

    def due(self) -> bool:
        return len(self.session.store) >= self.retry

    def cut(self, before: Callable[[], None]) -> bool:
        """A new segment if the session is settled, `before()` called first (the rows,
        up to date, are still in `session.store`); whether it was cut."""
        session = self.session
        session.pipeline.sync()  # the pairing, which settled() reads
        if session._timed() and session.settled():
            # the annotation and the statistics count the rows before they go: not at
            # every try (1M frames of mix843779584 in 16 ms reads: 81 refreshes, each
            # over the 32 units' gaps and requests, against 23 one frame a packet)
            session.refresh()
            before()
            session.new_segment()
            self.retry = self.window
            session.pipeline.hold_bytes = None
            return True
        # try again once more rows came (the test costs a scan), at the end of a smaller
        # hold of reads: a hold of 512 KiB ends mid-frame or with a request open as often
        # as not in 16 ms reads of a slow line. 1M frames of mix843779584 (32 slaves,
        # 38400 baud) in 16 ms reads were dropped twice, the rest (584k rows) kept to the
        # end, peak RSS 91 MB against 63 MB one frame a packet; now 11 times, at most 132k
        # rows, 57 MB
        self.retry = len(session.store) + max(1, self.window // 64)
        session.pipeline.hold_bytes = SETTLING_HOLD_BYTES
        return False


READING_CHUNKS = 256  # frames per-frame stamps are told frame starts or ends from
READING_SLACK = 50e-6  # how much two frames may seem to overlap and still fit


def _open(writer: Writer | None) -> Writer | None:
    """The writer, if it still writes its sidecar (not abandoned: a folder filled up)."""
    return writer if writer is not None and writer.out is not None else None


def open_session(
    path: str | Path,
    options: ReadOptions | None = None,
    *,
    bindings: Mapping[int, Binding] | None = None,
    timeout: float | None = None,
    index: bool = True,
    interactive: bool = False,
) -> tuple[Session, Capture]:
    """A session for a capture file, not yet ingested: feed it `capture.chunks()`.

    With `index` (and MODSCOPE_NO_INDEX unset), a capture of at least
    `sniffer.session.index.MIN_SIZE` bytes is read back by `Session.ingest` from its sidecar index
    when one fits it (the capture itself is then not read), and gets one once it has been
    read to its end: for the TUI (`interactive`) whatever the capture, for a command that
    reads it through once where a sidecar pays (`sniffer.session.index.pays`).
    """
    options = options or ReadOptions()
    if options.estimator is None:  # a logic capture without --baud: its line measured
        options = replace(options, estimator=estimate_line)
    capture = open_capture(path, options)
    line = options.line(capture.info.line)
    resolution, basis = declared_resolution(capture.info)
    session = Session(
        line,
        bindings=bindings,
        exact_timing=capture.info.exact_timing,
        timeout=timeout,
        source=str(path),
        labels=capture.info.labels,
        stamps=capture.info.stamps,
        resolution=resolution,
        network=capture.info.channels if capture.info.network else None,
    )
    session.pipeline.clock.basis = basis
    if index and (interactive or sidecar.pays(capture, line.mode)):
        _sidecar(session, capture, Path(path), options, timeout)
    return session, capture


def _sidecar(
    session: Session, capture: Capture, path: Path, options: ReadOptions, timeout: float | None
) -> None:
    try:
        if not sidecar.enabled() or not path.is_file() or path.stat().st_size < sidecar.MIN_SIZE:
            return
    except OSError:
        return
    key = sidecar.settings_key(session.annotator, options, timeout)
    session._sidecar = (path, capture, key)


def replay_file(
    path: str | Path,
    options: ReadOptions | None = None,
    *,
    bindings: Mapping[int, Binding] | None = None,
    timeout: float | None = None,
    progress: Progress | None = None,
) -> Session:
    """Open, frame, pair and annotate a whole capture file."""
    session, capture = open_session(path, options, bindings=bindings, timeout=timeout)
    session.ingest(capture.chunks(), progress)
    session.warnings.extend(capture.warnings)
    return session
