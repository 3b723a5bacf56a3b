"""The watcher against a real Mosquitto (#26, #30): it waits for its publisher and
follows it through a restart; reads that come out of order are fed in order and only
reads that never come count as lost; a network capture is framed by connection, as its
publisher framed it; hostile messages are skipped, counted and reported once.

Independent sides: `modscope replay` (the listing the watcher must match) and a plain
paho client publishing hand-made messages.
"""

from __future__ import annotations

import json
import shutil
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from sniffer.model import Chunk
from sniffer.outputs.mqtt import subscribe
from sniffer.outputs.mqtt.payload import raw_payload, read_raw
from sniffer.outputs.mqtt.subscribe import MqttReader
from sniffer.outputs.mqtt.target import parse_target
from sniffer.session.session import DEMO_CAPTURE
from sniffer.sources import open_capture
from tests.support.broker import Broker, broker

__all__ = ["broker"]  # (the fixture)
from tests.support.netbuild import Conversation, pcap
from tests.support.virtual_bus import wait_ready

pytestmark = [
    pytest.mark.peer,
    pytest.mark.skipif(shutil.which("mosquitto") is None, reason="apt-get install mosquitto"),
]
paho = pytest.importorskip("paho.mqtt.client")

MODSCOPE = str(Path(sys.executable).with_name("modscope"))


def _client(broker: Broker) -> Any:
    client = paho.Client(paho.CallbackAPIVersion.VERSION2)
    client.connect("127.0.0.1", broker.port)
    client.loop_start()
    return client


def _put(client: Any, topic: str, payload: bytes | str, retain: bool = False) -> None:
    client.publish(topic, payload, qos=1, retain=retain).wait_for_publish(10)


def _interface(session: str, **extra: Any) -> str:
    return json.dumps(
        {"line": {"baud": 19200, "parity": "E", "mode": "rtu"}, "session": session, **extra}
    )


def _frames(text: str) -> list[dict[str, Any]]:
    return [r for r in (json.loads(line) for line in text.splitlines()) if "raw" in r]


def _stop(proc: subprocess.Popen[str]) -> tuple[str, str]:
    proc.send_signal(signal.SIGINT)
    return proc.communicate(timeout=30)


# -- in order, lost only when never come -------------------------------------------------


def test_reads_out_of_order_are_fed_in_order_and_gaps_count_only_when_never_filled(
    broker: Broker, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(subscribe, "REORDER_WAIT", 0.5)
    base = "site/order"
    pub = _client(broker)
    _put(pub, f"{base}/interface", _interface("a"), retain=True)
    reader = MqttReader(parse_target(f"mqtt://127.0.0.1:{broker.port}/{base}"))
    reader.open(wait=5, forever=False)
    feed = reader.subscribe(1000)
    reader.start()
    chunks = [Chunk(bytes([1, 3, k]), 100.0 + k) for k in range(12)]
    try:
        # a reconnecting publisher's new read (5) ahead of its backlog (3, 4)
        for n in (1, 2, 5, 3, 4, 6):
            _put(pub, f"{base}/raw", raw_payload(chunks[n - 1], n))
        got: list[Chunk] = []
        end = time.monotonic() + 10
        while len(got) < 6 and time.monotonic() < end:
            got += feed.get(0.1)
        assert [c.data for c in got] == [c.data for c in chunks[:6]]
        assert reader.lost_messages == 0
        # 8 and 9 never come: after REORDER_WAIT they are lost, said before 10
        for n in (7, 10):
            _put(pub, f"{base}/raw", raw_payload(chunks[n - 1], n))
        got = []
        end = time.monotonic() + 10
        while len(got) < 3 and time.monotonic() < end:
            got += feed.get(0.1)
        assert [c.event for c in got] == ["", "data lost", ""]
        assert got[1].note.startswith("2 published reads never reached this watcher")
        assert got[1].t_end == chunks[9].t_end and got[2].data == chunks[9].data
        assert reader.lost_messages == 2
        # a publisher run begins again (new session, numbered from 1): no loss, no gap
        _put(pub, f"{base}/interface", _interface("b"), retain=True)
        _put(pub, f"{base}/raw", raw_payload(chunks[0], 1))
        _put(pub, f"{base}/raw", raw_payload(chunks[1], 2))
        got = []
        end = time.monotonic() + 10
        while len(got) < 2 and time.monotonic() < end:
            got += feed.get(0.1)
        assert [c.data for c in got] == [chunks[0].data, chunks[1].data]
        assert reader.restarts == 1 and reader.lost_messages == 2
    finally:
        reader.stop()
        pub.loop_stop()


# -- a watcher before its publisher, through a restart ------------------------------------


@pytest.mark.slow
def test_a_watcher_waits_for_its_publisher_and_follows_it_through_a_restart(
    broker: Broker,
) -> None:
    url = f"mqtt://127.0.0.1:{broker.port}/site/line1"
    watch = subprocess.Popen(
        [MODSCOPE, "live", url, "--format", "jsonl"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert watch.stderr is not None
        first = watch.stderr.readline()
        assert "waiting for a modscope to publish under 'site/line1'" in first
        publish = [MODSCOPE, "replay", str(DEMO_CAPTURE), "--mqtt", url]
        subprocess.run(publish, check=True, capture_output=True, timeout=60)
        wait_ready(watch.stderr)
        time.sleep(2)
        subprocess.run(publish, check=True, capture_output=True, timeout=60)  # again
        time.sleep(3)
    finally:
        out, err = _stop(watch)
    assert watch.returncode == 0, err
    # no read lost: none "never reached this watcher" / "never came" (a unit's liveness
    # line may say "last answer never", the demo's unit 4 never answering)
    assert "started again" in err and "never reached" not in err and "never came" not in err
    want = _frames(
        subprocess.run(
            [MODSCOPE, "replay", str(DEMO_CAPTURE), "--format", "jsonl"],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    )
    frames = _frames(out)
    # both runs, each read once: the first run's frames as replay lists them
    assert [r["raw"] for r in frames[: len(want)]] == [r["raw"] for r in want]
    assert len(frames) >= 2 * len(want) - 2


# -- the carrier travels with the bus -----------------------------------------------------


def _modbus_tcp_capture(path: Path) -> None:
    conv = Conversation()
    packets = [*conv.handshake()]
    for k in range(20):
        request = struct.pack(">HHHB", k + 1, 0, 6, 1) + bytes([3, 0, k, 0, 2])
        answer = struct.pack(">HHHB", k + 1, 0, 7, 1) + bytes([3, 4, 0, k, 0, 1])
        packets += [conv.client(request), conv.server(answer)]
    t0 = 1_768_464_000.0
    path.write_bytes(pcap(1, [(t0 + 0.01 * k, p) for k, p in enumerate(packets)]))


@pytest.mark.slow
def test_a_watched_network_capture_reads_as_its_publisher_read_it(
    broker: Broker, tmp_path: Path
) -> None:
    capture = tmp_path / "plant.pcap"
    _modbus_tcp_capture(capture)
    want = _frames(
        subprocess.run(
            [MODSCOPE, "replay", str(capture), "--format", "jsonl"],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    )
    kinds = [r["kind"] for r in want]
    assert kinds.count("request") == kinds.count("response") == 20 and "noise" not in kinds
    url = f"mqtt://127.0.0.1:{broker.port}/site/plant"
    watch = subprocess.Popen(
        [MODSCOPE, "live", url, "--format", "jsonl"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert watch.stderr is not None
        assert "waiting for a modscope" in watch.stderr.readline()
        subprocess.run(
            [MODSCOPE, "replay", str(capture), "--mqtt", url],
            check=True,
            capture_output=True,
            timeout=60,
        )
        wait_ready(watch.stderr)
        time.sleep(3)
    finally:
        out, err = _stop(watch)
    assert watch.returncode == 0, err
    frames = _frames(out)
    keys = ("raw", "kind", "unit", "function")
    assert [[r.get(k) for k in keys] for r in frames] == [[r.get(k) for k in keys] for r in want]


# -- hostile messages (#30) -----------------------------------------------------------------


@pytest.mark.slow
def test_hostile_messages_are_skipped_counted_and_reported_once(broker: Broker) -> None:
    base = "site/hostile"
    url = f"mqtt://127.0.0.1:{broker.port}/{base}"
    reads = [c for c in open_capture(DEMO_CAPTURE).chunks() if not c.event][:4]
    pub = _client(broker)
    _put(pub, f"{base}/interface", _interface("h"), retain=True)
    watch = subprocess.Popen(
        [MODSCOPE, "live", url, "--format", "jsonl"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert watch.stderr is not None
        wait_ready(watch.stderr)
        raw = f"{base}/raw"
        _put(pub, raw, raw_payload(reads[0], 1))
        channel = bytearray(raw_payload(reads[1], 2))
        channel[8:12] = struct.pack("<I", 300)  # interface id 300
        _put(pub, raw, bytes(channel))
        _put(pub, raw, raw_payload(reads[1], 2))
        _put(pub, f"{base}/interface", '{"a":' * 1000 + "1" + "}" * 1000)
        _put(pub, f"{base}/interface", '{"line": {"baud": 1e999}, "session": "h"}')
        _put(pub, f"{base}/interface", '{"line": {"baud": "fast"}, "session": "h"}')
        _put(pub, raw, b"\0" * (10 * 1024 * 1024))
        _put(pub, raw, raw_payload(reads[2], 2**63))
        future = Chunk(reads[2].data, 1.8e10, None)
        _put(pub, raw, raw_payload(future, 3))
        _put(pub, raw, raw_payload(reads[2], 3))
        _put(pub, raw, raw_payload(reads[3], 4))
        time.sleep(3)
    finally:
        out, err = _stop(watch)
        pub.loop_stop()
    assert "Traceback" not in err
    assert watch.returncode == 1, err  # trouble in the data
    frames = _frames(out)
    assert "".join(r["raw"] for r in frames) == b"".join(c.data for c in reads).hex()
    notices = [n for n in err.splitlines() if n.startswith("modscope: mqtt: a bad message")]
    for said in (
        "on channel 300",
        "nested",
        "baud is not a finite number",
        "10,485,760 bytes refused",
        "numbered 9,223,372,036,854,775,808",
        "in the future",
    ):  # each kind once (the second bad baud, "fast", only counted)
        assert sum(said in line for line in notices) == 1, (said, notices)
    assert len(notices) == 6
    assert "7 bad messages skipped" in err and "1 refused over the size limit" in err


# -- the backlog in order across broker restarts ----------------------------------------------


@pytest.mark.slow
def test_reads_reach_the_broker_in_order_across_restarts(broker: Broker) -> None:
    """A live publisher (never waiting) goes on publishing while the broker restarts
    three times; a persistent subscriber gets every read once, numbered in order: no
    new read ahead of the backlog, no gap (nothing was dropped)."""
    from sniffer.outputs.mqtt.publish import PublisherOptions, open_publisher
    from sniffer.session.session import open_session

    base = "site/order"
    seen: list[int] = []

    def on_message(client: Any, userdata: Any, message: Any) -> None:
        seen.append(read_raw(bytes(message.payload)).sequence or 0)

    def on_connect(client: Any, *args: Any) -> None:
        client.subscribe(f"{base}/raw", qos=1)

    reader = paho.Client(
        paho.CallbackAPIVersion.VERSION2, client_id="order-reader", clean_session=False
    )
    reader.on_message, reader.on_connect = on_message, on_connect
    reader.reconnect_delay_set(1, 2)
    reader.connect("127.0.0.1", broker.port)
    reader.loop_start()
    session, capture = open_session(DEMO_CAPTURE)
    target = parse_target(f"mqtt://127.0.0.1:{broker.port}/{base}")
    pub = open_publisher(target, session, {}, PublisherOptions(block=False), info=capture.info)
    chunks = list(capture.chunks())
    hook = pub.link._on_connect_hook
    assert hook is not None

    def slow_connect() -> None:  # widens the window in which a new read could overtake
        hook()  # paho's re-sends, which come right after this callback
        time.sleep(0.3)

    pub.link._on_connect_hook = slow_connect
    try:
        for k, chunk in enumerate(chunks):
            if k in (300, 700, 1100):
                broker.stop()  # while reads are in flight
            if k in (350, 750, 1150):
                broker.start()
            time.sleep(0.003)  # reads go on while the publisher reconnects
            pub.chunk(chunk)
            session.feed(chunk)
        session.finish()
        report = pub.close(drain=30)
        assert "dropped" not in report and pub.raw == len(chunks)
        end = time.monotonic() + 30
        while len(set(seen)) < len(chunks) and time.monotonic() < end:
            time.sleep(0.1)
    finally:
        reader.loop_stop()
        reader.disconnect()
    first = list(dict.fromkeys(seen))  # QoS 1 may deliver a read twice: its first place
    assert first == list(range(1, len(chunks) + 1))


def test_one_read_stamped_far_ahead_does_not_shut_out_the_reads_after_it(
    broker: Broker, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A read stamped a day ahead (capture-relative times have no clock to compare with)
    gets through; the reads after it look 'older' and are refused, but only
    BACK_STREAK - 1 of them: then the watcher follows the stream again."""
    monkeypatch.setattr(subscribe, "REORDER_WAIT", 0.3)
    base = "site/ahead"
    pub = _client(broker)
    _put(pub, f"{base}/interface", _interface("a"), retain=True)
    notes: list[str] = []
    reader = MqttReader(parse_target(f"mqtt://127.0.0.1:{broker.port}/{base}"), notify=notes.append)
    reader.open(wait=5, forever=False)
    feed = reader.subscribe(1000)
    reader.start()
    try:
        stamps = [100.0, 86_500.0, 101.0, 102.0, 103.0, 104.0]
        for n, t in enumerate(stamps, 1):
            _put(pub, f"{base}/raw", raw_payload(Chunk(bytes([n]), t), n))
        got: list[Chunk] = []
        end = time.monotonic() + 10
        while sum(1 for c in got if not c.event) < 4 and time.monotonic() < end:
            got += feed.get(0.1)
    finally:
        reader.stop()
        pub.loop_stop()
    assert [c.data[0] for c in got if not c.event] == [1, 2, 5, 6]
    assert reader.bad_kinds == {"time": subscribe.BACK_STREAK - 1}
    assert any("went back" in n and "following them from here" in n for n in notes), notes
    # the two refused reads' numbers never came as good reads: also counted lost (a
    # foreign message must not take a number a real read may still bring)
    assert reader.lost_messages == 2
