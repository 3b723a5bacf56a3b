"""Provides the connection to a broker: a paho client with a bounded buffer and counts.

Every message is QoS 1. While the broker is away paho keeps messages (and re-sends
them on reconnection, which is automatic) up to `limit` undelivered messages; past the
bound a message is dropped and counted, never waited for: capture never stops for the
broker. While the broker is there but slower than the bus, `publish(block=True)` (what
a replay uses) waits for room, so a fast replay loses nothing; a live capture publishes
with `block=False` and drops instead.
"""

from __future__ import annotations

import contextlib
import ssl
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from sniffer.outputs.mqtt import MqttError, require_paho
from sniffer.outputs.mqtt.target import MqttTarget

DEFAULT_LIMIT = 100_000  # undelivered messages kept while the broker is away or slow
BLOCK_SECONDS = 5.0  # longest wait for room while connected, before a message is dropped
KEEPALIVE = 15

Notify = Callable[[str], None]


@dataclass
class LinkCounts:
    """What happened to the messages offered to a link."""

    offered: int = 0
    delivered: int = 0  # acknowledged by the broker
    dropped: int = 0  # refused: the buffer was full
    connects: int = 0
    disconnects: int = 0

    @property
    def pending(self) -> int:
        return self.offered - self.delivered - self.dropped


class MqttLink:
    """One broker connection. `start()`, `publish()` from any one thread, `close()`."""

    def __init__(
        self,
        target: MqttTarget,
        *,
        will: tuple[str, str] | None = None,
        limit: int = DEFAULT_LIMIT,
        client_id: str | None = None,
        notify: Notify | None = None,
        on_connect: Callable[[], None] | None = None,
    ) -> None:
        require_paho()
        import paho.mqtt.client as paho
        from paho.mqtt.enums import CallbackAPIVersion

        if limit < 1:
            raise MqttError(f"the MQTT buffer holds at least one message, not {limit}")
        self.target = target
        self.limit = limit
        self.notify = notify
        self.counts = LinkCounts()
        self.connected = threading.Event()
        self.last_error = ""
        self._on_connect_hook = on_connect
        self._cond = threading.Condition()
        self._dropping = False
        self._closing = False
        self._paho = paho
        client = paho.Client(
            CallbackAPIVersion.VERSION2,
            client_id=client_id or f"modscope-{uuid.uuid4().hex[:12]}",
            protocol=paho.MQTTv311,
        )
        client.max_inflight_messages_set(1000)
        client.max_queued_messages_set(0)  # the bound is ours (see publish)
        client.reconnect_delay_set(1, 5)
        if target.username is not None:
            client.username_pw_set(target.username, target.password)
        if target.tls:
            context = ssl.create_default_context(cafile=target.ca)
            client.tls_set_context(context)
        if will is not None:
            client.will_set(will[0], will[1], qos=1, retain=True)
        client.on_connect = self._connected
        client.on_disconnect = self._disconnected
        client.on_publish = self._published
        self.client = client

    # -- lifetime ----------------------------------------------------------------------------

    def start(self, wait: float = 0.0) -> bool:
        """Connect in the background (retried until it works); wait up to `wait` seconds
        for the first connection. True when connected."""
        try:
            self.client.connect_async(self.target.host, self.target.port, keepalive=KEEPALIVE)
        except (OSError, ValueError) as exc:
            raise MqttError(f"{self.target.describe()}: cannot connect ({exc})") from None
        self.client.loop_start()
        if wait > 0:
            return self.connected.wait(wait)
        return self.connected.is_set()

    def close(self, drain: float = 10.0, last: tuple[str, str] | None = None) -> LinkCounts:
        """Publish `last` (topic, retained payload), wait up to `drain` seconds for what is
        buffered to be delivered, then disconnect."""
        if last is not None:
            self.publish(last[0], last[1], retain=True, block=True)
        self.drain(drain)
        self._closing = True
        with contextlib.suppress(Exception):
            self.client.disconnect()
        self.client.loop_stop()
        return self.counts

    def drain(self, timeout: float) -> bool:
        """Wait until every accepted message was delivered (or `timeout`). True if so."""
        end = time.monotonic() + timeout
        with self._cond:
            while self.counts.pending > 0:
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(min(left, 0.1))
        return True

    # -- publishing --------------------------------------------------------------------------

    def publish(
        self, topic: str, payload: bytes | str, *, retain: bool = False, block: bool = False
    ) -> bool:
        """Queue one QoS 1 message. False if it was dropped (the buffer is full)."""
        with self._cond:
            c = self.counts
            if c.pending >= self.limit and block and self.connected.is_set():
                end = time.monotonic() + BLOCK_SECONDS
                while c.pending >= self.limit and self.connected.is_set():
                    left = end - time.monotonic()
                    if left <= 0:
                        break
                    self._cond.wait(min(left, 0.05))
            c.offered += 1
            if c.pending > self.limit:
                c.dropped += 1
                if not self._dropping:
                    self._dropping = True
                    self._tell(
                        f"mqtt: buffer full ({self.limit} messages); dropping until "
                        f"{self.target.describe()} takes messages again"
                    )
                return False
        info = self.client.publish(topic, payload, qos=1, retain=retain)
        if info.rc == self._paho.MQTT_ERR_QUEUE_SIZE:
            # any other result (no connection, connection lost) leaves a QoS 1 message
            # in paho's store, sent again after reconnecting
            with self._cond:
                self.counts.dropped += 1
            return False
        return True

    # -- paho callbacks (paho's thread) ------------------------------------------------------

    def _connected(
        self, client: Any, userdata: Any, flags: Any, reason: Any, properties: Any
    ) -> None:
        if getattr(reason, "is_failure", False):
            self.last_error = str(reason)
            self._tell(f"mqtt: {self.target.describe()} refused the connection: {reason}")
            return
        self.counts.connects += 1
        self.connected.set()
        with self._cond:
            self._dropping = False
            self._cond.notify_all()
        if self.counts.connects > 1:
            self._tell(f"mqtt: connected again to {self.target.describe()}")
        if self._on_connect_hook is not None:
            self._on_connect_hook()

    def _disconnected(
        self, client: Any, userdata: Any, flags: Any, reason: Any, properties: Any
    ) -> None:
        was = self.connected.is_set()
        self.connected.clear()
        with self._cond:
            self._cond.notify_all()
        if was and not self._closing:
            self.counts.disconnects += 1
            self._tell(
                f"mqtt: lost {self.target.describe()} ({reason}); buffering up to "
                f"{self.limit} messages and reconnecting"
            )

    def _published(
        self, client: Any, userdata: Any, mid: int, reason: Any, properties: Any
    ) -> None:
        with self._cond:
            self.counts.delivered += 1
            self._cond.notify_all()

    def _tell(self, text: str) -> None:
        if self.notify is not None:
            self.notify(text)

    def report(self) -> str:
        c = self.counts
        text = f"mqtt: {c.delivered:,} messages delivered to {self.target.describe()}"
        if c.dropped:
            text += f", {c.dropped:,} dropped while the broker was away or slow"
        if c.pending:
            text += f", {c.pending:,} not delivered when modscope stopped"
        if c.disconnects:
            text += f"; the connection was lost {c.disconnects} time(s)"
        return text
