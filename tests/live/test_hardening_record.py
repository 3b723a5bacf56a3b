"""A full disk while recording (issue #30, item 5): `modscope record -w` under a real file
size limit (RLIMIT_FSIZE) stops with one line naming the file and the limit, exit status
1, no traceback, and a file that reads back whole to its last block, then says why it
ends (the last bytes under the limit were kept for that); a ring buffer on a disk
that fills (ENOSPC from a file wrapper that counts the folder's real bytes) frees its
oldest file and goes on; `record -w - | head` blames the pipe, not the disk."""

from __future__ import annotations

import errno
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import IO, BinaryIO, cast

from dissectors.checks import with_crc
from sniffer.live.port import PortSpec
from sniffer.live.recorder import Recorder, RecordError, Ring, WholeBlocks
from sniffer.model import Chunk, LineSettings
from sniffer.sources import open_capture
from tests.support.virtual_bus import VirtualBus, wait_ready

LINE = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
MODSCOPE = str(Path(sys.executable).with_name("modscope"))
FRAME = with_crc(bytes.fromhex("010300000005"))
T0 = 1_750_000_000.0
LIMIT = 4096  # bytes: the file size limit of the recording process
RESERVE = 4096  # bytes: the hidden file that holds a recording's last room (a disk counts it)


def _limit_file_size() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of a killing signal
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def test_record_at_the_file_size_limit_stops_with_one_line(tmp_path: Path) -> None:
    path = tmp_path / "rec.pcapng"
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        proc = subprocess.Popen(
            [MODSCOPE, "record", str(tap), "--parity", "N", "--stopbits", "2", "-w", str(path)],
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=_limit_file_size,
        )
        try:
            wait_ready(proc.stderr)
            deadline = time.monotonic() + 20
            while proc.poll() is None and time.monotonic() < deadline:
                bus.inject(FRAME, source="master")
                time.sleep(0.003)
        finally:
            if proc.poll() is None:
                proc.terminate()
            _out, err = proc.communicate(timeout=10)
    assert proc.returncode == 1, err
    assert "Traceback" not in err and "bug" not in err
    errors = [line for line in err.splitlines() if "error" in line]
    assert len(errors) == 1 and str(path) in errors[0], err
    assert "the size limit (4,096 bytes)" in errors[0], err
    size = path.stat().st_size
    assert 0 < size <= LIMIT
    capture = open_capture(path)
    chunks = list(capture.chunks())
    data = [c.data for c in chunks if not c.event]
    # whole frames only (a loaded machine may read two or more in one read)
    joined = b"".join(data)
    assert data and joined == FRAME * (len(joined) // len(FRAME))
    assert capture.warnings == []  # whole blocks to the end: no truncated block
    last = [c for c in chunks if c.event and c.event != "capture complete"][-1]
    assert (last.event, last.note) == (
        "recording stopped",
        "the file reached the size limit (4,096 bytes)",
    )


class SmallDisk:
    """Opens files that raise ENOSPC when the folder's files would pass `capacity` bytes
    (measured on disk at each write), as a small disk does; a write may take part of a
    block before it fails, as a real one does."""

    def __init__(self, folder: Path, capacity: int, error: int = errno.ENOSPC) -> None:
        self.folder = folder
        self.capacity = capacity
        self.error = error  # what a full one says (EDQUOT: a quota)

    def used(self) -> int:
        return sum(f.stat().st_size for f in self.folder.iterdir() if f.is_file())

    def open(self, path: Path) -> BinaryIO:
        disk = self
        raw = path.open("wb", buffering=0)

        class Limited:
            def write(self, data: memoryview | bytes) -> int:
                room = disk.capacity - disk.used()
                if room <= 0:
                    raise OSError(disk.error, os.strerror(disk.error))
                return raw.write(bytes(data[:room]))  # part of it, when that is all

            def __getattr__(self, name: str) -> object:
                return getattr(raw, name)

        return cast("BinaryIO", WholeBlocks(cast("BinaryIO", Limited())))


def test_a_ring_on_a_full_disk_frees_its_oldest_file_and_goes_on(tmp_path: Path) -> None:
    disk = SmallDisk(tmp_path, 9000 + RESERVE)
    rec = Recorder(
        tmp_path / "bus.pcapng",
        [PortSpec("/dev/ttyUSB0", LINE)],
        ring=Ring(size=3000),  # no --keep: only the full disk frees files
        opener=disk.open,
    )
    for k in range(1000):
        rec.write(Chunk(FRAME, T0 + k * 0.01))
    rec.close()
    assert rec.stopped is None and rec.freed  # it went on, by freeing the oldest files
    assert all(not f.exists() for f in rec.freed)
    files = sorted(tmp_path.glob("bus_*.pcapng"))
    assert files == rec.files and disk.used() <= 9000 + RESERVE
    numbers = [int(f.name.split("_")[1]) for f in files]
    assert numbers == list(range(numbers[0], numbers[0] + len(files)))
    newest = [c for c in open_capture(files[-1]).chunks() if c.data][-1]
    assert newest.data == FRAME and abs(newest.t_end - (T0 + 999 * 0.01)) < 1e-6
    for f in files:
        assert open_capture(f).warnings == []  # every file whole to its last block


def test_one_file_on_a_full_disk_stops_once_and_ends_on_a_whole_block(tmp_path: Path) -> None:
    disk = SmallDisk(tmp_path, 2500 + RESERVE)
    rec = Recorder(tmp_path / "bus.pcapng", [PortSpec("/dev/ttyUSB0", LINE)], opener=disk.open)
    written = 0
    try:
        for k in range(1000):
            rec.write(Chunk(FRAME, T0 + k * 0.01))
            written += 1
    except RecordError as exc:
        message = str(exc)
    else:
        raise AssertionError("the disk never filled")
    rec.close()  # no traceback from close either
    assert str(tmp_path / "bus.pcapng") in message and "disk is full" in message
    capture = open_capture(tmp_path / "bus.pcapng")
    assert capture.warnings == []
    assert [c.data for c in capture.chunks() if c.data] == [FRAME] * written


def test_record_to_a_closed_pipe_blames_the_pipe(tmp_path: Path) -> None:
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        proc = subprocess.Popen(
            [MODSCOPE, "record", str(tap), "--parity", "N", "--stopbits", "2", "-w", "-"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=False,
        )
        assert proc.stdout is not None and proc.stderr is not None
        try:
            wait_ready(_Text(proc.stderr))
            proc.stdout.read(64)  # `head -c 64`: the header, then the reader goes away
            proc.stdout.close()
            deadline = time.monotonic() + 20
            while proc.poll() is None and time.monotonic() < deadline:
                bus.inject(FRAME, source="master")
                time.sleep(0.01)
        finally:
            if proc.poll() is None:
                proc.terminate()
            err = proc.stderr.read().decode()
            proc.wait(timeout=10)
    assert "Traceback" not in err and "bug" not in err
    assert "closed the pipe" in err and "disk" not in err, err


class _Text:
    """Lines of a binary stream as text (for wait_ready)."""

    def __init__(self, stream: IO[bytes]) -> None:
        self.stream = stream

    def readline(self) -> str:
        return self.stream.readline().decode()
