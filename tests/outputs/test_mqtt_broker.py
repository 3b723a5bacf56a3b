"""modscope against a real Mosquitto broker started on a free loopback port.

Independent readers: `mosquitto_sub` and a plain paho client. Covers the demo published
with Home Assistant discovery, a second modscope reading the bus back byte for byte, and
the broker stopped and restarted in the middle of a replay.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import threading
import time
from collections.abc import Iterator

import pytest

from sniffer.meaning.annotate import load_bindings
from sniffer.model import Chunk
from sniffer.outputs.mqtt.link import MqttLink
from sniffer.outputs.mqtt.payload import raw_payload, read_raw, slug
from sniffer.outputs.mqtt.publish import (
    BusPublisher,
    PublisherOptions,
    open_publisher,
    publish_replay,
)
from sniffer.outputs.mqtt.subscribe import MqttReader
from sniffer.outputs.mqtt.target import parse_target
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, open_session
from tests.support.broker import Broker, broker

__all__ = ["broker"]  # (the fixture)

pytestmark = [
    pytest.mark.peer,
    pytest.mark.skipif(shutil.which("mosquitto") is None, reason="apt-get install mosquitto"),
]
paho = pytest.importorskip("paho.mqtt.client")


def _retained(broker: Broker, *topics: str) -> dict[str, str]:
    """Retained messages under `topics`, read with mosquitto_sub."""
    args = ["mosquitto_sub", "-p", str(broker.port), "-v", "-W", "2", "--retained-only"]
    for t in topics:
        args += ["-t", t]
    done = subprocess.run(args, capture_output=True, timeout=30, check=False)
    found = {}
    for line in done.stdout.decode().splitlines():
        topic, _, payload = line.partition(" ")
        found[topic] = payload
    return found


def test_demo_fills_the_broker_with_every_named_register(broker: Broker) -> None:
    bindings = load_bindings(DEMO_BUS)
    target = parse_target(f"mqtt://127.0.0.1:{broker.port}/modscope/demo")
    session, capture = open_session(DEMO_CAPTURE, bindings=bindings)
    options = PublisherOptions(bus="demo", ha_prefix="homeassistant")
    pub = open_publisher(target, session, bindings, options, info=capture.info)
    publish_replay(session, capture.chunks(), pub)
    report = pub.close()
    assert "dropped" not in report
    # what the capture says, found independently of the publisher: last value per register
    last: dict[tuple[int, str], object] = {}
    for i in range(len(session.store)):
        d = session.describer.detail(i)
        if d.view.kind.name == "RESPONSE" and d.view.check_ok:
            for r in d.registers:
                if not r.partial:
                    last[(d.view.unit, r.name)] = r.value
    assert {u for u, _ in last} == {1, 2, 3}
    values = _retained(broker, "modscope/demo/unit/+/+")
    by_name = {}
    for topic, payload in values.items():
        if not topic.endswith("/status"):
            msg = json.loads(payload)
            by_name[(msg["unit"], msg["name"])] = msg["value"]
            assert topic == f"modscope/demo/unit/{msg['unit']}/" + topic.rsplit("/", 1)[1]
    assert by_name == {k: v for k, v in last.items()}
    configs = _retained(broker, "homeassistant/#")
    assert len(configs) >= len(last)
    voltage = json.loads(
        configs[f"homeassistant/sensor/modscope_modscope_demo_2/{slug('Voltage')}/config"]
    )
    assert voltage["state_topic"] == "modscope/demo/unit/2/voltage"
    assert voltage["device_class"] == "voltage" and voltage["unit_of_measurement"] == "V"
    status = _retained(broker, "modscope/demo/status", "modscope/demo/unit/+/status")
    assert status["modscope/demo/status"] == "offline"  # the publisher said goodbye
    unit3 = json.loads(status["modscope/demo/unit/3/status"])
    st3 = session.stats.units[3]
    assert (unit3["requests"], unit3["answers"], unit3["exceptions"]) == (
        st3.requests,
        st3.responses,
        st3.exception_count,
    )
    unit4 = json.loads(status["modscope/demo/unit/4/status"])
    assert unit4["state"] == "silent" and unit4["timeouts"] == session.stats.units[4].timeouts


def test_a_second_modscope_frames_the_published_bus_byte_for_byte(broker: Broker) -> None:
    bindings = load_bindings(DEMO_BUS)
    target = parse_target(f"mqtt://127.0.0.1:{broker.port}/modscope/demo")
    session, capture = open_session(DEMO_CAPTURE, bindings=bindings)
    pub = open_publisher(target, session, bindings, PublisherOptions(bus="demo"), info=capture.info)
    reader = MqttReader(target)
    reader.open(wait=5)
    feed = reader.subscribe(100_000)
    reader.start()
    try:
        publish_replay(session, capture.chunks(), pub)
        pub.close()
        got: list[Chunk] = []
        deadline = time.monotonic() + 20
        while len(got) < session.chunks and time.monotonic() < deadline:
            got += feed.get(0.2)
    finally:
        reader.stop()
    assert len(got) == session.chunks
    assert reader.specs[0].line == session.line
    other = Session(
        reader.specs[0].line,
        bindings=bindings,
        exact_timing=reader.exact_timing,
        timeout=reader.timeout,
    )
    for chunk in got:
        other.feed(chunk)
    other.finish()
    a, b = session.store, other.store
    assert len(a) == len(b) == 1562
    for i in range(len(a)):
        assert (a.raw(i), a.kind[i], a.t[i], a.t_end[i], a.status[i]) == (
            b.raw(i),
            b.kind[i],
            b.t[i],
            b.t_end[i],
            b.status[i],
        )


def test_broker_restart_during_a_replay(broker: Broker) -> None:
    """The broker stops after 500 reads are delivered; capture goes on; 200 more are
    buffered, the rest dropped and counted; after the restart the buffer is delivered."""
    n_first, limit = 500, 200
    base = "modscope/restart"
    received: list[bytes] = []
    lock = threading.Lock()

    def on_message(client: object, userdata: object, message: object) -> None:
        with lock:
            received.append(bytes(message.payload))  # type: ignore[attr-defined]

    sessions: list[bool] = []  # session_present at each connection of the reader

    def on_connect(client: object, userdata: object, flags: object, *args: object) -> None:
        sessions.append(bool(flags.session_present))  # type: ignore[attr-defined]
        client.subscribe(f"{base}/raw", qos=1)  # type: ignore[attr-defined]

    reader = paho.Client(
        paho.CallbackAPIVersion.VERSION2, client_id="restart-reader", clean_session=False
    )
    reader.on_message = on_message
    reader.on_connect = on_connect
    reader.reconnect_delay_set(1, 2)
    reader.connect("127.0.0.1", broker.port)
    reader.loop_start()
    target = parse_target(f"mqtt://127.0.0.1:{broker.port}/{base}")
    bindings = load_bindings(DEMO_BUS)
    session, capture = open_session(DEMO_CAPTURE, bindings=bindings)
    link = MqttLink(target, will=(target.topic("status"), "offline"), limit=limit)
    pub = BusPublisher(link, session, bindings, PublisherOptions(bus="demo"), info=capture.info)
    assert link.start(5)
    chunks = list(capture.chunks())

    def reads() -> Iterator[Chunk]:
        for k, chunk in enumerate(chunks):
            if k == n_first:
                assert link.drain(20)
                end = time.monotonic() + 20  # the reader has everything sent so far
                while len(set(received)) < n_first and time.monotonic() < end:
                    time.sleep(0.02)
                broker.stop()
                # the broker kept the reader's session (its subscription), so the reads
                # buffered by the publisher wait for the reader whoever reconnects first
                assert (broker.folder / "mosquitto.db").stat().st_size > 0
                assert _wait_false(link.connected)
            yield chunk

    try:
        publish_replay(session, reads(), pub, refresh_every=1e9)
        assert len(session.store) == 1562  # capture did not stop
        # the buffer keeps the first reads after the loss (up to the bound, shared with
        # the other topics) and drops the later ones
        kept = len(chunks) - n_first - pub.raw_dropped
        assert kept == limit
        broker.start()
        report = pub.close(drain=30)
        assert link.counts.dropped >= pub.raw_dropped
        assert f"{link.counts.dropped:,} dropped" in report
        assert link.counts.delivered == link.counts.offered - link.counts.dropped
        expected = {raw_payload(c, k + 1) for k, c in enumerate(chunks[: n_first + kept])}
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            with lock:
                if len(set(received)) >= len(expected):
                    break
            time.sleep(0.1)
        with lock:
            got = set(received)
        # the reader's persistent session survived the restart: every read the
        # publisher delivered reached it, whichever of the two reconnected first
        assert sessions[0] is False and sessions[-1] is True and len(sessions) >= 2
        # and the reads the publisher dropped are one `data lost` read, numbered next,
        # at the last dropped read's time, counting them: the loss said where it happened
        extra = [read_raw(p) for p in got - expected]
        assert got >= expected and len(extra) == 1
        said = extra[0]
        assert said.sequence == n_first + kept + 1 and said.chunk.event == "data lost"
        assert said.chunk.note.startswith(f"{pub.raw_dropped:,} reads from t=")
        assert said.chunk.t_end == chunks[-1].t_end
    finally:
        reader.loop_stop()
        reader.disconnect()


def _wait_false(event: threading.Event, timeout: float = 10) -> bool:
    end = time.monotonic() + timeout
    while event.is_set() and time.monotonic() < end:
        time.sleep(0.02)
    return not event.is_set()
