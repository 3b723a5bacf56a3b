"""Provides the statistics of network captures and gateways, as `replay --stats` prints
them: transactions per server and unit, and the gateway section (links by verdict, the
delay the gateway adds on each side)."""

from __future__ import annotations

import statistics
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

from sniffer.analysis.gateway import Link, Verdict
from sniffer.analysis.stats import nearest_rank
from sniffer.framing.pairing import measure
from sniffer.framing.store import FrameStore
from sniffer.vocab import BAD_CHECK, Kind, Status


@dataclass
class _Counts:
    requests: int = 0
    answers: int = 0
    exceptions: int = 0
    timeouts: int = 0
    check_errors: int = 0
    latencies: list[float] = field(default_factory=list)


def _quantile(values: Sequence[float], q: float) -> float | None:
    return nearest_rank(values, q)


def _ms(x: float | None) -> str:
    if x is None:
        return "-"
    if 0 <= x < 0.0001:  # to the microsecond, as `--stats`: never one that reads as 0
        return "<0.001" if x < 0.0000005 else f"{x * 1000:.3f}"
    return f"{x * 1000:.1f}"


_FRAMES = (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION, Kind.UNKNOWN)


def server_table(store: FrameStore) -> str:
    """Requests, answers, exceptions, timeouts, frames with a bad check and latency per
    (server, unit) of a network capture's rows, counted and measured as the per-unit
    table counts them (`sniffer.analysis.stats`: frames with a good check; latencies
    as `measure` gives them, nearest-rank quantiles); empty when no row has a server
    (not a network capture)."""
    if not store.servers:
        return ""
    store.sync()
    table: dict[tuple[str, int], _Counts] = {}
    for i in range(len(store)):
        k = store.kind[i]
        if k not in _FRAMES:
            continue
        server = store.servers.get(store.channel[i])
        if server is None:
            continue
        c = table.setdefault((server, store.unit[i]), _Counts())
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
        if measured is not None and not measured.bound:
            c.latencies.append(measured.seconds)
    head = (
        f"{'server':<22} {'unit':>4} {'req':>7} {'resp':>7} {'exc':>5} {'t/o':>5} "
        f"{'chk':>5} {'median':>8} {'p95':>8} {'max':>8}"
    )
    lines = ["per server and unit (latency in ms)", head, "-" * len(head)]
    for (server, unit), c in sorted(table.items()):
        lines.append(
            f"{server:<22} {unit:>4} {c.requests:>7} {c.answers:>7} {c.exceptions:>5} "
            f"{c.timeouts:>5} {c.check_errors:>5} {_ms(_quantile(c.latencies, 0.5)):>8} "
            f"{_ms(_quantile(c.latencies, 0.95)):>8} {_ms(_quantile(c.latencies, 1)):>8}"
        )
    return "\n".join(lines)


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
