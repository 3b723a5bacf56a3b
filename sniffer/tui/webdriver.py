"""The driver the app runs under when `modscope serve` shows it in a browser.

textual-serve starts each visitor's app with Textual's WebDriver, which frames everything
it sends the server as packets on one pipe (stdout): a type byte, a 4-byte length, the
payload. It writes the screen from the app's thread and a download's chunks (64 KiB each)
from its input thread, each with a bare `os.write`. On Linux a write to a pipe of more
than PIPE_BUF bytes is not atomic: when the pipe is full (a server slowed by a loaded
machine) the writer sleeps part-way and the other thread's packet lands inside its chunk.
From there the server reads lengths out of the middle of a payload; the download waits
for a chunk that never comes and the browser is handed a file cut short, and the screen
stops (seen on a 2-core machine running the tests; textual-serve issue #29 reports
unreliable downloads). `os.write` may also return having written part of a packet.

WholeWrites gives every packet one writer at a time, written to its last byte.
"""

from __future__ import annotations

import os
import threading

from textual.drivers.web_driver import WebDriver


class WholeWrites(WebDriver):
    """Textual's WebDriver, whose packets reach the pipe whole and one at a time."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self._one_writer = threading.Lock()
        self._write = self._whole  # type: ignore[assignment]  # (a partial of os.write)

    def _whole(self, data: bytes) -> int:
        """Write `data` to the pipe to its last byte, no other packet between its bytes."""
        view = memoryview(data)
        with self._one_writer:
            while view:
                view = view[os.write(self.fileno, view) :]
        return len(data)
