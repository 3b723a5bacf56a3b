"""Provides a published bus as a live source: `raw` messages back into chunks.

`MqttReader` looks like the serial `LiveReader` to `LiveCapture` (open, subscribe,
start, stop, specs, clock, stats), so `modscope live mqtt://host/base` and the TUI
watch a bus another modscope publishes. The retained `interface` message gives the
line settings and how the publisher framed (exact timing, response timeout), so the
chunks frame here exactly as they did there.

Its clock follows the publisher's timestamps (the last chunk's time plus the time since
it arrived), so a replay published faster than real time does not time out requests
that were answered.
"""

from __future__ import annotations

import json
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable
from typing import Any

from sniffer.live.port import DEFAULT_QUEUE, ChunkFeed, PortSpec, PortStats
from sniffer.model import Chunk, LineSettings, Stamp
from sniffer.outputs.mqtt import MqttError, require_paho
from sniffer.outputs.mqtt.payload import PayloadError, RawMessage, read_raw
from sniffer.outputs.mqtt.target import MqttTarget

Notify = Callable[[str], None]
RETAINED_GRACE = 1.0  # seconds for retained messages to follow the subscription's ack
DUPLICATES = 4096  # recent raw messages remembered to drop QoS 1 re-deliveries


def lost_text(count: int) -> str:
    return (
        f"{count:,} published reads never reached this watcher: the broker dropped them "
        "(raise its max_queued_messages) or the publisher's buffer was full"
    )


class StreamClock:
    """Unix time as the publisher's chunks tell it (see the module doc)."""

    def __init__(self) -> None:
        self._t: float | None = None
        self._mono = 0.0
        self._lock = threading.Lock()

    def seen(self, t: float) -> None:
        with self._lock:
            if self._t is None or t >= self._t:
                self._t = t
                self._mono = time.monotonic()

    def now(self) -> float:
        with self._lock:
            if self._t is None:
                return time.time()
            return self._t + (time.monotonic() - self._mono)


def line_from_interface(message: dict[str, Any]) -> LineSettings:
    line = message.get("line") or {}
    try:
        return LineSettings(
            baud=int(line.get("baud", 19200)),
            bytesize=int(line.get("bytesize", 8)),
            parity=str(line.get("parity", "E")),
            stopbits=int(line.get("stopbits", 1)),
            mode=str(line.get("mode", "auto")),
        )
    except (TypeError, ValueError) as exc:
        raise MqttError(f"the interface message has unusable line settings: {exc}") from None


class MqttReader:
    """Chunks of a bus published under `target`'s base topic, offered to feeds."""

    def __init__(self, target: MqttTarget, *, notify: Notify | None = None) -> None:
        require_paho()
        import paho.mqtt.client as paho
        from paho.mqtt.enums import CallbackAPIVersion

        self.target = target
        self.notify = notify
        self.clock = StreamClock()
        self.warnings: list[str] = []
        self.failure: str | None = None  # as LiveReader: a reading thread ended by a bug
        self.error: Exception | None = None
        self.stats = [PortStats(target.describe())]
        self.feeds: list[ChunkFeed] = []
        self.specs: list[PortSpec] = []
        self.interface: dict[str, Any] = {}
        self.publisher_state = ""
        self.bad_messages = 0
        self.duplicates = 0
        self.lost_messages = 0  # reads the publisher counted that never came
        self.last_sequence: int | None = None
        self._got_interface = threading.Event()
        self._connected = threading.Event()
        self._subscribed = threading.Event()  # the broker acknowledged the subscriptions
        self._recent: deque[int] = deque(maxlen=DUPLICATES)
        self._recent_set: set[int] = set()
        self._held: list[Chunk] = []  # chunks that came before start()
        self._started = False
        self._stopped = False
        self._lock = threading.Lock()
        client = paho.Client(
            CallbackAPIVersion.VERSION2,
            client_id=f"modscope-watch-{uuid.uuid4().hex[:12]}",
            protocol=paho.MQTTv311,
        )
        client.reconnect_delay_set(1, 5)
        if target.username is not None:
            client.username_pw_set(target.username, target.password)
        if target.tls:
            import ssl

            client.tls_set_context(ssl.create_default_context(cafile=target.ca))
        client.on_connect = self._on_connect
        client.on_message = self._on_message
        client.on_subscribe = self._on_subscribe
        client.on_disconnect = self._on_disconnect
        self.client = client

    # -- lifetime (as LiveReader) ----------------------------------------------------------------

    def open(self, wait: float = 5.0) -> None:
        """Connect and wait for the publisher's `interface` message (MqttError if none)."""
        try:
            self.client.connect_async(self.target.host, self.target.port, keepalive=15)
        except (OSError, ValueError) as exc:
            raise MqttError(f"{self.target.describe()}: cannot connect ({exc})") from None
        self.client.loop_start()
        if not self._wait_interface(wait):
            self.client.loop_stop()
            where = self.target.describe()
            if not self._connected.is_set():
                raise MqttError(
                    f"{where}: no broker answers there; check the host and port (and "
                    "mqtts:// for TLS)"
                )
            raise MqttError(
                f"{where}: no modscope publishes under {self.target.base!r} (no retained "
                f"{self.target.topic('interface')} message); check the base topic"
            )
        line = line_from_interface(self.interface)
        self.specs = [PortSpec(self.target.describe(), line)]

    def _wait_interface(self, wait: float) -> bool:
        """The retained interface message comes right after the broker acknowledged the
        subscription: give it `RETAINED_GRACE` seconds from then, `wait` in all."""
        end = time.monotonic() + wait
        if self._subscribed.wait(wait):
            end = min(end, time.monotonic() + RETAINED_GRACE)
        return self._got_interface.wait(max(0.0, end - time.monotonic()))

    def subscribe(self, maxsize: int = DEFAULT_QUEUE) -> ChunkFeed:
        feed = ChunkFeed(maxsize)
        self.feeds = [*self.feeds, feed]
        return feed

    attach = subscribe

    def detach(self, feed: ChunkFeed) -> None:
        self.feeds = [f for f in self.feeds if f is not feed]
        feed.close()

    def start(self) -> None:
        with self._lock:
            self._started = True
            held, self._held = self._held, []
        for chunk in held:
            self._emit(chunk)

    def stop(self, timeout: float = 2.0) -> None:
        if self._stopped:
            return
        self._stopped = True
        self.client.disconnect()
        self.client.loop_stop()
        for feed in self.feeds:
            feed.close()

    @property
    def running(self) -> bool:
        return self._started and not self._stopped

    # -- what the setup needs ----------------------------------------------------------------

    @property
    def exact_timing(self) -> bool:
        return bool(self.interface.get("exact_timing", False))

    @property
    def timeout(self) -> float | None:
        found = self.interface.get("timeout")
        return float(found) if isinstance(found, int | float) else None

    @property
    def stamps(self) -> Stamp:
        """What the published times mean (the publisher's source's stamps)."""
        found = self.interface.get("stamps")
        return next((s for s in Stamp if s.value == found), Stamp.READ_END)

    @property
    def resolution(self) -> float:
        """What the published times are worth as the publisher's source declared it (0:
        measured here from the reads, as the publisher did)."""
        found = self.interface.get("resolution")
        return float(found) if isinstance(found, int | float) and found >= 0 else 0.0

    @property
    def merge_slack(self) -> float | None:
        found = self.interface.get("merge_slack")
        return float(found) if isinstance(found, int | float) else None

    # -- paho's thread -------------------------------------------------------------------------

    def _on_connect(self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        if getattr(reason, "is_failure", False):
            self._tell(f"mqtt: {self.target.describe()} refused the connection: {reason}")
            return
        again = self._connected.is_set()
        self._connected.set()
        client.subscribe(
            [
                (self.target.topic("interface"), 1),
                (self.target.topic("raw"), 1),
                (self.target.topic("status"), 1),
            ]
        )
        if again:
            self._tell(f"mqtt: connected again to {self.target.describe()}")

    def _on_subscribe(self, client: Any, userdata: Any, mid: int, *args: Any) -> None:
        self._subscribed.set()

    def _on_disconnect(
        self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any
    ) -> None:
        if not self._stopped:
            self.stats[0].connected = False
            self._tell(f"mqtt: lost {self.target.describe()} ({reason}); reconnecting")

    def _on_message(self, client: Any, userdata: Any, message: Any) -> None:
        topic = message.topic
        payload: bytes = message.payload
        if topic.endswith("/raw"):
            self._raw(payload)
        elif topic.endswith("/interface"):
            try:
                found = json.loads(payload)
            except (UnicodeDecodeError, ValueError):
                found = None
            if isinstance(found, dict):
                self.interface = found
                self._got_interface.set()
            else:
                self._tell(f"mqtt: {topic}: not a JSON object; ignored")
        elif topic.endswith("/status"):
            state = payload.decode("utf-8", errors="replace")
            if state != self.publisher_state and self.publisher_state:
                self._tell(f"mqtt: the publisher of {self.target.base} is {state}")
            self.publisher_state = state
            self.stats[0].connected = True

    def _raw(self, payload: bytes) -> None:
        key = hash(payload)
        if key in self._recent_set:
            self.duplicates += 1
            return
        if len(self._recent) == self._recent.maxlen:
            self._recent_set.discard(self._recent[0])
        self._recent.append(key)
        self._recent_set.add(key)
        try:
            message = read_raw(payload)
        except PayloadError as exc:
            self.bad_messages += 1
            message = RawMessage(
                Chunk(
                    b"", self.clock.now(), event="data lost", note=f"unreadable raw message: {exc}"
                ),
                None,
            )
        chunk = message.chunk
        chunks = [chunk]
        lost = self._missed(message.sequence)
        if lost:
            self.lost_messages += lost
            chunks.insert(0, Chunk(b"", chunk.t_end, event="data lost", note=lost_text(lost)))
        self.clock.seen(chunk.t_end)
        stats = self.stats[0]
        stats.reads += 1
        stats.bytes += len(chunk.data)
        with self._lock:
            if not self._started:
                self._held.extend(chunks)
                return
        for c in chunks:
            self._emit(c)

    def _missed(self, sequence: int | None) -> int:
        """Reads the publisher counted between the last message and this one."""
        last, self.last_sequence = self.last_sequence, sequence
        if sequence is None or last is None or sequence <= last:
            return 0  # the first message, an old publisher, or a publisher started again
        return sequence - last - 1

    def _emit(self, chunk: Chunk) -> None:
        for feed in self.feeds:
            feed.offer(chunk)

    def _tell(self, text: str) -> None:
        if self.notify is not None:
            self.notify(text)
