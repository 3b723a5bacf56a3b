"""Provides the poll cycle: per unit, which requests the master repeats, how often, how
steadily, and where the cycle stalled.

A request repeats when the same bytes (unit, function, address, count; written values
left out) are sent again. Its period is the median time between two sendings, its
jitter the spread of those times (95th minus 5th percentile), and a gap is a wait of
more than twice the period: the master stopped polling, or the unit was skipped.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from itertools import pairwise

from dissectors.dissect import dissect
from dissectors.values import Role
from sniffer.stats import nearest_rank
from sniffer.store import FrameStore
from sniffer.vocab import BAD_CHECK, Flag, Kind

GAP_FACTOR = 2.0  # a wait longer than this many periods is a gap
MIN_REPEATS = 3  # sendings before a request counts as part of the cycle


@dataclass(frozen=True, slots=True)
class Gap:
    """A wait of more than GAP_FACTOR periods between two sendings of a request."""

    start: float  # when the request was last sent before the gap
    length: float  # seconds until it was sent again


@dataclass(frozen=True, slots=True)
class Poll:
    """One repeating request."""

    unit: int
    function: int
    what: str  # "holding 3200-3211", "coil 16", "FC 8"
    count: int  # times sent
    period: float  # median seconds between sendings
    jitter: float  # p95 - p5 of those seconds
    gaps: tuple[Gap, ...]
    first: float
    last: float
    retries: int = 0  # sendings that repeated one left unanswered (counted in `count`)


@dataclass
class UnitCycle:
    """The repeating requests of one unit and the unit's whole cycle."""

    unit: int
    polls: list[Poll] = field(default_factory=list)
    once: int = 0  # requests sent fewer than MIN_REPEATS times

    @property
    def period(self) -> float | None:
        """The longest period of its repeating requests: the time for a whole cycle."""
        return max((p.period for p in self.polls), default=None)

    @property
    def gaps(self) -> list[Gap]:
        return sorted({g for p in self.polls for g in p.gaps}, key=lambda g: g.start)


_TABLE_WORDS = {
    "holding_registers": "holding",
    "input_registers": "input",
    "coils": "coil",
    "discrete_inputs": "input bit",
}
_READS = {1: "coils", 2: "discrete_inputs", 3: "holding_registers", 4: "input_registers"}


def _what(body: bytes) -> tuple[tuple[object, ...], str]:
    """The request's identity (values written left out) and a short description."""
    d = dissect(body, Role.REQUEST)
    address = d.field("address")
    quantity = d.field("quantity")
    start = address.value if address is not None and isinstance(address.value, int) else None
    count = quantity.value if quantity is not None and isinstance(quantity.value, int) else None
    table = _READS.get(d.function) or (d.data[0].table if d.data else None)
    if count is None and d.data:
        count = len(d.data[0].values)
    if table is None or start is None:
        return (d.function, body[2:]), f"FC {d.function}"
    word = _TABLE_WORDS.get(table, table)
    span = f"{start}" if not count or count == 1 else f"{start}-{start + count - 1}"
    verb = "write" if d.function in (5, 6, 15, 16) else "read"
    return (d.function, start, count), f"{verb} {word} {span}"


def _quantile(values: list[float], q: float) -> float:
    found = nearest_rank(values, q)
    assert found is not None  # called with the waits of a request seen at least twice
    return found


def poll_cycles(store: FrameStore) -> dict[int, UnitCycle]:
    """Every unit's poll cycle, from the requests in `store`."""
    store.sync()
    sendings: dict[int, dict[tuple[object, ...], tuple[str, int, list[float], list[float]]]] = {}
    # a polling master sends the same requests all day: each is taken apart once
    # (1M frames: about 6 us a request dissected, well under 1 us looked up)
    known: dict[bytes, tuple[tuple[object, ...], str]] = {}
    request = int(Kind.REQUEST)
    for i in range(len(store)):
        if store.kind[i] != request or store.flags[i] & BAD_CHECK:
            continue
        unit = store.unit[i]
        raw = store.raw(i)
        found_what = known.get(raw)
        if found_what is None:
            found_what = known[raw] = _what(store.view(i).body())
            if len(known) > 65536:  # writes with changing values: keep the memory bounded
                known.clear()
        key, what = found_what
        found = sendings.setdefault(unit, {}).setdefault(key, (what, store.fc[i], [], []))
        found[2].append(store.t[i])
        if store.flags[i] & Flag.RETRY:
            found[3].append(store.t[i])
    out: dict[int, UnitCycle] = {}
    for unit, requests in sorted(sendings.items()):
        cycle = out[unit] = UnitCycle(unit)
        for what, fc, times, retries in requests.values():
            if len(times) < MIN_REPEATS:
                cycle.once += 1
                continue
            waits = [b - a for a, b in pairwise(times)]
            period = _quantile(waits, 0.5)
            jitter = _quantile(waits, 0.95) - _quantile(waits, 0.05)
            gaps = tuple(Gap(a, b - a) for a, b in pairwise(times) if b - a > GAP_FACTOR * period)
            cycle.polls.append(
                Poll(
                    unit,
                    fc,
                    what,
                    len(times),
                    period,
                    jitter,
                    gaps,
                    times[0],
                    times[-1],
                    len(retries),
                )
            )
        cycle.polls.sort(key=lambda p: (p.period, p.what))
    return out


def _ms(seconds: float) -> str:
    return f"{seconds * 1000:.0f}ms" if seconds < 10 else f"{seconds:.1f}s"


def cycle_table(cycles: Mapping[int, UnitCycle], labels: Mapping[int, str] | None = None) -> str:
    """The poll cycle as text for `--stats`."""
    labels = labels or {}
    rows = [
        "poll cycle",
        "unit  request                       sent   period   jitter  gaps  retries",
    ]
    for unit, cycle in cycles.items():
        label = labels.get(unit, "")
        for n, p in enumerate(cycle.polls):
            head = f"{unit:>4}  " if n == 0 else "      "
            gaps = str(len(p.gaps)) if p.gaps else "-"
            retries = str(p.retries) if p.retries else "-"
            rows.append(
                f"{head}{p.what:<28} {p.count:>6} {_ms(p.period):>8} {_ms(p.jitter):>8}  "
                f"{gaps:>4}  {retries:>7}"
            )
        if not cycle.polls:
            rows.append(f"{unit:>4}  (no request repeated {MIN_REPEATS} times)")
        if label and cycle.polls:
            rows[-len(cycle.polls)] += f"  {label}"
        for g in cycle.gaps[:3]:
            rows.append(f"      gap at {g.start:.3f}s: {_ms(g.length)} without polls")
        if len(cycle.gaps) > 3:
            rows.append(f"      ... {len(cycle.gaps) - 3} more gaps")
    return "\n".join(rows)
