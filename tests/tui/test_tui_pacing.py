"""Tests that a replay at the original speed gives the capture read by read: a reader passes
runs of reads as one batch (`Reads`), seconds of the demo capture in one chunk, and a
paced feed must not hand over seconds of rows at once (`s` moved in 4-second jumps)."""

from __future__ import annotations

from sniffer.model import Chunk
from sniffer.session.session import DEMO_CAPTURE
from sniffer.sources import open_capture
from sniffer.sources.reads import Reads, batching
from sniffer.tui.feed import Pacing


def demo_chunks() -> list[Chunk]:
    with batching():
        return list(open_capture(DEMO_CAPTURE).chunks())


def test_the_demo_capture_comes_in_batches_spanning_seconds() -> None:
    batches = [c for c in demo_chunks() if isinstance(c, Reads)]
    assert batches, "the reader gave no batch: this test would prove nothing"
    longest = max(b.t_ends[-1] - b.t_ends[0] for b in batches)
    assert longest > 1.0


def test_a_paced_feed_gives_the_reads_of_a_batch_one_by_one() -> None:
    chunks = demo_chunks()
    reads = sum(len(c) if isinstance(c, Reads) else 1 for c in chunks)
    pacing = Pacing(speed=1e9)  # paced, but too fast to wait for anything
    paced = list(pacing.pace(chunks))
    assert not any(isinstance(c, Reads) for c in paced)
    assert len(paced) == reads
    times = [t for c in chunks for t in (c.t_ends if isinstance(c, Reads) else [c.t_end])]
    assert [c.t_end for c in paced] == times  # each read with its own time, in order
    assert b"".join(c.data for c in paced) == b"".join(c.data for c in chunks)


def test_as_fast_as_possible_the_batches_stay_whole() -> None:
    chunks = demo_chunks()
    assert list(Pacing(None).pace(chunks)) == chunks
