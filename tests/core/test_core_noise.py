"""Stray bytes are framed as noise by the compiled scan itself, with the rows of the
pure-Python core: the noise row, the frame after it (timed, unpaired and setting the
open request as the slow path does), wherever the reads cut them, and the slow path's
search is left only what its compiled copy cannot decide (`rtu_search` in
sniffer/_core.c).
"""

from __future__ import annotations

import random
from pathlib import Path
from types import ModuleType

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.mixes import mix_frames, random_mix, write_reads
from dissectors.checks import with_crc
from sniffer.framing.lengths import RtuLengths
from sniffer.session.session import Session
from tests.core.test_core import _assert_same, _cut, _ingest
from tests.support.core import _compiled, _frame
from tests.support.reads import LINE, T0, _recording

CHAR = LINE.char_time
GAP = LINE.t35 * 1.2  # the silence between two frames
# a request for two holding registers of unit 1, its answer; a write of unit 2 (FC 6)
READ = with_crc(bytes([1, 3, 0, 0, 0, 2]))
ANSWER = with_crc(bytes([1, 3, 4, 0, 7, 0, 9]))
WRITE = with_crc(bytes([2, 6, 0, 1, 0, 5]))
TAIL = with_crc(bytes([5, 4, 0, 0, 0, 1]))  # a request of a unit no other frame is of


@pytest.fixture
def compiled() -> ModuleType:
    return _compiled()


def _searches(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts the slow path's searches in Python (one item a search)."""
    calls: list[int] = []
    search = RtuLengths.candidates

    def counted(self: RtuLengths, *args: object) -> tuple[int, int, bool]:
        calls.append(1)
        return search(self, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(RtuLengths, "candidates", counted)
    return calls


def _wire(pieces: list[bytes], gaps: list[float] | None = None) -> list[tuple[bytes, float]]:
    """The pieces on the wire, each with the end time of its last byte: a stray byte
    right after what came before it, a frame after the silence `gaps` gives (GAP)."""
    out: list[tuple[bytes, float]] = []
    t = T0
    for k, piece in enumerate(pieces):
        t += (gaps[k] if gaps is not None else GAP) if len(piece) > 3 else CHAR
        t += len(piece) * CHAR
        out.append((piece, t))
    return out


def _reads(wire: list[tuple[bytes, float]], cuts: list[int]) -> list[tuple[bytes, float]]:
    """The wire in reads of the sizes `cuts` gives, each stamped when its last byte came."""
    return _cut(wire, cuts, 0.0)


def _rows(session: Session) -> list[tuple[int, int, int]]:
    store = session.store
    return [(store.offset[i], store.length[i], store.kind[i]) for i in range(len(store))]


def _same_and_compiled(
    tmp_path: Path,
    compiled: ModuleType,
    monkeypatch: pytest.MonkeyPatch,
    reads: list[tuple[bytes, float]],
    searches: int = 0,
) -> list[tuple[int, int, int]]:
    """The rows of `reads`, the same with either core (batched and read by read), none of
    them left to the slow path's search in Python by the compiled core (but `searches`).
    A read of one
    request after silence ends them (its row left out): a search at a read after silence
    waits for the next silence (`silence_framed`), which the end of the bytes stands for
    only in the slow path."""
    path = tmp_path / "r.pcapng"
    end = len(b"".join(data for data, _ in reads))
    _recording(path, [*reads, (TAIL, reads[-1][1] + 3 * GAP)])
    for batched in (True, False):
        pure = _assert_same(path, compiled, batched)
    calls = _searches(monkeypatch)
    _ingest(path, compiled)
    assert len(calls) == searches
    *rows, last = _rows(pure)
    assert last == (end, 8, 1)
    return rows


def test_a_stray_byte_before_a_request(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    reads = [(b"".join(p for p, _ in _wire([WRITE, b"\x55", READ, ANSWER])), T0 + 0.1)]
    rows = _same_and_compiled(tmp_path, compiled, monkeypatch, reads)
    assert rows == [(0, 8, 1), (8, 1, 0), (9, 8, 1), (17, 9, 2)]


def test_a_stray_byte_between_a_request_and_its_answer(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    reads = [(WRITE + READ + b"\x07" + ANSWER + WRITE, T0 + 0.1)]
    rows = _same_and_compiled(tmp_path, compiled, monkeypatch, reads)
    assert rows == [(0, 8, 1), (8, 8, 1), (16, 1, 0), (17, 9, 2), (26, 8, 1)]
    path = tmp_path / "r.pcapng"
    pure = _ingest(path, None)
    assert pure.store.partner[3] == 1  # the answer after the stray byte is paired


def test_stray_bytes_cut_by_a_read_boundary(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Three stray bytes, the reads cut before, between and after them, and inside the
    answer that follows. Where the cut falls among them the search at the read after
    waits for the next silence (that read follows one); the reads come one by one, so
    the frame after the noise is then in a read that is neither the newest one nor the
    one holding the noise when the compiled scan is called, and its search is the slow
    path's (the write after it, begun in that read too, is then framed by the Python
    fast path, timed by the reads' spans)."""
    wire = _wire([WRITE, READ, b"\x00\xff\x13", ANSWER, WRITE])
    stream = b"".join(p for p, _ in wire)
    for at in range(16, 22):
        reads = _reads(wire, [at, len(stream) - at])
        left = 1 if at in (17, 18) else 0
        rows = _same_and_compiled(tmp_path, compiled, monkeypatch, reads, left)
        assert rows == [(0, 8, 1), (8, 8, 1), (16, 3, 0), (19, 9, 2), (28, 8, 1)], at


def test_a_stray_byte_that_looks_like_a_unit_and_a_function_code(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A stray 0x01 before unit 1's answer reads as unit 1, FC 1 (its request and answer
    lengths both 8 bytes here): their checks fail, so it is noise; and a stray 0x02 before
    unit 1's request reads as unit 2, FC 1."""
    reads = [(READ + b"\x01" + ANSWER + b"\x02" + READ + ANSWER, T0 + 0.1)]
    rows = _same_and_compiled(tmp_path, compiled, monkeypatch, reads)
    assert rows == [(0, 8, 1), (8, 1, 0), (9, 9, 2), (18, 1, 0), (19, 8, 1), (27, 9, 2)]


def test_a_stray_byte_alone_between_silences(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A read of one stray byte after silence, the next frame after silence too: the
    search asks the silences (silence_framed), which frame nothing one byte long. The
    reads come one by one (silence between them), and the frame's read is then neither
    the newest one nor the one the scan stood in when the compiled scan is called, so
    that frame is left to the slow path's search."""
    wire = _wire([READ, ANSWER, b"\x42", WRITE], [GAP, GAP, GAP, GAP])
    reads = [(b"".join(p for p, _ in wire[:2]), wire[1][1])]
    reads += [(b"\x42", wire[1][1] + 3 * GAP), (WRITE, wire[1][1] + 6 * GAP)]
    rows = _same_and_compiled(tmp_path, compiled, monkeypatch, reads, searches=1)
    assert rows == [(0, 8, 1), (8, 9, 2), (17, 1, 0), (18, 8, 1)]


def test_a_stray_byte_before_a_frame_the_reads_have_not_finished(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The search at the stray byte waits for a length that runs past the read (a
    counted answer's count byte), then finds nothing once it has come."""
    wire = _wire([READ, b"\x01", ANSWER])
    stream = b"".join(p for p, _ in wire)
    rows = _same_and_compiled(tmp_path, compiled, monkeypatch, _reads(wire, [10, 9]))
    assert rows == [(0, 8, 1), (8, 1, 0), (9, 9, 2)]
    assert len(stream) == 18


# kinds of exchange that the fast paths take whole (no noise, no damage of their own)
CLEAN = ["read"] * 4 + ["exception", "echo", "write", "broadcast", "silent", "zeros"]
UNITS = (1, 2, 7, 247)


def _stray(rng: random.Random, look: str) -> bytes:
    """1-3 stray bytes: random, or one that looks like a unit address, or a unit and a
    function code."""
    if look == "unit":
        return bytes([rng.choice(UNITS)])
    if look == "unit and code":
        return bytes([rng.choice(UNITS), rng.choice((1, 3, 4, 5, 6, 15, 16, 0x83))])
    return rng.randbytes(rng.randint(1, 3))


def _noisy(seed: int, n: int, rate: float, look: str) -> list[tuple[bytes, float]]:
    """n exchanges, stray bytes after a share `rate` of the frames (between a request and
    its answer too), each piece with its end time: a stray byte right after the frame
    before it or after silence, a frame a little more than t3.5 after the piece before."""
    rng = random.Random(seed)
    out: list[tuple[bytes, float]] = []
    t = T0
    for _ in range(n):
        for frame in _frame(rng, rng.choice(CLEAN)):
            t += len(frame) * CHAR
            out.append((frame, t))
            t += LINE.t35 * rng.uniform(1.05, 1.5)
            if rng.random() < rate:
                stray = _stray(rng, look)
                t += (0.0 if rng.random() < 0.8 else LINE.t35 * 2) + len(stray) * CHAR
                out.append((stray, t))
                t += LINE.t35 * rng.uniform(0.2, 1.5)
    return out


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 10**6),
    n=st.integers(1, 80),
    rate=st.sampled_from([0.05, 0.2, 0.6]),
    look=st.sampled_from(["random", "unit", "unit and code"]),
    cuts=st.one_of(st.just([0]), st.lists(st.integers(1, 90), min_size=1, max_size=40)),
    batched=st.booleans(),
)
def test_stray_bytes_between_frames_give_the_same_rows_with_either_core(
    tmp_path_factory: pytest.TempPathFactory,
    seed: int,
    n: int,
    rate: float,
    look: str,
    cuts: list[int],
    batched: bool,
) -> None:
    fast = _compiled()
    path = tmp_path_factory.mktemp("noise") / "r.pcapng"
    _recording(path, _cut(_noisy(seed, n, rate, look), cuts, 0.0))
    _assert_same(path, fast, batched)


def test_the_bus_with_stray_bytes_leaves_few_searches_to_python(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The benchmark's bus with 1% stray bytes (mix742668188), 16 ms reads: the same rows
    with either core, and the compiled one searches in Python a small part of the times
    the pure one does (stray bytes of two runs in a row, 4 bytes or more, stay there)."""
    mix = random_mix(742668188)
    path = tmp_path / "mix.pcapng"
    write_reads(path, mix, mix_frames(mix, 4000))
    _assert_same(path, compiled)
    calls = _searches(monkeypatch)
    pure = _ingest(path, None)
    searched = len(calls)
    del calls[:]
    _ingest(path, compiled)
    assert sum(1 for kind in pure.store.kind if kind == 0) > 20  # noise rows
    assert searched > 50
    assert len(calls) * 10 < searched
