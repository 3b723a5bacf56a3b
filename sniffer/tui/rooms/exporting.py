"""Provides the export's room: `e` writes the rows shown to a file, `c` `C` copy the
selected row (hex, JSON) to the clipboard.

Under `modscope serve` (MODSCOPE_SERVED set by it) a visitor names no path on this
machine: the answer is a plain file name, written inside the folder `serve --export-dir`
gave (never over a file) and handed to the browser as a download; without the folder it
is only a download (docs/untrusted-input.md, "serve").
"""

from __future__ import annotations

import io
import os
import tempfile
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
# set by `modscope serve` for the apps it starts (the names its command module uses)
SERVED_ENV = "MODSCOPE_SERVED"
EXPORT_DIR_ENV = "MODSCOPE_SERVE_EXPORT_DIR"


def served() -> bool:
    """Whether this app runs for a browser visitor of `modscope serve`."""
    return bool(os.environ.get(SERVED_ENV))


def served_path(answer: str) -> tuple[Path | None, str]:
    """Where a served visitor's file `answer` goes: (a path inside the export folder, "")
    or (None, "") for a download only when there is no folder, or (None, why) when the
    answer is refused (a folder in it, a hidden name, a file already there)."""
    name = answer.strip()
    if not name or Path(name).name != name or name.startswith(".") or "\\" in name:
        return None, f"{answer!r}: give a plain file name (it goes to the export folder)"
    folder = os.environ.get(EXPORT_DIR_ENV)
    if not folder:
        return None, ""
    path = Path(folder) / name
    if path.exists() or path.is_symlink():
        return None, f"{name} exists in the export folder already; give another name"
    return path, ""


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
        path: Path | None = Path(answer).expanduser()
        if served():
            path, why = served_path(answer)
            if why:
                self.app.say(why, severity="error")
                return
        name = answer.strip()
        write = partial(self._write, path, name, rows, describer, model.absolute)
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

    def _write(
        self,
        path: Path | None,
        name: str,
        rows: Iterable[int],
        describer: Describer,
        absolute: bool,
    ) -> None:
        """The export's worker (a thread). `path` None: a served visitor's download only,
        written to an unnamed temporary file."""
        app = self.app
        suffix = Path(name).suffix.lower().lstrip(".")
        fmt = EXPORT_FORMATS.get(suffix, "text")
        assert fmt in FORMATS
        newline = "" if fmt == "csv" else None
        where = str(path) if path is not None else f"the download {name}"
        try:
            if path is None:
                binary = tempfile.TemporaryFile()  # noqa: SIM115 (closed by deliver_binary)
                out = io.TextIOWrapper(binary, encoding="utf-8", newline=newline)
                n = Lister(out, fmt, describer, absolute=absolute).write(rows, flush=False)
                out.flush()
                out.detach()
                binary.seek(0)
                app.call_from_thread(app.deliver_binary, binary, save_filename=name)
            else:  # "x": a served visitor never overwrites; a local user means what he typed
                opened = path.open("x", encoding="utf-8", newline=newline) if served() else None
                with opened or path.open("w", encoding="utf-8", newline=newline) as text:
                    n = Lister(text, fmt, describer, absolute=absolute).write(rows, flush=False)
                if served():
                    app.call_from_thread(app.deliver_binary, path, save_filename=name)
        except OSError as exc:
            reason = f"cannot write {where}: {exc.strerror or exc}"
            app.call_from_thread(app.say, reason, severity="error")
            return
        app.call_from_thread(app.say, f"wrote {n:,} rows to {where} ({fmt})")

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
