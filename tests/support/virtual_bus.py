"""Provides a virtual RS-485 bus for tests: pseudo-terminal ends joined by a relay thread.

Every byte one end transmits (writes to its pty) reaches every other attached end, as
on a half-duplex RS-485 line. Each end is reached through a stable symbolic link (like
`/dev/serial/by-id/...`), so an end can be unplugged (its pty destroyed) and plugged in
again as a new pty behind the same path. The relay keeps what every end transmitted,
so a test can prove that an end never sent a byte.

Also here: `Tripwire`, a serial port double that fails on anything that could drive a
line; `ModbusServer` and `modbus_client`, pymodbus's serial server (units 1 and 2, known
register values) and client for a bus; `wait_ready`, which waits for a modscope
subprocess to say it listens.
"""

from __future__ import annotations

import asyncio
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
from typing import Any

import serial


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

    def echoes(self, name: str) -> bool:
        """Whether the end's terminal still echoes what it receives (cooked mode). Read
        through the relay's own descriptor: a program may hold the port exclusively."""
        with self._lock:
            fd = self.ends[name].slave
        return bool(termios.tcgetattr(fd)[3] & termios.ECHO)

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


# -- a serial port double ------------------------------------------------------------------


class ForbiddenError(AssertionError):
    """The code under test did something that could drive the line."""


class Tripwire(serial.Serial):
    """A serial port double. Reads come from a pipe the test writes into; anything that
    could put a signal on the line raises (and is remembered, in case it was caught)."""

    def __init__(self, name: str = "") -> None:
        self.calls: list[str] = []
        self.violations: list[str] = []
        self.feed_fd = -1
        super().__init__()  # no port given: pyserial does not open

    def _forbid(self, what: str) -> None:
        self.violations.append(what)
        raise ForbiddenError(what)

    # -- what a passive reader may do ------------------------------------------------------

    def open(self) -> None:
        self.calls.append("open")
        if self.rts or self.dtr:
            self._forbid(f"opened with RTS={self.rts} DTR={self.dtr}")
        if self.xonxoff or self.rtscts or self.dsrdtr:
            self._forbid("opened with flow control (the driver would send XON/XOFF or RTS)")
        read_end, self.feed_fd = os.pipe()
        self.fd = read_end
        self.is_open = True

    def close(self) -> None:
        self.calls.append("close")
        if self.is_open and self.fd is not None:
            os.close(self.fd)
            self.fd = None
        self.is_open = False

    def set_low_latency_mode(self, low_latency_settings: bool) -> None:
        self.calls.append(f"low_latency={low_latency_settings}")

    def unplug(self) -> None:
        """The far end goes away: reads hit end of file."""
        if self.feed_fd >= 0:
            os.close(self.feed_fd)
            self.feed_fd = -1

    def push(self, data: bytes) -> None:
        os.write(self.feed_fd, data)

    # -- everything that could drive the line ------------------------------------------------

    def write(self, b: Any, /) -> int:
        self._forbid("write")
        return 0

    def writelines(self, lines: Any, /) -> None:
        self._forbid("writelines")

    def send_break(self, duration: float = 0.25) -> None:
        self._forbid("send_break")

    def flush(self) -> None:
        self._forbid("flush (drains output)")

    def reset_output_buffer(self) -> None:
        self._forbid("reset_output_buffer")

    def set_output_flow_control(self, enable: bool = True) -> None:
        self._forbid("set_output_flow_control")

    def set_input_flow_control(self, enable: bool = True) -> None:
        self._forbid("set_input_flow_control (XON/XOFF are transmitted)")

    def _update_break_state(self) -> None:
        self._forbid("break_condition")

    def _update_rts_state(self) -> None:
        if self.rts:
            self._forbid("RTS asserted")
        if self.is_open:
            self._forbid("RTS changed on an open port")

    def _update_dtr_state(self) -> None:
        if self.dtr:
            self._forbid("DTR asserted")
        if self.is_open:
            self._forbid("DTR changed on an open port")

    def _reconfigure_port(self, force_update: bool = False) -> None:
        if self.is_open:
            self._forbid("line settings changed on an open port")

    @property
    def rs485_mode(self) -> Any:
        return None

    @rs485_mode.setter
    def rs485_mode(self, settings: Any) -> None:
        self._forbid("rs485_mode (drives RTS around transmissions)")


class Made:
    """A factory handing out tripwires and keeping them for the test to inspect."""

    def __init__(self) -> None:
        self.ports: list[Tripwire] = []

    def __call__(self, name: str) -> serial.Serial:
        port = Tripwire(name)
        self.ports.append(port)
        return port

    def violations(self) -> list[str]:
        return [v for p in self.ports for v in p.violations]


# -- a real Modbus peer ------------------------------------------------------------------------


def holding(unit: int) -> list[int]:
    """The holding registers the test server gives `unit`: 100*unit + address."""
    return [100 * unit + k for k in range(32)]


def inputs(unit: int) -> list[int]:
    """The input registers the test server gives `unit`: 1000*unit + address."""
    return [1000 * unit + k for k in range(32)]


def coils(unit: int) -> list[bool]:
    """The coils (and discrete inputs) of `unit`: every address divisible by 3 or by `unit` + 3."""
    return [k % 3 == 0 or k % (unit + 3) == 0 for k in range(32)]


class ModbusServer:
    """pymodbus's serial server in a thread, serving `units` on `port` (RTU, 8N2)."""

    def __init__(self, port: Path, units: tuple[int, ...] = (1, 2), baud: int = 19200) -> None:
        self.port = port
        self.units = units
        self.baud = baud
        self._loop = asyncio.new_event_loop()
        self._server: Any = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="pymodbus-server", daemon=True)

    def start(self) -> ModbusServer:
        self._thread.start()
        if not self._ready.wait(5):
            raise RuntimeError("the pymodbus server did not start")
        if self._error is not None:
            raise RuntimeError(f"the pymodbus server failed: {self._error}")
        return self

    def _run(self) -> None:
        from pymodbus import FramerType
        from pymodbus.server import ModbusSerialServer
        from pymodbus.simulator import DataType, SimData, SimDevice

        def device(unit: int) -> Any:
            bits = DataType.BITS
            words = DataType.REGISTERS
            return SimDevice(
                id=unit,
                simdata=(
                    [SimData(0, values=coils(unit), datatype=bits)],
                    [SimData(0, values=coils(unit), datatype=bits)],
                    [SimData(0, values=holding(unit), datatype=words)],
                    [SimData(0, values=inputs(unit), datatype=words)],
                ),
            )

        async def serve() -> None:
            self._server = ModbusSerialServer(
                [device(u) for u in self.units],
                framer=FramerType.RTU,
                port=str(self.port),
                baudrate=self.baud,
                parity="N",
                stopbits=2,
                trace_packet=self._silence_absent_units,
            )
            await self._server.serve_forever(background=True)
            self._ready.set()
            await self._server.serving

        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(serve())
        except BaseException as exc:  # reported by start()
            self._error = exc
            self._ready.set()

    def _silence_absent_units(self, sending: bool, packet: bytes) -> bytes:
        """pymodbus 3.16 answers a unit it does not serve with an exception; a real
        bus stays silent, so such answers are dropped."""
        if sending and packet and packet[0] not in self.units:
            return b""
        return packet

    def stop(self) -> None:
        if self._server is not None and self._loop.is_running():
            future = asyncio.run_coroutine_threadsafe(self._server.shutdown(), self._loop)
            with contextlib.suppress(Exception):
                future.result(3)
        self._thread.join(3)


def modbus_client(port: Path, baud: int = 19200, timeout: float = 0.5) -> Any:
    """A connected pymodbus serial client (RTU, 8N2) on `port`."""
    from pymodbus import FramerType
    from pymodbus.client import ModbusSerialClient

    client = ModbusSerialClient(
        str(port),
        framer=FramerType.RTU,
        baudrate=baud,
        parity="N",
        stopbits=2,
        timeout=timeout,
        retries=0,
    )
    if not client.connect():
        raise RuntimeError(f"the pymodbus client could not open {port}")
    return client


def wait_ready(stderr: Any, limit: int = 20) -> list[str]:
    """Read a modscope's stderr until it says it listens or records; returns the lines."""
    lines: list[str] = []
    while len(lines) < limit:
        line = stderr.readline()
        if not line:
            raise RuntimeError("modscope ended before it was ready: " + "".join(lines))
        lines.append(line)
        if "listening on" in line or "modscope: recording" in line:
            return lines
    raise RuntimeError("modscope did not say it was ready: " + "".join(lines))
