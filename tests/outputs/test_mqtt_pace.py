"""A replay waits for the broker once a few thousand messages are unacknowledged
(`sniffer.outputs.mqtt.link.IN_FLIGHT`), not only when its buffer of 100,000 is full.

Found measuring #29: a replay of 200k frames to a local Mosquitto let up to 100,000
messages go unacknowledged; paho then spent its thread on that queue (each
acknowledgement looks over the messages still queued), took 1.6k acknowledgements a
second, and 20k messages were dropped after 25 s, 24k left undelivered."""

from __future__ import annotations

import time

from sniffer.outputs.mqtt.link import IN_FLIGHT, MqttLink
from sniffer.outputs.mqtt.target import parse_target
from tests.support.broker import Broker, broker

__all__ = ["broker"]  # (the fixture)

MESSAGES = 10_000


def test_a_fast_replay_loses_nothing_to_a_broker_that_keeps_up(broker: Broker) -> None:
    target = parse_target(f"mqtt://127.0.0.1:{broker.port}/pace")
    link = MqttLink(target)
    assert link.start(5)
    most = 0
    start = time.monotonic()
    for _ in range(MESSAGES):
        link.publish(target.topic("raw"), b"x" * 100, block=True)  # as a replay does
        most = max(most, link.counts.pending)
    counts = link.close(drain=20)
    took = time.monotonic() - start
    assert counts.dropped == 0 and counts.pending == 0
    assert counts.delivered == MESSAGES, f"{counts} after {took:.1f} s"
    assert most <= IN_FLIGHT + 1  # waited for the broker, not for the buffer
