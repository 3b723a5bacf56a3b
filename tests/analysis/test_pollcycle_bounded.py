"""The poll cycle in bounded memory (issue 29): a request's times are kept while they are
few (EXACT), then its waits are counted in buckets. The table is then that of every
wait within the bound the buckets give (the period to half a bucket, the jitter to a
bucket, the gaps counted as at least the sure ones, with the unsure ones said), the
same where the buckets hold each wait exactly; what it keeps does not grow with the
sendings; the requests followed are capped, the others counted and said."""

from __future__ import annotations

import random
import tracemalloc
from array import array
from itertools import accumulate, pairwise, repeat
from operator import mul

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer import core
from sniffer.analysis import pollcycle
from sniffer.analysis.pollcycle import (
    GAP_FACTOR,
    Poll,
    PollCycles,
    _poll,
    _Sent,
    cycle_table,
    poll_cycles,
)
from sniffer.analysis.stats import nearest_rank
from sniffer.framing.store import FrameStore
from sniffer.session.session import DEMO_CAPTURE, replay_file
from sniffer.vocab import Kind
from tests.support.core import _compiled

T0 = 1_764_000_000.0  # epoch stamps: their waits are whole multiples of 2**-22 s


def _exact(times: list[float]) -> tuple[float, float, list[tuple[float, float]]]:
    """The definition: period, jitter and gaps (start, length) of every wait."""
    waits = [b - a for a, b in pairwise(times)]
    period = nearest_rank(waits, 0.5)
    high, low = nearest_rank(waits, 0.95), nearest_rank(waits, 0.05)
    assert period is not None and high is not None and low is not None
    limit = GAP_FACTOR * period
    gaps = [(a, b - a) for a, b in pairwise(times) if b - a > limit]
    return period, high - low, gaps


def _bucketed(times: list[float], block: int) -> Poll:
    """The line of a request sent at `times`, fed `block` times at a time, bucketed."""
    sent = _Sent("read holding 0", 3)
    for lo in range(0, len(times), block):
        sent.feed(array("d", times[lo : lo + block]))
    assert sent.times is None and sent.waits is not None  # (bucketed, as meant)
    return _poll(1, sent, 0.0)


def _check(poll: Poll, times: list[float]) -> None:
    period, jitter, gaps = _exact(times)
    error = poll.quantum  # 0.0: every wait counted exactly
    assert abs(poll.period - period) <= error / 2
    assert abs(poll.jitter - jitter) <= error
    assert poll.gap_count <= len(gaps) <= poll.gap_count + poll.unsure_gaps
    if not error:
        assert (poll.period, poll.jitter, poll.unsure_gaps) == (period, jitter, 0)
        assert poll.gap_count == len(gaps)
    listed = [(g.start, g.length) for g in poll.gaps]
    assert set(listed) <= set(gaps)  # a gap listed is a gap
    if not poll.gaps_cut and not poll.unsure_gaps:  # and they are the first
        assert listed[:3] == gaps[:3]


# (the limits set are the same for every example)
@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    seed=st.integers(0, 1 << 30),
    period=st.floats(0.005, 20.0),
    spread=st.floats(0.0, 1.5),
    stalls=st.floats(0.0, 0.05),
    rounding=st.sampled_from([1e-6, 1e-3, 0.016]),
    block=st.sampled_from([1, 7, 512]),
)
def test_bucketed_waits_are_within_the_bound_of_every_wait(
    seed: int,
    period: float,
    spread: float,
    stalls: float,
    rounding: float,
    block: int,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # small limits, so that a few thousand sendings go through every stage: times, each
    # distinct wait apart, buckets, buckets made coarser
    monkeypatch.setattr(pollcycle, "EXACT", 64)
    monkeypatch.setattr(pollcycle, "SPARSE", 128)
    monkeypatch.setattr(pollcycle, "BUCKETS", 256)
    monkeypatch.setattr(pollcycle, "FAR", 32)
    rng = random.Random(seed)
    times, t = [], T0
    for _ in range(rng.randrange(100, 3000)):
        t += period * (1 + spread * (rng.random() - 0.5))
        if rng.random() < stalls:
            t += period * rng.uniform(1, 50)  # the master stopped a while
        times.append(round(t / rounding) * rounding)  # stamps of that resolution
    _check(_bucketed(times, block), times)


def test_steady_polls_of_epoch_stamps_stay_exact_past_their_times(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # few distinct waits (stamps to the ms): each counted apart, so the table is exact
    monkeypatch.setattr(pollcycle, "EXACT", 1000)
    rng = random.Random(29)
    times, t = [], T0
    for k in range(20_000):
        t += 0.25 + rng.choice((-0.002, -0.001, 0.0, 0.001, 0.002))
        if k in (5000, 15000):
            t += 2.0
        times.append(round(t, 3))
    poll = _bucketed(times, 4096)
    assert poll.quantum == 0.0
    _check(poll, times)
    assert poll.gap_count == 2 and poll.unsure_gaps == 0


def test_an_error_the_printed_step_can_show_is_marked() -> None:
    poll = Poll(1, 3, "read holding 0", 9, 0.25, 0.01, (), 0.0, 1.0, quantum=0.0004)
    assert poll.period_text() == "250ms" and poll.jitter_text() == "10ms"
    poll = Poll(1, 3, "read holding 0", 9, 0.25, 0.01, (), 0.0, 1.0, quantum=0.002)
    assert poll.period_text() == "≈250ms" and poll.jitter_text() == "≈10ms"
    poll = Poll(1, 3, "read holding 0", 9, 0.25, 0.01, (), 0.0, 1.0, more_gaps=4, unsure_gaps=2)
    assert poll.gaps_text() == "≥4"


# -- memory ------------------------------------------------------------------------------


def _blocks(sendings: int, polls: int = 20) -> list[list[array[float]]]:
    """`sendings` requests of `polls` polls (every 0.2-2 s, 5% jitter, stamps to the µs,
    a stall of 60 periods now and then), in blocks as the windowed replay hands them
    over: for each block, each poll's times."""
    rng = random.Random(29)
    periods = [rng.uniform(0.2, 2.0) for _ in range(polls)]
    # the waits, in periods: drawn once, taken from at another place by each poll
    factors = [60.0 if rng.random() < 0.001 else rng.uniform(0.95, 1.05) for _ in range(1 << 16)]
    per_block = 4096 // polls
    clocks = [T0] * polls
    out = []
    for b in range(sendings // (per_block * polls)):
        row = []
        for k in range(polls):
            at = (b * per_block + 977 * k) % (len(factors) - per_block)
            steps = map(mul, factors[at : at + per_block], repeat(periods[k]))
            block = array("d", map(round, accumulate(steps, initial=clocks[k]), repeat(6)))
            del block[0]  # (the time before: sent in the block before)
            clocks[k] = block[-1]
            row.append(block)
        out.append(row)
    return out


@pytest.mark.slow
def test_what_the_poll_cycle_keeps_does_not_grow_with_the_sendings() -> None:
    # 8 polls, 280k sendings (35k a poll: past the 32,768 kept exactly), then 280k more:
    # keeping each time would take 2.2 MB more; the buckets are allocated once (256 KB a
    # poll), the distinct waits kept apart and the first gaps are capped, so what is kept
    # stays within a small margin (tracemalloc: the bytes still allocated after each)
    blocks = _blocks(560_000, polls=8)
    cycles = PollCycles()
    sent = [_Sent(f"read holding {k}", 3) for k in range(len(blocks[0]))]
    cycles.sendings[1] = {(3, k, 1): s for k, s in enumerate(sent)}
    kept = []
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for n, row in enumerate(blocks, 1):
            for s, times in zip(sent, row, strict=True):
                cycles._feed(s, times)
            if n in (len(blocks) // 2, len(blocks)):
                kept.append(tracemalloc.get_traced_memory()[0] - before)
    finally:
        tracemalloc.stop()
    assert all(s.times is None for s in sent)  # (all past EXACT: counted in buckets)
    assert sum(s.count for s in sent) > 540_000
    small, large = kept
    assert small < len(sent) * (4 * pollcycle.BUCKETS + 200_000), small
    assert large - small < 1_000_000, (small, large)


# -- the requests followed -----------------------------------------------------------------


def _store(distinct: int, rounds: int) -> FrameStore:
    """Unit 1 polled for `distinct` registers in turn, `rounds` times over."""
    store = FrameStore()
    stream = store.stream(0)
    t = T0
    for _ in range(rounds):
        for k in range(distinct):
            raw = with_crc(bytes([1, 3, k >> 8, k & 0xFF, 0, 1]))
            stream += raw
            store.add_row(0, len(stream) - len(raw), len(raw), t, t, int(Kind.REQUEST), 0)
            t += 0.01
    store.sync()
    return store


def test_requests_past_the_cap_are_counted_and_said(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(pollcycle, "MAX_REQUESTS", 50)
    cycles = poll_cycles(_store(80, 4))
    assert len(cycles[1].polls) == 50 and cycles[1].unfollowed == 30 * 4
    table = cycle_table(cycles)
    assert "120 sendings of other requests counted, not followed (past 50 requests" in table
    # under the cap, nothing is said
    monkeypatch.setattr(pollcycle, "MAX_REQUESTS", 80)
    cycles = poll_cycles(_store(80, 4))
    assert len(cycles[1].polls) == 80 and cycles[1].unfollowed == 0
    assert "not followed" not in cycle_table(cycles)


def test_the_times_kept_by_all_requests_are_capped(monkeypatch: pytest.MonkeyPatch) -> None:
    # many requests each under EXACT: past TIMES_BUDGET the largest are bucketed, and the
    # table stays within their bound
    monkeypatch.setattr(pollcycle, "TIMES_BUDGET", 2000)
    store = _store(40, 100)
    found = PollCycles()
    found.add(store)
    assert found.timed <= 2000
    assert any(s.times is None for s in found.sendings[1].values())
    times = [store.t[i] for i in range(0, len(store), 40)]
    for poll in found.cycles()[1].polls:
        if poll.what == "read holding 0":
            _check(poll, times)


# -- a capture's table, its requests counted in buckets --------------------------------


def test_the_demo_table_is_the_same_with_every_request_counted(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # every request past its 4th sending counted instead of kept: its distinct waits
    # each apart (epoch stamps: exact), so the printed table is the same, byte for byte
    store = replay_file(DEMO_CAPTURE).store
    exact = poll_cycles(store)
    monkeypatch.setattr(pollcycle, "EXACT", 4)
    counted = poll_cycles(store)
    assert cycle_table(counted) == cycle_table(exact)
    # and in buckets of 2**16 from zero: each figure within the bound it says
    monkeypatch.setattr(pollcycle, "SPARSE", 4)
    monkeypatch.setattr(pollcycle, "BUCKETS", 1 << 10)
    bucketed = poll_cycles(store)
    assert bucketed.keys() == exact.keys()
    for unit, cycle in exact.items():
        found = {p.what: p for p in bucketed[unit].polls}
        for p in cycle.polls:
            q = found[p.what]
            assert q.count == p.count and q.retries == p.retries
            if q.period_bound or q.period == float("inf"):
                continue  # (a bound of coarse stamps: from the same median within its error)
            assert abs(q.period - p.period) <= q.quantum / 2
            assert abs(q.jitter - p.jitter) <= q.quantum
            assert q.gap_count <= p.gap_count <= q.gap_count + q.unsure_gaps


def _densified(
    far: dict[int, int], span: int, quantum: float, exact: bool
) -> tuple[list[int], dict[int, int], float, bool]:
    """`_Waits.densify` as it was written first, a Python step a key: the reference."""
    items = sorted(far.items())
    n = sum(c for _, c in items)
    rank, seen, high = n * 99 // 100, 0, 1
    for k, c in items:
        seen += c
        if seen > rank:
            high = max(1, 2 * k)
            break
    shift = 0
    while (span << shift) < high:
        shift += 1
    dense = [0] * span
    kept: dict[int, int] = {}
    low = (1 << shift) - 1
    for k, c in items:
        if k & low:
            exact = False
        k >>= shift
        if 0 <= k < span:
            dense[k] += c
        else:
            kept[k] = kept.get(k, 0) + c
    return dense, kept, quantum * (1 << shift), exact


@settings(max_examples=300, deadline=None)
@given(
    far=st.dictionaries(
        st.one_of(
            st.integers(-50, 5000),
            st.integers(-(2**40), 2**40),
            # about a second's wait, either side of one 30-bit digit; past 61 bits
            st.integers(2**30 - 5000, 2**30 + 5000),
            st.integers(2**61 - 2, 2**64),
            st.integers(-(2**64), -(2**61) + 2),
        ),
        st.one_of(st.integers(0, 1000), st.integers(2**32 - 2, 2**62)),
        max_size=300,
    ),
    span=st.sampled_from((1, 2, 8, 64, 1024)),
    exact=st.booleans(),
    compiled=st.booleans(),
)
def test_densify_buckets_as_its_reference_does(
    far: dict[int, int], span: int, exact: bool, compiled: bool
) -> None:
    """The waits kept apart go to the same buckets, the same far ones, with the same
    width and exactness, as the first, key-by-key writing of `densify` puts them:
    negative and huge keys (a clock set back, long gaps), keys of no count, ties at the
    99th percentile; with either core (the compiled one hands keys or counts past 61
    bits, and a bucket past 32, back to Python)."""
    waits = pollcycle._Waits(span=span, exact=exact)
    waits.far.update(far)  # (keys of a count of 0 too)
    want_dense, want_far, want_quantum, want_exact = _densified(
        dict(waits.far), span, waits.quantum, exact
    )
    assume(max(want_dense, default=0) < 2**32)  # (no core counts past a uint32 bucket)
    pollcycle.FAR, saved = 1 << 30, pollcycle.FAR  # (no coarsening: densify alone)
    saved_core = core.FAST
    core.FAST = _compiled() if compiled else None
    try:
        waits.densify()
    finally:
        pollcycle.FAR = saved
        core.FAST = saved_core
    assert list(waits.dense) == want_dense
    assert dict(waits.far) == want_far
    assert (waits.quantum, waits.exact) == (want_quantum, want_exact)
