"""Provides the statistics of network captures and gateways, as `replay --stats` prints
them: transactions per server and unit, and the gateway section (links by verdict, the
delay the gateway adds on each side)."""

from __future__ import annotations

import statistics
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from math import isnan

from sniffer.analysis.gateway import Link, Verdict
from sniffer.analysis.stats import nearest_rank
from sniffer.framing.pairing import measure
from sniffer.framing.store import FrameStore
from sniffer.vocab import BAD_CHECK, Kind, Status

# a latency as the table prints it (`_ms`), as a key that sorts as the latencies do:
# (the figure printed, as a float; its form: -1 negative, 0 "<0.001", 1 to the
# microsecond, 2 to 0.1 ms). Printing is monotonic in the latency, so the latency at a
# rank, printed, is the printed figure at that rank: counting the figures gives the
# very quantiles every value would, in memory that grows with the number of distinct
# figures, not of frames (as `sniffer.analysis.stats.Tallies` counts a unit's).
Figure = tuple[float, int]


def _figure(x: float) -> Figure:
    if x < 0:
        return float(f"{x * 1000:.1f}"), -1
    text = _ms(x)
    if text.startswith("<"):
        return 0.0, 0
    return float(text), 1 if x < 0.0001 else 2


def _figure_text(figure: Figure) -> str:
    value, form = figure
    if form == 0:
        return "<0.001"
    return f"{value:.3f}" if form == 1 else f"{value:.1f}"


@dataclass
class _Counts:
    requests: int = 0
    answers: int = 0
    exceptions: int = 0
    timeouts: int = 0
    check_errors: int = 0
    latencies: Counter[Figure] = field(default_factory=Counter)


def _ranked_figure(tally: Counter[Figure], q: float) -> str:
    """The nearest-rank q-quantile of the latencies counted, as printed; "-" for none."""
    n = tally.total()
    if not n:
        return "-"
    rank = min(n - 1, max(0, round(q * (n - 1))))
    seen = 0
    for key in sorted(tally):
        seen += tally[key]
        if seen > rank:
            return _figure_text(key)
    raise AssertionError("a rank within the tally")


def _quantile(values: Sequence[float], q: float) -> float | None:
    return nearest_rank(values, q)


def _ms(x: float | None) -> str:
    if x is None:
        return "-"
    if 0 <= x < 0.0001:  # to the microsecond, as `--stats`: never one that reads as 0
        return "<0.001" if x < 0.0000005 else f"{x * 1000:.3f}"
    return f"{x * 1000:.1f}"


_FRAMES = (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION, Kind.UNKNOWN)


class ServerCounts:
    """Requests, answers, exceptions, timeouts, frames with a bad check and latency per
    (server, unit) of a network capture's rows, counted and measured as the per-unit
    table counts them (`sniffer.analysis.stats`: frames with a good check; latencies as
    `measure` gives them, nearest-rank quantiles): counted a segment of rows at a time
    (`add`, as `replay --stats` drops them: no pair spans two segments), the latencies
    as their printed figures (`Figure`), so memory does not grow with the frames."""

    def __init__(self) -> None:
        self.table: dict[tuple[str, int], _Counts] = {}
        self.servers = False  # whether any row had a server (a network capture)

    def add(self, store: FrameStore) -> None:
        """Count the rows of `store` (every row of the segment, paired as they end)."""
        if not store.servers:
            return
        self.servers = True
        store.sync()
        table = self.table
        for i in range(len(store)):
            k = store.kind[i]
            if k not in _FRAMES:
                continue
            server = store.servers.get(store.channel[i])
            if server is None:
                continue
            c = table.get((server, store.unit[i]))
            if c is None:
                c = table[server, store.unit[i]] = _Counts()
            if store.flags[i] & BAD_CHECK:
                c.check_errors += 1
                continue
            if k == Kind.REQUEST:
                c.requests += 1
                if store.status[i] == Status.TIMEOUT:
                    c.timeouts += 1
                continue
            if k == Kind.UNKNOWN:
                continue
            c.answers += 1
            if k == Kind.EXCEPTION:
                c.exceptions += 1
            measured = measure(store, i)
            if measured is not None and not measured.bound and not isnan(measured.seconds):
                c.latencies[_figure(measured.seconds)] += 1

    def text(self) -> str:
        """The table; empty when no row had a server (not a network capture)."""
        if not self.servers:
            return ""
        head = (
            f"{'server':<22} {'unit':>4} {'req':>7} {'resp':>7} {'exc':>5} {'t/o':>5} "
            f"{'chk':>5} {'median':>8} {'p95':>8} {'max':>8}"
        )
        lines = ["per server and unit (latency in ms)", head, "-" * len(head)]
        for (server, unit), c in sorted(self.table.items()):
            lat = c.latencies
            lines.append(
                f"{server:<22} {unit:>4} {c.requests:>7} {c.answers:>7} {c.exceptions:>5} "
                f"{c.timeouts:>5} {c.check_errors:>5} {_ranked_figure(lat, 0.5):>8} "
                f"{_ranked_figure(lat, 0.95):>8} {_ranked_figure(lat, 1):>8}"
            )
        return "\n".join(lines)


def server_table(store: FrameStore) -> str:
    """`ServerCounts` of the rows of one store, as text (empty when no row has a server)."""
    counts = ServerCounts()
    counts.add(store)
    return counts.text()


VERDICT_WORDS = {
    Verdict.OK: "answered on both sides, same answer",
    Verdict.NOT_SENT: "never sent on the serial line (gateway dropped or queued it)",
    Verdict.DEVICE_TIMEOUT: "sent on the serial line, the device did not answer",
    Verdict.ANSWER_LOST: "the device answered, the gateway did not pass it on",
    Verdict.GATEWAY_EXCEPTION: "gateway exception 0x0A/0x0B, the serial side agrees",
    Verdict.LINE_ERROR: "the device's answer was garbled on the serial line",
    Verdict.GATEWAY_FAULT: "gateway exception 0x0A/0x0B although the device answered intact",
    Verdict.MISMATCH: "both answered, the answers differ",
}


def gateway_table(links: Sequence[Link]) -> str:
    """The gateway section: TCP transactions by verdict, and the delay the gateway adds
    on each side (request in: serial request start - TCP request end; answer out: TCP
    answer start - serial answer end)."""
    counts = Counter(x.verdict for x in links)
    lines = [f"gateway: {len(links)} Modbus TCP transaction(s) linked to the serial side"]
    for v in Verdict:
        if counts[v]:
            lines.append(f"  {v.value:<18} {counts[v]:>7}  {VERDICT_WORDS[v]}")
    delay_in = [x.delay_in for x in links if x.delay_in is not None]
    delay_out = [x.delay_out for x in links if x.delay_out is not None]
    lines.append(f"  {'delay (ms)':<18} {'n':>7} {'min':>8} {'median':>8} {'p95':>8} {'max':>8}")
    for name, values in (("request in", delay_in), ("answer out", delay_out)):
        median = statistics.median(values) if values else None
        lines.append(
            f"  {name:<18} {len(values):>7} {_ms(_quantile(values, 0)):>8} {_ms(median):>8} "
            f"{_ms(_quantile(values, 0.95)):>8} {_ms(_quantile(values, 1)):>8}"
        )
    return "\n".join(lines)
