"""Provides the bus publisher: what a session sees, published under one base topic.

The publisher is an output beside the listing: it gets every chunk as it is read (the
`raw` topic) and the session's rows as they are framed (values, events, statuses).
Topics under the base (see docs/mqtt.md for an example of each message):

- `raw`: every read as recorded, a pcapng block (see `payload`);
- `interface` (retained): line settings, channels, bound units;
- `unit/<N>/<register-slug>` (retained): a named register's decoded value, published when
  it changes and at least every `every` seconds (capture time) while it is read;
- `events`: exceptions, timeouts, check errors, noise, source events, device rule
  violations, each a JSON object naming its frame;
- `unit/<N>/status` (retained): counts, latency, polling period, seconds since its last
  answer and last frame (to the live clock), online, silent or unknown;
- `status` (retained, and the connection's last will): `online` or `offline`;
- `findings` (retained): the bus doctor's findings on the rows held, which it names
  (docs/doctor.md);
- with Home Assistant discovery, `<prefix>/.../config` (retained): the bus, each unit
  polled, each named register (see `sniffer.outputs.mqtt.ha`); a unit's configs are
  published again when the bus shows its software or hardware version.

Retained messages are published again after a reconnection, so a broker restarted
without persistence gets them back.

Each run has a `session` (in the `interface` message) and numbers the reads it hands to
the broker from 1, so a watcher tells reads the broker lost (a gap) from reads that only
came late. Reads the publisher itself drops (its buffer full while the broker is away)
take no number: they become one `data lost` read where they were dropped, published as
soon as there is room, so each loss is counted where it happened. A network capture's
connections (carrier and peers, `SourceInfo.channels`) are learnt as it is read: the
`interface` message is published again when a read comes on a channel it does not name
yet, before that read.
"""

from __future__ import annotations

import json
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from dissectors.dictionary.model import Entry, RegisterValue, ValueSpec
from sniffer import __version__
from sniffer.analysis.liveness import SILENT_AFTER as SILENT_AFTER
from sniffer.analysis.liveness import SILENT_MIN as SILENT_MIN
from sniffer.analysis.liveness import UnitState, unit_liveness
from sniffer.analysis.stats import RECENT, UnitStats, median_gap, nearest_rank, resolved_period
from sniffer.framing.pairing import Latency
from sniffer.framing.store import NO_PARTNER
from sniffer.meaning.annotate import Binding
from sniffer.meaning.describe import FrameDetail
from sniffer.model import Chunk, SourceInfo
from sniffer.outputs.listing import KIND_NAMES, shown_latency_max_ms, shown_latency_ms
from sniffer.outputs.mqtt.findings import FindingsClock, findings_payload
from sniffer.outputs.mqtt.ha import (
    UnitDevice,
    bus_configs,
    register_configs,
    unit_configs,
    versions_from,
)
from sniffer.outputs.mqtt.link import MqttLink, Notify
from sniffer.outputs.mqtt.payload import RegisterKey, Slugs, iso_time, json_value, raw_payload
from sniffer.outputs.mqtt.target import MqttTarget
from sniffer.session.session import Cutter, Session
from sniffer.sources.linktypes import describe_interface
from sniffer.vocab import PROBLEM_MASK, Flag, Kind, Status

DEFAULT_EVERY = 60.0  # seconds between two publications of an unchanged value
STATUS_EVERY = 5.0  # seconds between two unit status messages
# (SILENT_AFTER and SILENT_MIN, imported above, are the one rule of every view; the
# metrics import them from here)
WINDOW = RECENT  # answers (and requests) a unit's latency quantiles and poll period are over
READ_IDENTIFICATION = 43  # FC 43 (MEI 14 Read Device Identification names the versions)


# a unit's liveness as the status message's `state` says it: `online` while it answers
# within its threshold, `silent` once past it (or asked and never answering), `unknown`
# where its period is not known to judge by, or it was never asked
UNIT_STATES = {UnitState.OK: "online", UnitState.SILENT: "silent"}


def _seconds(value: float | None) -> float | None:
    return None if value is None else round(value, 3)


class UnitWindow:
    """A unit's latest latencies and request times, bounded: a status message costs
    the same on the millionth answer as on the tenth. It reads the newest entries of the
    session's statistics for the unit (`UnitStats.newest_latencies`), whether they keep
    everything or, live, only their newest (`sniffer.analysis.stats.RECENT`, as many as this
    window holds)."""

    def __init__(self, size: int = WINDOW) -> None:
        self.latencies: deque[float] = deque(maxlen=size)
        self.requests: deque[float] = deque(maxlen=size)
        self._seen_latencies = 0
        self._seen_requests = 0

    def update(self, unit: UnitStats) -> None:
        size = self.latencies.maxlen or WINDOW
        count = unit.latency_count
        self.latencies.extend(unit.newest_latencies(min(size, count - self._seen_latencies)))
        self._seen_latencies = count
        count = unit.request_count
        self.requests.extend(unit.newest_requests(min(size, count - self._seen_requests)))
        self._seen_requests = count

    def latency_ms(self, q: float) -> float | None:
        """The q-quantile (nearest rank) of the window's latencies, in ms."""
        found = nearest_rank(self.latencies, q)
        return None if found is None else found * 1000

    def polling_period(self) -> float | None:
        """The median gap between the window's requests, in seconds."""
        return median_gap(self.requests)

    def period(self, resolution: float) -> Latency | None:
        """The window's polling period as stamps of `resolution` vouch for it
        (`sniffer.analysis.stats.resolved_period`: a value, a bound, or None)."""
        return resolved_period(self.polling_period(), resolution)


@dataclass
class _Published:
    value: Any
    raw: tuple[int, ...]
    t: float


@dataclass
class PublisherOptions:
    """What to publish, besides the always-published topics."""

    bus: str = "bus"
    every: float = DEFAULT_EVERY
    ha_prefix: str | None = None  # Home Assistant discovery prefix, None for none
    block: bool = True  # wait for room while the broker is there (replay); live drops
    status_every: float = STATUS_EVERY
    extra: dict[str, Any] = field(default_factory=dict)  # more for the interface message


class BusPublisher:
    """Publishes one session's bus through `link` (see the module doc)."""

    def __init__(
        self,
        link: MqttLink,
        session: Session,
        bindings: Mapping[int, Binding],
        options: PublisherOptions,
        *,
        info: SourceInfo | None = None,
        clock: Callable[[], float] | None = None,
    ) -> None:
        self.link = link
        self.clock = clock  # a live capture's clock: units fall silent while the bus is
        self.target: MqttTarget = link.target
        self.session = session
        self.bindings = dict(bindings)
        self.options = options
        self.info = info
        self.next = 0  # the next store row to look at
        self._base = session.base  # the segment `next` counts in (`Session.base`)
        self.values = 0
        self.events = 0
        self.raw = 0  # reads handed to the broker: the last sequence number
        self.raw_dropped = 0  # reads dropped by this publisher (buffer full)
        self.session_id = uuid.uuid4().hex[:16]
        self._unsaid: list[Chunk] = []  # the first and last read dropped since the last said
        self._unsaid_count = 0
        self._named: set[int] = set()  # channels the published interface names
        self._slugs = Slugs()
        self._entries: dict[int, dict[tuple[str, int, str], Entry]] = {}
        self._params: dict[int, dict[str, ValueSpec]] = {}
        for unit, b in sorted(self.bindings.items()):
            index = self._entries[unit] = {}
            for e in b.dictionary.entries:
                index[(e.table, e.address, e.name)] = e
                self._slugs.add(RegisterKey(unit, e.table, e.address, e.name))
            self._params[unit] = {
                p.name: p.spec for w in b.dictionary.windows for p in w.parameters.values()
            }
        self._last: dict[str, _Published] = {}
        self._retained: dict[str, str] = {}
        self._discovered: set[str] = set()
        # Home Assistant: each unit's registers discovered (state topic -> entry, slug),
        # the units whose device is announced, and the versions the bus showed
        self._ha_registers: dict[int, dict[str, tuple[Entry, str]]] = {}
        self._ha_units: set[int] = set()
        self._versions: dict[int, dict[str, str]] = {}
        self._open: set[int] = set()
        self._answered: dict[int, float] = {}
        self._status_t: float | None = None
        self._windows: dict[int, UnitWindow] = {}
        self._last_t = 0.0
        self._resend = threading.Event()
        self.findings = FindingsClock()
        link._on_connect_hook = self._on_connect

    # -- the link's connection ----------------------------------------------------------------

    def _on_connect(self) -> None:
        # paho's thread: say online at once (the link hands it to paho ahead of the rest),
        # leave the retained state to the main thread, after what the link held
        self.link.publish(self.target.topic("status"), "online", retain=True)
        if self.link.counts.connects > 1:
            self._resend.set()

    def _resend_retained(self) -> None:
        if self._resend.is_set():
            self._resend.clear()
            for topic, payload in list(self._retained.items()):
                self.link.publish(topic, payload, retain=True, block=self.options.block)

    def _send(self, topic: str, payload: bytes | str, *, retain: bool = False) -> None:
        if retain:
            assert isinstance(payload, str)
            self._retained[topic] = payload
        self.link.publish(topic, payload, retain=retain, block=self.options.block)

    # -- what the session sees ----------------------------------------------------------------

    def announce(self) -> None:
        """The `interface` message: publish once, before the first chunk. With Home
        Assistant discovery, the bus's device and the bound units' devices too."""
        self._send(self.target.topic("interface"), json.dumps(self.interface()), retain=True)
        prefix = self.options.ha_prefix
        if prefix is not None:
            for config in bus_configs(prefix, self.target.base, self.options.bus):
                self._send(config.topic, config.payload, retain=True)
            for unit in sorted(self.bindings):
                self._discover_unit(unit)

    def interface(self) -> dict[str, Any]:
        line = self.session.line
        pipeline = self.session.pipeline
        channels: dict[str, Any] = {}
        if self.info is not None:
            channels = {str(k): {"name": v} for k, v in sorted(self.info.channels.items())}
            self._named = set(self.info.channels)
        network = self.info is not None and self.info.network
        return {
            "bus": self.options.bus,
            "session": self.session_id,
            # a network capture: channels are connections whose names say the carrier
            # (modbus-tcp, rtu-over-tcp, ...) and peers; frame them as connections
            "network": network,
            "source": self.session.source,
            "format": self.info.format if self.info is not None else "",
            "description": describe_interface(line),
            "line": {
                "baud": line.baud,
                "bytesize": line.bytesize,
                "parity": line.parity,
                "stopbits": line.stopbits,
                "mode": line.mode,
            },
            "exact_timing": pipeline.exact_timing,
            "timeout": pipeline.pairer.timeout,
            "merge_slack": pipeline.merge_slack,
            "stamps": self.info.stamps.value if self.info is not None else "read-end",
            # what the stamps are worth as the source says (0: measured from the reads),
            # so that a watcher shows latencies as this session does
            "resolution": pipeline.clock.declared,
            "channels": channels,
            "units": {
                str(u): {"label": b.label, "model": b.dictionary.model, "name": b.dictionary.name}
                for u, b in sorted(self.bindings.items())
            },
            "raw": "pcapng enhanced packet block, link type 250 (RTAC serial); see docs/mqtt.md",
            "modscope": __version__,
            **self.options.extra,
        }

    def chunk(self, chunk: Chunk) -> None:
        """Publish one read (or source event) as it was recorded (module doc)."""
        self._resend_retained()
        info = self.info
        if (
            info is not None
            and info.network
            and chunk.channel not in self._named
            and chunk.channel in info.channels
        ):  # a new connection: say what it carries, before its first read
            self._send(self.target.topic("interface"), json.dumps(self.interface()), retain=True)
        if self._unsaid_count and not self._say_dropped():
            self._drop(chunk)
            return
        if not self._publish_raw(chunk):
            self._drop(chunk)

    def _publish_raw(self, chunk: Chunk) -> bool:
        sequence = self.raw + 1
        payload = raw_payload(chunk, sequence)
        if self.link.publish(self.target.topic("raw"), payload, block=self.options.block):
            self.raw = sequence
            return True
        return False

    def _drop(self, chunk: Chunk) -> None:
        self.raw_dropped += 1
        self._unsaid_count += 1
        self._unsaid = [self._unsaid[0] if self._unsaid else chunk, chunk]

    def _say_dropped(self) -> bool:
        """Publish the reads dropped since the last time as one `data lost` read at the
        last one's time. True once published."""
        first, last = self._unsaid
        n = self._unsaid_count
        span = f" from t={first.t_end:.6f} to t={last.t_end:.6f}" if n > 1 else ""
        note = (
            f"{n:,} reads{span} dropped by the publisher: its buffer was full while the "
            "broker was away or slow"
        )
        lost = Chunk(b"", last.t_end, channel=last.channel, event="data lost", note=note)
        if not self._publish_raw(lost):
            return False
        self._unsaid, self._unsaid_count = [], 0
        return True

    def rows(self, final: bool = False) -> None:
        """Publish what the session's new rows say. Call after `session.refresh()`, and
        before a windowed session drops its rows (`Session.new_segment`): its next
        segment's rows are then read from the first."""
        self._resend_retained()
        if self.session.base != self._base:  # a new segment: none of its rows read yet
            self._base = self.session.base
            self.next = 0
            self._open.clear()  # (none: a segment ends with no request open)
        store = self.session.store
        store.sync()
        describer = self.session.describer
        for i in sorted(self._open):
            state = store.status[i]
            if state != Status.OPEN:
                self._open.discard(i)
                if state == Status.TIMEOUT:
                    self._event("timeout", describer.detail(i))
        end = len(store)
        for i in range(self.next, end):
            self._row(i)
        self.next = end
        if end:
            self._last_t = max(self._last_t, store.t_end[end - 1])
        if self.clock is not None:
            self._last_t = max(self._last_t, self.clock())
        if (
            final
            or self._status_t is None
            or self._last_t - self._status_t >= self.options.status_every
        ):
            self._status_t = self._last_t
            self.unit_status()
        if self.findings.due(final):  # (the bus doctor's findings: outputs/mqtt/findings.py)
            payload = findings_payload(self.session, self.bindings)
            self._send(self.target.topic("findings"), payload, retain=True)

    def _row(self, i: int) -> None:
        store = self.session.store
        kind = store.kind[i]
        flags = store.flags[i]
        describer = self.session.describer
        if kind == Kind.EVENT:
            self._event("event", describer.detail(i))
            return
        if kind == Kind.NOISE:
            self._event("noise", describer.detail(i))
            return
        unit = store.unit[i]
        if flags & (Flag.CHECK_BAD | Flag.NON_HEX):
            self._event("check error", describer.detail(i))
            return
        if kind == Kind.REQUEST:
            state = store.status[i]
            if state == Status.OPEN:
                self._open.add(i)
            elif state == Status.TIMEOUT:
                self._event("timeout", describer.detail(i))
                return
        d: FrameDetail | None = None
        if kind in (Kind.RESPONSE, Kind.EXCEPTION):
            self._answered[unit] = store.t_end[i]
        if kind == Kind.RESPONSE and store.fc[i] == READ_IDENTIFICATION:
            self._identification(describer.detail(i))
        if unit in self.bindings and kind == Kind.RESPONSE:
            d = describer.detail(i)
            self._values(d, "read")
            j = store.partner[i]
            if j != NO_PARTNER:
                self._values(describer.detail(j), "write")
        if kind == Kind.EXCEPTION:
            self._event("exception", d or describer.detail(i))
            return
        if flags & PROBLEM_MASK or store.status[i] == Status.ORPHAN:
            d = d or describer.detail(i)
            if d.problems:
                self._event("problem", d)
                return
        if unit in self.bindings and kind == Kind.REQUEST:
            d = d or describer.detail(i)
            if any(r.problems for r in d.registers):
                self._event("problem", d)

    # -- values ---------------------------------------------------------------------------------

    def _entry(self, unit: int, r: RegisterValue) -> Entry:
        found = self._entries.get(unit, {}).get((r.table, r.address, r.name))
        if found is not None:
            return found
        spec = self._params.get(unit, {}).get(r.name)
        if spec is None:
            kind = (
                "bool"
                if isinstance(r.value, bool)
                else "str"
                if isinstance(r.value, str)
                else "u16"
            )
            spec = ValueSpec(type=kind, unit=r.unit)
        return Entry(r.table, r.address, r.name, spec)

    def _values(self, d: FrameDetail, access: str) -> None:
        v = d.view
        if not d.registers or not v.check_ok:
            return
        if access == "write" and v.kind != Kind.REQUEST:
            return
        unit = v.unit
        binding = self.bindings[unit]
        for r in d.registers:
            if r.partial or not r.name:
                continue
            slug = self._slugs.add(RegisterKey(unit, r.table, r.address, r.name))
            topic = self.target.topic("unit", str(unit), slug)
            last = self._last.get(topic)
            value = json_value(r.value)
            if (
                last is not None
                and last.value == value
                and last.raw == r.raw
                and v.t - last.t < self.options.every
            ):
                continue
            entry = self._entry(unit, r)
            if self.options.ha_prefix is not None:
                if topic not in self._discovered:
                    self._discovered.add(topic)
                    self._ha_registers.setdefault(unit, {})[topic] = (entry, slug)
                    self._discover_register(unit, entry, slug, topic)
                if value is not None:
                    self._learn_versions(unit, {r.name: str(value)})
            message: dict[str, Any] = {
                "unit": unit,
                "device": binding.label,
                "model": binding.dictionary.model,
                "name": r.name,
                "table": r.table,
                "address": r.address,
                "value": value,
                "value_unit": r.unit,
                "text": r.text,
                "raw": list(r.raw),
                "t": v.t,
                "time": iso_time(v.t),
                "frame": v.index + self.session.base,  # in the whole capture (windowed live)
                "access": access,
            }
            if entry.spec.bits and isinstance(r.value, int) and not isinstance(r.value, bool):
                message["bits"] = {
                    str(bit): bool(r.value >> bit & 1) for bit in sorted(entry.spec.bits)
                }
            self._last[topic] = _Published(value, r.raw, v.t)
            self._send(topic, json.dumps(message, ensure_ascii=False), retain=True)
            self.values += 1

    # -- events and statuses ------------------------------------------------------------------

    def _event(self, kind: str, d: FrameDetail) -> None:
        v = d.view
        framed = v.kind not in (Kind.NOISE, Kind.EVENT)
        message: dict[str, Any] = {
            "kind": kind,
            "t": v.t,
            "time": iso_time(v.t),
            "frame": v.index + self.session.base,  # in the whole capture (windowed live)
            "frame_kind": KIND_NAMES[v.kind],
            "unit": v.unit if framed else None,
            "device": d.label,
            "function": v.function if framed else None,
            "name": d.name,
            "summary": d.summary,
            "problems": list(d.problem_texts),
            "raw": v.raw.hex(),
        }
        if v.kind == Kind.EXCEPTION:
            body = v.body()
            message["exception_code"] = body[2] if len(body) > 2 else None
        if v.partner != NO_PARTNER:
            message["partner"] = v.partner + self.session.base
            if v.kind != Kind.REQUEST:  # an answer: its latency pair, as listings give it
                message["latency_ms"] = shown_latency_ms(d)
                message["latency_max_ms"] = shown_latency_max_ms(d)
        self._send(self.target.topic("events"), json.dumps(message, ensure_ascii=False))
        self.events += 1

    def unit_status(self) -> None:
        """A retained status message for every unit seen so far."""
        if self.options.ha_prefix is not None:
            self._discover_polled()
        now = self._last_t
        for u, st in sorted(self.session.stats.units.items()):
            window = self._windows.setdefault(u, UnitWindow())
            window.update(st)
            measured = window.period(self.session.store.resolution)
            period = bound = None
            if measured is not None:
                period, bound = (None, measured.ms) if measured.bound else (measured.ms, None)
            answered = self._answered.get(u)
            newest = st.newest_requests(1)
            alive = unit_liveness(
                u,
                now,
                asked=st.requests > 0,
                last_frame=st.last_seen or None,
                last_answer=answered,
                last_request=newest[-1] if newest else None,
                period=measured.seconds if measured is not None else None,
                period_bound=measured.bound if measured is not None else False,
            )
            median, p95 = window.latency_ms(0.5), window.latency_ms(0.95)
            binding = self.bindings.get(u)
            message = {
                "unit": u,
                "device": binding.label if binding else "",
                "state": UNIT_STATES.get(alive.state, "unknown"),
                "requests": st.requests,
                "answers": st.responses,
                "exceptions": st.exception_count,
                "timeouts": st.timeouts,
                "check_errors": st.check_errors,
                "latency_median_ms": None if median is None else round(median, 3),
                "latency_p95_ms": None if p95 is None else round(p95, 3),
                "poll_period_ms": period,
                "poll_period_max_ms": bound,
                "last_answer": answered,
                # seconds to `t` (live: the port's clock, so they grow with no frame)
                "since_answer_s": _seconds(alive.since_answer),
                "since_frame_s": _seconds(alive.since_frame),
                "silent_after_s": _seconds(alive.silent_after),
                "t": now,
                "time": iso_time(now),
            }
            self._send(
                self.target.topic("unit", str(u), "status"), json.dumps(message), retain=True
            )

    # -- Home Assistant discovery ---------------------------------------------------------------

    def _device(self, unit: int) -> UnitDevice:
        binding = self.bindings.get(unit)
        versions = self._versions.get(unit, {})
        return UnitDevice(
            self.target.base,
            unit,
            label=binding.label if binding is not None else "",
            model=(binding.dictionary.name or binding.dictionary.model) if binding else "",
            sw_version=versions.get("sw_version", ""),
            hw_version=versions.get("hw_version", ""),
        )

    def _discover_unit(self, unit: int) -> None:
        assert self.options.ha_prefix is not None
        self._ha_units.add(unit)
        for config in unit_configs(self.options.ha_prefix, self._device(unit)):
            self._send(config.topic, config.payload, retain=True)

    def _discover_polled(self) -> None:
        """A device for each unit the master polls (a request with a good check), bound or
        not: not for unit bytes seen only in broken frames."""
        for unit, st in sorted(self.session.stats.units.items()):
            if unit not in self._ha_units and st.requests > 0:
                self._discover_unit(unit)

    def _discover_register(self, unit: int, entry: Entry, slug: str, topic: str) -> None:
        assert self.options.ha_prefix is not None
        for config in register_configs(
            self.options.ha_prefix, self._device(unit), entry, slug, topic
        ):
            self._send(config.topic, config.payload, retain=True)

    def _identification(self, d: FrameDetail) -> None:
        """Versions from a Read Device Identification answer (FC 43 / MEI 14):
        `MajorMinorRevision` is the software version."""
        if self.options.ha_prefix is None or not d.view.check_ok:
            return
        objects = next((f for f in d.fields if f.name == "objects"), None)
        if objects is not None:
            self._learn_versions(d.view.unit, {f.name: f.text for f in objects.children})

    def _learn_versions(self, unit: int, fields: Mapping[str, str]) -> None:
        """Keep the versions `fields` show; when they change a discovered unit's device,
        publish its configs again (Home Assistant takes device details from them)."""
        found = versions_from(fields)
        if not found:
            return
        known = self._versions.setdefault(unit, {})
        if all(known.get(k) == v for k, v in found.items()):
            return
        known.update(found)
        if unit in self._ha_units:
            self._discover_unit(unit)
        for topic, (entry, slug) in self._ha_registers.get(unit, {}).items():
            self._discover_register(unit, entry, slug, topic)

    def close(self, drain: float = 10.0) -> str:
        """Final statuses, `status` offline, wait for delivery; the link's report."""
        if self._unsaid_count:
            self.link.drain(drain / 2)
            self._say_dropped()
        self.rows(final=True)
        self.link.close(drain, last=(self.target.topic("status"), "offline"))
        return self.link.report()


def open_publisher(
    target: MqttTarget,
    session: Session,
    bindings: Mapping[int, Binding],
    options: PublisherOptions,
    *,
    info: SourceInfo | None = None,
    notify: Notify | None = None,
    limit: int | None = None,
    wait: float = 5.0,
    clock: Callable[[], float] | None = None,
) -> BusPublisher:
    """A connected (or connecting) publisher with its `interface` message sent."""
    kwargs: dict[str, Any] = {} if limit is None else {"limit": limit}
    link = MqttLink(target, will=(target.topic("status"), "offline"), notify=notify, **kwargs)
    publisher = BusPublisher(link, session, bindings, options, info=info, clock=clock)
    link.start(wait)  # MqttError (one line: the broker, the cause) unless it accepts us
    publisher.announce()
    return publisher


def publish_replay(
    session: Session,
    chunks: Iterable[Chunk],
    publisher: BusPublisher,
    *,
    original_speed: bool = False,
    refresh_every: float = 0.25,
    window: int | None = None,
    segment: Callable[[Session], None] | None = None,
) -> None:
    """Feed a capture's chunks to `session` and `publisher`: as fast as they are read, or
    at the pace they were recorded (`original_speed`). Ends with the session finished and
    its last rows published (the link stays open: `publisher.close()` ends it).

    `window`: rows the session keeps; past them, its rows are published and dropped at
    the next settled moment (`sniffer.session.session.Cutter`), so that memory stays
    flat in the capture's length (the statistics carry on, bounded), and
    `segment(session)` is called with each segment's rows just before they go, and with
    the last segment's at the end (what else needs every row counts it there)."""
    last = time.monotonic()
    first: tuple[float, float] | None = None
    cutter = None
    if window is not None:
        session.stats.bound()
        cutter = Cutter(session, window)

    def before_cut() -> None:
        publisher.rows()  # every row of the segment, before it goes
        if segment is not None:
            segment(session)

    # the stamps measured before any row is published, so that every latency and
    # timeout published is judged as the whole capture's are (and at once, not over the
    # seconds a replay at the original speed would take)
    chunks = session.learn_stamps(chunks)
    for chunk in chunks:
        if original_speed:
            if first is None:
                first = (chunk.t_end, time.monotonic())
            delay = first[1] + (chunk.t_end - first[0]) - time.monotonic()
            if delay > 0:
                session.refresh()
                publisher.rows()
                time.sleep(delay)
        publisher.chunk(chunk)
        session.feed(chunk)
        now = time.monotonic()
        if now - last >= refresh_every:
            last = now
            session.refresh()
            publisher.rows()
        if cutter is not None and cutter.due():
            cutter.cut(before_cut)
    session.finish()
    publisher.rows()
    if segment is not None:
        segment(session)
