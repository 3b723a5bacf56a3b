"""A full disk while recording, finished (issue #30): the recording ends with records
saying why (read back by modscope's reader, `replay` and tshark), the one line names the
file and the free space (statvfs) or the size limit, the exit status of `record` and
`live -w` is 1, the room for the last words is held from the start in a hidden reserve
file (a killed recorder's is removed by the next), and `live -w` goes on listing and
publishing after its recording stopped. The disk is `SmallDisk`: files that raise ENOSPC
when the folder would pass its capacity, counting the reserve as a disk would."""

from __future__ import annotations

import errno
import fcntl
import json
import os
import shutil
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any, BinaryIO, cast

import pytest

import sniffer.live.recorder as recorder_module
from sniffer.cli import main
from sniffer.live.port import PortSpec
from sniffer.live.recorder import (
    RESERVE_SUFFIX,
    Recorder,
    RecordError,
    Ring,
    WholeBlocks,
    size_words,
    sweep_reserves,
)
from sniffer.model import Chunk, LineSettings
from sniffer.sources import open_capture
from tests.live.test_hardening_record import FRAME, SmallDisk
from tests.support.broker import Broker
from tests.support.virtual_bus import VirtualBus

LINE = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
SERIAL = ["--parity", "N", "--stopbits", "2"]
T0 = 1_750_000_000.0
RESERVE = 4096  # bytes the reserve takes on this disk (one block)
ROOM = 2500  # bytes of the disk left for the recording itself


def _statvfs(free: int) -> Callable[[Any], SimpleNamespace]:
    """os.statvfs of a file system with `free` bytes free to us."""
    return lambda _path: SimpleNamespace(f_bavail=free, f_frsize=1)


def _mount(path: Path) -> str:
    folder = path.resolve()
    while not os.path.ismount(folder):
        folder = folder.parent
    return str(folder)


def _reserves(folder: Path) -> list[Path]:
    return sorted(folder.glob(f".*{RESERVE_SUFFIX}"))


def _fill(rec: Recorder, channel: int = 0) -> int:
    """Write reads until the recording stops; how many went in."""
    for k in range(10_000):
        try:
            rec.write(Chunk(FRAME, T0 + k * 0.01, channel=channel))
        except RecordError:
            return k
    raise AssertionError("the disk never filled")


def _events(path: Path) -> list[tuple[int, str, str]]:
    capture = open_capture(path)
    events = [(c.channel, c.event, c.note) for c in capture.chunks() if c.event]
    assert capture.warnings == []  # whole blocks to the end
    return events


def test_sizes_in_words() -> None:
    assert [size_words(n) for n in (0, 1, 999, 1000, 12_345, 999_499, 999_500)] == [
        "0 bytes",
        "1 byte",
        "999 bytes",
        "1.0 kB",
        "12 kB",
        "999 kB",
        "1.0 MB",
    ]
    assert size_words(78_000_000_000) == "78 GB"


def test_a_full_disk_ends_the_file_with_a_record_saying_why(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(os, "statvfs", _statvfs(12_000))
    disk = SmallDisk(tmp_path, ROOM + RESERVE)
    path = tmp_path / "bus.pcapng"
    rec = Recorder(path, [PortSpec("/dev/ttyUSB0", LINE)], opener=disk.open)
    written = _fill(rec)
    assert rec.stopped == (
        f"{path}: the disk is full (12 kB free on {_mount(tmp_path)}); the recording stopped "
        f"after {written} packets and the file ends with a record saying so; free space (or "
        "record with a ring buffer, --rotate-size and --keep) and record again"
    )
    assert rec.status == 1
    rec.close()
    assert disk.used() <= ROOM + RESERVE and _reserves(tmp_path) == []
    capture = open_capture(path)
    assert [c.data for c in capture.chunks() if c.data] == [FRAME] * written
    assert _events(path) == [
        (0, "recording stopped", "the disk is full (12 kB free)"),
        (0, "capture complete", ""),
    ]


def test_each_interface_gets_the_last_words(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(os, "statvfs", _statvfs(0))
    disk = SmallDisk(tmp_path, ROOM + RESERVE)
    ports = [PortSpec("/dev/ttyUSB0", LINE, channel=0), PortSpec("/dev/ttyUSB1", LINE, channel=1)]
    rec = Recorder(tmp_path / "bus.pcapng", ports, opener=disk.open)
    _fill(rec, channel=1)
    assert "the disk is full (0 bytes free on " in str(rec.stopped)
    rec.close()
    said = "the disk is full (0 bytes free)"
    assert _events(tmp_path / "bus.pcapng") == [
        (0, "recording stopped", said),
        (1, "recording stopped", said),
        (0, "capture complete", ""),
        (1, "capture complete", ""),
    ]


def test_a_ring_on_a_full_disk_still_frees_its_oldest_file(tmp_path: Path) -> None:
    disk = SmallDisk(tmp_path, 9000 + RESERVE)
    rec = Recorder(
        tmp_path / "bus.pcapng",
        [PortSpec("/dev/ttyUSB0", LINE)],
        ring=Ring(size=3000),
        opener=disk.open,
    )
    for k in range(1000):
        rec.write(Chunk(FRAME, T0 + k * 0.01))
    assert rec.stopped is None and rec.freed and len(_reserves(tmp_path)) == 1
    rec.close()
    assert _reserves(tmp_path) == []
    for f in rec.files:
        assert [e[1] for e in _events(f)] == ["capture complete"]  # never stopped


def test_a_quota_names_the_quota(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(os, "statvfs", _statvfs(5_000_000_000))

    quota = SmallDisk(tmp_path, ROOM + RESERVE, error=errno.EDQUOT)
    rec = Recorder(tmp_path / "bus.pcapng", [PortSpec("/dev/ttyUSB0", LINE)], opener=quota.open)
    _fill(rec)
    rec.close()
    assert "the disk quota is used up (5.0 GB free on the file system on " in str(rec.stopped)
    assert _events(tmp_path / "bus.pcapng")[0][1:] == (
        "recording stopped",
        "the disk quota is used up (5.0 GB free on the file system)",
    )


def test_a_size_limit_keeps_room_below_it_for_the_last_words(tmp_path: Path) -> None:
    limit = 3000
    path = tmp_path / "bus.pcapng"

    def limited(p: Path) -> BinaryIO:
        return cast("BinaryIO", WholeBlocks(p.open("wb", buffering=0), limit))

    rec = Recorder(path, [PortSpec("/dev/ttyUSB0", LINE)], opener=limited)
    _fill(rec)
    rec.close()
    assert "the file reached the size limit (3,000 bytes) (ulimit -f" in str(rec.stopped)
    assert rec.status == 1
    assert 2500 < path.stat().st_size <= limit
    assert _events(path) == [
        (0, "recording stopped", "the file reached the size limit (3,000 bytes)"),
        (0, "capture complete", ""),
    ]


def test_the_reserve_is_held_while_recording_and_a_dead_recorders_is_swept(tmp_path: Path) -> None:
    stale = tmp_path / f".old.pcapng.abc{RESERVE_SUFFIX}"  # a killed recorder's
    stale.write_bytes(bytes(4096))
    held = tmp_path / f".other.pcapng.def{RESERVE_SUFFIX}"  # a running recorder's
    held.write_bytes(bytes(4096))
    with held.open("rb") as other:
        fcntl.flock(other.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        rec = Recorder(tmp_path / "bus.pcapng", [PortSpec("/dev/ttyUSB0", LINE)])
        assert not stale.exists() and held.exists()
        ours = [r for r in _reserves(tmp_path) if r.name.startswith(".bus.pcapng.")]
        assert len(ours) == 1 and ours[0].stat().st_size >= 4096
        assert os.stat(ours[0]).st_blocks * 512 >= 4096  # allocated, not a hole
        assert sweep_reserves(tmp_path) == 0  # ours is locked too
        rec.write(Chunk(FRAME, T0))
        rec.close()
        assert _reserves(tmp_path) == [held]
    assert sweep_reserves(tmp_path) == 1 and _reserves(tmp_path) == []


def test_no_room_for_the_reserve_refuses_to_start(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(os, "statvfs", _statvfs(300))

    def full(fd: int, offset: int, size: int) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "posix_fallocate", full)
    path = tmp_path / "bus.pcapng"
    with pytest.raises(RecordError) as caught:
        Recorder(path, [PortSpec("/dev/ttyUSB0", LINE)])
    assert str(caught.value) == (
        f"{path}: no room to start a recording: the disk is full (300 bytes free on "
        f"{_mount(tmp_path)}); nothing recorded; free space and record again"
    )
    assert list(tmp_path.iterdir()) == []


def test_a_closed_pipe_is_not_a_failure() -> None:
    class Closed:
        def write(self, data: bytes) -> int:
            raise BrokenPipeError(errno.EPIPE, os.strerror(errno.EPIPE))

        def flush(self) -> None:
            pass

    with pytest.raises(RecordError, match="closed the pipe"):
        Recorder("-", [PortSpec("/dev/ttyUSB0", LINE)], stream=cast("BinaryIO", Closed()))


# -- the command line: record and live -w ---------------------------------------------------


@pytest.fixture
def small_disk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> SmallDisk:
    """Recordings of the command line go to a SmallDisk in `tmp_path/rec` with 12 kB
    free by statvfs."""
    folder = tmp_path / "rec"
    folder.mkdir()
    disk = SmallDisk(folder, ROOM + RESERVE)
    monkeypatch.setattr(recorder_module, "open_blocks", disk.open)
    monkeypatch.setattr(os, "statvfs", _statvfs(12_000))
    return disk


class Injector:
    """Frames onto the bus every `gap` seconds from a thread, until stopped."""

    def __init__(self, bus: VirtualBus, gap: float = 0.005) -> None:
        self.bus, self.gap = bus, gap
        self.sent = 0
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        time.sleep(0.3)  # the ports open
        while not self.done.is_set() and self.sent < 20_000:
            self.bus.inject(FRAME, source="master")
            self.sent += 1
            time.sleep(self.gap)

    def __enter__(self) -> Injector:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.done.set()
        self.thread.join(10)


def _stop_line(err: str, path: Path) -> str:
    assert "Traceback" not in err and "bug" not in err
    errors = [line for line in err.splitlines() if "error" in line]
    assert len(errors) == 1, err
    assert errors[0].startswith(f"modscope: error: {path}: the disk is full (12 kB free on ")
    return errors[0]


def test_record_on_a_full_disk_exits_1(
    tmp_path: Path, small_disk: SmallDisk, capsys: pytest.CaptureFixture[str]
) -> None:
    path = small_disk.folder / "bus.pcapng"
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        with Injector(bus):
            code = main(["record", str(tap), *SERIAL, "-w", str(path), "--duration", "60s"])
    err = capsys.readouterr().err
    assert code == 1, err
    _stop_line(err, path)
    assert _events(path)[-2:] == [
        (0, "recording stopped", "the disk is full (12 kB free)"),
        (0, "capture complete", ""),
    ]
    assert _reserves(small_disk.folder) == []
    # replay shows the stop as an event of the listing, and the file reads clean
    assert main(["replay", str(path), "--format", "jsonl"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [r["summary"] for r in rows if r["kind"] == "event"] == [
        "recording stopped: the disk is full (12 kB free)"
    ]


@pytest.mark.peer
@pytest.mark.skipif(shutil.which("tshark") is None, reason="apt-get install tshark")
def test_tshark_reads_the_stopped_file_whole(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(os, "statvfs", _statvfs(12_000))
    disk = SmallDisk(tmp_path, ROOM + RESERVE)
    path = tmp_path / "bus.pcapng"
    rec = Recorder(path, [PortSpec("/dev/ttyUSB0", LINE)], opener=disk.open)
    written = _fill(rec)
    rec.close()
    done = subprocess.run(
        ["tshark", "-r", str(path), "-V"], capture_output=True, text=True, timeout=120
    )
    said = [line for line in done.stderr.splitlines() if "Running as user" not in line]
    assert done.returncode == 0 and said == [], done.stderr
    frames = [line for line in done.stdout.splitlines() if line.startswith("Frame ")]
    assert len(frames) == written + 2  # every read, then the last words
    assert done.stdout.count("Event Type: CAPTURE_DATA_LOST") == 1
    assert done.stdout.count("Event Type: CAPTURE_COMPLETE") == 1
    assert "Packet comments\n    recording stopped: the disk is full (12 kB free)\n" in done.stdout


def _subscriber(port: int, topic: str) -> tuple[Any, list[bytes]]:
    import paho.mqtt.client as paho
    from paho.mqtt.enums import CallbackAPIVersion

    got: list[bytes] = []
    ready = threading.Event()
    client = paho.Client(CallbackAPIVersion.VERSION2, client_id="full-disk-reader")
    client.on_connect = lambda c, *a: c.subscribe(topic, 1)
    client.on_subscribe = lambda *a: ready.set()
    client.on_message = lambda c, u, m: got.append(bytes(m.payload))
    client.connect("127.0.0.1", port)
    client.loop_start()
    assert ready.wait(20)
    return client, got


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    pytest.importorskip("paho.mqtt.client")
    folder = tmp_path / "broker"
    folder.mkdir()
    b = Broker(folder)
    b.start()
    try:
        yield b
    finally:
        b.stop()


@pytest.mark.peer
@pytest.mark.skipif(shutil.which("mosquitto") is None, reason="apt-get install mosquitto")
def test_live_on_a_full_disk_goes_on_listing_and_publishing_then_exits_1(
    tmp_path: Path, small_disk: SmallDisk, broker: Broker, capsys: pytest.CaptureFixture[str]
) -> None:
    path = small_disk.folder / "bus.pcapng"
    rows = 300
    url = f"mqtt://127.0.0.1:{broker.port}/site/line1"
    client, raw = _subscriber(broker.port, "site/line1/raw")
    try:
        with VirtualBus(tmp_path) as bus:
            tap = bus.attach("tap")
            bus.attach("master")
            with Injector(bus, gap=0.01):
                argv = ["live", str(tap), *SERIAL, "-w", str(path), "--mqtt", url]
                code = main([*argv, "--format", "jsonl", "-c", str(rows)])
        deadline = time.monotonic() + 10
        recorded = [c for c in open_capture(path).chunks() if c.data]
        while len(raw) < 3 * len(recorded) and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        client.loop_stop()
        client.disconnect()
    out, err = capsys.readouterr()
    assert code == 1, err
    _stop_line(err, path)
    listed = [json.loads(line) for line in out.splitlines()]
    # the listing and the broker went on well past what the file holds
    assert len([r for r in listed if r.get("kind") == "request"]) == rows
    assert 0 < len(recorded) < rows // 3
    assert len(raw) >= 3 * len(recorded)
    assert _events(path)[-2][1:] == ("recording stopped", "the disk is full (12 kB free)")
    assert "data lost" not in err  # the stopped recording's feed was let go, not overrun
