"""Provides the feeding of a session from a background thread: a capture file or a live line.

The thread frames, pairs and counts; the UI only reads rows below the count published
with each `FeedProgress` (all columns of those rows are complete). A capture can be
replayed as fast as possible or at its original speed, and paused; a live capture
(`sniffer.live.engine.LiveCapture`, see `LiveSource`) is pumped. Nothing here imports Textual.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from sniffer.live.recorder import Recorder
from sniffer.model import Chunk
from sniffer.session import index
from sniffer.session.index import DamagedError
from sniffer.session.paged import PagedStore
from sniffer.session.session import Session
from sniffer.sources.procio import bytes_read
from sniffer.sources.reads import Reads, batching


class LiveSource(Protocol):
    """A live line as the TUI consumes it: `sniffer.live.engine.LiveCapture`, already started.

    `pump(timeout)` feeds what the ports read to the session (waiting up to `timeout`)
    and brings it up to date; it is called from the feeding thread only. `stop()` ends
    the capture (the caller of `run_tui` does that after the app has returned).
    Optional attributes the TUI shows when present: `messages` (a deque of what
    happened on the ports; the TUI takes them out), `failure`, `recorder` (with `files`),
    `feed` (with `lost_bytes`).
    """

    def pump(self, timeout: float = ...) -> range: ...


@runtime_checkable
class Recordable(Protocol):
    """A live source that can start and stop a recording while it runs (`r`)."""

    recorder: Recorder | None

    def start_recording(self, path: Path) -> Recorder: ...

    def stop_recording(self) -> list[Path]: ...


@dataclass(frozen=True, slots=True)
class LiveStatus:
    """What the status bar says about a live capture."""

    recording: str = ""
    recorded_bytes: int | None = None
    lost_bytes: int = 0
    failure: str = ""
    reconnecting: bool = False  # a port was lost; the capture waits for it to come back


def live_status(source: object) -> LiveStatus:
    """Recording file and size, lost bytes and failure of a live capture, if it has them."""
    recorder = getattr(source, "recorder", None)
    files = getattr(recorder, "files", None) or []
    recording = str(files[-1]) if files else ""
    size: int | None = None
    if recording:
        try:
            size = os.stat(recording).st_size
        except OSError:
            size = None
    lost = int(getattr(source, "lost_bytes", 0) or 0)
    failure = str(getattr(source, "failure", "") or "")
    stats = getattr(getattr(source, "reader", None), "stats", None) or []
    reconnecting = any(not getattr(s, "connected", True) for s in stats)
    return LiveStatus(recording, size, lost, failure, reconnecting)


@dataclass(frozen=True, slots=True)
class FeedProgress:
    """What the feeding thread published: rows below `rows` are complete."""

    rows: int
    bytes_done: int
    done: bool = False
    error: str = ""
    # the sidecar index whose rows were being shown is damaged: open the capture again
    # (its rows start over from none; the sidecar is not read again)
    reopen: bool = False
    # how far through the capture (0-0.99), if the feed can tell (see feed_capture)
    share: float | None = None


Publish = Callable[[FeedProgress], None]


class Pacing:
    """How a capture is fed, shared between the UI and the feeding thread.

    `speed` None: as fast as possible; 1.0: the original speed (chunk times drive
    the feed). `paused` holds the feed. `stop` ends it (the app quits or restarts).
    """

    def __init__(self, speed: float | None = None) -> None:
        self._speed = speed
        self.paused = False
        self.stop = threading.Event()
        self._anchor: tuple[float, float] | None = None  # (wall clock, capture time)

    @property
    def speed(self) -> float | None:
        return self._speed

    @speed.setter
    def speed(self, value: float | None) -> None:
        self._speed = value
        self._anchor = None

    def stopped(self) -> bool:
        return self.stop.is_set()

    def pace(self, chunks: Iterable[Chunk]) -> Iterator[Chunk]:
        """The chunks, held back while paused and timed to the speed.

        At a speed, a batch of reads (`Reads`, seconds of a capture as one chunk) is
        given read by read, each when it is due: the rows then arrive at the capture's
        own pace, not a batch's worth at a time."""
        for chunk in chunks:
            if self._speed and isinstance(chunk, Reads):
                for read in chunk.split():
                    if not self._wait(read):
                        return
                    yield read
                continue
            if not self._wait(chunk):
                return
            yield chunk

    def _wait(self, chunk: Chunk) -> bool:
        """Wait until `chunk` is due (paused: until resumed); False if the feed stops."""
        if self.paused:
            while self.paused and not self.stop.is_set():
                time.sleep(0.05)
            self._anchor = None
        if self.stop.is_set():
            return False
        speed = self._speed
        if speed:
            now = time.monotonic()
            if self._anchor is None:
                self._anchor = (now, chunk.t_end)
            wall, t0 = self._anchor
            due = wall + (chunk.t_end - t0) / speed
            while due - now > 0 and not self.stop.is_set() and not self.paused:
                time.sleep(min(0.05, due - now))
                now = time.monotonic()
                if self._anchor is None:  # speed changed while waiting
                    break
        return True


def feed_capture(
    session: Session,
    chunks: Iterable[Chunk],
    pacing: Pacing,
    publish: Publish,
    *,
    every: float = 0.25,
    first: float = 0.05,
    warnings: list[str] | None = None,
    breather: float = 0.005,
    paged: PagedStore | None = None,
    size: int | None = None,
) -> None:
    """Ingest a capture in this thread, publishing progress after `first` seconds, then
    every `every` seconds, and once at the end.

    `paged`: the rows go there instead, a segment at a time (a windowed ingest writing
    the sidecar, or the sidecar read back a block at a time), and only those rows are
    published; the session's store holds one segment (see `sniffer.session.paged`).

    `size`: the capture file's, to publish how far the feed is (`FeedProgress.share`):
    the share of the sidecar read back, or of the file's bytes this process has read
    (Linux: `sniffer.sources.procio`; not the data bytes, which leave out each format's
    overhead per packet).

    After each publication the thread sleeps `breather` seconds: Python runs one thread
    at a time, and this lets the UI take the new rows and draw them at once instead of
    waiting for its turn."""

    bytes_done = good_rows = 0
    last = float("-inf")
    from_sidecar = False
    read_before = bytes_read()

    def share(done: int) -> float | None:
        if not size:
            return None
        if from_sidecar:  # `done`: the share of the sidecar read, in the capture's bytes
            return min(0.99, done / size)
        now = bytes_read()
        if now is None or read_before is None:
            return None
        return min(0.99, max(0.0, (now - read_before) / size))

    def opened(path: Path, fd: int, start: int, header: dict[str, Any]) -> None:
        nonlocal from_sidecar
        from_sidecar = True
        if paged is not None:
            paged.attach(path, fd, start, header)

    def progress(done: int, rows: int) -> None:
        nonlocal bytes_done, good_rows, last
        if paged is not None:
            paged.reach(rows)  # (a sidecar read back: its blocks up to `rows`)
            rows = len(paged)
        first_rows = rows and not good_rows
        bytes_done, good_rows = done, rows
        now = time.monotonic()
        interval = every if pacing.speed is None else min(every, 0.1)  # replays look live
        if (now - last >= interval or first_rows) and not pacing.stopped():
            last = now
            publish(FeedProgress(rows, done, share=share(done)))
            time.sleep(breather)

    def written(session: Session, writer: Any) -> None:
        assert paged is not None
        paged.take(session, writer)
        if not good_rows:  # the first rows: on screen now, not at the next progress
            progress(bytes_done, len(paged))

    paging: dict[str, Any] = {"opened": opened}
    if paged is not None:
        session.annotator.keep_rows = True  # what it records numbered as `paged` numbers rows
        paging = {
            # segments that fit a sidecar block: one block each
            "window": max(1, index.BLOCK * 15 // 16),
            "segment": _ignore,
            "written": written,
            "opened": opened,
        }
    try:
        if pacing.speed is not None:
            # the stamps measured from the file before the pace holds them back (a
            # replay at the original speed would else show nothing while the clock learns)
            with batching(session.batch_reads):  # (as ingest reads them)
                chunks = session.learn_stamps(chunks)
        session.ingest(
            pacing.pace(chunks),
            progress,
            every=first,
            should_stop=pacing.stopped,
            shown=True,
            index=pacing.speed is None,  # a replay at the original speed reads the capture
            **paging,
        )
    except DamagedError as exc:
        publish(FeedProgress(good_rows, bytes_done, True, str(exc), reopen=True))
        return
    except Exception as exc:  # a reader bug must not kill the UI: keep what was indexed
        error = f"{type(exc).__name__}: {exc}"
        publish(FeedProgress(good_rows, bytes_done, True, error))
        return
    if warnings:
        session.warnings.extend(warnings)
    if not pacing.stopped():
        rows = len(paged) if paged is not None else len(session.store)
        publish(FeedProgress(rows, bytes_done, done=True, share=share(bytes_done)))


def _ignore(session: Session) -> None:
    """A windowed ingest's segments, taken by `PagedStore.take` instead."""


def feed_live(
    session: Session,
    source: LiveSource,
    pacing: Pacing,
    publish: Publish,
    *,
    every: float = 0.1,
    pump_timeout: float = 0.05,
    report: Callable[[str], None] | None = None,
) -> None:
    """Pump a live capture until `pacing.stop` is set, publishing every `every` seconds.
    What happens on the ports (`source.messages`) is passed to `report`."""
    last = 0.0
    ended = ""
    messages = getattr(source, "messages", None)
    try:
        while not pacing.stopped():
            source.pump(pump_timeout)
            while messages and report is not None:
                report(str(messages.popleft()))
            now = time.monotonic()
            if now - last >= every:
                last = now
                store = session.store
                publish(FeedProgress(len(store), store.bytes_total))
    except Exception as exc:  # the capture broke: keep what was framed, say why
        ended = f"{type(exc).__name__}: {exc}"
    if not pacing.stopped() or ended:
        store = session.store
        publish(FeedProgress(len(store), store.bytes_total, bool(ended), ended))
