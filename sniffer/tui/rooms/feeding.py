"""Provides the feed's room: the thread that indexes a capture or reads a live line, and
what it publishes (rows, the end, errors, how far indexing got)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from textual.message import Message

from sniffer.model import Chunk
from sniffer.sources.reads import Reads
from sniffer.tui.feed import FeedProgress, feed_capture, feed_live
from sniffer.tui.rooms.base import Room

if TYPE_CHECKING:
    from sniffer.tui.app import ModscopeApp

# bytes a capture file spends on each chunk besides its data (to estimate indexing progress)
RECORD_OVERHEAD = {"pcap": 16, "pcapng": 32, "raw": 0}


class Indexed(Message):
    """The feeding thread published rows (batched: a newer one replaces a queued one)."""

    def __init__(self, progress: FeedProgress, generation: int) -> None:
        super().__init__()
        self.progress = progress
        self.generation = generation

    def can_replace(self, message: Message) -> bool:
        return isinstance(message, Indexed) and message.generation == self.generation


class PortNotice(Message):
    """Something happened on a live port (lost, back, data lost)."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.text = text


class Flag:
    """A flag set once on the UI thread; `wait` polls it from async code (tests, benchmarks)."""

    def __init__(self) -> None:
        self.value = False

    def set(self) -> None:
        self.value = True

    def is_set(self) -> bool:
        return self.value


class Feeding(Room):
    """Starts the feed of the app's session and takes in what it publishes."""

    def __init__(self, app: ModscopeApp) -> None:
        super().__init__(app)
        self.note = ""  # why the feed stopped ('' while it runs, or if it ended well)
        self._file_size: int | None = None  # of the capture file, for indexing progress
        self._bytes_done = 0
        self._share: float | None = None  # how far the feed said it is
        self._chunks_done = [0]
        # what waits for rows not read yet (a jump, an export typed at start-up): each
        # runs once its condition holds, checked as rows and filter results arrive
        self._waiting: dict[str, tuple[Callable[[], bool], Callable[[], None]]] = {}

    def when(self, name: str, ready: Callable[[], bool], then: Callable[[], None]) -> None:
        """Run `then` once `ready()` holds (now if it does); a newer wait of the same
        `name` replaces an older one (a second `g` replaces the first)."""
        if ready():
            self._waiting.pop(name, None)
            then()
            return
        self._waiting[name] = (ready, then)

    def forget(self, name: str) -> None:
        self._waiting.pop(name, None)

    def run_waiting(self) -> None:
        for name, (ready, then) in list(self._waiting.items()):
            if self._waiting.get(name) == (ready, then) and ready():
                del self._waiting[name]
                then()

    def read_all(self) -> bool:
        """Whether the rows shown are all there will be for now: the capture is read and
        the filter has caught up with it, or the rows come at their own pace (a live
        line, a replay at the original speed), which nothing should wait for."""
        app, model = self.app, self.model
        if app.live is not None or app.pacing.speed is not None:
            return True
        job = model.job
        caught_up = job is None or (job.caught_up and job.upto >= model.shown)
        return model.done and caught_up

    def start(self) -> None:
        app = self.app
        gen = app.generation
        session, pacing = app.session, app.pacing

        def publish(p: FeedProgress) -> None:
            app.post_message(Indexed(p, gen))

        def report(text: str) -> None:
            app.post_message(PortNotice(text))

        if app.live is not None:
            live = app.live
            app.run_worker(
                lambda: feed_live(session, live, pacing, publish, report=report),
                thread=True,
                group="feed",
            )
        elif app.capture is not None:
            capture = app.capture
            try:
                self._file_size = Path(capture.info.path).stat().st_size
            except OSError:
                self._file_size = None
            counter = self._chunks_done = [0]

            def counted(chunks: Iterable[Chunk]) -> Iterator[Chunk]:
                for chunk in chunks:  # (packets: a batch of reads is one per read)
                    counter[0] += len(chunk) if isinstance(chunk, Reads) else 1
                    yield chunk

            chunks: Iterable[Chunk] = counted(capture.chunks())
            paged = self.model.paged
            app.run_worker(
                lambda: feed_capture(
                    session,
                    chunks,
                    pacing,
                    publish,
                    warnings=capture.warnings,
                    paged=paged,
                    size=self._file_size,
                ),
                thread=True,
                group="feed",
            )
        else:  # a session ingested before the app started
            session.store.sync()
            app.post_message(Indexed(FeedProgress(len(session.store), 0, True), gen))

    def indexed(self, message: Indexed) -> None:
        app = self.app
        if message.generation != app.generation or not self.main.alive:
            return
        p = message.progress
        if p.reopen:  # the rows start over: as a restart, from the capture this time
            app.say(f"{p.error}: indexing the capture again", severity="warning")
            app.playback.restart(app.pacing.speed)
            return
        self._bytes_done = p.bytes_done
        self._share = p.share
        self.model.publish(p.rows)
        if p.done:
            self.model.done = True
            app.indexed.set()
            if p.error:
                self.note = p.error
                app.say(p.error, title="the feed stopped", severity="error")
            for w in app.session.warnings[:5]:
                app.say(w, title="capture", severity="warning")
        if not app.paused:
            app.filtering.show_new_rows()
            app.panes.refresh_ladder()
        # the header follows the columns here, not only through ColumnsChanged: that is
        # posted while the list draws, and it was seen not to arrive (row numbers grew
        # a digit and the header stayed as it was)
        self.main.header.show(self.frames.columns())
        app.status_line.show()
        self.run_waiting()

    def index_progress(self) -> float | None:
        """How far indexing got: as the feed says (`FeedProgress.share`), else estimated
        from the file's size (pcap formats, raw)."""
        if self._share is not None:
            return self._share
        capture = self.app.capture
        overhead = RECORD_OVERHEAD.get(capture.info.format) if capture is not None else None
        if overhead is None or self._file_size is None or not self._file_size:
            return None
        done = self._bytes_done + self._chunks_done[0] * overhead
        return max(0.0, min(0.99, done / self._file_size))

    def stop(self) -> None:
        self.app.pacing.stop.set()
