"""Provides the recording's room: `r` records the live line to a file, stops it or goes on in a
new file without a gap; `q` asks before it ends a recording; on leaving, where each one is.

A recording is evidence: no single key ends it. While one runs, `r` and `q` ask first
(the next key answers: the same key again does it, any other keeps recording), and a
new file is started while the old one is still being written, so no read falls between
the two.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from sniffer.live.recorder import Recorder, RecordError
from sniffer.tui.feed import Recordable
from sniffer.tui.rooms.base import Room
from sniffer.tui.rooms.exporting import served, served_path
from sniffer.tui.widgets.status import size_text

if TYPE_CHECKING:
    from sniffer.tui.app import ModscopeApp

NOTICE_SECONDS = 30  # a notice about the evidence stays this long (others fade sooner)


@runtime_checkable
class Switchable(Protocol):
    """A live source that can go on recording into a new file without a gap."""

    def switch_recording(self, path: Path) -> tuple[Recorder, list[Path]]: ...


@dataclass
class Made:
    """A recording made during this run: its files and how much went into it."""

    files: list[Path]
    reads: int  # reads (pcapng packets) written
    first_row: int  # the session's row count when it began
    last_row: int | None = None  # ... and when it ended (None: still running)
    ended: bool = field(default=False)


def file_size(path: Path) -> str:
    try:
        return size_text(os.stat(path).st_size)
    except OSError:
        return "size unknown (the file cannot be read)"


class Recording(Room):
    """Records what a live line brings (a file capture is a file already)."""

    def __init__(self, app: ModscopeApp) -> None:
        super().__init__(app)
        self.made: list[Made] = []
        self._current: Made | None = None

    # -- what runs -----------------------------------------------------------------------------

    def recorder(self) -> Recorder | None:
        """The running recording, if the live source has one."""
        recorder = getattr(self.app.live, "recorder", None)
        return recorder if isinstance(recorder, Recorder) else None

    def _running(self) -> Made | None:
        """The running recording's account (a `-w` recording is taken in when first seen)."""
        recorder = self.recorder()
        if recorder is None:
            return None
        if self._current is None:
            # begun before the app (modscope live -w): every row of the run is in it
            self._current = Made(recorder.files, 0, 0)
            self.made.append(self._current)
        self._current.files = recorder.files
        return self._current

    def _rows(self) -> int:
        return len(self.app.session.store)

    def describe(self, made: Made, recorder: Recorder | None = None, *, whole: bool = False) -> str:
        """Where a recording is, its size, frames and reads ('rec.pcapng, 24.8 kB, ...');
        `whole`: the files' absolute paths (said on leaving, when the folder may be
        forgotten)."""
        last = made.last_row if made.last_row is not None else self._rows()
        reads = recorder.packets if recorder is not None else made.reads
        files = [f.absolute() for f in made.files] if whole else made.files
        names = ", ".join(str(f) for f in files) or "no file on disk"
        sizes = " + ".join(file_size(f) for f in made.files) or "0 B"
        frames = max(0, last - made.first_row)
        return f"{names}: {sizes}, {frames:,} frames ({reads:,} reads)"

    # -- r ---------------------------------------------------------------------------------

    def toggle(self) -> None:
        """Start recording the live line to a file; while one runs, ask what to do first."""
        app = self.app
        live = app.live
        if live is None or not isinstance(live, Recordable):
            app.say(
                "recording is for a live line (modscope live PORT); this capture is a file "
                "already: e exports the rows shown"
            )
            return
        running = self._running()
        recorder = self.recorder()
        if running is not None and recorder is not None:
            self.main.prompt.confirm(
                f"recording to {self.describe(running, recorder)}: r stops it, n goes on in "
                "a new file, any other key keeps recording",
                self._decided,
            )
            return
        app.keyboard.ask("record to (pcapng):", self._record, self._new_name())

    @staticmethod
    def _new_name() -> str:
        return f"modscope-{time.strftime('%Y%m%d-%H%M%S')}.pcapng"

    def _decided(self, key: str) -> None:
        app = self.app
        if key == "r":
            self._stop()
        elif key == "n":
            app.keyboard.ask(
                "go on recording in (the current file records until you answer):",
                self._switch,
                self._new_name(),
            )
        else:
            self._still()

    def _still(self) -> None:
        recorder = self.recorder()
        if recorder is not None:
            where = recorder.files[-1] if recorder.files else recorder.path
            self.app.say(f"still recording to {where}")

    def _stop(self) -> None:
        app = self.app
        live = app.live
        running = self._running()
        if not isinstance(live, Recordable) or running is None:
            return
        reads = live.recorder.packets if live.recorder is not None else 0
        running.files = live.stop_recording()
        self._close(running, reads)
        app.say(f"recording stopped: {self.describe(running)}", timeout=NOTICE_SECONDS)
        app.status_line.show()

    def _close(self, made: Made, reads: int) -> None:
        made.reads = reads
        made.last_row = self._rows()
        made.ended = True
        self._current = None

    def _record(self, answer: str | None) -> None:
        app = self.app
        live = app.live
        if not answer or not isinstance(live, Recordable):
            return
        path: Path | None = Path(answer).expanduser()
        if served():  # a browser visitor records only inside serve's --export-dir
            path, why = served_path(answer)
            if path is None:
                why = why or "recording needs `modscope serve --export-dir DIR`"
                app.say(why, severity="error")
                return
        try:
            recorder = live.start_recording(path)
        except RecordError as exc:
            app.say(str(exc), severity="error")
            return
        self._current = Made(recorder.files, 0, self._rows())
        self.made.append(self._current)
        app.say(f"recording to {recorder.files[-1] if recorder.files else answer}")
        app.status_line.show()

    def _switch(self, answer: str | None) -> None:
        """Go on in a new file: the old one records until the new one runs (both hold the
        reads of that moment)."""
        app = self.app
        live = app.live
        old = self._running()
        if not answer:
            self._still()
            return
        if not isinstance(live, Switchable) or not isinstance(live, Recordable) or old is None:
            app.say("this live source cannot switch files; r then r stops, r starts anew")
            return
        path: Path | None = Path(answer).expanduser()
        if served():  # the new file too only inside serve's --export-dir
            path, why = served_path(answer)
            if path is None:
                app.say(
                    why or "recording needs `modscope serve --export-dir DIR`", severity="error"
                )
                return
        reads = live.recorder.packets if live.recorder is not None else 0
        rows = self._rows()
        try:
            recorder, old_files = live.switch_recording(path)
        except RecordError as exc:
            app.say(f"{exc} (still recording to the old file)", severity="error")
            return
        old.files = old_files
        self._close(old, reads)
        self._current = Made(recorder.files, 0, rows)
        self.made.append(self._current)
        app.say(
            f"recording goes on in {recorder.files[-1] if recorder.files else answer}; "
            f"ended: {self.describe(old)}",
            timeout=NOTICE_SECONDS,
        )
        app.status_line.show()

    # -- q ---------------------------------------------------------------------------------

    def quit(self) -> None:
        """Leave; while a recording runs, only once `q` is typed again."""
        running = self._running()
        recorder = self.recorder()
        if running is None or recorder is None:
            self.app.leave()
            return
        app = self.app
        for _ in range(len(app.screen_stack) - 1):  # ctrl+q over the ladder, a plot, a
            if app.screen is self.main:  # table: the question is asked on the main screen
                break
            app.pop_screen()
        self.main.prompt.confirm(
            f"q again quits and ends the recording to {self.describe(running, recorder)}; "
            "any other key keeps going",
            self._quit_decided,
        )

    def _quit_decided(self, key: str) -> None:
        if key in ("q", "ctrl+q"):
            self.app.leave()
        else:
            self._still()

    # -- leaving -----------------------------------------------------------------------------

    def report(self) -> list[str]:
        """Where every recording of the run is, its size, frames and reads: one line each
        (call once the live source has stopped: the files are complete then)."""
        self._running()
        lines = []
        recorder = self.recorder()
        for made in self.made:
            if not made.ended and recorder is not None:
                made.files = recorder.files
                self._close(made, recorder.packets)
            lines.append(f"recorded {self.describe(made, whole=True)}")
        return lines
