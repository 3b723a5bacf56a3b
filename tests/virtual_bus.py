"""Provides a virtual RS-485 bus for tests: pseudo-terminal ends joined by a relay thread.

Every byte one end transmits (writes to its pty) reaches every other attached end, as
on a half-duplex RS-485 line. Each end is reached through a stable symbolic link (like
`/dev/serial/by-id/...`), so an end can be unplugged (its pty destroyed) and plugged in
again as a new pty behind the same path. The relay keeps what every end transmitted,
so a test can prove that an end never sent a byte.
"""

from __future__ import annotations

import contextlib
import os
import select
import termios
import threading
import time
import tty
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType


@dataclass
class _End:
    name: str
    link: Path
    master: int = -1
    slave: int = -1
    sent: bytearray = field(default_factory=bytearray)  # what this end transmitted
    dropped: int = 0  # bytes the relay could not deliver to it (its reader was stuck)


def open_pty(raw: bool = True) -> tuple[int, int, str]:
    """A pty pair (master, slave, slave path); the slave raw unless asked otherwise."""
    master, slave = os.openpty()
    if raw:
        tty.setraw(slave)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


def echo_enabled(path: str | Path) -> bool:
    """Whether the terminal at `path` still echoes what it receives (cooked mode)."""
    fd = os.open(path, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        return bool(termios.tcgetattr(fd)[3] & termios.ECHO)
    finally:
        os.close(fd)


class VirtualBus:
    """Ends are pty pairs: programs open `bus.attach(name)`; the relay copies bytes."""

    def __init__(self, directory: Path) -> None:
        self.directory = directory
        self.ends: dict[str, _End] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._wake_r, self._wake_w = os.pipe()
        self._thread = threading.Thread(target=self._relay, name="virtual-bus", daemon=True)
        self._thread.start()

    # -- ends ----------------------------------------------------------------------------

    def attach(self, name: str, *, raw: bool = True) -> Path:
        """A new end; returns the stable path to open. `raw=False` leaves the pty in its
        fresh cooked state (echo on), as a real port is before a program configures it."""
        link = self.directory / name
        end = _End(name, link)
        self._plug(end, raw)
        with self._lock:
            self.ends[name] = end
        self._wake()
        return link

    def unplug(self, name: str) -> None:
        """Destroy the end's pty, as pulling a USB adapter does; the path dangles."""
        with self._lock:
            end = self.ends[name]
            master, slave = end.master, end.slave
            end.master = end.slave = -1
        self._wake()
        with contextlib.suppress(FileNotFoundError):
            end.link.unlink()
        for fd in (master, slave):
            if fd >= 0:
                os.close(fd)

    def plug(self, name: str, *, raw: bool = True) -> None:
        """Bring an unplugged end back as a new pty behind the same path."""
        with self._lock:
            end = self.ends[name]
        self._plug(end, raw)
        self._wake()

    def _plug(self, end: _End, raw: bool) -> None:
        master, slave, path = open_pty(raw)
        with contextlib.suppress(FileNotFoundError):
            end.link.unlink()
        end.link.symlink_to(path)
        with self._lock:
            end.master, end.slave = master, slave

    def sent_by(self, name: str) -> bytes:
        """Every byte the end has transmitted onto the bus so far."""
        with self._lock:
            return bytes(self.ends[name].sent)

    def inject(self, data: bytes, *, source: str = "") -> None:
        """Put bytes on the bus as a device would (all ends but `source` receive them)."""
        with self._lock:
            self._deliver(data, source)

    # -- the relay -----------------------------------------------------------------------

    def _wake(self) -> None:
        os.write(self._wake_w, b"x")

    def _relay(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                fds = {end.master: end for end in self.ends.values() if end.master >= 0}
            ready, _, _ = select.select([self._wake_r, *fds], [], [], 0.5)
            for fd in ready:
                if fd == self._wake_r:
                    os.read(self._wake_r, 4096)
                    continue
                with self._lock:
                    end = fds[fd]
                    if end.master != fd:  # unplugged meanwhile
                        continue
                    try:
                        data = os.read(fd, 4096)
                    except (BlockingIOError, InterruptedError):
                        continue
                    except OSError:
                        data = b""
                    if not data:
                        continue
                    end.sent += data
                    self._deliver(data, end.name)

    def _deliver(self, data: bytes, source: str) -> None:
        for other in self.ends.values():
            if other.name == source or other.master < 0:
                continue
            view = memoryview(data)
            deadline = time.monotonic() + 0.5
            while view:
                try:
                    n = os.write(other.master, view)
                except BlockingIOError:
                    if time.monotonic() > deadline:
                        other.dropped += len(view)
                        break
                    time.sleep(0.001)
                    continue
                except OSError:
                    other.dropped += len(view)
                    break
                view = view[n:]

    # -- lifetime ------------------------------------------------------------------------

    def close(self) -> None:
        self._stop.set()
        self._wake()
        self._thread.join(timeout=2)
        for name in list(self.ends):
            self.unplug(name)
        os.close(self._wake_r)
        os.close(self._wake_w)

    def __enter__(self) -> VirtualBus:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
