"""`live`/`record --mqtt` publishing a bus as it runs, and `live mqtt://...` watching one.

Real peers: a Mosquitto broker on a free loopback port (see test_mqtt_broker), the
virtual RS-485 bus for the serial side, `modscope` itself as a subprocess on both ends,
and a plain paho client as the independent reader.
"""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.analysis.stats import UnitStats
from sniffer.model import Chunk, LineSettings
from sniffer.outputs.mqtt.payload import chunk_from_raw, raw_payload, read_raw
from sniffer.outputs.mqtt.publish import (
    PublisherOptions,
    UnitWindow,
    open_publisher,
    publish_replay,
)
from sniffer.session.session import DEMO_BUS, Session, open_session
from sniffer.sources import open_capture
from tests.support.broker import Broker, running
from tests.support.virtual_bus import VirtualBus, wait_ready

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
SERIAL = ["--parity", "N", "--stopbits", "2"]


# -- pure: the status window -------------------------------------------------------------------


def _nearest_rank(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q * (len(ordered) - 1))))]


def _unit(latencies: list[float], requests: list[float], bounded: bool) -> UnitStats:
    """A unit's statistics holding these values, as a replay keeps them or, bounded, as
    a headless live capture does (fed in two parts, as its updates would)."""
    unit = UnitStats(1)
    half_l, half_r = len(latencies) // 2, len(requests) // 2
    unit.latencies.extend(latencies[:half_l])
    unit.request_times.extend(requests[:half_r])
    if bounded:
        unit.bound()
        assert unit.tallies is not None
        unit.tallies.add_latencies(latencies[half_l:])
        unit.tallies.add_requests(requests[half_r:])
    else:
        unit.latencies.extend(latencies[half_l:])
        unit.request_times.extend(requests[half_r:])
    return unit


@given(
    st.lists(st.floats(0, 10, allow_nan=False), min_size=1, max_size=300),
    st.integers(1, 50),
    st.integers(1, 40),
    st.booleans(),
)
def test_status_window_is_the_quantile_of_the_latest_answers(
    latencies: list[float], size: int, step: int, bounded: bool
) -> None:
    """Fed in steps, as statuses are published, the window holds exactly the latest
    `size` latencies, whatever came before; from statistics that keep every latency or
    (live, bounded) only the newest."""
    window = UnitWindow(size)
    for end in range(step, len(latencies) + step, step):
        window.update(_unit(latencies[:end], [], bounded))
    latest = latencies[-size:]
    assert list(window.latencies) == latest
    for q in (0.5, 0.95):
        got = window.latency_ms(q)
        assert got is not None and got == _nearest_rank(latest, q) * 1000


@pytest.mark.parametrize("bounded", [False, True])
def test_status_window_poll_period_is_the_median_gap_of_the_latest_requests(
    bounded: bool,
) -> None:
    window = UnitWindow(4)
    window.update(_unit([], [0.0, 1.0, 2.0, 3.0], bounded))
    assert window.polling_period() == 1.0
    window.update(_unit([], [0.0, 1.0, 2.0, 3.0, 3.5, 4.0, 4.5], bounded))
    assert list(window.requests) == [3.0, 3.5, 4.0, 4.5]
    assert window.polling_period() == 0.5


def test_raw_messages_carry_the_publishers_count() -> None:
    capture = open_capture(DEMO_BUS.with_name("demo.pcapng"))
    chunk = next(iter(capture.chunks()))
    message = read_raw(raw_payload(chunk, 7))
    assert message.chunk == chunk and message.sequence == 7
    assert read_raw(raw_payload(chunk)).sequence is None
    assert chunk_from_raw(raw_payload(chunk, 2**40)) == chunk


# -- with a broker ---------------------------------------------------------------------------


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    pytest.importorskip("paho.mqtt.client")
    with running(tmp_path) as b:
        yield b


class Reader:
    """A paho client with a persistent session, keeping every message of `topics`."""

    def __init__(self, port: int, *topics: str) -> None:
        import paho.mqtt.client as paho
        from paho.mqtt.enums import CallbackAPIVersion

        self.messages: list[tuple[str, bytes]] = []
        self.lock = threading.Lock()
        self.client = paho.Client(
            CallbackAPIVersion.VERSION2, client_id="test-reader", clean_session=False
        )

        def on_connect(client: Any, *args: Any) -> None:
            client.subscribe([(t, 1) for t in topics])

        def on_message(client: Any, userdata: Any, message: Any) -> None:
            with self.lock:
                self.messages.append((message.topic, bytes(message.payload)))

        self.client.on_connect = on_connect
        self.client.on_message = on_message
        self.client.reconnect_delay_set(1, 2)
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()

    def on(self, topic: str) -> list[bytes]:
        with self.lock:
            return [p for t, p in self.messages if t == topic]

    def wait(self, topic: str, count: int, timeout: float = 20) -> list[bytes]:
        end = time.monotonic() + timeout
        while len(self.on(topic)) < count and time.monotonic() < end:
            time.sleep(0.05)
        return self.on(topic)

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


def _stop(proc: subprocess.Popen[str]) -> tuple[str, str]:
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    return out, err


@pytest.mark.slow
@pytest.mark.peer
@pytest.mark.skipif(shutil.which("mosquitto") is None, reason="apt-get install mosquitto")
def test_record_publishes_and_keeps_recording_while_the_broker_restarts(
    tmp_path: Path, broker: Broker
) -> None:
    """`record --mqtt`: every read reaches the broker as recorded; the broker stopping
    neither stops nor holds up the recording; what was read meanwhile is buffered and
    delivered after the automatic reconnection."""
    path = tmp_path / "rec.pcapng"
    base = "modscope/line1"
    url = f"mqtt://127.0.0.1:{broker.port}/{base}"
    reader = Reader(broker.port, f"{base}/raw", f"{base}/status")
    frames = [with_crc(bytes([1, 3, 0, k, 0, 2])) for k in range(30)]
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        proc = subprocess.Popen(
            [MODSCOPE, "record", str(tap), *SERIAL, "-w", str(path), "--mqtt", url],
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            assert proc.stderr is not None
            wait_ready(proc.stderr)
            for frame in frames[:10]:
                bus.inject(frame, source="master")
                time.sleep(0.05)
            assert len(reader.wait(f"{base}/raw", 10)) == 10
            broker.stop()
            for frame in frames[10:20]:  # read and recorded while the broker is away
                bus.inject(frame, source="master")
                time.sleep(0.05)
            time.sleep(0.5)
            broker.start()
            for frame in frames[20:]:
                bus.inject(frame, source="master")
                time.sleep(0.05)
            raws = reader.wait(f"{base}/raw", 30)
        finally:
            _out, err = _stop(proc)
            reader.close()
    assert proc.returncode == 0, err
    recorded = [c for c in open_capture(path).chunks() if not c.event]
    assert b"".join(c.data for c in recorded) == b"".join(frames)
    published = [read_raw(p) for p in raws]
    # every read, as recorded (time, channel, bytes), once, numbered in order
    assert [m.chunk.data for m in published] == [c.data for c in recorded]
    assert [m.chunk.t_end for m in published] == pytest.approx([c.t_end for c in recorded])
    assert [m.sequence for m in published] == list(range(1, len(recorded) + 1))
    assert "lost mqtt://127.0.0.1" in err and "connected again" in err
    assert "messages to the broker" in err and "dropped" not in err
    assert reader.on(f"{base}/status")[-1] == b"offline"


@pytest.mark.slow
@pytest.mark.peer
@pytest.mark.skipif(shutil.which("mosquitto") is None, reason="apt-get install mosquitto")
def test_a_second_modscope_lists_the_published_demo_byte_for_byte(
    tmp_path: Path, broker: Broker
) -> None:
    """`modscope live mqtt://host/base` watching a replay of the demo lists the frames
    `modscope replay` lists: same bytes, kinds, times, decoding. A request listed while
    it waited for its answer gets its answer as an update record (docs/output.md). Without
    --bus the watcher binds the units the publisher names (the demo's three models)."""
    url = f"mqtt://127.0.0.1:{broker.port}/modscope/demo"
    publish = [MODSCOPE, "replay", "--mqtt", url]
    subprocess.run(publish, check=True, capture_output=True, timeout=60)  # the interface
    watch = subprocess.Popen(
        [MODSCOPE, "live", url, "--format", "jsonl"],  # units bound as the publisher's
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert watch.stderr is not None
        wait_ready(watch.stderr)
        subprocess.run(publish, check=True, capture_output=True, timeout=60)
        time.sleep(3)
    finally:
        out, err = _stop(watch)
    assert watch.returncode == 0, err
    expected = subprocess.run(
        [MODSCOPE, "replay", "--format", "jsonl"], check=True, capture_output=True, text=True
    ).stdout
    want = [json.loads(line) for line in expected.splitlines()]
    records = [json.loads(line) for line in out.splitlines()]
    frames = [r for r in records if "raw" in r]  # jq 'select(.raw)': each frame once
    rows = {r["index"]: r for r in frames}
    assert len(rows) == len(frames)
    for update in (r for r in records if "update" in r):
        # what pairing learnt after the row was listed (its answer, its timeout)
        assert rows[update["update"]]["transaction"]["status"] == "open"
        rows[update["update"]].update({k: v for k, v in update.items() if k != "update"})
    assert len(want) == 1562 and [r["index"] for r in frames] == [r["index"] for r in want]
    assert "never reached" not in err
    for row in want:
        assert rows[row["index"]] == row


@pytest.mark.slow
@pytest.mark.peer
@pytest.mark.skipif(shutil.which("mosquitto") is None, reason="apt-get install mosquitto")
def test_live_lists_and_publishes_the_same_bus(tmp_path: Path, broker: Broker) -> None:
    """`live PORT --mqtt URL`: the listing goes on as before; the broker gets the reads,
    the interface (line settings, the port as channel 0) and the unit's status."""
    base = "modscope/tap"  # the default base topic: modscope/<port name>
    reader = Reader(broker.port, f"{base}/#")
    publish = ["--mqtt", f"mqtt://127.0.0.1:{broker.port}", "--mqtt-every", "1"]
    request = with_crc(bytes.fromhex("010300000002"))
    answer = with_crc(bytes.fromhex("0103040001000a"))
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        bus.attach("slave")
        proc = subprocess.Popen(
            [MODSCOPE, "live", str(tap), *SERIAL, "--format", "jsonl", *publish],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            assert proc.stderr is not None
            wait_ready(proc.stderr)
            for _ in range(5):
                bus.inject(request, source="master")
                time.sleep(0.02)
                bus.inject(answer, source="slave")
                time.sleep(0.2)
            raws = reader.wait(f"{base}/raw", 10)
        finally:
            out, err = _stop(proc)
            reader.close()
    assert proc.returncode == 0, err
    rows = [json.loads(line) for line in out.splitlines()]
    frames = [bytes.fromhex(r["raw"]) for r in rows if "raw" in r]
    assert frames == [request, answer] * 5
    assert b"".join(read_raw(p).chunk.data for p in raws) == (request + answer) * 5
    interface = json.loads(reader.on(f"{base}/interface")[0])
    assert interface["line"] == {
        "baud": 19200,
        "bytesize": 8,
        "parity": "N",
        "stopbits": 2,
        "mode": "auto",
    }
    assert interface["channels"]["0"]["name"] == str(tap)
    status = json.loads(reader.on(f"{base}/unit/1/status")[-1])
    assert (status["requests"], status["answers"], status["state"]) == (5, 5, "online")
    assert status["latency_median_ms"] is not None


@pytest.mark.slow
@pytest.mark.peer
@pytest.mark.skipif(shutil.which("mosquitto") is None, reason="apt-get install mosquitto")
def test_a_watcher_reports_reads_the_broker_dropped(tmp_path: Path) -> None:
    """A broker that keeps few messages for a slow subscriber drops the rest; the watcher
    sees the gap in the publisher's count and frames a `data lost` event there. (A loss
    shows when the next read comes: the test releases the watcher before the end.)"""
    pytest.importorskip("paho.mqtt.client")
    from sniffer.outputs.mqtt.subscribe import MqttReader
    from sniffer.outputs.mqtt.target import parse_target

    broker = Broker(tmp_path)
    with broker.conf.open("a") as f:
        f.write("max_inflight_messages 1\nmax_queued_messages 50\n")
    broker.start()
    try:
        target = parse_target(f"mqtt://127.0.0.1:{broker.port}/modscope/demo")
        announce = open_publisher(target, Session(LineSettings()), {}, PublisherOptions())
        announce.close()  # the retained interface a watcher starts from
        reader = MqttReader(target)
        reader.open(wait=5)
        feed = reader.subscribe(100_000)
        gate = threading.Event()
        original = reader._raw

        def slow(payload: bytes) -> None:  # a subscriber busy elsewhere
            gate.wait(60)
            original(payload)

        reader._raw = slow  # type: ignore[method-assign]
        reader.start()
        session, capture = open_session(DEMO_BUS.with_name("demo.pcapng"))
        pub = open_publisher(target, session, {}, PublisherOptions(bus="demo"))
        chunks = list(capture.chunks())

        def reads() -> Iterator[Chunk]:
            for k, chunk in enumerate(chunks):
                if k == 1000:  # the watcher's queue at the broker overflowed long ago
                    assert pub.link.drain(20)
                    gate.set()
                if k >= 1000:
                    time.sleep(0.005)  # from now on at a pace the watcher keeps up with
                yield chunk

        try:
            publish_replay(session, reads(), pub)
            assert "dropped" not in pub.close()
            got: list[Chunk] = []
            end = time.monotonic() + 20
            # the reads after the gap are held until the missing ones have not come for
            # REORDER_WAIT seconds: then the gap counts as lost, where it was
            while time.monotonic() < end and (reader.fed_sequence or 0) < len(chunks):
                got += feed.get(0.2)
            got += feed.get(0.2)
        finally:
            reader.stop()
    finally:
        broker.stop()
    reads_got = [c for c in got if not c.event]
    losses = [c for c in got if c.event == "data lost"]
    assert losses and reads_got
    lost = sum(int(c.note.split(" ", 1)[0].replace(",", "")) for c in losses)
    assert lost == reader.lost_messages > 0
    # every read the publisher counted is accounted for: received, or reported lost
    assert reader.last_sequence == len(chunks)
    assert len(reads_got) + lost == len(chunks)
    received = [c.data for c in reads_got]
    assert received[:3] == [c.data for c in chunks[:3]] and received[-1] == chunks[-1].data


def _demo_reads() -> list[Any]:
    return [c for c in open_capture(DEMO_BUS.with_name("demo.pcapng")).chunks() if not c.event]


@pytest.mark.peer
@pytest.mark.skipif(shutil.which("mosquitto") is None, reason="apt-get install mosquitto")
def test_a_published_bus_is_watched_alone(broker: Broker) -> None:
    url = f"mqtt://127.0.0.1:{broker.port}/nothing/here"
    done = subprocess.run(
        [MODSCOPE, "live", url, "/dev/ttyUSB0"],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert done.returncode == 2 and "is a published bus; watch it alone" in done.stderr


@pytest.mark.slow
@pytest.mark.peer
def test_watching_where_no_broker_answers_says_so(broker: Broker) -> None:
    port = broker.port
    broker.stop()  # a port where nothing listens now
    done = subprocess.run(
        [MODSCOPE, "live", f"mqtt://127.0.0.1:{port}/modscope/demo"],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert done.returncode == 2
    assert done.stderr == (
        f"modscope: error: mqtt://127.0.0.1:{port}/modscope/demo: connection refused: "
        f"nothing listens on port {port}; check the port\n"
    )
