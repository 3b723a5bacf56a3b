"""Provides a published bus as a live source: `raw` messages back into chunks.

`MqttReader` looks like the serial `LiveReader` to `LiveCapture` (open, subscribe,
start, stop, specs, clock, stats), so `modscope live mqtt://host/base` and the TUI
watch a bus another modscope publishes. The retained `interface` message gives the
carrier (a serial line, or a network capture's connections with their peers and
carriers), the line settings and how the publisher framed (exact timing, response
timeout), so the chunks frame here exactly as they did there.

A watcher may start before its publisher: it says it waits, and waits. It follows the
publisher through restarts: each publisher run has its own `session` (in the interface
message) and numbers its reads from 1 (`epb_packetid`). Reads that arrive ahead of
missing ones (a broker or a publisher reconnecting can deliver a new read before the
backlog) are held, up to `REORDER_WAIT` seconds without progress or `REORDER_HOLD`
reads, and fed in order once the missing ones came; only numbers that never came count
as lost, with a `data lost` event where they were missing.

Every message is untrusted: sizes, channels, sequence jumps, times and the interface's
numbers are checked where they enter; a bad message is skipped and counted, and its
kind reported once (an event in the listing and a line on stderr), never a traceback.

Its clock follows the publisher's timestamps (the last chunk's time plus the time since
it arrived), so a replay published faster than real time does not time out requests
that were answered.
"""

from __future__ import annotations

import json
import math
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any

from sniffer.live.port import DEFAULT_QUEUE, ChunkFeed, PortSpec, PortStats
from sniffer.model import Chunk, LineSettings, Stamp
from sniffer.outputs.mqtt import MqttError, require_paho
from sniffer.outputs.mqtt.link import (
    FIRST_WAIT,
    FirstConnection,
    connect_first,
    tls_context,
)
from sniffer.outputs.mqtt.payload import PayloadError, read_raw
from sniffer.outputs.mqtt.target import MqttTarget

Notify = Callable[[str], None]
RETAINED_GRACE = 1.0  # seconds for retained messages to follow the subscription's ack
DUPLICATES = 4096  # recent unnumbered raw messages remembered to drop QoS 1 re-deliveries
REORDER_WAIT = 5.0  # seconds without progress before missing reads count as lost
REORDER_HOLD = 100_000  # reads held behind a gap at most (then the gap counts as lost)
WAIT_NOTICE = 30.0  # seconds between two "still waiting for the publisher" lines

# bounds on what a message may hold (#30): past them a message is refused or skipped
MAX_RAW = 256 * 1024  # bytes of a raw message (a read is at most a 64 KiB packet)
MAX_INTERFACE = 256 * 1024  # bytes of an interface message
MAX_STATUS = 64  # bytes of the publisher's status (`online`, `offline`)
MAX_CHANNEL = 255  # channel (pcapng interface) ids a session frames
MAX_GAP = 10_000_000  # reads a sequence may skip; more is a broken counter, not a loss
MAX_BACK = 60.0  # seconds a read may be older than the newest (merged ports)
MAX_AHEAD = 86400.0  # seconds a Unix time may be ahead of this machine's clock
MAX_SPAN = 86400.0  # seconds from a read's start to its end
BACK_STREAK = 3  # reads in a row older than MAX_BACK after which the stream is followed
MAX_BAUD = 100_000_000
MAX_SECONDS = 86400.0  # the interface's timeout, merge slack and resolution
MAX_DEPTH = 16  # nesting of an interface message's JSON


def _depth(found: Any) -> int:
    """How deep `found` nests (without recursion: a hostile message may nest deep)."""
    deepest = 0
    stack: list[tuple[Any, int]] = [(found, 1)]
    while stack:
        item, depth = stack.pop()
        deepest = max(deepest, depth)
        if depth > MAX_DEPTH:
            return depth
        if isinstance(item, dict):
            stack.extend((v, depth + 1) for v in item.values())
        elif isinstance(item, list):
            stack.extend((v, depth + 1) for v in item)
    return deepest


def lost_text(count: int) -> str:
    return (
        f"{count:,} published reads never reached this watcher: the broker dropped them "
        "(raise its max_queued_messages) or lost them in a restart without persistence"
    )


class BadMessageError(ValueError):
    """A message outside the bounds; `kind` groups it for the once-only report."""

    def __init__(self, kind: str, text: str) -> None:
        super().__init__(text)
        self.kind = kind


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

    def reset(self) -> None:
        with self._lock:
            self._t = None

    def now(self) -> float:
        with self._lock:
            if self._t is None:
                return time.time()
            return self._t + (time.monotonic() - self._mono)


def _number(found: Any, name: str, low: float, high: float, *, whole: bool = False) -> float | None:
    """A finite number in [low, high] (None when absent); BadMessageError otherwise."""
    if found is None:
        return None
    kind = f"interface {name}"
    if isinstance(found, bool) or not isinstance(found, int | float):
        raise BadMessageError(kind, f"interface {name} is not a number")
    if isinstance(found, float) and not math.isfinite(found):
        raise BadMessageError(kind, f"interface {name} is not a finite number")
    if not low <= found <= high or (whole and found != int(found)):
        raise BadMessageError(kind, f"interface {name} {found!r:.40} is out of range")
    return float(found)


def line_from_interface(message: Mapping[str, Any]) -> LineSettings:
    """The publisher's line settings (BadMessageError naming what is unusable)."""
    line = message.get("line") or {}
    if not isinstance(line, dict):
        raise BadMessageError("interface", "line is not an object")
    baud = _number(line.get("baud", 19200), "baud", 1, MAX_BAUD, whole=True)
    bytesize = _number(line.get("bytesize", 8), "bytesize", 7, 8, whole=True)
    stopbits = _number(line.get("stopbits", 1), "stopbits", 1, 2, whole=True)
    try:
        return LineSettings(
            baud=int(baud or 19200),
            bytesize=int(bytesize or 8),
            parity=str(line.get("parity", "E"))[:4],
            stopbits=int(stopbits or 1),
            mode=str(line.get("mode", "auto"))[:8],
        )
    except (TypeError, ValueError) as exc:
        raise BadMessageError("interface", f"unusable line settings: {exc}") from None


def checked_interface(found: Any) -> dict[str, Any]:
    """An interface message within bounds (BadMessageError otherwise): the numbers a session
    takes are finite and in range, channel ids fit, the channels' names are text."""
    if not isinstance(found, dict):
        raise BadMessageError("interface", "not a JSON object")
    if _depth(found) > MAX_DEPTH:
        raise BadMessageError("interface", f"nested deeper than {MAX_DEPTH} levels")
    line_from_interface(found)
    _number(found.get("timeout"), "timeout", 0, MAX_SECONDS)
    _number(found.get("merge_slack"), "merge_slack", 0, MAX_SECONDS)
    _number(found.get("resolution"), "resolution", 0, MAX_SECONDS)
    channels = found.get("channels", {})
    if not isinstance(channels, dict):
        raise BadMessageError("interface", "channels is not an object")
    for key, value in channels.items():
        if not key.isdigit() or int(key) > MAX_CHANNEL:
            raise BadMessageError("interface", f"channel id {key!r:.20} is not 0 to {MAX_CHANNEL}")
        if not isinstance(value, dict) or not isinstance(value.get("name", ""), str):
            raise BadMessageError("interface", f"channel {key} has no name")
    units = found.get("units", {})
    if not isinstance(units, dict):
        raise BadMessageError("interface", "units is not an object")
    session = found.get("session")
    if session is not None and not isinstance(session, str):
        raise BadMessageError("interface", "session is not text")
    return found


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
        self.channel_labels: dict[int, str] = {}  # a network bus's connections (carrier)
        self.publisher_state = ""
        self.session: str | None = None  # the publisher run the reads come from
        self.bad_messages = 0  # skipped: outside the bounds or unreadable
        self.refused = 0  # refused unread: over the size limit
        self.bad_kinds: dict[str, int] = {}
        self.duplicates = 0
        self.late = 0  # reads that came after they had been counted lost
        self.lost_messages = 0  # reads the publisher numbered that never came
        self.restarts = 0  # publisher runs followed after the first
        self.last_sequence: int | None = None
        self._expected: int | None = None  # the next sequence number to feed
        self._ahead: dict[int, Chunk] = {}  # reads that came before missing ones
        self._progress = 0.0  # monotonic time the held reads last moved
        self._timer: threading.Timer | None = None
        self._newest: float | None = None  # the newest read's time (bounds)
        self._back = 0  # reads in a row refused as older than the newest
        self._got_interface = threading.Event()
        self._first = FirstConnection()
        self._connected = threading.Event()
        self._subscribed = threading.Event()  # the broker acknowledged the subscriptions
        self._recent: deque[int] = deque(maxlen=DUPLICATES)
        self._recent_set: set[int] = set()
        self._held: list[Chunk] = []  # chunks that came before start()
        self._started = False
        self._stopped = False
        self._lock = threading.RLock()
        client = paho.Client(
            CallbackAPIVersion.VERSION2,
            client_id=f"modscope-watch-{uuid.uuid4().hex[:12]}",
            protocol=paho.MQTTv311,
        )
        client.reconnect_delay_set(1, 5)
        if target.username is not None:
            client.username_pw_set(target.username, target.password)
        if target.tls:
            client.tls_set_context(tls_context(target))
        client.on_connect = self._on_connect
        client.on_message = self._on_message
        client.on_subscribe = self._on_subscribe
        client.on_disconnect = self._on_disconnect
        self.client = client

    # -- lifetime (as LiveReader) ----------------------------------------------------------------

    def open(self, wait: float = FIRST_WAIT, *, forever: bool = True) -> None:
        """Connect (MqttError naming the broker and the cause if it cannot be used), then
        wait for the publisher's `interface` message: for ever (saying so) when `forever`,
        else MqttError after `wait` seconds."""
        connect_first(self.client, self.target, self._first, wait)
        try:
            if not self._wait_interface(wait):
                if not forever:
                    raise MqttError(
                        f"{self.target.describe()}: no modscope publishes under "
                        f"{self.target.base!r} (no retained "
                        f"{self.target.topic('interface')} message); check the base topic"
                    )
                self._tell(
                    f"mqtt: waiting for a modscope to publish under {self.target.base!r} on "
                    f"{self.target.describe()} (its retained "
                    f"{self.target.topic('interface')} message); Ctrl-C to stop"
                )
                while not self._got_interface.wait(WAIT_NOTICE):
                    self._tell(f"mqtt: still waiting for a publisher under {self.target.base!r}")
                self._tell(f"mqtt: a modscope publishes under {self.target.base!r}; watching")
        except BaseException:
            self._stopped = True
            self.client.disconnect()
            self.client.loop_stop()
            raise
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
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
            if self._ahead:  # still missing at the end: lost
                self._give_up()
                while self._ahead:
                    self._give_up()
        self.client.disconnect()
        self.client.loop_stop()
        for feed in self.feeds:
            feed.close()
        if self.trouble:
            self._tell(self.summary())

    @property
    def fed_sequence(self) -> int | None:
        """The publisher's number of the last read fed on (all before it fed or lost)."""
        with self._lock:
            return None if self._expected is None else self._expected - 1

    @property
    def trouble(self) -> bool:
        """Whether reads were lost or messages skipped (the watcher then exits 1)."""
        return bool(self.lost_messages or self.bad_messages)

    def summary(self) -> str:
        """What went wrong between the publisher and this watcher, counted."""
        parts = []
        if self.lost_messages:
            parts.append(f"{self.lost_messages:,} published reads never came")
        if self.bad_messages:
            kinds = ", ".join(f"{k} {n:,}" for k, n in sorted(self.bad_kinds.items()))
            parts.append(
                f"{self.bad_messages:,} bad messages skipped ({kinds}; {self.refused:,} "
                "refused over the size limit)"
            )
        return f"mqtt: {self.target.describe()}: " + "; ".join(parts)

    @property
    def running(self) -> bool:
        return self._started and not self._stopped

    # -- what the setup needs ----------------------------------------------------------------

    @property
    def network(self) -> bool:
        """Whether the publisher read a network capture (framed by connection)."""
        return self.interface.get("network") is True

    @property
    def exact_timing(self) -> bool:
        return self.interface.get("exact_timing") is True

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
        self._first.connected(reason)
        if getattr(reason, "is_failure", False):
            if self._connected.is_set():
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
        self._first.disconnected(reason)
        if not self._stopped and self._connected.is_set():
            self.stats[0].connected = False
            self._tell(f"mqtt: lost {self.target.describe()} ({reason}); reconnecting")

    def _on_message(self, client: Any, userdata: Any, message: Any) -> None:
        topic = str(message.topic)
        payload: bytes = message.payload
        try:
            if topic == self.target.topic("raw"):
                self._size(payload, MAX_RAW, "raw")
                self._raw(payload)
            elif topic == self.target.topic("interface"):
                self._size(payload, MAX_INTERFACE, "interface")
                self._interface(payload)
            elif topic == self.target.topic("status"):
                self._size(payload, MAX_STATUS, "status")
                self._status(payload)
        except BadMessageError as exc:
            self._bad(exc)

    def _size(self, payload: bytes, limit: int, kind: str) -> None:
        if len(payload) > limit:
            self.refused += 1
            raise BadMessageError(
                f"{kind} size", f"{kind} message of {len(payload):,} bytes refused (over {limit:,})"
            )

    def _bad(self, exc: BadMessageError) -> None:
        """Skip a bad message: counted; its kind reported once, on stderr and as an event."""
        self.bad_messages += 1
        seen = self.bad_kinds.get(exc.kind, 0)
        self.bad_kinds[exc.kind] = seen + 1
        if seen:
            return
        text = f"a bad message from {self.target.describe()} skipped: {exc}"
        self._tell(f"mqtt: {text} (more like it are counted, not shown)")
        t = self.clock.now() if self._newest is None else self._newest
        with self._lock:
            self._out(Chunk(b"", t, event="data lost", note=text))

    def _interface(self, payload: bytes) -> None:
        try:
            found = json.loads(payload)
        except (UnicodeDecodeError, ValueError, RecursionError) as exc:
            what = "nested too deep" if isinstance(exc, RecursionError) else "not JSON"
            raise BadMessageError(f"interface {what}", f"interface message {what}") from None
        found = checked_interface(found)
        with self._lock:
            session = found.get("session")
            if self._got_interface.is_set() and session != self.session:
                self._restarted("a new publisher run (session) began")
            self.session = session
            self.interface = found
            for key, value in found.get("channels", {}).items():
                name = value.get("name", "")
                if found.get("network") is True and name:
                    self.channel_labels[int(key)] = name
        self._got_interface.set()

    def _status(self, payload: bytes) -> None:
        state = payload.decode("utf-8", errors="replace")
        state = state if state in ("online", "offline") else "unknown"
        if state != self.publisher_state and self.publisher_state:
            self._tell(f"mqtt: the publisher of {self.target.base} is {state}")
        self.publisher_state = state
        self.stats[0].connected = True

    def _raw(self, payload: bytes) -> None:
        try:
            message = read_raw(payload)
        except PayloadError as exc:
            raise BadMessageError("unreadable raw", f"unreadable raw message: {exc}") from None
        chunk, sequence = message.chunk, message.sequence
        self._check_chunk(chunk)
        with self._lock:
            if sequence is None:
                key = hash(payload)
                if key in self._recent_set:
                    self.duplicates += 1
                    return
                if len(self._recent) == self._recent.maxlen:
                    self._recent_set.discard(self._recent[0])
                self._recent.append(key)
                self._recent_set.add(key)
                self._accept(chunk)
                return
            self._ordered(chunk, sequence)

    def _check_chunk(self, chunk: Chunk) -> None:
        if chunk.channel > MAX_CHANNEL:
            raise BadMessageError(
                "channel", f"raw message on channel {chunk.channel} (ids are 0 to {MAX_CHANNEL})"
            )
        t = chunk.t_end
        if chunk.t_start is not None and not 0 <= t - chunk.t_start <= MAX_SPAN:
            raise BadMessageError(
                "time", f"raw message whose read starts {t - chunk.t_start:.6g} s before it ends"
            )
        if t > 86400 * 366 and t > time.time() + MAX_AHEAD:
            raise BadMessageError(
                "time", f"raw message stamped {t - time.time():.6g} s in the future"
            )
        newest = self._newest
        if newest is not None and t < newest - MAX_BACK:
            self._back += 1
            if self._back < BACK_STREAK:
                raise BadMessageError(
                    "time", f"raw message {newest - t:.6g} s older than the newest read"
                )
            # reads keep coming from before the newest: that one was the odd one (a bad
            # stamp that came through, or the publisher's clock set back): go on from here
            self._tell(
                f"mqtt: the reads of {self.target.base} went back {newest - t:.6g} s in "
                "time; following them from here"
            )
            self._newest = None
        self._back = 0

    # -- order and loss (under self._lock) -------------------------------------------------

    def _ordered(self, chunk: Chunk, sequence: int) -> None:
        expected = self._expected
        self.last_sequence = sequence
        if expected is None:
            self._expected = sequence + 1
            self._accept(chunk)
            return
        if sequence == expected:
            self._expected = sequence + 1
            self._accept(chunk)
            self._release()
            return
        if sequence > expected:
            if sequence - expected > MAX_GAP:
                raise BadMessageError(
                    "sequence", f"raw message numbered {sequence:,}, {expected:,} expected"
                )
            if sequence in self._ahead:
                self.duplicates += 1
                return
            if not self._ahead:
                self._progress = time.monotonic()
                self._arm()
            self._ahead[sequence] = chunk
            if len(self._ahead) > REORDER_HOLD:
                self._give_up()
            return
        if sequence == 1:  # numbering began again: a publisher run we had no interface of
            self._restarted("the publisher numbers its reads from 1 again")
            self._expected = 2
            self._accept(chunk)
            return
        self.duplicates += 1  # already fed (a QoS 1 re-delivery) or counted lost
        return

    def _release(self) -> None:
        """Feed the held reads that follow on from what was fed."""
        moved = False
        while self._expected in self._ahead:
            self._accept(self._ahead.pop(self._expected))
            self._expected += 1
            moved = True
        if moved:
            self._progress = time.monotonic()

    def _give_up(self) -> None:
        """The missing reads before the first held one count as lost, where they were."""
        if not self._ahead or self._expected is None:
            return
        first = min(self._ahead)
        lost = first - self._expected
        if lost > 0:
            self.lost_messages += lost
            at = self._ahead[first]
            self._out(
                Chunk(b"", at.t_end, channel=at.channel, event="data lost", note=lost_text(lost))
            )
        self._expected = first
        self._release()

    def _arm(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
        timer = threading.Timer(REORDER_WAIT / 4, self._tick)
        timer.daemon = True
        self._timer = timer
        timer.start()

    def _tick(self) -> None:
        with self._lock:
            self._timer = None
            if self._stopped or not self._ahead:
                return
            if time.monotonic() - self._progress >= REORDER_WAIT:
                self._give_up()
            if self._ahead:
                self._arm()

    def _restarted(self, why: str) -> None:
        """A new publisher run: what the old one left missing is lost; start afresh."""
        self._give_up()
        while self._ahead:
            self._give_up()
        self._expected = None
        self._newest = None
        self.clock.reset()
        self.restarts += 1
        self._tell(f"mqtt: the publisher of {self.target.base} started again ({why})")

    def _accept(self, chunk: Chunk) -> None:
        self._newest = chunk.t_end if self._newest is None else max(self._newest, chunk.t_end)
        self.clock.seen(chunk.t_end)
        stats = self.stats[0]
        stats.reads += 1
        stats.bytes += len(chunk.data)
        self._out(chunk)

    def _out(self, chunk: Chunk) -> None:
        if not self._started:
            self._held.append(chunk)
            return
        self._emit(chunk)

    def _emit(self, chunk: Chunk) -> None:
        for feed in self.feeds:
            feed.offer(chunk)

    def _tell(self, text: str) -> None:
        if self.notify is not None:
            self.notify(text)
