"""The per-unit statistics, counted column by column, hold to their definition: a walk over
the rows one at a time (below), on random stores and on the demo capture, in one update
or in many as rows arrive, and after requests still open time out."""

from __future__ import annotations

import math
import random
from array import array
from collections import Counter
from dataclasses import dataclass, field

import pytest

from sniffer.analysis.stats import Stats
from sniffer.framing.pairing import UNRESOLVED, measure
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.model import Stamp
from sniffer.session.session import DEMO_CAPTURE, replay_file
from sniffer.vocab import BAD_CHECK, Kind, Status
from tests.support.random_rows import random_store


@dataclass
class Expected:
    requests: int = 0
    responses: int = 0
    exceptions: Counter[int] = field(default_factory=Counter)
    timeouts: int = 0
    check_errors: int = 0
    latencies: list[float] = field(default_factory=list)
    request_times: list[float] = field(default_factory=list)
    last_seen: float = 0.0
    below_resolution: int = 0
    unmeasured: int = 0


class RowByRow:
    """What the statistics mean, one row at a time (pairing.measure for every latency)."""

    def __init__(self, store: FrameStore) -> None:
        self.store = store
        self.units: dict[int, Expected] = {}
        self.next = 0
        self.noise_bytes = self.noise_spans = self.events = 0
        self.open: set[int] = set()

    def update(self) -> None:
        s = self.store
        s.sync()
        for i in sorted(self.open):
            if s.status[i] != Status.OPEN:
                self.open.discard(i)
                if s.status[i] == Status.TIMEOUT:
                    self.units.setdefault(s.unit[i], Expected()).timeouts += 1
        for i in range(self.next, len(s)):
            k = s.kind[i]
            if k == Kind.NOISE:
                self.noise_spans += 1
                self.noise_bytes += s.length[i]
                continue
            if k == Kind.EVENT:
                self.events += 1
                continue
            st = self.units.setdefault(s.unit[i], Expected())
            st.last_seen = s.t_end[i]
            if s.flags[i] & BAD_CHECK:
                st.check_errors += 1
                continue
            if k == Kind.REQUEST:
                st.requests += 1
                st.request_times.append(s.t[i])
                if s.status[i] == Status.TIMEOUT:
                    st.timeouts += 1
                elif s.status[i] == Status.OPEN:
                    self.open.add(i)
            elif k in (Kind.RESPONSE, Kind.EXCEPTION):
                st.responses += 1
                if s.fc[i] & 0x80:
                    body = s.view(i).body()
                    st.exceptions[body[2] if len(body) > 2 else 0] += 1
                if s.partner[i] == NO_PARTNER:
                    continue
                lat = measure(s, i)
                if lat is not None and not lat.bound:
                    st.latencies.append(lat.raw)  # as the row times give it
                elif lat is not None or resolved(s):
                    # a bound; or stamps that resolve some time yet contradict here
                    # (an answer before its request's end): below what they resolve
                    st.below_resolution += 1
                else:
                    st.unmeasured += 1
        self.next = len(s)


def resolved(s: FrameStore) -> bool:
    """Whether the store's stamps resolve some time: not synthetic, not print times
    (each bounded or not on its own), a resolution that bounds."""
    return s.stamps not in (Stamp.NONE, Stamp.PRINT) and 0 < s.resolution < math.inf


def same(stats: Stats, expected: RowByRow) -> None:
    assert list(stats.units) == list(expected.units)  # in order of first appearance
    for u, want in expected.units.items():
        got = stats.units[u]
        assert (got.requests, got.responses, got.timeouts) == (
            want.requests,
            want.responses,
            want.timeouts,
        ), u
        assert (got.check_errors, got.below_resolution, got.unmeasured) == (
            want.check_errors,
            want.below_resolution,
            want.unmeasured,
        ), u
        assert got.exceptions == want.exceptions, u
        assert list(got.exceptions) == list(want.exceptions), u
        assert got.latencies.tobytes() == array("d", want.latencies).tobytes(), u
        assert got.request_times.tobytes() == array("d", want.request_times).tobytes(), u
        assert got.last_seen == want.last_seen, u
    assert (stats.noise_spans, stats.noise_bytes, stats.events) == (
        expected.noise_spans,
        expected.noise_bytes,
        expected.events,
    )
    assert stats._open == expected.open


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("stamps", list(Stamp))
def test_random_rows_counted_as_row_by_row(seed: int, stamps: Stamp) -> None:
    rng = random.Random(seed * 31 + len(stamps.name))
    resolution = rng.choice((0.0, 0.016))
    store = random_store(
        rng, 400, channels=rng.choice((1, 2)), stamps=stamps, resolution=resolution,
        odd_framing=seed % 2 == 1,
    )  # fmt: skip
    # rows arrive in batches, and open requests time out between updates
    full = FrameStore(store.streams)
    full.stamps, full.resolution = store.stamps, store.resolution
    stats, expected = Stats(full), RowByRow(full)
    done = 0
    while done < len(store):
        step = rng.choice((1, 7, 60, 500))
        for i in range(done, min(len(store), done + step)):
            full.copy_row(store, i)
            full.sync()
            full.partner[i] = store.partner[i]
            full.status[i] = store.status[i]
        done = min(len(store), done + step)
        for i in rng.sample(range(done), min(done, 5)):
            if full.status[i] == Status.OPEN:
                full.status[i] = rng.choice((Status.TIMEOUT, Status.OK, Status.OPEN))
        stats.update()
        expected.update()
        same(stats, expected)
    assert stats.table() == stats.table()


def test_latencies_at_the_edges_are_sorted_out_as_measure_does() -> None:
    for stamps in Stamp:
        for resolution in (0.0, 0.016):
            store = FrameStore()
            store.stamps, store.resolution = stamps, resolution
            stream = store.stream(0)
            for k, gap in enumerate((-0.5, -1e-9, 0.0, 5e-7, UNRESOLVED, 2e-6, 0.3, math.nan)):
                stream += bytes.fromhex("0103000000010a84") + bytes.fromhex("0103020000b844")
                t = float(k)
                store.add_row(0, 15 * k, 8, t, t + 0.001, int(Kind.REQUEST), 0)
                store.add_row(0, 15 * k + 8, 7, t + 0.001 + gap, t + 0.01, int(Kind.RESPONSE), 0)
                store.partner[2 * k], store.partner[2 * k + 1] = 2 * k + 1, 2 * k
            stats, expected = Stats(store), RowByRow(store)
            stats.update()
            expected.update()
            got, want = stats.units[1], expected.units[1]
            assert (got.below_resolution, got.unmeasured) == (
                want.below_resolution,
                want.unmeasured,
            ), (stamps, resolution)
            assert got.latencies.tobytes() == array("d", want.latencies).tobytes()


def test_the_demo_capture_counted_as_row_by_row() -> None:
    session = replay_file(DEMO_CAPTURE)
    expected = RowByRow(session.store)
    expected.update()
    same(session.stats, expected)  # counted as the capture was read, in several updates
