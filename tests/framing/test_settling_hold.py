"""A windowed replay drops its rows only where the framers stand settled at the end of
what they were given (`Session.settled`). The pipeline frames the batches of reads it
holds once they pass `Pipeline.hold_bytes` (512 KiB unless set): while a replay waits
for a settled moment it holds less (`SETTLING_HOLD_BYTES`), so that it looks at more
read ends, and the output stays that of one store holding every row."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from benchmarks.mixes import mix_frames, random_mix, write_reads
from sniffer.framing import pipeline as pipeline_module
from sniffer.framing.pipeline import Pipeline
from sniffer.model import Chunk
from sniffer.session import session as session_module
from sniffer.session.session import Session, open_session
from sniffer.sources.reads import Reads, batching
from tests.support.core import _compiled, running

LINE = random_mix(843779584).line


def _reads(path: Path) -> Iterator[Chunk]:
    """The capture's chunks as a replay reads them: runs of reads as batches."""
    _, capture = open_session(path, index=False)
    with batching(True):
        yield from capture.chunks()


@pytest.fixture(scope="module")
def slow_bus(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """4000 frames of 32 slaves at 38400 baud in 16 ms reads (the benchmark's mix
    843779584): a read holds a few frames, so most reads end inside one."""
    mix = random_mix(843779584)
    path = tmp_path_factory.mktemp("slow") / "slow.pcapng"
    write_reads(path, mix, mix_frames(mix, 4000))
    return path


def test_a_pipeline_frames_what_it_holds_past_its_own_hold(slow_bus: Path) -> None:
    chunks = list(_reads(slow_bus))
    whole = Pipeline(LINE)
    for chunk in chunks:
        whole.feed(chunk)
    whole.finish()
    held = Pipeline(LINE)
    first = 3  # the first read by read: the framer starts, the clock is measured
    for chunk in chunks[:first]:
        held.feed(chunk)
    held.sync()
    batch = chunks[first]
    assert isinstance(batch, Reads) and len(batch.data) > 1
    held.feed(batch)
    rows = len(held.store)
    assert held.holding  # under 512 KiB: held
    held.hold_bytes = len(batch.data) + 1
    held.feed(chunks[first + 1])  # past the pipeline's own hold: framed
    assert not held.holding and len(held.store) > rows
    held.hold_bytes = None
    for chunk in chunks[first + 2 :]:
        held.feed(chunk)
    held.finish()
    for name in ("offset", "length", "t", "t_end", "kind", "unit", "fc", "partner", "status"):
        assert getattr(held.store, name) == getattr(whole.store, name), name


@pytest.mark.parametrize("compiled", [True, False])
def test_a_replay_waiting_to_settle_holds_less_and_counts_the_same(
    slow_bus: Path, monkeypatch: pytest.MonkeyPatch, compiled: bool
) -> None:
    # holds of 8 KiB and 1 KiB stand for 512 KiB and 32 KiB on a file this small
    # (about 240 KiB, a batch of reads about 14 KiB)
    monkeypatch.setattr(pipeline_module, "HOLD_BYTES", 8192)
    monkeypatch.setattr(session_module, "SETTLING_HOLD_BYTES", 1024)
    tries: list[tuple[int | None, bool]] = []
    settled = Session.settled

    def noted(self: Session) -> bool:
        done = settled(self)
        tries.append((self.pipeline.hold_bytes, done))
        return done

    monkeypatch.setattr(Session, "settled", noted)

    def replay(window: int | None) -> tuple[list[int], str]:
        sizes: list[int] = []
        session, capture = open_session(slow_bus, index=False)
        session.stats.bound()
        session.ingest(
            capture.chunks(), window=window, segment=lambda s: sizes.append(len(s.store))
        )
        return sizes, session.stats.table()

    with running(_compiled() if compiled else None):
        whole = replay(None)
        tries.clear()
        windowed = replay(300)
    assert windowed[1] == whole[1]
    assert len(windowed[0]) >= 3 and sum(windowed[0]) == sum(whole[0])
    # after a try that found the framers unsettled, the next try looked at the end of a
    # smaller hold; after a cut (two tries in a row that found them settled: the test,
    # then new_segment's own), the pipeline holds as much as before
    assert any(not done for _, done in tries)
    for k in range(1, len(tries)):
        if not tries[k - 1][1]:
            assert tries[k][0] == 1024
        elif k >= 2 and tries[k - 2][1]:
            assert tries[k][0] is None
