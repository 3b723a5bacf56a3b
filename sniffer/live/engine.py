"""Provides the live-capture engine: ports being read, framed into a session and recorded.

`LiveCapture` ties a `LiveReader` (threads reading the ports) to a `Session` (framing,
pairing, annotation) and a `Recorder` (pcapng link type 250). The recorder drains its
own feed in its own thread, so a slow screen or pipe never costs the recording a byte;
the session is fed by whoever calls `pump()`: the command line's loop, or the TUI.

Headless (a listing, a recording with --mqtt), the capture is given a `window`: once the
session's store holds that many rows, the next `pump()` at a settled moment (see
`Session.new_segment`) forgets them and goes on in an empty store, rows numbered on from
`session.base`. Its statistics are kept bounded too (`Stats.bound`: the latencies and
poll gaps counted per figure the table prints). Memory then stays bounded however long
the capture runs; the rows live on in the recording (-w) if one is made. `GlobalRows`
shows a windowed session's rows to
a lister or exporter with their numbers in the whole capture.

For the TUI: `run_tui(session, None, live=capture)` gets a started `LiveCapture`. Call
`capture.pump(timeout)` from one thread (it feeds the session and returns the range of
new rows in `session.store`); `capture.messages` holds what happened on the ports
(port lost, reconnect, data lost); `capture.now()` is the time on the stamps' clock (the
ages liveness shows are measured to it); `capture.stop()` ends it (idempotent).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, Protocol, cast

from sniffer.framing.store import COLUMNS, NO_PARTNER, FrameStore, FrameView
from sniffer.live.port import DEFAULT_QUEUE, ChunkFeed, PortSpec, PortStats
from sniffer.live.recorder import Recorder, RecordError
from sniffer.meaning.describe import Describer, FrameDetail, Shared
from sniffer.model import Chunk
from sniffer.session.session import Session

IDLE_QUIET = 0.02  # seconds without bytes after which the session is told the line is idle
PUMP_SECONDS = 0.05  # longest wait of one pump for new chunks
# a headless pump woken by a read or two lets more gather this long before it frames
# them: a pump costs about the same for one read as for ten, so on a busy line gathering
# saves much of the CPU; the listing is that much later, well within its 50 ms
PUMP_GATHER = 0.010
GATHER_READS = 4  # ... unless this many reads were waiting already
RECORD_GATHER = 0.002  # seconds the recorder lets reads gather before writing them
# rows a headless live session keeps before it starts a new segment: about 7 MB of store
# (65 bytes a row) and some 30 s of a 921600 baud line
WINDOW_ROWS = 100_000

Notify = Callable[[str], None]


class Clock(Protocol):
    def now(self) -> float: ...


class Reader(Protocol):
    """What LiveCapture reads from: the serial `LiveReader`, or `MqttReader` (a bus
    another modscope publishes)."""

    @property
    def specs(self) -> Sequence[PortSpec]: ...
    @property
    def clock(self) -> Clock: ...
    @property
    def stats(self) -> Sequence[PortStats]: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def failure(self) -> str | None: ...
    @property
    def error(self) -> Exception | None: ...
    @property
    def running(self) -> bool: ...
    def subscribe(self, maxsize: int = DEFAULT_QUEUE) -> ChunkFeed: ...
    def attach(self, maxsize: int = DEFAULT_QUEUE) -> ChunkFeed: ...
    def detach(self, feed: ChunkFeed) -> None: ...
    def start(self) -> None: ...
    def stop(self, timeout: float = 2.0) -> None: ...


class Publisher(Protocol):
    """An output fed as the session is (`sniffer.outputs.mqtt.publish.BusPublisher`): every chunk
    as it is read, then the new rows after each pump. It must never block for long."""

    next: int  # the next store row it will look at (back to 0 in a new segment)

    def chunk(self, chunk: Chunk) -> None: ...
    def rows(self, final: bool = False) -> None: ...
    def close(self, drain: float = 10.0) -> str: ...


PUBLISH_DRAIN = 5.0  # seconds a stopping capture waits for its publisher's buffer


def event_text(chunk: Chunk) -> str:
    return chunk.event + (f": {chunk.note}" if chunk.note else "")


class LiveCapture:
    """Ports being read, framed into `session` and written by `recorder`, as they run."""

    def __init__(
        self,
        reader: Reader,
        session: Session | None,
        *,
        recorder: Recorder | None = None,
        queue_size: int = DEFAULT_QUEUE,
        notify: Notify | None = None,
        quiet: float | None = None,
        publisher: Publisher | None = None,
        window: int | None = None,
        gather: float = 0.0,
    ) -> None:
        """`window`: rows the session keeps in memory before a new segment starts (see
        the module's docstring); None keeps every row (the TUI scrolls back through
        them). `gather`: seconds a pump woken by fewer than GATHER_READS reads waits for
        more before it frames them (PUMP_GATHER headless; 0 for none)."""
        if publisher is not None and session is None:
            raise ValueError("a publisher is fed from the session: give the capture one")
        self.reader = reader
        self.session = session
        self.recorder = recorder
        self.publisher = publisher
        self.publish_report: str | None = None
        self.notify = notify
        self.queue_size = queue_size
        line = session.line if session is not None else reader.specs[0].line
        self.quiet = quiet if quiet is not None else max(line.t35, IDLE_QUIET)
        self.messages: deque[str] = deque(maxlen=200)
        self.failure: str | None = None
        self.shown = 0  # rows of the session's store handed out by pump()
        self.window = window
        self.gather = gather
        self.segments = 0  # new segments started
        # given the rows of each segment just before they are dropped (what counts over
        # the whole capture: the --stats poll cycle, `sniffer.analysis.pollcycle.PollCycles`)
        self.segment: Callable[[Session], None] | None = None
        if window is not None and session is not None:
            # the statistics too: counted per printed figure, not kept value by value
            session.stats.bound()
        self.feed: ChunkFeed | None = None
        if session is not None:
            self.feed = reader.subscribe(queue_size)
        self._rec_feed: ChunkFeed | None = None
        if recorder is not None:
            self._rec_feed = reader.subscribe(queue_size)
        self._rec_thread: threading.Thread | None = None
        self._last_data = time.monotonic()
        self._lock = threading.Lock()
        self._pumping = threading.Lock()  # pump() and stop() feed the session in turn
        self._stopped = False

    # -- lifetime --------------------------------------------------------------------------

    def start(self) -> None:
        self.reader.start()
        if self._rec_feed is not None:
            self._rec_thread = threading.Thread(
                target=self._record, name="modscope-recorder", daemon=True
            )
            self._rec_thread.start()

    def stop(self) -> range:
        """Stop reading, frame what is left, close the recording. Returns the last rows."""
        with self._lock:
            if self._stopped:
                return range(self.shown, self.shown)
            self._stopped = True
        self.reader.stop()
        rows = range(self.shown, self.shown)
        if self.session is not None and self.feed is not None:
            with self._pumping:
                while not self.feed.closed:
                    self._take(self.feed.get(0))
                self.session.finish()
                rows = self._new_rows()
                if self.publisher is not None:
                    self.publish_report = self.publisher.close(PUBLISH_DRAIN)
                    self._report(self.publish_report)
        if self._rec_thread is not None:
            self._rec_thread.join(30)
            if self._rec_thread.is_alive():
                self._report("error: the recording did not finish writing; its disk is stuck")
                return rows
        if self.recorder is not None:
            self.recorder.close(self.reader.clock.now())
        return rows

    # -- recording on demand (the TUI's `r`) ----------------------------------------------

    def start_recording(self, path: str | Path) -> Recorder:
        """Record from now on into `path` (pcapng, link type 250), while reading goes on.
        RecordError if the file cannot be written or a recording is already running."""
        with self._lock:
            if self.recorder is not None:
                raise RecordError(f"already recording to {self.recorder.path}; stop it first")
            recorder = Recorder(path, self.reader.specs)
            self.recorder = recorder
            self._rec_feed = self.reader.attach(self.queue_size)
            self._rec_thread = threading.Thread(
                target=self._record, name="modscope-recorder", daemon=True
            )
            self._rec_thread.start()
        return recorder

    def stop_recording(self) -> list[Path]:
        """Finish the running recording (everything read so far is written); its files."""
        with self._lock:
            recorder, feed, thread = self.recorder, self._rec_feed, self._rec_thread
            self.recorder, self._rec_feed, self._rec_thread = None, None, None
        if recorder is None or feed is None:
            return []
        self.reader.detach(feed)
        if thread is not None:
            thread.join(30)
        recorder.close(self.reader.clock.now())
        return list(recorder.files)

    def now(self) -> float:
        """The current time on the clock the frame stamps are read by (the ports' wall
        clock, advanced monotonically): what liveness measures ages against, so they grow
        while no frame comes (`sniffer.analysis.liveness`)."""
        return self.reader.clock.now()

    def switch_recording(self, path: str | Path) -> tuple[Recorder, list[Path]]:
        """Go on recording into `path` without a gap: the new file is fed from before the
        running one stops, so the reads at the switch are in both. The new recorder and
        the files of the one that ended (nothing ends if none was running)."""
        with self._lock:
            old, old_feed, old_thread = self.recorder, self._rec_feed, self._rec_thread
            recorder = Recorder(path, self.reader.specs)  # RecordError: the old one goes on
            self.recorder = recorder
            self._rec_feed = self.reader.attach(self.queue_size)
            self._rec_thread = threading.Thread(
                target=self._record, name="modscope-recorder", daemon=True
            )
            self._rec_thread.start()
        if old is None or old_feed is None:
            return recorder, []
        self.reader.detach(old_feed)
        if old_thread is not None:
            old_thread.join(30)
        old.close(self.reader.clock.now())
        return recorder, list(old.files)

    @property
    def lost_bytes(self) -> int:
        """Bytes the display and the recording could not keep up with, together."""
        feeds = (self.feed, self._rec_feed)
        return sum(f.lost_bytes for f in feeds if f is not None)

    @property
    def running(self) -> bool:
        return self.reader.running and self.failure is None

    def _report(self, text: str) -> None:
        self.messages.append(text)
        if self.notify is not None:
            self.notify(text)

    # -- the session side ------------------------------------------------------------------

    def pump(self, timeout: float = PUMP_SECONDS) -> range:
        """Feed what the ports read since the last call (waiting up to `timeout` for it)
        to the session; tell it when the line went quiet. Returns the new rows."""
        if self.session is None or self.feed is None:
            raise RuntimeError("this capture has no session to pump")
        with self._pumping:
            if self._stopped:
                return range(self.shown, self.shown)
            if self.window is not None and self.shown >= self.window:
                # every row so far was handed out last time and has been listed: the
                # store may start afresh if the line is at a settled moment
                self._cut()
            chunks = self.feed.get(timeout)
            if chunks and self.gather > 0 and len(chunks) < GATHER_READS:
                # gather until the oldest read is `gather` old, not `gather` from now: a
                # pump that woke late (a loaded machine) frames at once rather than adding
                # its wait to a delay the reads already had
                rest = self.gather - (self.reader.clock.now() - chunks[0].t_end)
                if rest > 0:
                    time.sleep(min(rest, self.gather))
                chunks += self.feed.get(0)
            self._take(chunks)
            if time.monotonic() - self._last_data >= self.quiet:
                self.session.idle(self.reader.clock.now())
            else:
                self.session.refresh()
            if self.publisher is not None:
                self.publisher.rows()
            return self._new_rows()

    def _take(self, chunks: list[Chunk]) -> None:
        assert self.session is not None
        feed = self.session.feed
        publish = self.publisher.chunk if self.publisher is not None else None
        got_data = False
        for chunk in chunks:
            if chunk.event:
                self._report(event_text(chunk))
            if publish is not None:
                publish(chunk)
            feed(chunk)
            got_data = got_data or bool(chunk.data)
        if got_data:
            self._last_data = time.monotonic()

    def _cut(self) -> None:
        assert self.session is not None
        session = self.session
        if self.shown == len(session.store) and session.settled():
            if self.segment is not None:
                self.segment(session)
            session.new_segment()
            self.shown = 0
            self.segments += 1
            if self.publisher is not None:
                self.publisher.next = 0

    def _new_rows(self) -> range:
        assert self.session is not None
        end = len(self.session.store)
        rows = range(self.shown, end)
        self.shown = end
        return rows

    # -- the recording side ------------------------------------------------------------------

    def _record(self) -> None:
        feed, recorder = self._rec_feed, self.recorder
        assert feed is not None and recorder is not None
        lost = 0
        while not feed.closed:
            chunks = feed.get(0.5)
            if chunks and not feed.closed:
                # let a few more reads gather: one wake-up per few reads, not per read
                time.sleep(RECORD_GATHER)
                chunks += feed.get(0)
            try:
                for chunk in chunks:
                    recorder.write(chunk)
                    if chunk.event and self.session is None:
                        self._report(event_text(chunk))
            except RecordError as exc:
                # the ports go on being read for the listing and MQTT: the recording's
                # feed lets go, so nothing piles up in it or counts as lost
                self.reader.detach(feed)
                self.failure = str(exc)
                piped = recorder.stopped is not None and not recorder.status  # a closed pipe
                self._report(str(exc) if piped else f"error: {exc}")
                return
            if feed.lost_bytes > lost and self.session is not None:
                self._report(
                    f"data lost: the recording fell behind; {feed.lost_bytes - lost} bytes "
                    "not recorded (marked in the file)"
                )
                lost = feed.lost_bytes


# -- a windowed session's rows, numbered as in the whole capture --------------------------


class _Column:
    """A column of the session's current store, indexed by row number in the capture."""

    __slots__ = ("name", "session")

    def __init__(self, session: Session, name: str) -> None:
        self.session = session
        self.name = name

    def __getitem__(self, i: int) -> Any:
        session = self.session
        return getattr(session.store, self.name)[i - session.base]


class _Partners(_Column):
    """The partner column, rows and partners numbered in the capture."""

    __slots__ = ()

    def __getitem__(self, i: int) -> int:
        session = self.session
        base = session.base
        j: int = session.store.partner[i - base]
        return j if j == NO_PARTNER else j + base


class _Keyed(_Column):
    """A per-row dict of the current store (notes, links), keyed by row in the capture."""

    __slots__ = ()

    def _rows(self) -> dict[int, Any]:
        found: dict[int, Any] = getattr(self.session.store, self.name)
        return found

    def __contains__(self, i: int) -> bool:
        return i - self.session.base in self._rows()

    def __getitem__(self, i: int) -> Any:
        return self._rows()[i - self.session.base]

    def get(self, i: int, default: Any = None) -> Any:
        return self._rows().get(i - self.session.base, default)

    def __bool__(self) -> bool:
        return bool(self._rows())


# every column but the partner, which _Partners gives by capture row number
_ROW_COLUMNS = tuple(name for name in COLUMNS if name != "partner")


class _GlobalStore:
    """What a lister or an exporter reads of the store, by row number in the capture:
    every per-row column (partners numbered in the capture too), the notes and links,
    and views; anything else (streams, stamps, peers) is the current store's."""

    def __init__(self, session: Session) -> None:
        self._session = session
        for name in _ROW_COLUMNS:
            setattr(self, name, _Column(session, name))
        self.partner = _Partners(session, "partner")
        self.notes = _Keyed(session, "notes")
        self.links = _Keyed(session, "links")

    def __getattr__(self, name: str) -> Any:
        return getattr(self._session.store, name)

    def __len__(self) -> int:
        return self._session.base + len(self._session.store)

    def view(self, i: int) -> FrameView:
        session = self._session
        return _shifted(session.store.view(i - session.base), session.base)


def _shifted(v: FrameView, by: int) -> FrameView:
    """View `v` with its row and partner numbered `by` rows on."""
    if not by:
        return v
    partner = v.partner + by if v.partner != NO_PARTNER else NO_PARTNER
    return replace(v, index=v.index + by, partner=partner)


class GlobalRows(Describer):
    """The details of a windowed live session's rows by their number in the whole
    capture (`session.base` plus the row in the current store): index, partner and
    transaction ids as one store of every row would give them. For a `Lister` or a
    `PcapExporter`; give it rows from `session.base` on. Contents shared among rows
    (`Describer.shared`) are the session's describer's: they hold no row numbers."""

    def __init__(self, session: Session) -> None:  # the session's describer does the work
        self.session = session
        self.store = cast(FrameStore, _GlobalStore(session))
        self.shared_size = session.describer.shared_size

    def shared(self, i: int) -> Shared | None:
        session = self.session
        return session.describer.shared(i - session.base)

    def contents(
        self, rows: Iterable[int], values: bool = True, writes: bool = False
    ) -> Iterator[tuple[int, Shared | None]]:
        """The session's describer's walk (`Describer.contents`, answers with other
        values sharing a content too), renumbered: the live listing's rows cost what a
        replay's do, rather than a lookup and a new content each."""
        base = self.session.base
        for i, shared in self.session.describer.contents((r - base for r in rows), values, writes):
            yield i + base, shared

    def view(self, i: int) -> FrameView:
        session = self.session
        return _shifted(session.describer.view(i - session.base), session.base)

    def complete(self, view: FrameView, content: Shared) -> FrameDetail:
        session = self.session
        base = session.base
        d = session.describer.complete(_shifted(view, -base), content)
        return replace(d, view=view) if base else d

    def forget(self, i: int) -> None:
        self.session.describer.forget(i - self.session.base)

    def detail(self, i: int) -> FrameDetail:
        session = self.session
        base = session.base
        d = session.describer.detail(i - base)
        return replace(d, view=_shifted(d.view, base)) if base else d
