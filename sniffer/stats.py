"""Provides per-unit statistics, kept up to date as frames are indexed."""

from __future__ import annotations

from array import array
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise

from sniffer.model import Stamp
from sniffer.pairing import UNRESOLVED, measure
from sniffer.store import NO_PARTNER, FrameStore
from sniffer.vocab import BAD_CHECK, Kind, Status


@dataclass
class UnitStats:
    unit: int
    requests: int = 0
    responses: int = 0
    exceptions: Counter[int] = field(default_factory=Counter)
    timeouts: int = 0
    check_errors: int = 0
    latencies: array[float] = field(default_factory=lambda: array("d"))  # seconds
    request_times: array[float] = field(default_factory=lambda: array("d"))
    last_seen: float = 0.0
    below_resolution: int = 0  # answers faster than the timing resolves
    unmeasured: int = 0  # answers whose latency the timing cannot give at all

    @property
    def exception_count(self) -> int:
        return sum(self.exceptions.values())

    def latency_ms(self, q: float) -> float | None:
        """The q-quantile (0..1) of answer latency in ms, nearest rank."""
        found = nearest_rank(self.latencies, q)
        return None if found is None else found * 1000

    def polling_period(self) -> float | None:
        """Median seconds between two requests to this unit."""
        return median_gap(self.request_times)


def nearest_rank(values: Sequence[float], q: float) -> float | None:
    """The q-quantile (0..1) of `values`, nearest rank (what --stats, the poll cycle and
    the MQTT unit status all report); None for no values."""
    if not values:
        return None
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q * (len(ordered) - 1))))]


def median_gap(times: Sequence[float]) -> float | None:
    """The median gap between consecutive `times` (a polling period); None for fewer
    than two."""
    if len(times) < 2:
        return None
    return nearest_rank([b - a for a, b in pairwise(times)], 0.5)


NOISE, REQUEST, RESPONSE = int(Kind.NOISE), int(Kind.REQUEST), int(Kind.RESPONSE)
EXCEPTION, EVENT = int(Kind.EXCEPTION), int(Kind.EVENT)
TIMEOUT, OPEN = Status.TIMEOUT, Status.OPEN


class Stats:
    """Per-unit counts over a store; call `update()` as rows arrive."""

    def __init__(self, store: FrameStore) -> None:
        self.store = store
        self.units: dict[int, UnitStats] = {}
        self.next = 0
        self.noise_bytes = 0
        self.noise_spans = 0
        self.events = 0
        self._timed_out: set[int] = set()
        self._open: set[int] = set()

    def unit(self, u: int) -> UnitStats:
        found = self.units.get(u)
        if found is None:
            found = self.units[u] = UnitStats(u)
        return found

    def update(self) -> None:
        s = self.store
        s.sync()
        # requests still open last time may have timed out since
        for i in list(self._open):
            if s.status[i] != Status.OPEN:
                self._open.discard(i)
                if s.status[i] == Status.TIMEOUT:
                    self.unit(s.unit[i]).timeouts += 1
        kind, unit, flags, status = s.kind, s.unit, s.flags, s.status
        t, t_end, fc, partner = s.t, s.t_end, s.fc, s.partner
        units = self.units
        # pairing.measure, inlined for its common case (any stamps, a latency above
        # UNRESOLVED is shown as it is): a Latency object per answer cost about 1 us
        stamped = s.stamps != Stamp.NONE
        for i in range(self.next, len(s)):
            k = kind[i]
            if k == NOISE:
                self.noise_spans += 1
                self.noise_bytes += s.length[i]
                continue
            if k == EVENT:
                self.events += 1
                continue
            u = unit[i]
            st = units.get(u) or self.unit(u)
            st.last_seen = t_end[i]
            if flags[i] & BAD_CHECK:
                st.check_errors += 1
                continue
            if k == REQUEST:
                st.requests += 1
                st.request_times.append(t[i])
                state = status[i]
                if state == TIMEOUT:
                    st.timeouts += 1
                elif state == OPEN:
                    self._open.add(i)
            elif k in (RESPONSE, EXCEPTION):
                st.responses += 1
                if fc[i] & 0x80:
                    body = s.view(i).body()
                    st.exceptions[body[2] if len(body) > 2 else 0] += 1
                j = partner[i]
                if j != NO_PARTNER:
                    raw = t[i] - t_end[j]  # i answers j (as pairing.latency)
                    if stamped and raw >= UNRESOLVED:
                        st.latencies.append(raw)
                        continue
                    lat = measure(s, i)
                    if lat is None:
                        st.unmeasured += 1
                    elif lat.bound:
                        st.below_resolution += 1
                    else:
                        st.latencies.append(lat.seconds)
        self.next = len(s)

    def table(self, labels: dict[int, str] | None = None) -> str:
        """The per-unit table, as `modscope replay --stats` prints it."""
        labels = labels or {}
        head = (
            f"{'unit':>4}  {'device':<16} {'req':>7} {'resp':>7} {'exc':>5} {'t/o':>5} "
            f"{'chk':>5} {'lat min':>8} {'median':>8} {'p95':>8} {'max':>8} {'period':>8}"
        )
        lines = [head, "-" * len(head)]

        def ms(x: float | None) -> str:
            return "-" if x is None else f"{x:.1f}"

        for u in sorted(self.units):
            st = self.units[u]
            period = st.polling_period() if self.store.stamps != Stamp.NONE else None
            lines.append(
                f"{u:>4}  {labels.get(u, '')[:16]:<16} {st.requests:>7} {st.responses:>7} "
                f"{st.exception_count:>5} {st.timeouts:>5} {st.check_errors:>5} "
                f"{ms(st.latency_ms(0)):>8} {ms(st.latency_ms(0.5)):>8} "
                f"{ms(st.latency_ms(0.95)):>8} {ms(st.latency_ms(1)):>8} "
                f"{'-' if period is None else f'{period * 1000:.0f}ms':>8}"
            )
            if st.exceptions:
                codes = ", ".join(f"{c:02d} x{n}" for c, n in sorted(st.exceptions.items()))
                lines.append(f"{'':>4}  exceptions by code: {codes}")
        lines.append(
            f"noise: {self.noise_spans} spans, {self.noise_bytes} bytes; events: {self.events}"
        )
        lines.append(self.timing_line())
        return "\n".join(lines)

    def timing_line(self) -> str:
        """What the latencies and periods above are worth, given the source's stamps."""
        s = self.store
        below = sum(u.below_resolution for u in self.units.values())
        unmeasured = sum(u.unmeasured for u in self.units.values())
        if s.stamps == Stamp.NONE:
            return (
                "timing: synthetic (the source has no timestamps): "
                "no latency or poll period is measured"
            )
        text = f"timing: {TIMING_WORDS[s.stamps]}"
        if s.resolution > 0:
            text += f", resolution about {s.resolution * 1000:.3g} ms"
        if below:
            text += f"; {below} answer(s) faster than that (<{s.resolution * 1000:.3g} ms)"
        if unmeasured:
            text += f"; {unmeasured} latency(ies) the stamps cannot give"
        if below or unmeasured:
            text += ", left out of the latency columns"
        return text


TIMING_WORDS = {
    Stamp.EXACT: "exact (per character)",
    Stamp.READ_END: "end of each host read",
    Stamp.FRAME_START: "start of each frame",
    Stamp.FRAME_END: "end of each frame",
    Stamp.PRINT: "when each line was logged",
    Stamp.NONE: "synthetic",
}
