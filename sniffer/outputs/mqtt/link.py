"""Provides the connection to a broker: a paho client with a bounded buffer and counts.

Every message is QoS 1. While the broker is away paho keeps messages (and re-sends
them on reconnection, which is automatic) up to `limit` undelivered messages; past the
bound a message is dropped and counted, never waited for: capture never stops for the
broker. While the broker is there but slower than the bus, `publish(block=True)` (what
a replay uses) waits once `IN_FLIGHT` messages are unacknowledged, for as long as the
broker takes one every BLOCK_SECONDS, so a fast replay loses nothing; a live capture
publishes with `block=False` and drops instead.

The first connection is made before `start()` returns: a broker that cannot be reached,
a TLS certificate refused, a wrong CA, or credentials refused end with an `MqttError`
naming the broker and the cause (`connect_first`), never with a silent retry. Once
connected, a broker lost is reported and retried for ever.

Order: paho re-sends what it held when the connection dropped right after the broker
acknowledges the new connection, but a message published in between would go first.
So from a loss until the broker acknowledged the first message of the new connection
(the `status` message `online`, published from the connect callback, so its
acknowledgement comes after paho's re-sends) new messages wait in our own queue, and
go out after that, in the order they were offered.
"""

from __future__ import annotations

import contextlib
import socket
import ssl
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from sniffer.outputs.mqtt import MqttError, require_paho
from sniffer.outputs.mqtt.target import MqttTarget

DEFAULT_LIMIT = 100_000  # undelivered messages kept while the broker is away or slow
BLOCK_SECONDS = 5.0  # longest wait for the broker to take a message, while connected
# messages a waiting publisher (`block`: a replay) lets go unacknowledged while the broker
# is there. A replay runs on the CPU and paho reads the broker's acknowledgements in a
# thread of its own: with 100,000 let go (the buffer), a replay of 200k frames of issue
# #29's bus got 1.6k acknowledgements a second from a local Mosquitto, filled the buffer,
# and dropped 20k messages after 25 s; waiting at 2,000 leaves paho the time to read them
IN_FLIGHT = 2_000
KEEPALIVE = 15
FIRST_WAIT = 5.0  # seconds for the broker to answer the first connection

Notify = Callable[[str], None]

_AUTH_REASONS = ("not authorized", "bad user name or password", "bad username or password")


def tls_context(target: MqttTarget) -> ssl.SSLContext:
    """The TLS context of an mqtts:// target (MqttError naming an unusable CA file)."""
    try:
        return ssl.create_default_context(cafile=target.ca)
    except (OSError, ssl.SSLError) as exc:
        reason = getattr(exc, "strerror", None) or getattr(exc, "reason", None) or str(exc)
        raise MqttError(
            f"--mqtt-ca {target.ca}: not a readable PEM CA certificate ({reason}); give the "
            "file of the CA that signed the broker's certificate"
        ) from None


class FirstConnection:
    """How the first connection ended, told by paho's callbacks (paho's thread)."""

    def __init__(self) -> None:
        self.done = threading.Event()
        self.refused: str | None = None  # the broker's CONNACK reason
        self.closed: str | None = None  # the connection closed before any CONNACK

    def connected(self, reason: Any) -> None:
        if not self.done.is_set():
            if getattr(reason, "is_failure", False):
                self.refused = str(reason)
            self.done.set()

    def disconnected(self, reason: Any) -> None:
        if not self.done.is_set():
            self.closed = str(reason)
            self.done.set()


def _cause(exc: BaseException, target: MqttTarget) -> str:
    """What a failed connect() means, and the fix."""
    if isinstance(exc, ssl.SSLCertVerificationError):
        why = exc.verify_message or exc.reason or str(exc)
        if "hostname" in str(why).lower() or "ip address mismatch" in str(why).lower():
            return (
                f"the broker's TLS certificate is not for {target.host!r} ({why}); connect "
                "with the name the certificate gives"
            )
        hint = "give the CA that signed it with --mqtt-ca FILE"
        if target.ca is not None:
            hint = f"--mqtt-ca {target.ca} is not the CA that signed it"
        return f"the broker's TLS certificate was refused ({why}); {hint}"
    if isinstance(exc, ssl.SSLError):
        return (
            f"TLS failed ({exc.reason or exc}); is port {target.port} a TLS listener? "
            "(mqtt:// for a plain one)"
        )
    if isinstance(exc, socket.gaierror):
        return f"cannot resolve {target.host!r} ({exc.strerror}); check the host name"
    if isinstance(exc, ConnectionRefusedError):
        return f"connection refused: nothing listens on port {target.port}; check the port"
    if isinstance(exc, TimeoutError):
        return "no answer (timed out); check the host, the port and any firewall"
    if isinstance(exc, OSError):
        return f"cannot connect ({exc.strerror or exc}); check the host and port"
    return f"cannot connect ({exc})"


def connect_first(client: Any, target: MqttTarget, first: FirstConnection, wait: float) -> None:
    """Connect `client` to `target` and start its loop; MqttError (one line: the broker
    without credentials, the cause, the fix) unless the broker accepted the connection
    within `wait` seconds. paho retries by itself from then on."""
    where = target.describe()
    client.connect_timeout = wait
    try:
        client.connect(target.host, target.port, keepalive=KEEPALIVE)
    except (OSError, ValueError) as exc:
        raise MqttError(f"{where}: {_cause(exc, target)}") from None
    client.loop_start()
    ok = first.done.wait(wait)
    if ok and first.refused is None and first.closed is None:
        return
    with contextlib.suppress(Exception):
        client.disconnect()
    client.loop_stop()
    if not ok:
        raise MqttError(
            f"{where}: no MQTT answer within {wait:g} s; is it an MQTT broker (mqtts:// "
            "for a TLS listener)?"
        )
    if first.refused is not None:
        if first.refused.lower() in _AUTH_REASONS:
            who = f"user {target.username!r}" if target.username else "anonymous connections"
            raise MqttError(
                f"{where}: the broker refused {who} ({first.refused}); check the user and "
                "the password (URL, --mqtt-password-file or MODSCOPE_MQTT_PASSWORD)"
            )
        raise MqttError(f"{where}: the broker refused the connection ({first.refused})")
    tls = "" if target.tls else "; a TLS listener needs mqtts://"
    raise MqttError(
        f"{where}: the broker closed the connection before answering ({first.closed}){tls}"
    )


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
        self._stalled = -1  # `counts.delivered` when a wait for the broker last timed out
        self.notify = notify
        self.counts = LinkCounts()
        self.connected = threading.Event()
        self.last_error = ""
        self._on_connect_hook = on_connect
        self._cond = threading.Condition()
        self._dropping = False
        self._closing = False
        self._ready = False  # paho re-sent what it held: new messages may go to it
        self._order = threading.Lock()  # held by whoever hands held messages to paho
        self._in_connect = False  # paho's thread is in the connect callback
        self._marker = False  # a message was handed to paho from the connect callback
        self._caller = threading.current_thread()  # the publishing thread
        self._held: deque[tuple[str, bytes | str, bool]] = deque()  # offered while not ready
        self._first = FirstConnection()
        self._will = will
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
            client.tls_set_context(tls_context(target))
        if will is not None:
            client.will_set(will[0], will[1], qos=1, retain=True)
        client.on_connect = self._connected
        client.on_disconnect = self._disconnected
        client.on_publish = self._published
        self.client = client

    # -- lifetime ----------------------------------------------------------------------------

    def start(self, wait: float = FIRST_WAIT) -> bool:
        """Connect (MqttError saying why if the broker cannot be used, see
        `connect_first`); from then on paho reconnects by itself. True."""
        connect_first(self.client, self.target, self._first, max(wait, 0.5))
        end = time.monotonic() + max(wait, 0.5)
        with self._cond:  # the acknowledgement of `online`: what is offered goes straight on
            while not self._ready and time.monotonic() < end:
                self._cond.wait(0.05)
        return True

    def close(self, drain: float = 10.0, last: tuple[str, str] | None = None) -> LinkCounts:
        """Publish `last` (topic, retained payload), wait up to `drain` seconds for what is
        buffered to be delivered, then disconnect."""
        if last is not None:
            self.publish(last[0], last[1], retain=True, block=True)
        self.drain(drain)
        self._closing = True
        with self._cond:
            self._held.clear()
        with contextlib.suppress(Exception):
            self.client.disconnect()
        self.client.loop_stop()
        return self.counts

    def drain(self, timeout: float) -> bool:
        """Wait until every accepted message was delivered (or `timeout`). True if so."""
        end = time.monotonic() + timeout
        while True:
            self._flush()
            with self._cond:
                if self.counts.pending <= 0:
                    return True
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(min(left, 0.1))

    # -- publishing --------------------------------------------------------------------------

    def publish(
        self, topic: str, payload: bytes | str, *, retain: bool = False, block: bool = False
    ) -> bool:
        """Queue one QoS 1 message. False if it was dropped (the buffer is full)."""
        with self._cond:
            c = self.counts
            room = min(self.limit, IN_FLIGHT)
            stalled = self._stalled == c.delivered  # (no wait again till one is taken)
            if block and c.pending >= room and self.connected.is_set() and not stalled:
                # wait while the broker takes messages; past BLOCK_SECONDS without one
                # taken, go on buffering (and past the buffer, drop)
                seen, end = c.delivered, time.monotonic() + BLOCK_SECONDS
                while c.pending >= room and self.connected.is_set():
                    now = time.monotonic()
                    if c.delivered != seen:
                        seen, end = c.delivered, now + BLOCK_SECONDS
                    if now >= end:
                        self._stalled = c.delivered
                        break
                    self._cond.wait(min(end - now, 0.05))
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
            if self._in_connect and threading.current_thread() is not self._caller:
                self._marker = True  # paho's thread, connecting: ahead of its re-sends
                marker = True
            else:
                # in order, after paho's re-sends (module doc): straight on when connected
                self._held.append((topic, payload, retain))
                marker = False
        if marker:
            return self._hand(topic, payload, retain)
        self._flush()
        return True

    def _hand(self, topic: str, payload: bytes | str, retain: bool) -> bool:
        info = self.client.publish(topic, payload, qos=1, retain=retain)
        if info.rc == self._paho.MQTT_ERR_QUEUE_SIZE:
            # any other result (no connection, connection lost) leaves a QoS 1 message
            # in paho's store, sent again after reconnecting
            with self._cond:
                self.counts.dropped += 1
            return False
        return True

    def _flush(self, paho_thread: bool = False) -> None:
        """Hand the messages held since the connection was lost to paho, in order, once
        paho re-sent what it had (module doc). `_order` keeps one thread at it; paho's
        thread never waits for it (the publishing thread may be waiting for paho's lock),
        and `_cond` is never held while paho's lock is taken."""
        if not self._order.acquire(blocking=paho_thread is False):
            return  # the publishing thread is handing them over
        try:
            while True:
                with self._cond:
                    if not self._ready or not self._held:
                        return
                    topic, payload, retain = self._held.popleft()
                self._hand(topic, payload, retain)
        finally:
            self._order.release()

    # -- paho callbacks (paho's thread) ------------------------------------------------------

    def _connected(
        self, client: Any, userdata: Any, flags: Any, reason: Any, properties: Any
    ) -> None:
        self._first.connected(reason)
        if getattr(reason, "is_failure", False):
            self.last_error = str(reason)
            if self.counts.connects:  # the first connection's refusal ends start()
                self._tell(f"mqtt: {self.target.describe()} refused the connection: {reason}")
            return
        self.counts.connects += 1
        self.connected.set()
        with self._cond:
            self._dropping = False
            self._ready = False
            self._marker = False
        if self.counts.connects > 1:
            self._tell(f"mqtt: connected again to {self.target.describe()}")
        # what is published now (the publisher's `online`) goes to paho at once: its
        # acknowledgement says paho's re-sends are out (module doc)
        self._in_connect = True
        try:
            if self._on_connect_hook is not None:
                self._on_connect_hook()
            elif self._will is not None:
                self.publish(self._will[0], "online", retain=True)
        finally:
            self._in_connect = False
        with self._cond:
            if not self._marker:  # nothing to wait for: no acknowledgement would come
                self._ready = True
            self._cond.notify_all()

    def _disconnected(
        self, client: Any, userdata: Any, flags: Any, reason: Any, properties: Any
    ) -> None:
        self._first.disconnected(reason)
        was = self.connected.is_set()
        self.connected.clear()
        with self._cond:
            self._ready = False
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
            became = not self._ready and self.connected.is_set()
            self._ready = self.connected.is_set()
            self._cond.notify_all()
        if became:  # an idle publisher's held messages go now, not with its next one
            self._flush(paho_thread=True)

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
