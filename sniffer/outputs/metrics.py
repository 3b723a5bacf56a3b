"""Provides Prometheus metrics of the buses a modscope process watches (`--metrics`).

`Metrics` serves, over HTTP in the Prometheus text format (prometheus_client, an optional
extra: `pip install 'modscope[metrics]'`), what each watched session counted:

- `modscope_frames_total`: Modbus frames framed (noise spans and port events left out);
- `modscope_requests_total{unit}`, `modscope_responses_total{unit}` (exceptions
  included), `modscope_exceptions_total{unit,code}`, `modscope_timeouts_total{unit}`:
  the figures of `modscope replay --stats` (`sniffer.analysis.stats`);
- `modscope_check_errors_total`: frames with a wrong CRC or LRC;
- `modscope_response_seconds{unit}`: a histogram of the latencies the timing measured;
  an answer faster than the stamps resolve, or one the stamps cannot time, is left out
  (its bound is never counted as a value); to 0.1 ms where a burst of more answers than
  a bounded unit keeps exactly (1,024) came between two updates;
- `modscope_unit_up{unit}`: 1 while the unit answers, 0 once it has not for three polling
  periods (at least 2 s), the rule of the MQTT unit status;
- `modscope_unit_info{unit,device,model}`: 1 for each unit, naming it;
- `modscope_lost_bytes_total`: bytes a live capture could not keep up with (0 for files);
- `modscope_noise_bytes_total`: bytes no frame claims.

Every metric has a `bus` label where one process watches several buses. The figures are
taken in the session's own thread (`update`, after each refresh) and handed to the HTTP
thread whole, so a scrape never sees a half-counted update.
"""

from __future__ import annotations

import bisect
import importlib.util
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import compress
from typing import TYPE_CHECKING, Any

from sniffer.analysis.stats import UnitStats, latency_figure, median_gap
from sniffer.framing.columns import flag_mask, marking
from sniffer.meaning.annotate import Binding
from sniffer.model import Chunk
from sniffer.outputs.mqtt.publish import SILENT_AFTER, SILENT_MIN, WINDOW
from sniffer.session.session import Session
from sniffer.vocab import BAD_CHECK, Kind

if TYPE_CHECKING:
    from wsgiref.simple_server import WSGIServer

    from prometheus_client.metrics_core import Metric

EXTRA_HINT = "--metrics needs the prometheus_client library: pip install 'modscope[metrics]'"
DEFAULT_HOST = "127.0.0.1"
# upper bounds (seconds) of the latency histogram's buckets: a Modbus answer takes from
# a millisecond (a fast device on a fast line) to a few hundred (a slow one at 9600 baud)
BUCKETS = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)
_IS_ANSWER = marking((int(Kind.RESPONSE), int(Kind.EXCEPTION)))


class MetricsError(Exception):
    """Metrics cannot be served as asked. The message says what to do."""


def require_client() -> None:
    if importlib.util.find_spec("prometheus_client") is None:
        raise MetricsError(EXTRA_HINT)


def parse_listen(text: str) -> tuple[str, int]:
    """`--metrics [HOST:]PORT`: `9108`, `0.0.0.0:9108`, `[::1]:9108` (host 127.0.0.1 when
    not given; port 0 takes a free one). MetricsError says how to write it."""
    host, sep, port_text = text.strip().rpartition(":")
    if not sep:
        host = DEFAULT_HOST
    host = host.strip()
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if sep and not host:
        host = DEFAULT_HOST
    if not port_text.isdigit() or not 0 <= int(port_text) <= 65535:
        raise MetricsError(
            f"--metrics {text!r}: write [HOST:]PORT, e.g. 9108 or 0.0.0.0:9108 (a port from "
            "0 to 65535; 0 takes a free one)"
        )
    return host, int(port_text)


# -- what one bus counted ------------------------------------------------------------------------


@dataclass
class UnitFigures:
    """One unit's figures at one update."""

    requests: int = 0
    responses: int = 0
    exceptions: dict[int, int] = field(default_factory=dict)
    timeouts: int = 0
    buckets: list[int] = field(default_factory=lambda: [0] * (len(BUCKETS) + 1))
    latency_sum: float = 0.0
    latency_count: int = 0
    up: bool = False
    device: str = ""
    model: str = ""


@dataclass
class BusFigures:
    """One bus's figures at one update."""

    frames: int = 0
    check_errors: int = 0
    lost_bytes: int = 0
    noise_bytes: int = 0
    units: dict[int, UnitFigures] = field(default_factory=dict)


class _Latencies:
    """A unit's histogram, added to as its statistics grow."""

    def __init__(self) -> None:
        self.buckets = [0] * (len(BUCKETS) + 1)
        self.total = 0.0
        self.count = 0
        self.seen = 0  # the unit's latencies taken so far
        self.tally: Counter[float] = Counter()  # bounded units: the tally as last taken

    def add(self, seconds: Iterable[float], times: int = 1) -> None:
        for x in seconds:
            self.buckets[bisect.bisect_left(BUCKETS, x)] += times
            self.total += x * times
            self.count += times

    def take(self, st: UnitStats) -> None:
        """The latencies `st` measured since the last call."""
        count = st.latency_count
        new = count - self.seen
        if new <= 0:
            return
        tallies = st.tallies
        if tallies is None:  # every value kept: exactly those since last time
            self.add(st.latencies[self.seen : count])
        else:
            exact = st.newest_latencies(new)  # at most the RECENT a bounded unit keeps
            self.add(exact)
            if len(exact) < new:
                # a burst longer than the newest values kept: the rest from the tally of
                # printed figures (0.1 ms, 1 µs under 0.1 ms), less those taken exactly just above
                older = tallies.latency_ms - self.tally
                older.subtract(Counter(latency_figure(x * 1000) for x in exact))
                for ms, times in older.items():
                    if times > 0:
                        self.add((ms / 1000,), times)
            self.tally = Counter(tallies.latency_ms)
        self.seen = count


class BusWatch:
    """One session followed for its metrics. `update()` from the thread that feeds the
    session (after its refresh), never from another."""

    def __init__(
        self,
        name: str,
        session: Session,
        bindings: Mapping[int, Binding],
        *,
        clock: Callable[[], float] | None = None,
        lost: Callable[[], int] | None = None,
    ) -> None:
        self.name = name
        self.session = session
        self.bindings = dict(bindings)
        self.clock = clock  # a live capture's clock: units fall silent while the bus is
        self.lost = lost
        self._base = -1
        self._next = 0
        self._answered: dict[int, float] = {}
        self._requests: dict[int, tuple[int, list[float]]] = {}
        self._latencies: dict[int, _Latencies] = {}
        self._now = 0.0

    def update(self) -> BusFigures:
        session = self.session
        store = session.store
        store.sync()
        n = len(store)
        if session.base != self._base:  # a new segment: its rows count from 0
            self._base, self._next = session.base, 0
        self._scan_answers(self._next, n)
        self._next = n
        if n:
            self._now = max(self._now, store.t_end[n - 1])
        if self.clock is not None:
            self._now = max(self._now, self.clock())
        kinds = store.kind.tobytes()
        stats = session.stats
        figures = BusFigures(
            frames=session.frames_before
            + n
            - kinds.count(int(Kind.NOISE))
            - kinds.count(int(Kind.EVENT)),
            lost_bytes=self.lost() if self.lost is not None else 0,
            noise_bytes=stats.noise_bytes,
        )
        for u, st in sorted(stats.units.items()):
            figures.check_errors += st.check_errors
            if not st.requests and not st.responses and u not in self.bindings:
                continue  # a unit byte seen only in broken frames
            latencies = self._latencies.setdefault(u, _Latencies())
            latencies.take(st)
            binding = self.bindings.get(u)
            figures.units[u] = UnitFigures(
                requests=st.requests,
                responses=st.responses,
                exceptions=dict(st.exceptions),
                timeouts=st.timeouts,
                buckets=list(latencies.buckets),
                latency_sum=latencies.total,
                latency_count=latencies.count,
                up=self._up(u, st),
                device=binding.label if binding is not None else "",
                model=binding.dictionary.model if binding is not None else "",
            )
        return figures

    def _scan_answers(self, start: int, end: int) -> None:
        """The newest answer with a good check of each unit among rows start..end."""
        if start >= end:
            return
        store = self.session.store
        rows = list(
            compress(range(start, end), store.kind[start:end].tobytes().translate(_IS_ANSWER))
        )
        if not rows:
            return
        bad = flag_mask(store.flags, BAD_CHECK, start, end)
        wanted = {store.unit[i] for i in rows}
        for i in reversed(rows):
            u = store.unit[i]
            if u in wanted and not bad[i - start]:
                self._answered[u] = max(self._answered.get(u, 0.0), store.t_end[i])
                wanted.discard(u)
                if not wanted:
                    break

    def _up(self, u: int, st: UnitStats) -> bool:
        """Answered within three polling periods (at least SILENT_MIN seconds) of now, the
        polling period the median gap of its newest WINDOW requests."""
        seen, times = self._requests.get(u, (0, []))
        count = st.request_count
        if count > seen:
            times = [*times, *st.newest_requests(min(WINDOW, count - seen))][-WINDOW:]
            self._requests[u] = (count, times)
        answered = self._answered.get(u)
        if answered is None:
            return False
        period = median_gap(times) or 0.0
        return self._now - answered <= max(SILENT_MIN, SILENT_AFTER * period)


# -- the exposition ------------------------------------------------------------------------------


class Metrics:
    """The buses watched (`watch`), their latest figures, and the HTTP server (`serve`)."""

    def __init__(self, *, several: bool = False) -> None:
        require_client()
        self.several = several  # a `bus` label on every metric
        self.watches: list[BusWatch] = []
        self._figures: dict[str, BusFigures] = {}
        self._lock = threading.Lock()
        self._server: WSGIServer | None = None
        self._thread: threading.Thread | None = None
        self.url = ""
        self.scrapes = 0

    def watch(
        self,
        name: str,
        session: Session,
        bindings: Mapping[int, Binding],
        *,
        clock: Callable[[], float] | None = None,
        lost: Callable[[], int] | None = None,
    ) -> BusWatch:
        taken = {w.name for w in self.watches}
        chosen, n = name, 1
        while chosen in taken:  # the same file given twice: each its own `bus`
            n += 1
            chosen = f"{name} ({n})"
        found = BusWatch(chosen, session, bindings, clock=clock, lost=lost)
        self.watches.append(found)
        return found

    def rewatch(self, name: str, session: Session) -> None:
        """Follow `session` instead of the one watched as `name` (read again from the start)."""
        for k, old in enumerate(self.watches):
            if old.name == name:
                self.watches[k] = BusWatch(
                    name, session, old.bindings, clock=old.clock, lost=old.lost
                )

    def update(self) -> None:
        """Take every watched bus's figures (from the thread that feeds the sessions)."""
        figures = {w.name: w.update() for w in self.watches}
        with self._lock:
            self._figures.update(figures)

    # prometheus_client's collector protocol: `describe` (nothing to check ahead) and
    # `collect` (called by the HTTP thread at each scrape)
    def describe(self) -> list[Metric]:
        return []

    def collect(self) -> Iterator[Metric]:
        from prometheus_client.core import (
            CounterMetricFamily,
            GaugeMetricFamily,
            HistogramMetricFamily,
        )

        with self._lock:
            figures = dict(self._figures)
            self.scrapes += 1
        bus = ["bus"] if self.several else []
        unit = [*bus, "unit"]
        frames = CounterMetricFamily("modscope_frames", "Modbus frames framed", labels=bus)
        checks = CounterMetricFamily(
            "modscope_check_errors", "frames with a wrong CRC or LRC", labels=bus
        )
        lost = CounterMetricFamily(
            "modscope_lost_bytes", "bytes a live capture could not keep up with", labels=bus
        )
        noise = CounterMetricFamily("modscope_noise_bytes", "bytes no frame claims", labels=bus)
        requests = CounterMetricFamily(
            "modscope_requests", "requests with a good check", labels=unit
        )
        responses = CounterMetricFamily(
            "modscope_responses", "answers with a good check, exceptions included", labels=unit
        )
        exceptions = CounterMetricFamily(
            "modscope_exceptions", "exception answers by code", labels=[*unit, "code"]
        )
        timeouts = CounterMetricFamily(
            "modscope_timeouts", "requests nobody answered in time", labels=unit
        )
        latency = HistogramMetricFamily(
            "modscope_response_seconds",
            "measured answer latencies (answers the timing cannot measure are left out)",
            labels=unit,
        )
        up = GaugeMetricFamily(
            "modscope_unit_up", "1 while the unit answers, 0 once silent", labels=unit
        )
        info = GaugeMetricFamily(
            "modscope_unit_info",
            "the unit's device label and model",
            labels=[*unit, "device", "model"],
        )
        for name, f in sorted(figures.items()):
            b = [name] if self.several else []
            frames.add_metric(b, f.frames)
            checks.add_metric(b, f.check_errors)
            lost.add_metric(b, f.lost_bytes)
            noise.add_metric(b, f.noise_bytes)
            for u, uf in sorted(f.units.items()):
                k = [*b, str(u)]
                requests.add_metric(k, uf.requests)
                responses.add_metric(k, uf.responses)
                for code, count in sorted(uf.exceptions.items()):
                    exceptions.add_metric([*k, str(code)], count)
                timeouts.add_metric(k, uf.timeouts)
                running = 0
                buckets: list[tuple[str, float]] = []
                for bound, count in zip([*BUCKETS, float("inf")], uf.buckets, strict=True):
                    running += count
                    buckets.append((_le(bound), running))
                latency.add_metric(k, buckets, uf.latency_sum)
                up.add_metric(k, 1 if uf.up else 0)
                info.add_metric([*k, uf.device, uf.model], 1)
        yield from (frames, requests, responses, exceptions, timeouts, checks, latency, up)
        yield from (info, lost, noise)

    def serve(self, host: str, port: int) -> str:
        """Serve /metrics on host:port from a thread; the URL. MetricsError when the port
        cannot be had."""
        from prometheus_client import start_http_server
        from prometheus_client.registry import CollectorRegistry

        registry = CollectorRegistry(auto_describe=False)
        registry.register(self)
        try:
            self._server, self._thread = start_http_server(port, addr=host, registry=registry)
        except OSError as exc:
            raise MetricsError(
                f"--metrics {host}:{port}: cannot listen there ({exc.strerror or exc}); "
                "choose another port, or 0 for a free one"
            ) from None
        shown = f"[{host}]" if ":" in host else host
        self.url = f"http://{shown}:{self._server.server_port}/metrics"
        return self.url

    def hold(self, seconds: float) -> None:
        """Keep serving `seconds` more (a scrape can read the final figures); Ctrl-C ends
        the wait."""
        end = time.monotonic() + seconds
        try:
            while (left := end - time.monotonic()) > 0:
                time.sleep(min(left, 0.2))
        except KeyboardInterrupt:
            pass

    def close(self) -> None:
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._server = None
        if self._thread is not None:
            self._thread.join(5)
            self._thread = None

    def report(self) -> str:
        return f"metrics: {self.scrapes:,} scrapes of {self.url}"


def _le(bound: float) -> str:
    return "+Inf" if bound == float("inf") else repr(bound)


class MetricsFeed:
    """`Metrics` as a live capture's output (`sniffer.live.engine.Publisher`): its
    figures taken after every pump, a last time when the capture stops."""

    def __init__(self, metrics: Metrics) -> None:
        self.metrics = metrics
        self.next = 0

    def chunk(self, chunk: Chunk) -> None:
        """Nothing per read: the figures come from the session."""

    def rows(self, final: bool = False) -> None:
        self.metrics.update()

    def close(self, drain: float = 10.0) -> str:
        self.metrics.update()
        return self.metrics.report()


class Fanout:
    """Several live-capture outputs fed as one (`Publisher`): an MQTT publisher and the
    metrics, each in turn."""

    def __init__(self, outputs: Sequence[Any]) -> None:
        self.outputs = list(outputs)

    @property
    def next(self) -> int:
        return int(self.outputs[0].next)

    @next.setter
    def next(self, value: int) -> None:
        for o in self.outputs:
            o.next = value

    def chunk(self, chunk: Chunk) -> None:
        for o in self.outputs:
            o.chunk(chunk)

    def rows(self, final: bool = False) -> None:
        for o in self.outputs:
            o.rows(final)

    def close(self, drain: float = 10.0) -> str:
        return "; ".join(text for o in self.outputs if (text := o.close(drain)))
