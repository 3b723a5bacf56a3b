"""Provides the playback's room: pause (space), replay at the capture's own speed (`s`),
and the restart that indexes a capture file again from its first byte."""

from __future__ import annotations

from sniffer.session.paged import PagedStore
from sniffer.session.paged import wanted as paged_wanted
from sniffer.session.session import Session, open_session
from sniffer.sources import Capture, ReadOptions
from sniffer.tui.feed import LiveSource, Pacing
from sniffer.tui.model import ViewModel
from sniffer.tui.rooms.base import Room
from sniffer.tui.rooms.feeding import Flag


class Playback(Room):
    """How the rows arrive: paused or not, as fast as indexing goes or at the line's pace."""

    def pause(self) -> None:
        app = self.app
        app.paused = not app.paused
        app.pacing.paused = app.paused and app.live is None
        app.set_class(app.paused, "-paused")
        if not app.paused:
            app.filtering.show_new_rows()
        app.status_line.show()

    def speed(self) -> None:
        app = self.app
        if app.live is not None:
            app.say("a live capture runs at the line's own speed")
            return
        if app.pacing.speed is None:
            if self.model.done:
                self.restart(speed=1.0)
            else:
                app.pacing.speed = 1.0
                self.frames.action_follow()
        else:
            app.pacing.speed = None
        app.status_line.show()

    def restart(self, speed: float | None) -> None:
        """Index the capture again from its start (at `speed`, None: as fast as it reads),
        keeping how the rows are shown."""
        app = self.app
        try:
            session, capture = (app.reopen or (lambda: reopen_file(app.session)))()
        except Exception as exc:  # the file went away, or cannot be read again
            app.say(f"cannot replay the capture again: {exc}", severity="error")
            return
        app.pacing.stop.set()
        app.workers.cancel_group(app, "filter")
        app.watching.reset()
        old = app.model
        app.generation += 1
        app.session, app.capture = session, capture
        app.model = ViewModel(session, paged_store(session, None, speed))
        app.model.absolute, app.model.transactions = old.absolute, old.transactions
        app.model.problems_only, app.model.query = old.problems_only, old.query
        app.panes.units_cache = {}
        app.indexed = Flag()
        app.feeding.note = ""
        app.pacing = Pacing(speed)
        app.status_line.reset_rate()
        frames = self.frames
        frames.model = self.main.model = app.model
        frames.following = True
        app.filtering.restart()
        app.feeding.start()
        if self.main.lower.current == "watch":
            app.watching.start()


def reopen_file(session: Session) -> tuple[Session, Capture]:
    """Open the session's capture file again, with the same line settings and bindings."""
    line = session.line
    options = ReadOptions(
        baud=line.baud,
        bytesize=line.bytesize,
        parity=line.parity,
        stopbits=line.stopbits,
        mode=line.mode,
    )
    return open_session(
        session.source,
        options,
        bindings=session.annotator.bindings,
        timeout=session.pipeline.pairer.timeout,
        interactive=True,
    )


def paged_store(
    session: Session, live: LiveSource | None, speed: float | None
) -> PagedStore | None:
    """A store for the rows of a capture big enough to have a sidecar index, paged from
    it (see `sniffer.session.paged`); None: the session's store is shown as it is."""
    return PagedStore() if paged_wanted(session, live is not None, speed) else None
