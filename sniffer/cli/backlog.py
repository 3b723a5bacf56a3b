"""Provides the live listing's way out: text written only as fast as the reader of the
output takes it, never blocking the capture, never holding more than a bound.

A pipe that is not read (`modscope live ... | slow-consumer`) would otherwise stop the
loop in `write()`: the ports' feeds fill, Ctrl-C waits for the pipe, and rows pile up.
Here the loop asks `select()` whether the output takes bytes, writes at most one pipe
buffer's worth (PIPE_BUF, which a writable pipe takes without blocking; whole lines, so
that a row is never left cut when the reader is given up on), and goes back to the
capture. Rows that arrive while `limit` bytes wait are not rendered: they are
dropped and counted, and the listing's `index` column shows the gap.
"""

from __future__ import annotations

import io
import os
import select
import time
from typing import TextIO

BACKLOG_BYTES = 8 << 20  # listing bytes held for a slow reader before rows are dropped
CHUNK = getattr(select, "PIPE_BUF", 512)  # bytes a writable pipe takes without blocking


def _fileno(out: TextIO) -> int | None:
    try:
        return out.fileno()
    except (OSError, ValueError, AttributeError, io.UnsupportedOperation):
        return None


class Backlog:
    """Listing text on its way to `out`. With a real file descriptor (pipe, file,
    terminal) it is written without blocking; other streams (a StringIO) take it at once."""

    def __init__(self, out: TextIO, limit: int = BACKLOG_BYTES) -> None:
        self.out = out
        self.limit = limit
        self.fd = _fileno(out)
        self.pending = bytearray()
        self.dropped = 0  # rows not written: the output fell behind
        self.written = 0  # bytes written
        if self.fd is not None:
            out.flush()  # what went through `out` before stays in front

    @property
    def full(self) -> bool:
        return len(self.pending) >= self.limit

    def add(self, text: str) -> None:
        if not text:
            return
        if self.fd is None:
            self.out.write(text)
            self.out.flush()
            return
        self.pending += text.encode("utf-8")

    def drop(self, rows: int) -> None:
        self.dropped += rows

    def send(self, wait: float = 0.0) -> None:
        """Write what the output takes now, waiting up to `wait` seconds for it to take
        the first bytes. BrokenPipeError when its reader went away."""
        if self.fd is None:
            return
        while self.pending:
            _, ready, _ = select.select([], [self.fd], [], wait)
            if not ready:
                return
            wait = 0.0
            # whole lines, so that giving up never leaves half a row; a line longer
            # than CHUNK goes in pieces
            end = self.pending.rfind(b"\n", 0, CHUNK)
            n = os.write(self.fd, self.pending[: end + 1 if end >= 0 else CHUNK])
            del self.pending[:n]
            self.written += n

    def finish(self, grace: float) -> int:
        """Write what is left within `grace` seconds; returns the bytes given up (the
        output's reader did not take them in time)."""
        end = time.monotonic() + grace
        while self.pending:
            left = end - time.monotonic()
            if left <= 0:
                break
            self.send(min(left, 0.05))
        lost = len(self.pending)
        self.pending.clear()
        return lost
