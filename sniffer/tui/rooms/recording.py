"""Provides the recording's room: `r` records the live line to a file, or stops doing so."""

from __future__ import annotations

import time
from pathlib import Path

from sniffer.live.recorder import RecordError
from sniffer.tui.feed import Recordable
from sniffer.tui.rooms.base import Room
from sniffer.tui.rooms.exporting import served, served_path


class Recording(Room):
    """Records what a live line brings (a file capture is a file already)."""

    def toggle(self) -> None:
        """Start recording the live line to a file, or stop the running recording."""
        app = self.app
        live = app.live
        if live is None or not isinstance(live, Recordable):
            app.say(
                "recording is for a live line (modscope live PORT); this capture is a file "
                "already: e exports the rows shown"
            )
            return
        if getattr(live, "recorder", None) is not None:
            files = live.stop_recording()
            where = ", ".join(str(f) for f in files) or "nothing written"
            app.say(f"recording stopped: {where}")
            app.status_line.show()
            return
        stamp = time.strftime("%Y%m%d-%H%M%S")
        app.keyboard.ask("record to (pcapng; r stops):", self._record, f"modscope-{stamp}.pcapng")

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
        app.say(f"recording to {recorder.files[-1] if recorder.files else answer}")
        app.status_line.show()
