"""The same bytes on the line give the same frames, pairs and verdicts however the
adapter cut them into reads: one read per frame, or a read every 0.5, 4 or 16 ms that
cuts frames anywhere, with either core. Which path frames a row (the framer's fast path,
which pairs the answer its open request predicts as it frames it, or the search, whose
rows the `Pairer` pairs) must not show in the result.

Found on a late answer: a request, silence past the response timeout, then its answer.
Framed whole, it was paired and flagged late; split across two reads, the request was
timed out, its answer called an orphan and the master's next poll a retry."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import ModuleType

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.mixes import Mix, mix_frames, random_mix, write_frames, write_reads
from sniffer import core
from sniffer.framing import serial as framing
from sniffer.model import Chunk
from sniffer.session.session import Session, open_session
from sniffer.sources.reads import batching
from sniffer.vocab import Flag, Status
from tests.session.test_replay_window import (
    ANSWER,
    LINE,
    READ,
    STEPS,
    T0,
    WRITE,
    reads_of,
    recorded,
)
from tests.support.core import _compiled

# what a row's verdict is made of, beside its bytes and kind
VERDICT_FLAGS = Flag.LATE | Flag.RETRY | Flag.ANSWERED_BROADCAST
TIMEOUT = 0.2 + 256 * LINE.char_time  # the default response timeout at LINE (0.347 s)
# a late exchange: the answer (or the echo) comes well past the timeout, with nothing
# between; `late_write`'s echo past the timeout is the master's retry, not an answer
LATE = {"late": [READ, ANSWER], "late_write": [WRITE, WRITE]}


def script(steps: list[str], pauses: list[float], late: float) -> list[tuple[bytes, float]]:
    char = LINE.char_time
    frames: list[tuple[bytes, float]] = []
    t = 0.0
    for k, step in enumerate(steps):
        parts = LATE.get(step) or STEPS[step]
        for n, raw in enumerate(parts):
            if n and step in LATE:
                t += late
            frames.append((raw, t))
            t += len(raw) * char + 0.004
        t += pauses[k % len(pauses)]
    return frames


def per_frame(frames: list[tuple[bytes, float]]) -> list[Chunk]:
    """One read per frame, stamped at its end."""
    return [Chunk(raw, T0 + start + len(raw) * LINE.char_time) for raw, start in frames]


def verdicts(path: Path, fast: ModuleType | None) -> list[tuple[bytes, int, int, int, int]]:
    saved = core.FAST, framing.FAST_MIN_BYTES
    core.FAST = fast
    framing.FAST_MIN_BYTES = 0
    try:
        session, capture = open_session(path, index=False)
        session.batch_reads = False
        with batching(False):
            session.ingest(capture.chunks())
    finally:
        core.FAST, framing.FAST_MIN_BYTES = saved
    s: Session = session
    st_ = s.store
    return [
        (st_.raw(i), st_.kind[i], st_.status[i], st_.partner[i], st_.flags[i] & VERDICT_FLAGS)
        for i in range(len(st_))
    ]


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    steps=st.lists(st.sampled_from([*sorted(STEPS), *LATE]), min_size=1, max_size=30),
    pauses=st.lists(st.sampled_from([0.05, 0.11, 0.6, 2.0]), min_size=1, max_size=4),
    late=st.sampled_from([0.6, 1.0, 3.0]),
    every=st.sampled_from([0.0005, 0.004, 0.016]),
)
def test_the_reads_cut_nothing_of_the_verdicts(
    tmp_path_factory: pytest.TempPathFactory,
    steps: list[str],
    pauses: list[float],
    late: float,
    every: float,
) -> None:
    fast = _compiled()
    frames = script(steps, pauses, late)
    folder = tmp_path_factory.mktemp("shapes")
    whole = recorded(folder / "whole.pcapng", per_frame(frames))
    cut = recorded(folder / "cut.pcapng", reads_of(frames, every))
    reference = verdicts(whole, None)
    assert verdicts(whole, fast) == reference
    assert verdicts(cut, None) == reference
    assert verdicts(cut, fast) == reference


@pytest.mark.parametrize("fast", [False, True], ids=["python", "compiled"])
def test_a_late_answer_split_across_reads_is_still_its_answer(tmp_path: Path, fast: bool) -> None:
    """The case found: the answer 2 s after its request (timeout 0.347 s), its first
    three bytes in one read and the rest in the next; then a poll answered in time."""
    core_ = _compiled() if fast else None
    frames = script(["late", "read"], [0.6], 2.0)
    char = LINE.char_time
    (req, t_req), (answer, t_ans), *rest = frames
    chunks = [
        Chunk(req, T0 + t_req + len(req) * char),
        Chunk(answer[:3], T0 + t_ans + 3 * char),
        Chunk(answer[3:], T0 + t_ans + len(answer) * char),
        *per_frame(rest),
    ]
    rows = verdicts(recorded(tmp_path / "late.pcapng", chunks), core_)
    assert [(r[2], r[3], r[4]) for r in rows] == [
        (Status.OK, 1, 0),
        (Status.OK, 0, Flag.LATE),  # paired, flagged late
        (Status.OK, 3, 0),  # not a retry: the request before was answered
        (Status.OK, 2, 0),
    ]
    assert t_ans - t_req > 5 * TIMEOUT


def _mix_verdicts(folder: Path, mix: Mix, frames: int) -> None:
    wire = mix_frames(mix, frames)
    reads, whole = folder / "reads.pcapng", folder / "frames.pcapng"
    write_reads(reads, mix, wire)
    write_frames(whole, mix, wire)
    reference = verdicts(whole, None)
    assert len(reference) >= frames
    fast = _compiled()
    assert verdicts(whole, fast) == reference
    assert verdicts(reads, None) == reference
    assert verdicts(reads, fast) == reference


@pytest.mark.parametrize(
    ("seed", "why"),
    [
        # a write of 46 registers whose first 8 bytes pass as its answer: the search took
        # them for an answer nobody asked for, the fast path (frame whole) a request
        (0, "prefix"),
        # an echoed write's deadline counted from the end of the read that held the
        # request's last byte (reads of 1-8 bytes cut anywhere): the master's next write
        # to another register, past the timeout, was taken for the echo
        (6, "echo"),
    ],
)
def test_the_benchmark_mixes_that_told_the_shapes_apart(
    tmp_path: Path, seed: int, why: str
) -> None:
    _mix_verdicts(tmp_path, random_mix(seed), 3000)


@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10**9))
def test_a_random_bus_read_as_a_usb_adapter_reads_it(
    tmp_path_factory: pytest.TempPathFactory, seed: int
) -> None:
    """Any bus of the benchmark's mixes (slaves, codes, exceptions, timeouts, stray
    bytes, line format), read every 16 ms as a USB adapter delivers it, against the same
    frames one per read. (The mixes' reads of random sizes, cut anywhere whatever the
    silences, give bytes times the line never saw: they are held to the same frames by
    the seeds above only.)"""
    mix = replace(random_mix(seed), reads="usb", read_max=0)
    _mix_verdicts(tmp_path_factory.mktemp("mix"), mix, 800)
