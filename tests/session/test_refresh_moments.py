"""What a replay shows does not depend on when it looks.

`Session.ingest` refreshes the pairing and the statistics every quarter second of the
reader's own time, so a slower machine looks earlier in the capture. The stamps'
resolution is measured from the first stamps (`Pipeline.clock`); every wait the pairing
and the statistics judge must be judged against the resolution the whole capture gets,
whenever the refreshes come. Found by CI on a loaded machine: a refresh that came while
the clock was still learning counted 23 answers as latencies the stamps cannot give and
one as a measured 62 ms, where the capture's 92.6 ms resolution makes all 32 bounds.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings

from sniffer.model import Chunk
from sniffer.outputs.mqtt.publish import BusPublisher, PublisherOptions, publish_replay
from sniffer.outputs.mqtt.target import parse_target
from sniffer.session.session import Session, open_session
from sniffer.sources.reads import Reads, batching
from tests.core.test_core import RANDOM_RECORDING, _cut, _random_recording, _traffic
from tests.outputs.test_ha_discovery import KeepingLink
from tests.support.core import KINDS
from tests.support.reads import COLUMNS, _recording

MIXES = [["read"], KINDS, ["read", "echo", "exception", "broadcast", "write"]]


def _replayed(path: Path, every: float, batched: bool) -> Session:
    """The capture ingested with a refresh after every chunk (`every` 0), or none but
    the last (`every` infinite)."""
    session, capture = open_session(path, index=False)
    session.batch_reads = batched
    session.ingest(capture.chunks(), every=every)
    return session


def _assert_alike(path: Path, batched: bool) -> Session:
    eager, lazy = _replayed(path, 0.0, batched), _replayed(path, float("inf"), batched)
    for name in COLUMNS:
        assert getattr(eager.store, name) == getattr(lazy.store, name), name
    assert eager.store.resolution == lazy.store.resolution
    assert eager.stats.table() == lazy.stats.table()
    assert (eager.warnings, eager.notes) == (lazy.warnings, lazy.notes)
    return lazy


def test_the_capture_ci_found_counts_alike_however_often_it_is_refreshed(
    tmp_path: Path,
) -> None:
    path = tmp_path / "r.pcapng"
    frames = _traffic(215, 47, MIXES[2])
    cuts = [12, 5, 12, 68, 69, 5, 42, 6, 38, 37, 74, 52, 79]  # the reads' sizes, in turn
    _recording(path, _cut(frames, cuts, 0.05), "pcapng 147")
    lazy = _assert_alike(path, False)
    line = lazy.stats.timing_line()
    assert "resolution 92.6 ms" in line
    assert "32 answer(s) faster than that, only bounded" in line
    assert "the stamps cannot give" not in line


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=RANDOM_RECORDING)
def test_random_traffic_counts_alike_however_often_it_is_refreshed(
    tmp_path_factory: pytest.TempPathFactory, case: dict[str, Any]
) -> None:
    path = tmp_path_factory.mktemp("moments") / "r.pcapng"
    _assert_alike(path, _random_recording(path, case))


def _published(path: Path, every: float) -> dict[str, list[bytes | str]]:
    """What `replay --mqtt` publishes of the capture, topic by topic, refreshing after
    every chunk (`every` 0) or only at the end, through a link with no broker."""
    session, capture = open_session(path, index=False)
    link = KeepingLink(parse_target("mqtt://127.0.0.1/site/r", bus="r"))
    publisher = BusPublisher(link, session, {}, PublisherOptions(bus="r"), info=capture.info)
    assert link._on_connect_hook is not None
    link._on_connect_hook()
    publish_replay(session, capture.chunks(), publisher, refresh_every=every)
    publisher.rows(final=True)
    topics: dict[str, list[bytes | str]] = {}
    for topic, payload in link.messages:
        if not topic.endswith("/interface"):  # (names the publishing session: new each run)
            topics.setdefault(topic, []).append(payload)
    return topics


def test_what_a_replay_publishes_does_not_depend_on_when_it_refreshes(tmp_path: Path) -> None:
    path = tmp_path / "r.pcapng"
    frames = _traffic(215, 47, MIXES[2])
    cuts = [12, 5, 12, 68, 69, 5, 42, 6, 38, 37, 74, 52, 79]
    _recording(path, _cut(frames, cuts, 0.05), "pcapng 147")
    eager, lazy = _published(path, 0.0), _published(path, float("inf"))
    assert eager.keys() == lazy.keys()
    statuses = [t for t in lazy if t.endswith("/status")]
    assert len(statuses) == 6  # the bus's, and units 0, 1, 2, 7 and 247
    for topic in lazy:
        if topic in statuses or topic.endswith("/findings"):  # (as often as it refreshes)
            assert eager[topic][-1] == lazy[topic][-1], topic
        else:  # each exchange's events, exceptions as they come
            assert eager[topic] == lazy[topic], topic
    events = [json.loads(p) for p in lazy["site/r/events"]]
    exceptions = [e for e in events if e["kind"] == "exception"]
    assert len(exceptions) == 4
    # each exception's latency a bound of the 92.6 ms stamps (one or two steps), never a value
    assert {e["latency_ms"] for e in exceptions} == {None}
    assert {e["latency_max_ms"] for e in exceptions} <= {93.0, 186.0}
    units = [json.loads(lazy[t][-1]) for t in statuses if "/unit/" in t]
    assert {u["latency_median_ms"] for u in units} == {None}  # every answer only bounded


def test_a_replay_measuring_its_stamps_still_reads_them_in_batches(tmp_path: Path) -> None:
    """The stamps are measured from the first chunks before any is framed, and the reader
    decides at its first chunk whether it hands over batches of reads (the compiled
    readers' fast way): the measuring must start it as `ingest` reads it. (When it did
    not, 1M frames took 28 s of CPU instead of 0.5 s, every row the same.)"""
    path = tmp_path / "r.pcapng"
    reads = _cut(_traffic(7, 400, MIXES[1]), [16], 0.0)
    _recording(path, reads, "pcapng 147")
    stores = []
    for batched in (True, False):
        session, capture = open_session(path, index=False)
        session.batch_reads = batched
        handed: list[Chunk] = []

        def counted(chunks: Iterable[Chunk], into: list[Chunk] = handed) -> Iterator[Chunk]:
            for chunk in chunks:
                into.append(chunk)
                yield chunk

        session.ingest(counted(capture.chunks()))
        assert session.state.chunks == len(reads)  # every read, counted one by one
        if batched:  # batches of many reads each
            assert len(handed) * 20 < len(reads) and isinstance(handed[0], Reads)
        else:
            assert len(handed) == len(reads) and not any(isinstance(c, Reads) for c in handed)
        stores.append(session.store)
    for name in COLUMNS:
        assert getattr(stores[0], name) == getattr(stores[1], name), name


@pytest.mark.parametrize(
    ("seed", "n", "cuts", "learns"),
    [
        # the capture CI found: too few reads for the clock, judged at the end
        (215, 47, [12, 5, 12, 68, 69, 5, 42, 6, 38, 37, 74, 52, 79], False),
        # enough reads: judged as the clock stops learning, counted as they come after
        (3, 400, [16], True),
    ],
)
def test_a_live_session_judges_its_first_answers_once_the_clock_has_learnt(
    tmp_path: Path, seed: int, n: int, cuts: list[int], learns: bool
) -> None:
    """Live, the rows come before the stamps' resolution is measured (the first 64
    reads): the answers counted then wait, said in the timing line, and are judged once
    it is, so that the table ends as a replay's, which measures the stamps first."""
    path = tmp_path / "r.pcapng"
    _recording(path, _cut(_traffic(seed, n, MIXES[2]), cuts, 0.05), "pcapng 147")
    live, capture = open_session(path, index=False)
    said: list[str] = []
    with batching(False):
        for chunk in capture.chunks():
            live.feed(chunk)
            live.refresh()  # as a live capture does after each pump
            if live.pipeline.clock.learning:
                said.append(live.stats.timing_line())
    waiting = "answer(s) wait until the stamps' resolution is measured"
    assert any(waiting in line for line in said)
    assert live.pipeline.clock.learning is not learns
    live.finish()
    assert waiting not in live.stats.timing_line()
    assert live.stats.table() == _replayed(path, float("inf"), False).stats.table()
