"""Live capture: chunks from ports through bounded feeds into a session, losses and lost
ports shown as events, two ports merged by time, the command line's streaming listing."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from dissectors.checks import with_crc
from sniffer.cli import main
from sniffer.cli.lines import parse_roles
from sniffer.live.engine import LiveCapture
from sniffer.live.port import ChunkFeed, LiveReader, PortSpec, WallClock, counter_events
from sniffer.live.port import _Counters as Counters
from sniffer.live.recorder import RecordError
from sniffer.model import Chunk, Direction, LineSettings
from sniffer.session.session import Session
from sniffer.sources import open_capture
from sniffer.vocab import Kind, Status
from tests.support.virtual_bus import Made, VirtualBus, wait_ready

LINE = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
MODSCOPE = str(Path(sys.executable).with_name("modscope"))
LINE_ARGS = ["--baud", "19200", "--parity", "N", "--stopbits", "2"]


def req(unit: int, fc: int, addr: int, qty: int) -> bytes:
    return with_crc(bytes([unit, fc]) + addr.to_bytes(2, "big") + qty.to_bytes(2, "big"))


def answer(unit: int, fc: int, words: list[int]) -> bytes:
    data = b"".join(w.to_bytes(2, "big") for w in words)
    return with_crc(bytes([unit, fc, len(data)]) + data)


def pump_until(capture: LiveCapture, predicate: Any, timeout: float = 4.0) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        capture.pump(0.02)
        if predicate():
            return
    raise AssertionError("timed out waiting for the capture")


@pytest.fixture
def bus(tmp_path: Path) -> Iterator[VirtualBus]:
    with VirtualBus(tmp_path) as b:
        yield b


# -- feeds ---------------------------------------------------------------------------------


def test_feed_counts_what_it_drops_and_says_so_where_the_gap_is() -> None:
    feed = ChunkFeed(maxsize=3)
    for k in range(10):
        feed.offer(Chunk(bytes([k]) * 4, 100.0 + k))
    first = feed.get(0)
    assert [c.data[0] for c in first] == [0, 1, 2]
    assert (feed.lost_reads, feed.lost_bytes) == (7, 28)
    feed.offer(Chunk(b"\x0b", 111.0))
    second = feed.get(0)
    assert [c.event for c in second] == ["data lost", ""]
    assert second[0].note.startswith("28 bytes in 7 reads dropped since 103.000")
    assert second[1].data == b"\x0b"


def test_feed_never_blocks_the_reader_and_wakes_its_consumer() -> None:
    feed = ChunkFeed(maxsize=1)
    got: list[Chunk] = []

    def consume() -> None:
        got.extend(feed.get(5))

    thread = threading.Thread(target=consume)
    thread.start()

    def produce() -> None:
        for k in range(1000):
            feed.offer(Chunk(b"x", float(k)))

    producer = threading.Thread(target=produce)
    producer.start()
    producer.join(10)
    assert not producer.is_alive()  # a full feed drops; it never waits for its consumer
    thread.join(5)
    assert got and got[0].data == b"x"
    feed.close()
    # what the consumer has not taken yet: a read or two may still be queued ahead of the
    # loss (the consumer can wake between two offers), then the loss, told even at the end
    rest: list[Chunk] = []
    while not feed.closed:
        rest.extend(feed.get(0))
    assert rest and rest[-1].event == "data lost"
    delivered = [c for c in got + rest if not c.event]
    assert len(delivered) + feed.lost_reads == 1000  # every read delivered or counted lost
    assert feed.lost_reads > 0


def test_clock_is_monotonic_and_anchored_to_wall_time() -> None:
    clock = WallClock()
    assert abs(clock.now() - time.time()) < 0.05
    a = clock.at(clock.mono0 + 1_500_000_000)
    assert a == pytest.approx(clock.wall0 + 1.5)


def test_driver_counters_become_events() -> None:
    old = Counters(frame=1, overrun=0, parity=5, brk=0)
    new = Counters(frame=3, overrun=7, parity=5, brk=1)
    assert counter_events(old, new) == [
        ("data lost", "the driver dropped 7 bytes (overrun)"),
        ("framing error", "2 framing errors on the line"),
        ("break", "1 breaks on the line"),
    ]


# -- a live session ------------------------------------------------------------------------


def test_live_frames_pair_and_time_out_from_idle(bus: VirtualBus) -> None:
    tap = bus.attach("tap")
    bus.attach("master")
    reader = LiveReader([PortSpec(str(tap), LINE)])
    session = Session(LINE, timeout=0.15)
    capture = LiveCapture(reader, session)
    capture.start()
    try:
        bus.inject(req(1, 3, 0, 2), source="master")
        bus.inject(answer(1, 3, [100, 101]), source="master")
        pump_until(capture, lambda: len(session.store) >= 2)
        bus.inject(req(9, 3, 0, 1), source="master")  # nobody answers
        pump_until(capture, lambda: Status.TIMEOUT in session.store.status)
    finally:
        capture.stop()
    store = session.store
    kinds = [Kind(k) for k in store.kind]
    assert kinds == [Kind.REQUEST, Kind.RESPONSE, Kind.REQUEST]
    assert list(store.status) == [Status.OK, Status.OK, Status.TIMEOUT]
    assert store.partner[0] == 1
    assert all(abs(t - time.time()) < 30 for t in store.t)  # wall-clock times


def test_losses_reach_the_listing_as_an_event_with_the_count() -> None:
    made = Made()
    reader = LiveReader([PortSpec("/dev/ttyDOUBLE0", LINE)], factory=made)
    session = Session(LINE)
    capture = LiveCapture(reader, session, queue_size=3)
    capture.start()
    try:
        frame = req(1, 3, 0, 1)
        for n in range(1, 11):  # ten reads while nobody pumps: seven do not fit
            made.ports[0].push(frame)
            deadline = time.monotonic() + 2
            while reader.stats[0].reads < n and time.monotonic() < deadline:
                time.sleep(0.001)
        assert reader.stats[0].reads == 10
        capture.pump(0)
        made.ports[0].push(frame)
        pump_until(capture, lambda: Kind.EVENT in session.store.kind)
    finally:
        capture.stop()
    events = [session.store.notes[i] for i, k in enumerate(session.store.kind) if k == Kind.EVENT]
    assert len(events) == 1
    assert events[0].startswith("data lost: 56 bytes in 7 reads dropped")
    assert capture.messages[0].startswith("data lost: 56 bytes in 7 reads")


def test_port_lost_and_back_is_marked_and_survived(bus: VirtualBus) -> None:
    tap = bus.attach("tap")
    bus.attach("master")
    reader = LiveReader([PortSpec(str(tap), LINE)], retry=0.1)
    session = Session(LINE)
    told: list[str] = []
    capture = LiveCapture(reader, session, notify=told.append)
    capture.start()
    try:
        bus.inject(req(1, 3, 0, 1), source="master")
        pump_until(capture, lambda: len(session.store) >= 1)
        bus.unplug("tap")
        pump_until(capture, lambda: any("port lost" in m for m in told))
        time.sleep(0.3)
        bus.plug("tap")
        pump_until(capture, lambda: any("reconnect" in m for m in told))
        bus.inject(req(2, 3, 0, 1), source="master")
        pump_until(capture, lambda: 2 in session.store.unit)
    finally:
        capture.stop()
    notes = [session.store.notes.get(i, "") for i in range(len(session.store))]
    assert [n.split(":")[0] for n in notes if n] == ["port lost", "reconnect"]
    assert str(tap) in notes[1]
    assert reader.stats[0].lost_port == 1
    assert list(session.store.unit)[-1] == 2


def test_two_ports_merge_by_time_with_their_directions(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    with VirtualBus(tmp_path / "a") as tx, VirtualBus(tmp_path / "b") as rx:
        port_a = tx.attach("adapter")
        port_b = rx.attach("adapter")
        tx.attach("master")
        rx.attach("slaves")
        roles = parse_roles("master,slave", 2)
        specs = [
            PortSpec(str(port_a), LINE, channel=0, direction=roles[0]),
            PortSpec(str(port_b), LINE, channel=1, direction=roles[1]),
        ]
        session = Session(LINE)
        capture = LiveCapture(LiveReader(specs), session)
        capture.start()
        try:
            for unit in (1, 2, 3):
                tx.inject(req(unit, 6, 5, 7), source="master")  # FC 6: answer echoes request
                time.sleep(0.03)
                rx.inject(req(unit, 6, 5, 7), source="slaves")
                time.sleep(0.03)
        finally:
            rows = capture.stop()
    store = session.store
    assert len(rows) == len(store) == 6
    assert list(store.channel) == [0, 1] * 3
    assert [Kind(k) for k in store.kind] == [Kind.REQUEST, Kind.RESPONSE] * 3
    assert list(store.t) == sorted(store.t)
    assert list(store.status) == [Status.OK] * 6


def test_roles_option() -> None:
    assert parse_roles(None, 2) == [Direction.UNKNOWN] * 2
    assert parse_roles("slave,master", 2) == [Direction.SLAVE, Direction.MASTER]
    with pytest.raises(Exception, match="one per port"):
        parse_roles("master", 2)
    with pytest.raises(Exception, match="not a role"):
        parse_roles("master,boss", 2)


# -- the command line ----------------------------------------------------------------------


def run_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["live"], "name the port to listen on"),
        (["live", "/dev/ttyA", "/dev/ttyB", "--directions", "master"], "one per port"),
        (["live", "/dev/ttyA", "--rotate-size", "10M"], "need -w FILE"),
        (["live", "/dev/ttyA", "--pcap", "-", "--format", "jsonl"], "drop --format"),
        (["live", "/dev/ttyA", "/dev/ttyA"], "named twice"),
        (["record", "/dev/ttyA", "-w", "x.pcapng", "--rotate-size", "lots"], "not a size"),
        (["live", "/dev/modscope-no-such-port", "--format", "text"], "no such serial port"),
    ],
)
def test_usage_errors_say_what_to_do(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = run_cli(args, capsys)
    assert code == 2
    assert out == ""
    assert err.startswith("modscope: error: ")
    assert message in err


def test_ports_lists_without_failing(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _err = run_cli(["ports", "--format", "jsonl"], capsys)
    assert code == 0
    for line in out.splitlines():
        assert "device" in json.loads(line)


def test_listing_streams_each_frame_as_it_comes(bus: VirtualBus, tmp_path: Path) -> None:
    tap = bus.attach("tap")
    bus.attach("master")
    proc = subprocess.Popen(
        [MODSCOPE, "live", str(tap), *LINE_ARGS, "--format", "jsonl", "--timeout", "0.2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stderr is not None and proc.stdout is not None
        wait_ready(proc.stderr)
        bus.inject(req(1, 3, 0, 2), source="master")
        bus.inject(answer(1, 3, [7, 8]), source="master")
        first = json.loads(proc.stdout.readline())  # arrives while modscope still runs
        second = json.loads(proc.stdout.readline())
        assert proc.poll() is None
        bus.inject(req(4, 3, 0, 1), source="master")  # no answer: listed, then an update
        third = json.loads(proc.stdout.readline())
        again = json.loads(proc.stdout.readline())
    finally:
        proc.send_signal(2)
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert (first["kind"], second["kind"]) == ("request", "response")
    assert second["transaction"]["status"] == "ok"
    assert [f["value"] for f in second["fields"] if f["name"] == "values"] == [[7, 8]]
    assert (third["index"], third["transaction"]["status"]) == (2, "open")
    assert (again["update"], again["transaction"]["status"]) == (2, "timeout")
    assert "raw" not in again and "index" not in again  # not a frame: `select(.raw)` skips it
    assert out == ""


def test_duration_ends_a_capture_by_itself(bus: VirtualBus, tmp_path: Path) -> None:
    tap = bus.attach("tap")
    rec = tmp_path / "rec.pcapng"
    started = time.monotonic()
    result = subprocess.run(
        [MODSCOPE, "record", str(tap), *LINE_ARGS, "-w", str(rec), "--duration", "0.5"],
        capture_output=True,
        text=True,
        timeout=20,
    )
    assert result.returncode == 0, result.stderr
    assert time.monotonic() - started < 10
    assert "0 bytes in 0 reads" in result.stderr
    assert rec.read_bytes()[:4] == b"\x0a\x0d\x0d\x0a"


def test_recording_starts_and_stops_while_listening(bus: VirtualBus, tmp_path: Path) -> None:
    """The TUI's `r`: a recording joins a running capture and holds exactly what was
    read between start and stop."""
    tap = bus.attach("tap")
    bus.attach("master")
    reader = LiveReader([PortSpec(str(tap), LINE)])
    session = Session(LINE)
    capture = LiveCapture(reader, session)
    capture.start()
    before, during, after = req(1, 3, 0, 1), req(2, 3, 0, 2), req(3, 3, 0, 3)
    path = tmp_path / "on-demand.pcapng"
    try:
        bus.inject(before, source="master")
        pump_until(capture, lambda: len(session.store) >= 1)
        recorder = capture.start_recording(path)
        with pytest.raises(RecordError, match="already recording"):
            capture.start_recording(tmp_path / "second.pcapng")
        bus.inject(during, source="master")
        pump_until(capture, lambda: len(session.store) >= 2)
        time.sleep(0.3)  # the recorder gathers reads before it writes them
        files = capture.stop_recording()
        assert capture.recorder is None and files == [path] == recorder.files
        bus.inject(after, source="master")
        pump_until(capture, lambda: len(session.store) >= 3)
    finally:
        capture.stop()
    recorded = open_capture(path)
    assert b"".join(c.data for c in recorded.chunks() if not c.event) == during
    assert recorded.info.line == LINE


# -- a reader of the listing that falls behind (issue 15, item 7) ------------------------------


def test_backlog_never_blocks_on_a_pipe_that_is_not_read() -> None:
    from sniffer.cli.backlog import Backlog

    read_end, write_end = os.pipe()
    block = '{"index": 1, "raw": "0103"}\n' * 100
    added = 0
    try:
        with os.fdopen(write_end, "w", closefd=False) as out:
            backlog = Backlog(out, limit=100_000)
            while not backlog.full:  # would hang in write() if the backlog blocked
                backlog.add(block)
                added += len(block)
                backlog.send()
            held = len(backlog.pending)
            assert backlog.written > 0 and backlog.written + held == added
            assert held < 100_000 + len(block)  # bounded by the limit, not by the input
            assert backlog.finish(0.05) == held  # the reader took nothing more: given up
            assert backlog.pending == bytearray()
        taken = os.read(read_end, 1 << 20)
        assert len(taken) == backlog.written and taken.startswith(block.encode()[:100])
    finally:
        os.close(read_end)
        os.close(write_end)


def readline_within(stream: Any, seconds: float) -> str:
    got: list[str] = []
    reader = threading.Thread(target=lambda: got.append(stream.readline()), daemon=True)
    reader.start()
    reader.join(seconds)
    return got[0] if got else f"(nothing within {seconds} s)"


def test_a_listing_nobody_reads_drops_rows_counted_and_stops_at_ctrl_c(bus: VirtualBus) -> None:
    """`modscope live ... | consumer` where the consumer stops reading: the capture goes
    on, the rows the pipe cannot take are dropped and reported with their count, and the
    first Ctrl-C ends it (the issue saw 100 s and 238 MB of writing after it)."""
    tap = bus.attach("tap")
    bus.attach("master")
    read_end, write_end = os.pipe()  # stdout: read by nobody until the end
    proc = subprocess.Popen(
        [MODSCOPE, "live", str(tap), *LINE_ARGS, "--format", "jsonl", "--backlog", "64k"],
        stdout=write_end,
        stderr=subprocess.PIPE,
        text=True,
    )
    os.close(write_end)
    try:
        assert proc.stderr is not None
        wait_ready(proc.stderr)
        pairs = 4000
        for k in range(pairs):
            bus.inject(req(1, 3, k % 100, 8) + answer(1, 3, list(range(k, k + 8))), source="master")
        said = readline_within(proc.stderr, 10)  # the loss is reported while it runs
        assert said.startswith("modscope: data lost: the listing fell behind"), said
        assert proc.poll() is None
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=10)  # the pipe is still not read
        rest = proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    listed = b""
    while chunk := os.read(read_end, 1 << 20):
        listed += chunk
    os.close(read_end)
    assert code == 0, rest
    assert "Traceback" not in rest
    rows = [json.loads(line) for line in listed.decode().splitlines()]
    indexes = [r["index"] for r in rows]
    assert indexes == sorted(indexes) and len(indexes) < 2 * pairs  # gaps where rows dropped
    final = [line for line in rest.splitlines() if "rows not listed" in line]
    assert final, rest
    dropped = int(final[-1].split("; ")[1].split(" rows")[0].replace(",", ""))
    assert dropped > 0


def test_feed_is_bounded_in_bytes_as_well_as_chunks() -> None:
    feed = ChunkFeed(maxsize=1000, max_bytes=100)
    for k in range(5):
        feed.offer(Chunk(bytes([k]) * 60, float(k)))
    assert (feed.lost_reads, feed.lost_bytes) == (4, 240)
    got = feed.get(0)
    assert [c.data[:1] for c in got] == [b"\x00"]
    feed.offer(Chunk(b"\x09" * 60, 9.0))  # room again: the loss is marked ahead of it
    got = feed.get(0)
    assert [c.event for c in got] == ["data lost", ""]
    assert got[0].note.startswith("240 bytes in 4 reads dropped")
