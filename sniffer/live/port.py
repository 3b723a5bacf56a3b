"""Provides the passive serial reader: ports opened without driving the line, read by threads.

Passive means the port is configured before it is opened with RTS and DTR not asserted
(pyserial raises both by default), in raw mode without software flow control (so the
driver never sends XON/XOFF), locked for exclusive use, and then only ever read: no
write, no break, no line setter, no output flush is called anywhere in this module.

One thread per port reads whatever the port has, stamps each read with
`time.monotonic_ns()` anchored once to the wall clock, and offers the chunk to every
subscribed `ChunkFeed`. A feed is bounded and never blocks the reader: when its consumer
(screen, disk) falls behind, chunks are dropped and counted, and the consumer finds a
"data lost" event chunk with the count where the gap is. A port that vanishes (adapter
unplugged) is reported with a "port lost" event, reopened every `retry` seconds, and the
gap closed with a "reconnect" event. On Linux the driver's own error counters
(TIOCGICOUNT: overruns, framing and parity errors, breaks) are read once a second and
become events too, so a loss in the driver is not silent either.
"""

from __future__ import annotations

import array
import contextlib
import errno
import fcntl
import os
import re
import select
import sys
import termios
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

import serial

from sniffer.errors import UserError
from sniffer.model import Chunk, Direction, LineSettings

READ_SIZE = 1 << 16  # bytes asked of one read: whatever the port has, up to this
POLL_SECONDS = 0.2  # longest wait of a reader before it looks at its stop flag
RETRY_SECONDS = 0.5  # how often a lost port is tried again
ICOUNT_SECONDS = 1.0  # how often the driver's error counters are read
DEFAULT_QUEUE = 100_000  # chunks a feed holds before it drops (and counts)
QUEUE_BYTES = 8 << 20  # bytes a feed holds before it drops: 90 s of a 921600 baud line
URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")
TIOCGICOUNT = 0x545D  # Linux: struct serial_icounter_struct
TIOCEXCL = getattr(termios, "TIOCEXCL", 0x540C)
TIOCNXCL = getattr(termios, "TIOCNXCL", 0x540D)

PortFactory = Callable[[str], serial.Serial]
"""Makes an unopened port object for a port name (a device path or a pyserial URL)."""


class PortError(UserError):
    """A port cannot be used. The message names the port and what to do."""


class SettingsRefusedError(PortError):
    """The port is there but refused the line settings asked of it; other settings may
    work (the scan skips the refused ones)."""


@dataclass(frozen=True, slots=True)
class PortSpec:
    """A port to listen on: its name, line settings, and the channel its chunks carry."""

    name: str
    line: LineSettings
    channel: int = 0
    direction: Direction = Direction.UNKNOWN

    @property
    def is_url(self) -> bool:
        return bool(URL.match(self.name))


class WallClock:
    """Monotonic time anchored once to the wall clock: `t = wall0 + (mono - mono0) / 1e9`.

    Unix seconds that never jump when the system clock is set, shared by all ports of a
    capture so that their chunks merge in true order."""

    def __init__(self) -> None:
        self.mono0 = time.monotonic_ns()
        self.wall0 = time.time()

    def at(self, mono_ns: int) -> float:
        return self.wall0 + (mono_ns - self.mono0) / 1e9

    def now(self) -> float:
        return self.at(time.monotonic_ns())


# -- opening a port without touching the line --------------------------------------------


def new_port(name: str) -> serial.Serial:
    """An unopened pyserial port for a device path or a URL (rfc2217://, socket://)."""
    if URL.match(name):
        port: serial.Serial = serial.serial_for_url(name, do_not_open=True)
        return port
    return serial.Serial()


def configure(port: serial.Serial, spec: PortSpec) -> None:
    """Set everything before `open()`: line format, RTS and DTR off, no flow control,
    exclusive access. Nothing here touches the line: the port is not open yet."""
    line = spec.line
    port.port = spec.name
    port.baudrate = line.baud
    port.bytesize = line.bytesize
    port.parity = line.parity
    port.stopbits = line.stopbits
    port.timeout = POLL_SECONDS
    port.xonxoff = False  # the driver would send XOFF when its buffer fills
    port.rtscts = False
    port.dsrdtr = False
    port.rts = False  # pyserial asserts both by default when it opens
    port.dtr = False
    with contextlib.suppress(AttributeError, ValueError, NotImplementedError):
        port.exclusive = True


def posix_fd(port: serial.Serial) -> int | None:
    """The file descriptor of an open local port (read directly), else None."""
    if sys.platform == "win32" or not isinstance(port, serial.Serial):
        return None
    fd = getattr(port, "fd", None)
    return fd if isinstance(fd, int) and fd >= 0 else None


def _code_and_text(exc: BaseException) -> tuple[int | None, str]:
    code = exc.errno if isinstance(exc, OSError) else None
    text = str(exc)
    if isinstance(exc, termios.error):
        # pyserial lets the termios call's own error through: (errno, text)
        args = exc.args
        code = args[0] if args and isinstance(args[0], int) else None
        text = str(args[1]) if len(args) > 1 else text
    return code, text


def refused_settings(exc: BaseException) -> bool:
    """The open failed on the line settings, not on the port: EINVAL from the tty
    ioctls, or an RFC 2217 server rejecting a value (pyserial's ValueError)."""
    code, text = _code_and_text(exc)
    if isinstance(exc, ValueError) and "rejected value" in text:
        return True
    return code == errno.EINVAL or "Invalid argument" in text


def explain(spec: PortSpec, exc: BaseException) -> str:
    """What went wrong opening `spec`, and what to do about it."""
    name = spec.name
    code, text = _code_and_text(exc)
    if code in (errno.ENOENT, errno.ENODEV, errno.ENXIO) or "No such file" in text:
        return (
            f"{name}: no such serial port; `modscope ports` lists the ports this machine "
            "has (is the adapter plugged in?)"
        )
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return (
            f"{name}: permission denied; add yourself to the dialout group "
            "(sudo usermod -aG dialout $USER, then log in again) or ask for access to the port"
        )
    if code in (errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK) or "exclusively lock" in text:
        return (
            f"{name}: the port is busy: another program holds it (a terminal, a Modbus "
            f"master, another modscope); close it and try again (`fuser {name}` shows who)"
        )
    if "Inappropriate ioctl" in text or code == errno.ENOTTY:
        return f"{name}: is not a serial port; give a serial device such as /dev/ttyUSB0"
    if refused_settings(exc):
        return (
            f"{name}: the port refused the line settings {spec.line.describe()} ({text}); "
            "check --baud, --parity and --stopbits (a pseudo-terminal may refuse even parity)"
        )
    if spec.is_url:
        return (
            f"{name}: cannot connect ({text}); check the URL, that the server runs and "
            "that it is reachable"
        )
    return f"{name}: cannot be opened ({text}); check the port name with `modscope ports`"


def open_passive(
    spec: PortSpec, factory: PortFactory | None = None
) -> tuple[serial.Serial, list[str]]:
    """Open `spec` passively (see the module doc). Returns the port and warnings."""
    warnings: list[str] = []
    try:
        port = (factory or new_port)(spec.name)
        configure(port, spec)
        port.open()
    except (serial.SerialException, OSError, ValueError, termios.error) as exc:
        # termios.error is not an OSError: pyserial raises it when the port refuses the
        # line settings (a pseudo-terminal refusing even parity, a tunnel's remote end)
        error = SettingsRefusedError if refused_settings(exc) else PortError
        raise error(explain(spec, exc)) from None
    fd = posix_fd(port)
    if fd is not None:
        with contextlib.suppress(OSError):
            fcntl.ioctl(fd, TIOCEXCL)  # a second open() now fails instead of sharing bytes
        warnings.extend(_low_latency(port, spec.name))
        warnings.extend(_shared_warning(spec.name))
    return port, warnings


def _low_latency(port: serial.Serial, name: str) -> list[str]:
    setter = getattr(port, "set_low_latency_mode", None)
    if setter is None:
        return []
    try:
        setter(True)
    except (ValueError, OSError, NotImplementedError) as exc:
        device = Path(name).resolve().name
        node = device if device.startswith("ttyUSB") else "ttyUSB0"
        return [
            f"{name}: low latency mode is not available ({exc}); bytes may arrive in "
            "bursts and gaps look shorter. For an FTDI adapter: "
            f"echo 1 > /sys/bus/usb-serial/devices/{node}/latency_timer"
        ]
    return []


def _shared_warning(name: str) -> list[str]:
    found = other_openers(name)
    if not found:
        return []
    who = ", ".join(f"{pid} ({comm})" for pid, comm in found[:5])
    return [
        f"{name}: also open in process {who}; two readers of one port split its bytes "
        "between them, so close the other program for a complete capture"
    ]


def other_openers(name: str) -> list[tuple[int, str]]:
    """Other processes (Linux, where /proc tells) holding the device open."""
    proc = Path("/proc")
    if not proc.is_dir():
        return []
    try:
        target = os.stat(name)
    except OSError:
        return []
    me = os.getpid()
    found: list[tuple[int, str]] = []
    for entry in proc.iterdir():
        if not entry.name.isdigit() or int(entry.name) == me:
            continue
        try:
            fds = list((entry / "fd").iterdir())
        except OSError:
            continue
        for fd in fds:
            try:
                st = os.stat(fd)
            except OSError:
                continue
            if st.st_rdev == target.st_rdev and st.st_ino == target.st_ino:
                try:
                    comm = (entry / "comm").read_text().strip()
                except OSError:
                    comm = "?"
                found.append((int(entry.name), comm))
                break
    return found


def close_port(port: serial.Serial) -> None:
    """Close quietly (the port may already be gone); undo the exclusive mode first."""
    fd = posix_fd(port)
    if fd is not None:
        with contextlib.suppress(OSError):
            fcntl.ioctl(fd, TIOCNXCL)
    with contextlib.suppress(Exception):
        port.close()


# -- handing chunks on ---------------------------------------------------------------------


@dataclass
class _Loss:
    reads: int = 0
    bytes: int = 0
    events: int = 0
    since: float = 0.0


class ChunkFeed:
    """One consumer's bounded, thread-safe queue of chunks. `offer` never blocks: when
    the queue holds `maxsize` chunks or `max_bytes` bytes the chunk is dropped and
    counted, and a "data lost" event chunk with the count is queued ahead of the next
    chunk that fits. Both bounds matter: a busy line gives few big reads."""

    def __init__(
        self,
        maxsize: int = DEFAULT_QUEUE,
        clock: WallClock | None = None,
        max_bytes: int = QUEUE_BYTES,
    ) -> None:
        if maxsize < 1:
            raise ValueError(f"a feed holds at least one chunk, not {maxsize}")
        self.maxsize = maxsize
        self.max_bytes = max_bytes
        self.clock = clock or WallClock()
        self._bytes = 0
        self._items: deque[Chunk] = deque()
        self._cond = threading.Condition()
        self._closed = False
        self._loss: dict[int, _Loss] = {}
        self.lost_reads = 0
        self.lost_bytes = 0
        self.lost_events = 0

    def offer(self, chunk: Chunk) -> None:
        with self._cond:
            if self._closed:
                return
            if len(self._items) >= self.maxsize or (
                self._bytes + len(chunk.data) > self.max_bytes and self._items
            ):
                loss = self._loss.get(chunk.channel)
                if loss is None:
                    loss = self._loss[chunk.channel] = _Loss(since=chunk.t_end)
                if chunk.event:
                    loss.events += 1
                    self.lost_events += 1
                else:
                    loss.reads += 1
                    loss.bytes += len(chunk.data)
                    self.lost_reads += 1
                    self.lost_bytes += len(chunk.data)
                return
            if self._loss:
                self._mark_losses(chunk.t_end)
            self._items.append(chunk)
            self._bytes += len(chunk.data)
            self._cond.notify()

    def _mark_losses(self, t: float) -> None:
        for channel, loss in sorted(self._loss.items()):
            parts = [f"{loss.bytes} bytes in {loss.reads} reads"]
            if loss.events:
                parts.append(f"{loss.events} events")
            note = (
                f"{' and '.join(parts)} dropped since {loss.since:.3f}: the display or disk "
                "fell behind the port"
            )
            self._items.append(Chunk(b"", t, channel=channel, event="data lost", note=note))
        self._loss.clear()

    def get(self, timeout: float | None = None) -> list[Chunk]:
        """Everything queued, waiting up to `timeout` seconds for the first chunk."""
        with self._cond:
            if not self._items and not self._closed:
                self._cond.wait(timeout)
            items = list(self._items)
            self._items.clear()
            self._bytes = 0
            if not items and self._closed and self._loss:
                self._mark_losses(self.clock.now())
                items = list(self._items)
                self._items.clear()
            return items

    def close(self) -> None:
        """No more chunks will come; a waiting `get` returns."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        with self._cond:
            return self._closed and not self._items and not self._loss

    def __len__(self) -> int:
        with self._cond:
            return len(self._items)


# -- reading ---------------------------------------------------------------------------------


@dataclass
class PortStats:
    """What one port delivered so far."""

    name: str
    reads: int = 0
    bytes: int = 0
    lost_port: int = 0  # times the port vanished
    connected: bool = True


class _PortLostError(Exception):
    """The port stopped working: unplugged, closed by the other side, read error."""


@dataclass
class _Counters:
    """The driver's error counters (Linux TIOCGICOUNT) as last read."""

    frame: int
    overrun: int
    parity: int
    brk: int


def read_icount(fd: int) -> _Counters | None:
    """The driver's counters of a local port; None where the driver has none (a pty)."""
    buf = array.array("i", [0] * 20)
    try:
        fcntl.ioctl(fd, TIOCGICOUNT, buf)
    except OSError:
        return None
    # cts, dsr, rng, dcd, rx, tx, frame, overrun, parity, brk, buf_overrun, reserved...
    return _Counters(frame=buf[6], overrun=buf[7] + buf[10], parity=buf[8], brk=buf[9])


def counter_events(old: _Counters, new: _Counters) -> list[tuple[str, str]]:
    """(event, note) for every counter that went up between two readings."""
    out: list[tuple[str, str]] = []
    if new.overrun > old.overrun:
        out.append(("data lost", f"the driver dropped {new.overrun - old.overrun} bytes (overrun)"))
    if new.frame > old.frame:
        out.append(("framing error", f"{new.frame - old.frame} framing errors on the line"))
    if new.parity > old.parity:
        out.append(("parity error", f"{new.parity - old.parity} parity errors on the line"))
    if new.brk > old.brk:
        out.append(("break", f"{new.brk - old.brk} breaks on the line"))
    return out


class LiveReader:
    """Reads ports in threads and offers every chunk to each subscribed feed.

    `open()` opens all ports (PortError if one fails, nothing left open), `subscribe()`
    adds a consumer's feed, `start()` starts reading, `stop()` stops and closes (safe to
    call twice). Feeds are closed when the reader stops.
    """

    def __init__(
        self,
        specs: Sequence[PortSpec],
        *,
        factory: PortFactory | None = None,
        clock: WallClock | None = None,
        retry: float = RETRY_SECONDS,
    ) -> None:
        if not specs:
            raise ValueError("give at least one port to listen on")
        self.specs = list(specs)
        self.factory = factory
        self.clock = clock or WallClock()
        self.retry = retry
        self.warnings: list[str] = []
        self.failure: str | None = None  # why a reading thread ended on its own (a bug)
        self.error: Exception | None = None  # and the exception that ended it
        self.stats = [PortStats(s.name) for s in self.specs]
        self.feeds: list[ChunkFeed] = []
        self._ports: list[serial.Serial | None] = [None] * len(self.specs)
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()
        self._wake_r, self._wake_w = os.pipe()
        self._lock = threading.Lock()
        self._started = False
        self._stopped = False

    # -- lifetime --------------------------------------------------------------------------

    def open(self) -> None:
        try:
            for n, spec in enumerate(self.specs):
                port, warnings = open_passive(spec, self.factory)
                self._ports[n] = port
                self.warnings.extend(warnings)
        except PortError:
            self._close_ports()
            raise

    def subscribe(self, maxsize: int = DEFAULT_QUEUE) -> ChunkFeed:
        if self._started:
            raise RuntimeError("subscribe before start()")
        feed = ChunkFeed(maxsize, self.clock)
        self.feeds.append(feed)
        return feed

    def attach(self, maxsize: int = DEFAULT_QUEUE) -> ChunkFeed:
        """A feed for a consumer that joins while the ports are being read (a recording
        started from the TUI). The list is replaced, not changed, so the reading threads
        never see it half-updated."""
        feed = ChunkFeed(maxsize, self.clock)
        self.feeds = [*self.feeds, feed]
        return feed

    def detach(self, feed: ChunkFeed) -> None:
        """Stop offering chunks to `feed` and close it (what it holds can still be read)."""
        self.feeds = [f for f in self.feeds if f is not feed]
        feed.close()

    def start(self) -> None:
        if self._started:
            return
        if any(p is None for p in self._ports):
            self.open()
        self._started = True
        for n, spec in enumerate(self.specs):
            thread = threading.Thread(
                target=self._run, args=(n,), name=f"modscope-read-{spec.name}", daemon=True
            )
            self._threads.append(thread)
            thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        if self._stopped:
            return
        self._stopped = True
        self._stop.set()
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")
        for thread in self._threads:
            thread.join(timeout)
        self._close_ports()
        for feed in self.feeds:
            feed.close()
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)

    @property
    def running(self) -> bool:
        """True while started, not stopped, and every reading thread is alive (a thread
        ends on its own only through a bug, which `failure` then describes)."""
        return (
            self._started
            and not self._stop.is_set()
            and self.failure is None
            and all(t.is_alive() for t in self._threads)
        )

    def __enter__(self) -> LiveReader:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    def _close_ports(self) -> None:
        with self._lock:
            ports, self._ports = self._ports, [None] * len(self.specs)
        for port in ports:
            if port is not None:
                close_port(port)

    # -- the reading threads -----------------------------------------------------------------

    def _emit(self, chunk: Chunk) -> None:
        for feed in self.feeds:
            feed.offer(chunk)

    def _event(self, n: int, event: str, note: str) -> None:
        spec = self.specs[n]
        self._emit(
            Chunk(
                b"",
                self.clock.now(),
                channel=spec.channel,
                direction=spec.direction,
                event=event,
                note=note,
            )
        )

    def _run(self, n: int) -> None:
        try:
            self._read_until_stopped(n)
        except Exception as exc:  # a bug: say so where the user looks, and stop running
            spec = self.specs[n]
            self.stats[n].connected = False
            self.error = exc
            self.failure = (
                f"{spec.name}: reading stopped by an internal error "
                f"({type(exc).__name__}: {exc}); this is a bug in modscope, please report it"
            )
            self._event(n, "reader stopped", self.failure)

    def _read_until_stopped(self, n: int) -> None:
        spec = self.specs[n]
        while not self._stop.is_set():
            with self._lock:
                port = self._ports[n]
            if port is None:
                return
            try:
                fd = posix_fd(port)
                if fd is not None:
                    self._read_fd(n, fd)
                else:
                    self._read_port(n, port)
                return  # stopped
            except _PortLostError as exc:
                if self._stop.is_set():
                    return
                self.stats[n].lost_port += 1
                self.stats[n].connected = False
                lost_at = time.monotonic()
                self._event(
                    n,
                    "port lost",
                    f"{spec.name}: {exc}; trying to reopen it every {self.retry:g} s",
                )
                with self._lock:
                    if self._ports[n] is port:
                        self._ports[n] = None
                close_port(port)
                if not self._reopen(n):
                    return
                self.stats[n].connected = True
                gap = time.monotonic() - lost_at
                self._event(
                    n,
                    "reconnect",
                    f"{spec.name}: back after {gap:.1f} s; what the line carried meanwhile "
                    "was not seen",
                )

    def _reopen(self, n: int) -> bool:
        """Try to open the lost port every `retry` seconds until it opens or reading
        stops. Why it cannot be opened is reported as an event whenever the reason
        changes (the adapter is back but refuses the line settings, is busy, ...)."""
        spec = self.specs[n]
        told = ""
        while not self._stop.wait(self.retry):
            try:
                port, _warnings = open_passive(spec, self.factory)
            except PortError as exc:
                reason = str(exc)
                missing = "no such serial port" in reason  # still unplugged: said already
                if reason != told and not missing:
                    self._event(n, "reopen failed", f"{reason}; trying again")
                told = reason
                continue
            with self._lock:
                if self._stop.is_set():
                    close_port(port)
                    return False
                self._ports[n] = port
            return True
        return False

    def _chunk(self, n: int, data: bytes, mono_ns: int) -> None:
        spec = self.specs[n]
        st = self.stats[n]
        st.reads += 1
        st.bytes += len(data)
        self._emit(
            Chunk(data, self.clock.at(mono_ns), channel=spec.channel, direction=spec.direction)
        )

    def _read_fd(self, n: int, fd: int) -> None:
        """A local port: poll and `os.read` whatever it has (one chunk per read)."""
        poller = select.poll()
        poller.register(fd, select.POLLIN | select.POLLERR | select.POLLHUP)
        poller.register(self._wake_r, select.POLLIN)
        counters = read_icount(fd)
        next_count = time.monotonic() + ICOUNT_SECONDS
        timeout_ms = int(POLL_SECONDS * 1000)
        mono = time.monotonic_ns
        while True:
            events = poller.poll(timeout_ms)
            if self._stop.is_set():
                return
            if events:
                try:
                    data = os.read(fd, READ_SIZE)
                except (BlockingIOError, InterruptedError):
                    data = None
                except OSError as exc:
                    raise _PortLostError(exc.strerror or str(exc)) from None
                if data is not None:
                    if not data:
                        raise _PortLostError("the device returned no data (disconnected?)")
                    self._chunk(n, data, mono())
            if counters is not None and time.monotonic() >= next_count:
                next_count = time.monotonic() + ICOUNT_SECONDS
                fresh = read_icount(fd)
                if fresh is not None:
                    for event, note in counter_events(counters, fresh):
                        self._event(n, event, note)
                    counters = fresh

    def _read_port(self, n: int, port: serial.Serial) -> None:
        """Any other port (URL handlers): read one byte with a timeout, then the rest."""
        mono = time.monotonic_ns
        while not self._stop.is_set():
            try:
                data = port.read(1)
                if not data:
                    continue
                waiting = port.in_waiting
                if waiting:
                    data += port.read(min(waiting, READ_SIZE))
            except (serial.SerialException, OSError) as exc:
                raise _PortLostError(str(exc) or type(exc).__name__) from None
            self._chunk(n, data, mono())


@dataclass
class PortListing:
    """One serial port as `modscope ports` shows it."""

    device: str
    description: str
    hwid: str
    vid: int | None = None
    pid: int | None = None
    serial_number: str | None = None
    manufacturer: str | None = None
    product: str | None = None
    location: str | None = None

    @property
    def usb_id(self) -> str:
        if self.vid is None or self.pid is None:
            return ""
        return f"{self.vid:04x}:{self.pid:04x}"


def list_ports(include_links: bool = True) -> Iterator[PortListing]:
    """The serial ports pyserial finds on this machine, sorted by device name."""
    from serial.tools import list_ports as lp

    infos = sorted(lp.comports(include_links=include_links), key=lambda p: p.device)
    for info in infos:
        vid = info.vid if isinstance(info.vid, int) else None
        pid = info.pid if isinstance(info.pid, int) else None
        yield PortListing(
            device=info.device,
            description=info.description or "",
            hwid=info.hwid or "",
            vid=vid,
            pid=pid,
            serial_number=info.serial_number,
            manufacturer=info.manufacturer,
            product=info.product,
            location=info.location,
        )
