"""Provides the export's room: `e` writes the rows shown to a file, `c` `C` copy the
selected row (hex, JSON) to the clipboard."""

from __future__ import annotations

import io
from array import array
from collections.abc import Iterable
from functools import partial
from pathlib import Path

from sniffer.meaning.describe import Describer
from sniffer.outputs.listing import FORMATS, Lister
from sniffer.tui.clipboard import clipboard_note
from sniffer.tui.rooms.base import Room

EXPORT_DEFAULT = "modscope-export.jsonl"
EXPORT_FORMATS = {"jsonl": "jsonl", "json": "jsonl", "ndjson": "jsonl", "csv": "csv"}


class Exporting(Room):
    """Writes rows out as `modscope replay --format` does, in a worker thread."""

    def export(self) -> None:
        count = len(self.model.view)
        ask = self.app.keyboard.ask
        ask(f"export {count:,} rows to (.jsonl .csv .txt):", self._export, EXPORT_DEFAULT)

    def _export(self, answer: str | None) -> None:
        if not answer:
            return
        if self._later(answer):
            return
        view = self.model.view
        rows: Iterable[int] = (
            range(view.count) if view.rows is None else array("Q", view.rows[: view.count])
        )
        # the rows, store and options of now: `s` may start the capture again (a new
        # store) while the file is being written
        model = self.model
        describer = Describer(model.reader, self.app.session.annotator, size=256)
        write = partial(self._write, Path(answer).expanduser(), rows, describer, model.absolute)
        self.app.run_worker(write, name="export", group="export", thread=True)

    def _later(self, answer: str) -> bool:
        """Typed while the capture is still being read (or filtered): the rows shown are
        not all there yet, so the file is written once they are. True if put off."""
        feeding = self.app.feeding
        if feeding.read_all():
            return False
        self.app.say(f"the export to {answer} is written once the capture is read")
        feeding.when("export", feeding.read_all, lambda: self._export(answer))
        return True

    def _write(self, path: Path, rows: Iterable[int], describer: Describer, absolute: bool) -> None:
        """The export's worker (a thread)."""
        app = self.app
        suffix = path.suffix.lower().lstrip(".")
        fmt = EXPORT_FORMATS.get(suffix, "text")
        assert fmt in FORMATS
        try:
            with path.open("w", encoding="utf-8", newline="" if fmt == "csv" else None) as out:
                lister = Lister(out, fmt, describer, absolute=absolute)
                n = lister.write(rows, flush=False)
        except OSError as exc:
            reason = f"cannot write {path}: {exc.strerror or exc}"
            app.call_from_thread(app.say, reason, severity="error")
            return
        app.call_from_thread(app.say, f"wrote {n:,} rows to {path} ({fmt})")

    def copy(self, what: str) -> None:
        row = self.frames.cursor_row
        if row is None:
            return
        model = self.model
        if what == "hex":
            text = model.reader.raw(row).hex(" ")
        else:
            out = io.StringIO()
            Lister(out, "jsonl", model.describer, absolute=model.absolute).write([row], flush=False)
            text = out.getvalue().strip()
        self.app.copy_to_clipboard(text)
        note = clipboard_note()
        if note is not None:  # sent, but it cannot arrive: say so, and how to fix it
            self.app.say(f"#{row} not copied: {note}", severity="warning", timeout=20)
            return
        self.app.say(
            f"copied #{row} as {what} ({len(text):,} characters) by OSC 52, if the terminal "
            "allows it"
        )
