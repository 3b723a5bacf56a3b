"""Passive means passive: modscope opens ports without asserting RTS or DTR, never writes,
never sends a break, never changes a line setting of an open port, and the far end of a
real pseudo-terminal reads back nothing from it (not even the tty's own echo)."""

from __future__ import annotations

import ast
import errno
import fcntl
import os
import select
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import serial

from dissectors.checks import with_crc
from sniffer.live.port import ChunkFeed, LiveReader, PortError, PortSpec, open_passive
from sniffer.model import Chunk, LineSettings
from tests.support.virtual_bus import ForbiddenError, Made, Tripwire, VirtualBus

LINE = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
REQUEST = with_crc(bytes.fromhex("010300000005"))
ANSWER = with_crc(bytes.fromhex("01030a00640065006600670068"))
ROOT = Path(__file__).resolve().parent.parent.parent
MODSCOPE = str(Path(sys.executable).with_name("modscope"))


def wait_for(feed: ChunkFeed, predicate: Any, timeout: float = 3.0) -> list[Chunk]:
    got: list[Chunk] = []
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got += feed.get(0.05)
        if predicate(got):
            return got
    raise AssertionError(f"timed out; got {got}")


def data_of(chunks: list[Chunk]) -> bytes:
    return b"".join(c.data for c in chunks)


# -- the double ----------------------------------------------------------------------------


def test_port_is_configured_before_it_opens_with_rts_and_dtr_off() -> None:
    made = Made()
    spec = PortSpec("/dev/ttyDOUBLE0", LINE)
    port, _warnings = open_passive(spec, made)
    try:
        assert isinstance(port, Tripwire)
        assert made.ports == [port]
        assert port.calls[0] == "open"
        assert (port.rts, port.dtr) == (False, False)
        assert (port.baudrate, port.bytesize, port.parity, port.stopbits) == (19200, 8, "N", 2)
        assert port.exclusive is True
        assert (port.xonxoff, port.rtscts, port.dsrdtr) == (False, False, False)
        assert "low_latency=True" in port.calls
        assert made.violations() == []
    finally:
        port.close()


def test_double_catches_what_pyserial_does_by_default() -> None:
    """The double is not toothless: a default pyserial open asserts RTS and DTR."""
    port = Tripwire()
    port.port = "/dev/ttyDOUBLE0"
    with pytest.raises(ForbiddenError, match="RTS=True DTR=True"):
        port.open()
    port = Tripwire()
    port.port = "/dev/ttyDOUBLE0"
    port.rts = False
    port.dtr = False
    port.open()
    with pytest.raises(ForbiddenError):
        port.write(b"x")
    with pytest.raises(ForbiddenError):
        port.send_break()
    with pytest.raises(ForbiddenError):
        port.break_condition = True
    with pytest.raises(ForbiddenError):
        port.rts = True
    with pytest.raises(ForbiddenError):
        port.baudrate = 9600
    port.close()


def test_reading_through_reconnects_never_drives_the_line() -> None:
    made = Made()
    reader = LiveReader([PortSpec("/dev/ttyDOUBLE0", LINE)], factory=made, retry=0.05)
    feed = reader.subscribe()
    reader.start()
    try:
        made.ports[0].push(REQUEST)
        made.ports[0].push(ANSWER)
        got = wait_for(feed, lambda c: data_of(c) == REQUEST + ANSWER)
        made.ports[0].unplug()
        got += wait_for(feed, lambda c: any(x.event == "reconnect" for x in c))
        assert len(made.ports) >= 2
        made.ports[-1].push(REQUEST)
        got += wait_for(feed, lambda c: data_of(c).endswith(REQUEST))
    finally:
        reader.stop()
    events = [c.event for c in got if c.event]
    assert events == ["port lost", "reconnect"]
    assert made.violations() == []
    assert all(p.calls[0] == "open" and p.calls[-1] == "close" for p in made.ports)
    assert not any(c for p in made.ports for c in p.calls if c not in _ALLOWED)


_ALLOWED = {"open", "close", "low_latency=True"}


class UrlTripwire(serial.serialutil.SerialBase):
    """A double for URL ports (read through pyserial's API, no file descriptor)."""

    def __init__(self) -> None:
        self.violations: list[str] = []
        self._r, self._w = os.pipe()
        super().__init__()

    def open(self) -> None:
        if self.rts or self.dtr:
            self.violations.append("opened with RTS/DTR asserted")
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    def read(self, size: int = 1, /) -> bytes:
        ready, _, _ = select.select([self._r], [], [], self.timeout)
        return os.read(self._r, size) if ready else b""

    @property
    def in_waiting(self) -> int:
        ready, _, _ = select.select([self._r], [], [], 0)
        return 4096 if ready else 0

    def write(self, b: Any, /) -> int:
        self.violations.append("write")
        raise ForbiddenError("write")

    def send_break(self, duration: float = 0.25) -> None:
        self.violations.append("send_break")
        raise ForbiddenError("send_break")

    def _update_rts_state(self) -> None:
        if self.rts:
            self.violations.append("RTS")

    def _update_dtr_state(self) -> None:
        if self.dtr:
            self.violations.append("DTR")

    def _update_break_state(self) -> None:
        self.violations.append("break")

    def _reconfigure_port(self) -> None:
        if self.is_open:
            self.violations.append("reconfigured while open")


def test_url_ports_are_read_through_pyserial_without_writing() -> None:
    doubles: list[UrlTripwire] = []

    def factory(name: str) -> Any:
        doubles.append(UrlTripwire())
        return doubles[-1]

    reader = LiveReader([PortSpec("socket://modbus-gw:4001", LINE)], factory=factory)
    feed = reader.subscribe()
    reader.start()
    try:
        os.write(doubles[0]._w, REQUEST)
        got = wait_for(feed, lambda c: data_of(c) == REQUEST)
    finally:
        reader.stop()
    assert got[0].channel == 0
    assert doubles[0].violations == []


def test_no_line_driving_call_in_the_live_code() -> None:
    """Belt and braces: the live modules contain no call that could transmit."""
    banned_calls = {
        "write",
        "writelines",
        "send_break",
        "reset_output_buffer",
        "setRTS",
        "setDTR",
        "setBreak",
        "set_output_flow_control",
        "set_input_flow_control",
        "tcsendbreak",
        "tcdrain",
    }
    banned_attrs = {"rts", "dtr", "break_condition", "rs485_mode"}
    # the modules that hold ports: those that import pyserial (the port and the scan);
    # the others (the recorder, the engine) write to files, never to a port
    sources = [
        path
        for path in sorted((ROOT / "sniffer").rglob("*.py"))
        if "serial" in _imported_packages(ast.parse(path.read_text()))
    ]
    assert {p.name for p in sources} == {"port.py", "scan.py"}
    trees = [ast.parse(source.read_text()) for source in sources]
    for node in (n for tree in trees for n in ast.walk(tree)):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            if _wakes_own_pipe(node):
                continue
            assert node.func.attr not in banned_calls, f"line {node.lineno}: {node.func.attr}"
        if isinstance(node, ast.Assign):
            for target in node.targets:
                if isinstance(target, ast.Attribute) and target.attr in banned_attrs:
                    value = node.value
                    assert isinstance(value, ast.Constant) and value.value is False, (
                        f"line {node.lineno}: {target.attr} set to something but False"
                    )


def _imported_packages(tree: ast.Module) -> set[str]:
    """The top-level packages a module imports, anywhere in it."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and not node.level:
            found.add(node.module.split(".")[0])
        elif isinstance(node, ast.Import):
            found.update(alias.name.split(".")[0] for alias in node.names)
    return found


def _wakes_own_pipe(call: ast.Call) -> bool:
    """`os.write(self._wake_w, ...)`: the reader waking its own threads, not a port."""
    func = call.func
    return (
        isinstance(func, ast.Attribute)
        and isinstance(func.value, ast.Name)
        and func.value.id == "os"
        and func.attr == "write"
        and bool(call.args)
        and isinstance(call.args[0], ast.Attribute)
        and call.args[0].attr == "_wake_w"
    )


# -- a real pseudo-terminal ------------------------------------------------------------------


@pytest.fixture
def bus(tmp_path: Path) -> Iterator[VirtualBus]:
    with VirtualBus(tmp_path) as b:
        yield b


def test_far_end_of_a_pty_reads_back_nothing(bus: VirtualBus) -> None:
    tap = bus.attach("tap", raw=False)  # a fresh tty echoes what it receives
    bus.attach("master")
    assert bus.echoes("tap")
    reader = LiveReader([PortSpec(str(tap), LINE)])
    feed = reader.subscribe()
    reader.start()
    try:
        assert not bus.echoes("tap"), "the port was left echoing"
        for _ in range(20):
            bus.inject(REQUEST, source="master")
            bus.inject(ANSWER, source="master")
        got = wait_for(feed, lambda c: len(data_of(c)) == 20 * (len(REQUEST) + len(ANSWER)))
        time.sleep(0.2)
    finally:
        reader.stop()
    assert data_of(got) == (REQUEST + ANSWER) * 20
    assert bus.sent_by("tap") == b"", "modscope put bytes on the bus"


def test_a_second_program_cannot_share_the_port(bus: VirtualBus) -> None:
    tap = bus.attach("tap")
    reader = LiveReader([PortSpec(str(tap), LINE)])
    reader.open()
    try:
        other = serial.Serial()
        other.port = str(tap)
        other.exclusive = True
        with pytest.raises(serial.SerialException):
            other.open()
        if os.geteuid() != 0:  # root may open a TIOCEXCL port anyway
            with pytest.raises(OSError) as info:
                os.close(os.open(tap, os.O_RDONLY | os.O_NOCTTY))
            assert info.value.errno == errno.EBUSY
    finally:
        reader.stop()
    # released on close: the port can be opened again
    again, _ = open_passive(PortSpec(str(tap), LINE))
    again.close()


def test_a_busy_port_is_reported_with_what_to_do(bus: VirtualBus) -> None:
    tap = bus.attach("tap")
    fd = os.open(tap, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(PortError, match=r"busy.*close it"):
            open_passive(PortSpec(str(tap), LINE))
        result = subprocess.run(
            [MODSCOPE, "live", str(tap), "--format", "jsonl"],
            capture_output=True,
            text=True,
            timeout=20,
            cwd=ROOT,
        )
    finally:
        os.close(fd)
    assert result.returncode == 2
    assert result.stdout == ""
    assert result.stderr.startswith(f"modscope: error: {tap}: the port is busy")


def test_missing_port_and_non_serial_file_are_explained(tmp_path: Path) -> None:
    with pytest.raises(PortError, match="no such serial port; `modscope ports` lists"):
        open_passive(PortSpec(str(tmp_path / "ttyNOPE"), LINE))
    plain_file = tmp_path / "notes.txt"
    plain_file.write_text("hello")
    with pytest.raises(PortError, match="is not a serial port"):
        open_passive(PortSpec(str(plain_file), LINE))


# -- a port that refuses the line settings (issue 15, items 1 and 2) --------------------------


class Refusing(Tripwire):
    """A port that opens at the OS level but refuses the line settings, as pyserial
    reports it: `termios.error` from tcsetattr (not an OSError). A pseudo-terminal on
    some systems, or the far end of a serial tunnel, refuses even parity this way."""

    def open(self) -> None:
        import termios

        self.calls.append("open")
        raise termios.error(errno.EINVAL, "Invalid argument")


class Flaky:
    """A factory handing out working ports, except the opens listed in `refuse` (0-based
    count of opens), which refuse the settings, and `crash`, which hits a bug."""

    def __init__(self, refuse: range = range(0), crash: int = -1) -> None:
        self.refuse = refuse
        self.crash = crash
        self.ports: list[Tripwire] = []

    def __call__(self, name: str) -> serial.Serial:
        k = len(self.ports)
        if k == self.crash:
            raise RuntimeError("a bug in the port factory")
        port = Refusing(name) if k in self.refuse else Tripwire(name)
        self.ports.append(port)
        return port

    @property
    def working(self) -> list[Tripwire]:
        return [p for p in self.ports if not isinstance(p, Refusing)]


def test_refused_line_settings_are_explained_not_a_traceback() -> None:
    spec = PortSpec("/dev/ttyDOUBLE0", LineSettings())  # the default, 19200 8E1
    with pytest.raises(PortError) as caught:
        open_passive(spec, Flaky(refuse=range(1)))
    text = str(caught.value)
    assert text.startswith("/dev/ttyDOUBLE0: the port refused the line settings 19200 8E1")
    assert "Invalid argument" in text and "--parity" in text


@pytest.mark.parametrize("command", ["live", "record"])
def test_live_and_record_say_the_port_refused_in_one_line(
    command: str,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
) -> None:
    import sniffer.live.port
    from sniffer.cli import main

    monkeypatch.setattr(sniffer.live.port, "new_port", Flaky(refuse=range(99)))
    argv = [command, "/dev/ttyDOUBLE0", "--format", "text"]
    if command == "record":
        argv = [command, "/dev/ttyDOUBLE0", "-w", str(tmp_path / "rec.pcapng")]
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert out == "" and "Traceback" not in err
    assert err == (
        "modscope: error: /dev/ttyDOUBLE0: the port refused the line settings 19200 8E1 "
        "auto (Invalid argument); check --baud, --parity and --stopbits (a pseudo-terminal "
        "may refuse even parity)\n"
    )
    assert not (tmp_path / "rec.pcapng").exists()


def test_a_lost_port_that_refuses_on_reopen_is_retried_and_reported() -> None:
    factory = Flaky(refuse=range(1, 4))  # the first open works, three reopens refuse
    reader = LiveReader([PortSpec("/dev/ttyDOUBLE0", LINE)], factory=factory, retry=0.02)
    feed = reader.subscribe()
    reader.start()
    try:
        factory.working[0].push(REQUEST)
        got = wait_for(feed, lambda c: data_of(c) == REQUEST)
        factory.working[0].unplug()
        got += wait_for(feed, lambda c: any(x.event == "port lost" for x in c))
        assert reader.running  # retrying, not dead
        got += wait_for(feed, lambda c: any(x.event == "reconnect" for x in c))
        assert reader.running and reader.stats[0].connected
        factory.working[-1].push(ANSWER)
        got += wait_for(feed, lambda c: data_of(c).endswith(ANSWER))
    finally:
        reader.stop()
    events = [(c.event, c.note) for c in got if c.event]
    assert [e for e, _ in events] == ["port lost", "reopen failed", "reconnect"]
    assert "refused the line settings" in events[1][1] and events[1][1].endswith("trying again")
    assert len(factory.ports) == 5 and len(factory.working) == 2
    assert not reader.running and reader.failure is None


def test_a_reader_thread_ended_by_a_bug_says_so_and_stops_running() -> None:
    factory = Flaky(crash=1)  # the reopen after the loss hits a bug
    reader = LiveReader([PortSpec("/dev/ttyDOUBLE0", LINE)], factory=factory, retry=0.02)
    feed = reader.subscribe()
    reader.start()
    try:
        factory.working[0].unplug()
        got = wait_for(feed, lambda c: any(x.event == "reader stopped" for x in c))
        end = time.monotonic() + 3
        while reader._threads[0].is_alive() and time.monotonic() < end:
            time.sleep(0.01)
        assert not reader.running
    finally:
        reader.stop()
    assert (
        reader.failure is not None and "RuntimeError: a bug in the port factory" in reader.failure
    )
    assert isinstance(reader.error, RuntimeError)
    assert [c.event for c in got if c.event] == ["port lost", "reader stopped"]


def test_live_ends_as_a_bug_when_its_reader_thread_dies(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import sniffer.live.port
    from sniffer.cli import main

    factory = Flaky(crash=1)
    monkeypatch.setattr(sniffer.live.port, "new_port", factory)

    def unplug_soon() -> None:
        end = time.monotonic() + 3
        while not factory.working and time.monotonic() < end:
            time.sleep(0.01)
        time.sleep(0.2)
        factory.working[0].unplug()

    import threading

    threading.Thread(target=unplug_soon, daemon=True).start()
    assert main(["live", "/dev/ttyDOUBLE0", "--format", "text", "--duration", "10s"]) == 70
    err = capsys.readouterr().err
    assert "modscope: reader stopped: /dev/ttyDOUBLE0: reading stopped by an internal error" in err
    assert "RuntimeError: a bug in the port factory" in err and "Traceback" in err


@pytest.mark.peer
@pytest.mark.needs("socat")
def test_live_on_a_socat_pty_with_the_default_8e1(tmp_path: Path) -> None:
    """The issue's recipe: `socat pty,raw,echo=0,link=A pty,raw,echo=0,link=B`, then
    `modscope live A` with the default settings. Where the pty takes 8E1 (Linux) the
    frames come through; where it refuses, the one-line message comes, never a traceback."""
    a, b = tmp_path / "A", tmp_path / "B"
    socat = subprocess.Popen(
        ["socat", f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        end = time.monotonic() + 5
        while not (a.exists() and b.exists()) and time.monotonic() < end:
            time.sleep(0.02)
        live = subprocess.Popen(
            [MODSCOPE, "live", str(a), "--format", "jsonl", "--duration", "3s"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=ROOT,
        )
        assert live.stderr is not None
        from tests.support.virtual_bus import wait_ready

        said = wait_ready(live.stderr)
        assert "(19200 8E1 auto)" in said[-1]
        with open(b, "wb", buffering=0) as far:
            far.write(REQUEST)
            time.sleep(0.05)
            far.write(ANSWER)
        out, rest = live.communicate(timeout=20)
    finally:
        socat.terminate()
        socat.wait(5)
    assert live.returncode == 0, rest
    assert "Traceback" not in rest
    raws = [line.split('"raw": "')[1].split('"')[0] for line in out.splitlines()]
    assert raws[:2] == [REQUEST.hex(), ANSWER.hex()]
