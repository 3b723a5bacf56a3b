"""Provides the progress line long commands show on a terminal: how far, and the time left.

Only on a terminal (stderr a tty), only after a second, and always on stderr, so it
never mixes into a listing. While a capture is read, how far is the share of the file's
bytes the process has read (Linux counts them in /proc/self/io, whatever the format's
overhead); elsewhere the line gives bytes and rows without a share. While rows are
written, it is the share of the rows.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TextIO

from sniffer.sources.procio import bytes_read as _bytes_read
from sniffer.text import plain

SHOW_AFTER = 1.0  # seconds before the line appears
EVERY = 0.25  # seconds between updates


def _left(elapsed: float, share: float) -> str:
    if share <= 0.0:
        return ""
    seconds = elapsed * (1.0 - share) / share
    if seconds < 1.0:
        return ", under a second left"
    if seconds < 90:
        return f", about {seconds:.0f} s left"
    return f", about {seconds / 60:.0f} min left"


class Progress:
    """`reading(bytes, rows)` is `Session.ingest`'s progress callback; `rows(...)` wraps
    the rows an output writes; `done()` clears the line."""

    def __init__(self, err: TextIO, name: str, path: Path | None = None) -> None:
        self.err = err
        self.name = plain(name)
        self.shown = False
        self.on = err.isatty()
        self.size = 0
        if path is not None:
            try:
                self.size = path.stat().st_size if path.is_file() else 0
            except OSError:
                self.size = 0
        self.base = _bytes_read() if self.on else None
        self.start = time.monotonic()
        self.last = 0.0
        self._writing: float | None = None  # when `share` was first told

    def _show(self, text: str) -> None:
        self.err.write("\r" + text + "\x1b[K")
        self.err.flush()
        self.shown = True

    def _due(self) -> float | None:
        """Seconds since the start, when the line is due for an update, else None."""
        if not self.on:
            return None
        now = time.monotonic()
        elapsed = now - self.start
        if elapsed < SHOW_AFTER or now - self.last < EVERY:
            return None
        self.last = now
        return elapsed

    def reading(self, done: int, rows: int) -> None:
        elapsed = self._due()
        if elapsed is None:
            return
        now_read = _bytes_read()
        if self.size and self.base is not None and now_read is not None:
            share = min(0.999, max(0.0, (now_read - self.base) / self.size))
            text = f"reading {self.name}: {share:.0%}, {rows:,} rows{_left(elapsed, share)}"
        else:
            text = f"reading {self.name}: {done / 1e6:.1f} MB, {rows:,} rows"
        self._show(text)

    def rows(self, rows: Iterable[int], total: int, verb: str = "writing") -> Iterator[int]:
        """The rows, passed on, with the share written shown as they go."""
        start = time.monotonic()
        for n, row in enumerate(rows):
            if n % 256 == 0 and total:
                elapsed = self._due()
                if elapsed is not None:
                    share = n / total
                    took = time.monotonic() - start
                    self._show(f"{verb} {self.name}: {share:.0%}{_left(took, share)}")
            yield row

    def share(self, done: int, total: int, verb: str = "writing") -> None:
        """`done` of `total` rows written (a second pass over a capture, its rows a
        segment at a time: `sniffer.cli.replaying.each_segment`)."""
        now = time.monotonic()
        if self._writing is None:
            self._writing = now
        elapsed = self._due()
        if elapsed is None or total <= 0:
            return
        share = min(0.999, max(0.0, done / total))
        self._show(f"{verb} {self.name}: {share:.0%}{_left(now - self._writing, share)}")

    def done(self) -> None:
        if self.shown:
            self.err.write("\r\x1b[K")
            self.err.flush()
            self.shown = False
