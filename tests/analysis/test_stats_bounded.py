"""A headless live capture keeps its statistics bounded (`Stats.bound`, issue 11): the
latencies and poll gaps counted per figure the table prints instead of kept one by one.
The table must print the same figures as the whole arrays give."""

from __future__ import annotations

from collections import Counter

from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.analysis.stats import RECENT, UnitStats, latency_figure, latency_text
from sniffer.model import LineSettings
from sniffer.sources.synth import polling_frames
from tests.support.live import FAST, Run, reads

QS = (0, 0.5, 0.95, 1)

# latencies in seconds: anywhere, or on (and a hair off) the 0.05 ms boundaries where
# the printed tenth of a millisecond turns over (and the microseconds under 0.1 ms)
_boundary = st.tuples(st.integers(1, 40_000), st.sampled_from((-1e-12, 0.0, 1e-12))).map(
    lambda kb: kb[0] / 20_000 + kb[1]
)
# under 0.1 ms, the half microseconds where the printed thousandth turns over
_fine = st.tuples(st.integers(1, 220), st.sampled_from((-1e-15, 0.0, 1e-15))).map(
    lambda kb: kb[0] / 2_000_000 + kb[1]
)
latency = st.one_of(st.floats(1e-6, 2.0), _boundary, _fine)
# gaps between requests: anywhere, or on the 0.5 ms boundaries of the printed period
gap = st.one_of(
    st.floats(0.0, 5.0),
    st.integers(0, 10_000).map(lambda k: k / 2000),
    st.sampled_from((0.0005, 0.0015, 0.0025, 0.1005)),
)


def printed(unit: UnitStats) -> tuple[list[str], str]:
    """The unit's latency columns and period as `Stats.table` prints them."""
    period = unit.polling_period()
    return (
        ["-" if x is None else latency_text(x) for x in unit.latencies_ms(*QS)],
        "-" if period is None else f"{period * 1000:.0f}ms",
    )


@settings(max_examples=200, deadline=None)
@given(
    st.lists(latency, max_size=3000),
    st.floats(1e9, 2e9),
    st.lists(gap, max_size=3000),
    st.integers(0, 3000),
    st.integers(1, 500),
)
def test_bounded_statistics_print_the_figures_of_the_whole_arrays(
    latencies: list[float], t0: float, gaps: list[float], split: int, step: int
) -> None:
    times = [t0]
    for g in gaps:
        times.append(times[-1] + g)  # as the clock gives them: gaps of floats
    exact = UnitStats(1)
    exact.latencies.extend(latencies)
    exact.request_times.extend(times)
    # bounded after `split` values (a capture bounded from the start has split 0), then
    # fed in steps, as updates come
    bounded = UnitStats(1)
    bounded.latencies.extend(latencies[:split])
    bounded.request_times.extend(times[:split])
    bounded.bound()
    tallies = bounded.tallies
    assert tallies is not None
    for k in range(split, max(len(latencies), len(times)), step):
        tallies.add_latencies(latencies[k : k + step])
        tallies.add_requests(times[k : k + step])
    assert printed(bounded) == printed(exact)
    assert len(bounded.latencies) == len(bounded.request_times) == 0
    assert bounded.latency_count == len(latencies)
    assert bounded.request_count == len(times)
    assert bounded.newest_latencies(RECENT) == latencies[-RECENT:]
    assert bounded.newest_requests(RECENT) == times[-RECENT:]


def test_a_live_capture_over_many_segments_keeps_bounded_statistics() -> None:
    """The windowed live run's statistics: the table of the whole run, and nothing kept
    per answer or request (counts per printed figure, the newest RECENT values)."""
    char = FAST.char_time
    frames: list[tuple[bytes, float]] = []
    t = 0.0
    for f in polling_frames(12_000, line=FAST):
        frames.append((f.raw, t))
        t += (len(f.raw) + 3.5) * char
    chunks = reads(frames, 0.001)
    batches = [chunks[k : k + 3] for k in range(0, len(chunks), 3)]
    whole = Run(FAST, batches, None)
    windowed = Run(FAST, batches, 500)
    assert windowed.capture.segments >= 15
    assert not whole.session.stats.bounded and windowed.session.stats.bounded
    assert windowed.session.stats.table() == whole.session.stats.table()
    values = kept = 0
    for u, unit in windowed.session.stats.units.items():
        full = whole.session.stats.units[u]
        tallies = unit.tallies
        assert tallies is not None
        assert len(unit.latencies) == len(unit.request_times) == 0
        assert tallies.latency_ms == Counter(latency_figure(x * 1000) for x in full.latencies)
        assert len(tallies.recent_latencies) <= RECENT >= len(tallies.recent_requests)
        assert list(tallies.recent_latencies) == list(full.latencies[-RECENT:])
        assert tallies.requests == len(full.request_times)
        values += len(full.latencies) + len(full.request_times)
        kept += len(tallies.latency_ms) + len(tallies.gap_ms)
    assert values > 5000 and kept < values / 10  # figures, not values


def test_a_tui_capture_keeps_every_value() -> None:
    line = LineSettings(baud=921600, parity="N", stopbits=1, mode="rtu")
    frames = [(f.raw, f.t) for f in polling_frames(200, line=line)]
    run = Run(FAST, [reads(frames, 0.001)], None)
    units = run.session.stats.units.values()
    assert all(u.tallies is None for u in units)
    assert sum(len(u.request_times) for u in units) > 50  # every value kept, not tallied
