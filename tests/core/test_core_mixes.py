"""Both cores give the same rows, pairs, statistics and warnings on the benchmark's bus
mixes (`benchmarks/mixes.py`): random slaves, function codes 1-6, 15 and 16, fresh
values, exceptions, timeouts, stray bytes, any line format, and reads that cut frames
anywhere (16 ms reads of a USB adapter, reads of random sizes); and the compiled core
frames a frame split across reads itself, where the pure-Python core's slow path does.
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


@pytest.mark.parametrize(("reads", "read_max"), [("usb", 0), ("random", 64)])
def test_the_compiled_core_frames_frames_split_across_reads(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch, reads: str, read_max: int
) -> None:
    path = _file(tmp_path, _clean(reads, read_max), 2000)
    searches = 0
    search = RtuLengths.candidates

    def counted(self: RtuLengths, *args: object) -> tuple[int, int, bool]:
        nonlocal searches
        searches += 1
        return search(self, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(RtuLengths, "candidates", counted)
    pure = _ingest(path, None)
    split = searches
    searches = 0
    comp = _ingest(path, compiled)
    # the pure-Python core's fast paths leave a frame begun in an earlier read to the
    # slow path's search; the compiled core frames those itself, the same rows, all but
    # a frame begun in a read that is neither the newest before the call nor the one the
    # scan stood in (three short reads in a row: a few in 2000 frames)
    assert split > 100
    assert searches * 50 < split
    assert comp.store.t == pure.store.t
    assert comp.store.partner == pure.store.partner
    assert comp.store.status == pure.store.status


def _searches(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """A counter of the slow path's searches (`RtuLengths.candidates` calls) in Python."""
    count = [0]
    search = RtuLengths.candidates

    def counted(self: RtuLengths, *args: object) -> tuple[int, int, bool]:
        count[0] += 1
        return search(self, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(RtuLengths, "candidates", counted)
    return count


@pytest.mark.parametrize("seed", [843779584, 186255415])
def test_slow_buses_of_many_slaves_keep_their_split_frames_compiled(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch, seed: int
) -> None:
    """32 slaves at 38400 baud in 16 ms reads, timeouts among them (two of the
    benchmark's mixes): a read holds a few frames, so about one frame in three is split
    across reads, and a request that times out is followed by a poll that may be of the
    same unit and code. The compiled core frames those itself (its search, where the
    fast paths cannot take a frame begun in an earlier read), the rows the same."""
    path = _file(tmp_path, random_mix(seed), 3000)
    searches = _searches(monkeypatch)
    _ingest(path, None)
    split = searches[0]
    searches[0] = 0
    _assert_same(path, compiled)
    # _assert_same ran both cores: what the compiled one left to Python is the rest
    left = searches[0] - split
    assert split > 500  # the pure-Python core searched at each split frame
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
