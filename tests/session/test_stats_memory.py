"""`replay --stats` counts each unit's latencies and request gaps in bounded form when no
sidecar keeps their values (`Stats.bound`, `Tallies`): what they hold grows with the
number of distinct printed figures, not with the frames (issue 29). Measured with
tracemalloc, so the figure is bytes the tallies keep, not time."""

from __future__ import annotations

import random
import tracemalloc
from array import array

from sniffer.analysis.stats import Tallies


def _kept_by_tallies(frames: int) -> int:
    """Bytes still allocated after `frames` latencies and request times were counted,
    in blocks of 4096 as the windowed replay hands them over."""
    rng = random.Random(29)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        tallies = Tallies()
        t = 1768464000.0
        for _ in range(frames // 4096):
            # latencies of 0.02-400 ms, requests every 1-600 ms
            tallies.add_latencies(array("d", (rng.uniform(2e-5, 0.4) for _ in range(4096))))
            times = array("d")
            for _ in range(4096):
                t += rng.uniform(0.001, 0.6)
                times.append(t)
            tallies.add_requests(times)
        after = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert tallies.latencies == tallies.requests == frames // 4096 * 4096
    return after - before


def test_bounded_statistics_do_not_grow_with_the_frames() -> None:
    # every printed figure of those ranges is met within the first N values, so 4N more
    # values add no key: the kept bytes stay within a margin far below the 8 bytes a
    # value (2 MB for 4N = 262144 values) that keeping each one would take
    n = 1 << 16
    small, large = _kept_by_tallies(n), _kept_by_tallies(4 * n)
    assert large - small < 64 * 1024, (small, large)
