"""Recording: pcapng link type 250 with the line settings in the interface description,
one block per read as the port gave it, events as RTAC records with comments, flushed
per block, ring buffer by size or time; replay frames a recording as live did."""

from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dissectors.checks import with_crc
from sniffer.live.engine import LiveCapture
from sniffer.live.port import LiveReader, PortSpec
from sniffer.live.recorder import Recorder, RecordError, Ring, parse_duration, parse_size
from sniffer.model import Chunk, Direction, LineSettings
from sniffer.session.session import Session, replay_file
from sniffer.sources import open_capture
from sniffer.sources.linktypes import (
    LINKTYPE_RTAC_SERIAL,
    RTAC_CAPTURE_COMPLETE,
    RTAC_CAPTURE_DATA_LOST,
    RTAC_DATA_RX_START,
    RTAC_FRAMING_ERROR,
    parse_rtac,
)
from tests.support.virtual_bus import VirtualBus, wait_ready

LINE = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
MODSCOPE = str(Path(sys.executable).with_name("modscope"))
T0 = 1_750_000_000.0


def blocks(path: Path) -> list[tuple[int, bytes]]:
    """(block type, body) of every block of a little-endian pcapng file."""
    raw = path.read_bytes()
    out = []
    pos = 0
    while pos < len(raw):
        kind, size = struct.unpack_from("<II", raw, pos)
        out.append((kind, raw[pos + 8 : pos + size - 4]))
        pos += size
    return out


def packets(path: Path) -> list[tuple[int, float, bytes]]:
    """(interface, time, packet) of every EPB (nanosecond resolution, as we write)."""
    out = []
    for kind, body in blocks(path):
        if kind == 6:
            iface, high, low, caplen, _ = struct.unpack_from("<IIIII", body)
            out.append((iface, ((high << 32) | low) / 1e9, body[20 : 20 + caplen]))
    return out


def test_interfaces_carry_port_names_and_line_settings(tmp_path: Path) -> None:
    ports = [
        PortSpec("/dev/ttyUSB0", LINE, 0, Direction.MASTER),
        PortSpec("/dev/ttyUSB1", LINE, 1, Direction.SLAVE),
    ]
    path = tmp_path / "rec.pcapng"
    rec = Recorder(path, ports)
    rec.close()
    idbs = [body for kind, body in blocks(path) if kind == 1]
    assert [struct.unpack_from("<H", b)[0] for b in idbs] == [LINKTYPE_RTAC_SERIAL] * 2
    assert b"/dev/ttyUSB0" in idbs[0] and b"modscope 19200 8N2 rtu master" in idbs[0]
    assert b"/dev/ttyUSB1" in idbs[1] and b"modscope 19200 8N2 rtu slave" in idbs[1]
    info = open_capture(path).info
    assert info.line == LINE


def test_every_read_is_one_block_and_reads_back_as_it_was(tmp_path: Path) -> None:
    path = tmp_path / "rec.pcapng"
    reads = [b"\x01\x03\x00", b"\x00\x00\x05\x85\xc9", b"\x01\x03\x0a" + bytes(12)]
    rec = Recorder(path, [PortSpec("/dev/ttyUSB0", LINE)])
    for k, data in enumerate(reads):
        rec.write(Chunk(data, T0 + k * 0.01))
        # flushed as written: the block is in the file before anything else happens
        assert len(packets(path)) == k + 1
        assert path.stat().st_size == rec.file_size
    rec.write(Chunk(b"", T0 + 0.03, event="data lost", note="3 bytes in 1 read dropped"))
    assert path.stat().st_size == rec.file_size
    rec.close(T0 + 1)
    got = packets(path)
    times = [T0, T0 + 0.01, T0 + 0.02, T0 + 0.03, T0 + 1]
    assert [p[1] for p in got] == pytest.approx(times, abs=1e-9)
    records = [parse_rtac(p[2]) for p in got]
    assert [r.data for r in records if r] == [*reads, b"", b""]
    assert [r.event for r in records if r] == [RTAC_DATA_RX_START] * 3 + [
        RTAC_CAPTURE_DATA_LOST,
        RTAC_CAPTURE_COMPLETE,
    ]
    # the RTAC time is when the first byte began: one character time per byte earlier
    first = records[0]
    assert first is not None
    assert first.seconds == pytest.approx(T0 - 3 * LINE.char_time, abs=1e-6)
    chunks = [c for c in open_capture(path).chunks() if c.data]
    assert [c.data for c in chunks] == reads
    assert [c.t_end for c in chunks] == pytest.approx([T0, T0 + 0.01, T0 + 0.02], abs=1e-9)


def test_events_are_rtac_records_with_comments(tmp_path: Path) -> None:
    path = tmp_path / "rec.pcapng"
    rec = Recorder(path, [PortSpec("/dev/ttyUSB0", LINE)])
    rec.write(Chunk(b"", T0, event="port lost", note="/dev/ttyUSB0: unplugged"))
    rec.write(Chunk(b"", T0 + 1, event="reconnect", note="/dev/ttyUSB0: back after 1.0 s"))
    rec.write(Chunk(b"", T0 + 2, event="data lost", note="12 bytes in 3 reads dropped"))
    rec.write(Chunk(b"", T0 + 3, event="framing error", note="2 framing errors"))
    rec.close(T0 + 4)
    got = packets(path)
    kinds = [r.event for r in (parse_rtac(p[2]) for p in got) if r]
    assert kinds == [RTAC_CAPTURE_DATA_LOST] * 3 + [RTAC_FRAMING_ERROR, RTAC_CAPTURE_COMPLETE]
    assert got[-1][1] == T0 + 4
    raw = path.read_bytes()
    for text in (
        b"port lost: /dev/ttyUSB0: unplugged",
        b"reconnect: /dev/ttyUSB0: back after 1.0 s",
        b"data lost: 12 bytes in 3 reads dropped",
    ):
        assert text in raw
    # replayed, each event says what happened, from the recorder's comment; the last
    # record tells when the capture ended
    chunks = list(open_capture(path).chunks())
    assert [c.event for c in chunks] == [
        "port lost",
        "reconnect",
        "data lost",
        "framing error",
        "capture complete",
    ]
    assert chunks[0].note == "/dev/ttyUSB0: unplugged"
    assert chunks[-1].t_end == pytest.approx(T0 + 4)


def test_ring_buffer_by_size_keeps_the_newest_files(tmp_path: Path) -> None:
    path = tmp_path / "bus.pcapng"
    rec = Recorder(path, [PortSpec("/dev/ttyUSB0", LINE)], ring=Ring(size=2000, keep=3))
    frame = with_crc(bytes.fromhex("010300000005"))
    for k in range(400):
        rec.write(Chunk(frame, T0 + k * 0.01))
    rec.close()
    files = sorted(tmp_path.glob("bus_*.pcapng"))
    assert files == rec.files
    assert len(files) == 3
    numbers = [int(f.name.split("_")[1]) for f in files]
    assert numbers == list(range(numbers[0], numbers[0] + 3)) and numbers[0] > 1
    for f in files[:-1]:
        assert 2000 <= f.stat().st_size < 2200
    total = 0
    for f in files:  # each file stands alone, with its line settings
        capture = open_capture(f)
        assert capture.info.line == LINE
        data = [c.data for c in capture.chunks() if not c.event]
        assert set(data) == {frame}
        total += len(data)
        assert capture.warnings == []
    assert total < 400


def test_ring_buffer_by_time(tmp_path: Path) -> None:
    path = tmp_path / "bus.pcapng"
    rec = Recorder(path, [PortSpec("/dev/ttyUSB0", LINE)], ring=Ring(seconds=60))
    for k in range(10):
        rec.write(Chunk(b"\x01", time.time() + k * 30))
    rec.close()
    files = sorted(tmp_path.glob("bus_*.pcapng"))
    assert len(files) == 5
    counts = [sum(not c.event for c in open_capture(f).chunks()) for f in files]
    assert counts == [2, 2, 2, 2, 2]


def test_ring_options_are_checked(tmp_path: Path) -> None:
    spec = [PortSpec("/dev/ttyUSB0", LINE)]
    with pytest.raises(RecordError, match="needs --rotate-size or --rotate-time"):
        Recorder(tmp_path / "x.pcapng", spec, ring=Ring(keep=3))
    with pytest.raises(RecordError, match="cannot be written"):
        Recorder(tmp_path / "no" / "such" / "dir.pcapng", spec)


@pytest.mark.parametrize(
    ("text", "size"),
    [
        ("10M", 10_000_000),
        ("10MiB", 10 * 2**20),
        ("500k", 500_000),
        ("4096", 4096),
        ("1k", 1000),  # the smallest ring file: `--rotate-size 1k` was refused (issue 15)
        ("1KiB", 1024),
    ],
)
def test_sizes(text: str, size: int) -> None:
    assert parse_size(text) == size


@pytest.mark.parametrize(
    ("text", "seconds"), [("30s", 30), ("15m", 900), ("1h", 3600), ("1d", 86400), ("2.5", 2.5)]
)
def test_durations(text: str, seconds: float) -> None:
    assert parse_duration(text) == seconds


def test_bad_sizes_and_durations() -> None:
    with pytest.raises(ValueError, match="not a size"):
        parse_size("ten megs")
    with pytest.raises(ValueError, match="at least 1k"):
        parse_size("100")
    with pytest.raises(ValueError, match="at least 1k"):
        parse_size("0.9k")
    with pytest.raises(ValueError, match="not a duration"):
        parse_duration("soon")


# -- live and replayed ---------------------------------------------------------------------


def test_replay_frames_a_recording_as_live_did(tmp_path: Path) -> None:
    path = tmp_path / "rec.pcapng"
    frames = [
        with_crc(bytes.fromhex("010300000002")),
        with_crc(bytes.fromhex("01030400640065")),
        with_crc(bytes.fromhex("020600050007")),
        with_crc(bytes.fromhex("020600050007")),
        with_crc(bytes.fromhex("0301000000")),  # noise: no such frame
        with_crc(bytes.fromhex("090300000001")),  # no answer
        with_crc(bytes.fromhex("011000000002040001000200")),
        with_crc(bytes.fromhex("011000000002")),
    ]
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        spec = PortSpec(str(tap), LINE)
        session = Session(LINE)
        capture = LiveCapture(LiveReader([spec]), session, recorder=Recorder(path, [spec]))
        capture.start()
        try:
            for frame in frames:
                # split reads, as an adapter delivers them
                bus.inject(frame[:3], source="master")
                time.sleep(0.002)
                bus.inject(frame[3:], source="master")
                time.sleep(0.01)
                capture.pump(0)
        finally:
            capture.stop()
    replayed = replay_file(path)

    def rows(s: Session) -> list[tuple[object, ...]]:
        st = s.store
        st.sync()
        return [
            (st.raw(i), st.kind[i], st.unit[i], st.fc[i], st.status[i], st.partner[i])
            for i in range(len(st))
        ]

    live_rows, replay_rows = rows(session), rows(replayed)
    assert len(live_rows) >= len(frames) - 1
    assert replay_rows == live_rows
    assert list(replayed.store.t) == pytest.approx(list(session.store.t), abs=2e-6)
    assert replayed.line == LINE


def test_killed_recorder_loses_at_most_the_block_being_written(tmp_path: Path) -> None:
    path = tmp_path / "rec.pcapng"
    frame = with_crc(bytes.fromhex("010300000005"))
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        proc = subprocess.Popen(
            [MODSCOPE, "record", str(tap), "--parity", "N", "--stopbits", "2", "-w", str(path)],
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            wait_ready(proc.stderr)
            for _ in range(30):
                bus.inject(frame, source="master")
                time.sleep(0.005)
            deadline = time.monotonic() + 5
            while len(packets(path)) < 30 and time.monotonic() < deadline:
                time.sleep(0.02)
        finally:
            os.kill(proc.pid, signal.SIGKILL)
            proc.communicate(timeout=5)
    capture = open_capture(path)
    data = b"".join(c.data for c in capture.chunks())
    assert data == frame * 30
    assert capture.warnings == []


def test_record_command_stops_cleanly_on_sigterm(tmp_path: Path) -> None:
    path = tmp_path / "rec.pcapng"
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        proc = subprocess.Popen(
            [MODSCOPE, "record", str(tap), "--parity", "N", "--stopbits", "2", "-w", str(path)],
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            wait_ready(proc.stderr)
            bus.inject(with_crc(bytes.fromhex("010300000005")), source="master")
            time.sleep(0.3)
        finally:
            proc.terminate()
            _out, err = proc.communicate(timeout=5)
    assert proc.returncode == 0
    assert "8 bytes in 1 reads; 1 packets to" in err
    last = [parse_rtac(p[2]) for p in packets(path)]
    assert [r.event for r in last if r] == [RTAC_DATA_RX_START, RTAC_CAPTURE_COMPLETE]


def test_record_to_standard_output(tmp_path: Path) -> None:
    frame = with_crc(bytes.fromhex("010300000005"))
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        proc = subprocess.Popen(
            [MODSCOPE, "record", str(tap), "--parity", "N", "--stopbits", "2", "-w", "-",
             "--duration", "1"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=False,
        )  # fmt: skip
        wait_ready(_Text(proc.stderr))
        bus.inject(frame, source="master")
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    path = tmp_path / "stdout.pcapng"
    path.write_bytes(out)
    capture = open_capture(path)
    assert [c.data for c in capture.chunks() if not c.event] == [frame]
    assert capture.info.line == LineSettings(baud=19200, parity="N", stopbits=2, mode="auto")


class _Text:
    def __init__(self, stream: object) -> None:
        self.stream = stream

    def readline(self) -> str:
        line = self.stream.readline()  # type: ignore[attr-defined]
        return line.decode() if isinstance(line, bytes) else str(line)
