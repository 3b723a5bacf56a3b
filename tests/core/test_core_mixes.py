"""Both cores give the same rows, pairs, statistics and warnings on the benchmark's bus
mixes (`benchmarks/mixes.py`): random slaves, function codes 1-6, 15 and 16, fresh
values, exceptions, timeouts, stray bytes, any line format, and reads that cut frames
anywhere (16 ms reads of a USB adapter, reads of random sizes); and the compiled core
frames a frame split across reads itself, as the pure-Python core's fast paths do.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import ModuleType

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.mixes import Mix, issue_mix, mix_frames, random_mix, write_reads
from sniffer.framing.lengths import RtuLengths
from sniffer.framing.serial import _Timeline
from sniffer.model import LineSettings
from tests.core.test_core import _assert_same, _ingest
from tests.support.core import _compiled


@pytest.fixture
def compiled() -> ModuleType:
    return _compiled()


def _file(folder: Path, mix: Mix, frames: int) -> Path:
    path = folder / f"{mix.name}.pcapng"
    write_reads(path, mix, mix_frames(mix, frames))
    return path


@pytest.mark.parametrize("seed", [3, 11, 29, 41, 77, 90])
def test_random_mixes_are_the_same_with_either_core(
    tmp_path: Path, compiled: ModuleType, seed: int
) -> None:
    mix = random_mix(seed)
    path = _file(tmp_path, mix, 1500)
    for batched in (True, False):
        pure = _assert_same(path, compiled, batched)
        assert len(pure.store) >= 1500


def test_the_bus_of_issue_29_is_the_same_with_either_core(
    tmp_path: Path, compiled: ModuleType
) -> None:
    pure = _assert_same(_file(tmp_path, issue_mix(), 3000), compiled)
    kinds = set(pure.store.kind)
    assert {1, 2, 3} <= kinds  # requests, answers and exceptions


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10**9), frames=st.integers(20, 400))
def test_any_mix_is_the_same_with_either_core(
    tmp_path_factory: pytest.TempPathFactory, seed: int, frames: int
) -> None:
    fast = _compiled()
    path = _file(tmp_path_factory.mktemp("mix"), random_mix(seed), frames)
    _assert_same(path, fast)


def _clean(reads: str, read_max: int = 0) -> Mix:
    """A bus without faults: every slow-path search is one a split frame causes."""
    line = LineSettings(baud=38400, bytesize=8, parity="E", stopbits=1, mode="rtu")
    weights = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    return Mix("clean", 5, line, (1, 2, 9), weights, 0.0, 0.0, 0.0, reads, read_max)


def _counter(monkeypatch: pytest.MonkeyPatch, cls: type, name: str) -> list[int]:
    """Counts the calls of `cls.name` (one item, the count)."""
    count = [0]
    method = getattr(cls, name)

    def counted(self: object, *args: object) -> object:
        count[0] += 1
        return method(self, *args)

    monkeypatch.setattr(cls, name, counted)
    return count


def _split_and_searched(monkeypatch: pytest.MonkeyPatch) -> tuple[list[int], list[int]]:
    """Counters of the frames Python times by the reads' spans (`_Timeline.start_time`:
    a frame begun in an earlier read, framed by its fast paths or its slow path, and any
    slow-path row) and of its slow path's searches (`RtuLengths.candidates`)."""
    return (
        _counter(monkeypatch, _Timeline, "start_time"),
        _counter(monkeypatch, RtuLengths, "candidates"),
    )


@pytest.mark.parametrize(("reads", "read_max"), [("usb", 0), ("random", 64)])
def test_the_compiled_core_frames_frames_split_across_reads(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch, reads: str, read_max: int
) -> None:
    path = _file(tmp_path, _clean(reads, read_max), 2000)
    timed, searched = _split_and_searched(monkeypatch)
    pure = _ingest(path, None)
    split, pure_searches = timed[0], searched[0]
    timed[0] = searched[0] = 0
    comp = _ingest(path, compiled)
    # the pure-Python core's fast paths take a frame begun in an earlier read (timed by
    # the reads' spans) without a search; the compiled core frames those itself, the
    # same rows, all but a frame begun in a read that is neither the newest before the
    # call nor the one the scan stood in (three short reads in a row: a few in 2000)
    assert split > 100
    assert pure_searches * 50 < split
    assert (timed[0] + searched[0]) * 50 < split
    assert comp.store.t == pure.store.t
    assert comp.store.partner == pure.store.partner
    assert comp.store.status == pure.store.status


@pytest.mark.parametrize("seed", [843779584, 186255415])
def test_slow_buses_of_many_slaves_keep_their_split_frames_compiled(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch, seed: int
) -> None:
    """32 slaves at 38400 baud in 16 ms reads, timeouts among them (two of the
    benchmark's mixes): a read holds a few frames, so about one frame in three is split
    across reads, and a request that times out is followed by a poll that may be of the
    same unit and code. The compiled core frames those itself (its fast paths, timing
    them by the reads' spans, or its search), the rows the same."""
    path = _file(tmp_path, random_mix(seed), 3000)
    timed, searched = _split_and_searched(monkeypatch)
    _ingest(path, None)
    split = timed[0]
    before = timed[0] + searched[0]
    _assert_same(path, compiled)
    # _assert_same ran both cores: what the compiled one left to Python is the rest
    left = timed[0] + searched[0] - 2 * before
    assert split > 500  # the pure-Python core timed each split frame by the spans
    assert left * 100 < split


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 10**9),
    frames=st.integers(50, 500),
    baud=st.sampled_from((9600, 19200, 38400)),
    timeouts=st.sampled_from((0.0, 0.01, 0.05, 0.2)),
    read_max=st.sampled_from((0, 3, 16, 64)),
)
def test_split_frames_of_any_slow_bus_are_the_same_with_either_core(
    tmp_path_factory: pytest.TempPathFactory,
    seed: int,
    frames: int,
    baud: int,
    timeouts: float,
    read_max: int,
) -> None:
    """A random bus made slow (reads of 16 ms, or of 1..read_max bytes, cut most frames)
    with timeouts up to one poll in five: the same rows, times, pairs and statistics
    from the compiled core as from the pure-Python one."""
    mix = random_mix(seed)
    mix = replace(
        mix,
        line=replace(mix.line, baud=baud),
        timeout_rate=timeouts,
        reads="random" if read_max else "usb",
        read_max=read_max,
    )
    path = _file(tmp_path_factory.mktemp("slow"), mix, frames)
    _assert_same(path, _compiled())
