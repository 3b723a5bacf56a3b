"""`replay --stats` keeps a window of rows (issue 11): once the store holds
`REPLAY_WINDOW` rows it drops them at the next settled moment (`Session.ingest` with a
window) and what needs every row at the end counts each segment before it goes: the poll
cycle (`PollCycles`), the baud check (`SpeedCheck`), the exit status, the statistics
(bounded). The output must be that of one store holding every row, byte for byte.

Each capture is replayed with a window of a few rows, so that segments are cut next to
open requests, timeouts, broadcasts and noise and every poll cycle spans many segments,
and compared with the replay as it was before windows: every row in one store, the
statistics' values kept one by one, the poll cycle and baud check over the whole store.
The sidecar index written a segment at a time must be the one a whole store writes, and
reading it back a block at a time must give the same output again."""

from __future__ import annotations

import io
import json
import random
import re
from array import array
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.analysis.baud import SpeedCheck, wrong_speed
from sniffer.analysis.stats import Stats
from sniffer.cli import build_parser
from sniffer.cli import replay as replay_cli
from sniffer.errors import UserError
from sniffer.framing.store import COLUMNS, FrameStore
from sniffer.live.port import PortSpec
from sniffer.live.recorder import Recorder
from sniffer.model import Chunk, LineSettings
from sniffer.session import index
from sniffer.session import session as session_module
from sniffer.session.session import Session, open_session
from sniffer.sources.reads import batching
from sniffer.sources.synth import polling_frames
from sniffer.vocab import Flag, Kind
from tests.support.random_rows import random_store

ROOT = Path(__file__).resolve().parent.parent.parent
LINE = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
T0 = 1_700_000_000.0


def _frame(hex_: str) -> bytes:
    return with_crc(bytes.fromhex(hex_))


READ = _frame("010300000002")
ANSWER = _frame("01030400070008")
READ_2 = _frame("020400100001")
ANSWER_2 = _frame("0204020011")
SILENT = _frame("040300000001")  # nobody answers: a timeout
BROADCAST = _frame("000600050007")
WRITE = _frame("010600050007")  # answered by its echo
EXCEPTION = _frame("018302")
BAD = READ[:-1] + bytes([READ[-1] ^ 0xFF])  # a bad check
NOISE = b"\x55\xaa\x13"


class Counted:
    """How many segments the replays below cut (Session.new_segment that succeeded)."""

    cuts = 0


@pytest.fixture(autouse=True)
def _counted(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Count the segments cut, and let the reads come one by one (a batch of reads, as
    the pcapng reader passes a run of them, is framed whole before a cut is tried: a
    small file would be one batch)."""
    new_segment = Session.new_segment
    monkeypatch.setattr(session_module, "batching", lambda on: batching(False))

    def counting(self: Session) -> bool:
        done = new_segment(self)
        Counted.cuts += done
        return done

    monkeypatch.setattr(Session, "new_segment", counting)
    Counted.cuts = 0
    yield


def replayed(argv: list[str], window: int | None) -> tuple[str, str, int]:
    """stdout, stderr and status of `modscope replay ARGV --stats` with `window` rows
    (None: as before windows: every row in one store, the statistics unbounded)."""
    args = build_parser().parse_args(["replay", *argv, "--stats"])
    out, err = io.StringIO(), io.StringIO()
    saved = replay_cli.REPLAY_WINDOW, Stats.bound
    try:
        if window is None:
            replay_cli.REPLAY_WINDOW = None  # type: ignore[assignment]
            Stats.bound = lambda self, spill=None: None  # type: ignore[method-assign]
        else:
            replay_cli.REPLAY_WINDOW = window
        status = args.func(args, out, err)
    finally:
        replay_cli.REPLAY_WINDOW, Stats.bound = saved  # type: ignore[method-assign]
    return out.getvalue(), err.getvalue(), status


def recorded(path: Path, chunks: list[Chunk]) -> Path:
    recorder = Recorder(path, [PortSpec("/dev/ttyUSB0", LINE)])
    for chunk in chunks:
        recorder.write(chunk)
    recorder.close(chunks[-1].t_end if chunks else T0)
    return path


def reads_of(frames: list[tuple[bytes, float]], every: float) -> list[Chunk]:
    """Frames (bytes, start time) as an adapter reads them: a read every `every`
    seconds holding the bytes on the wire by then (frames cut anywhere)."""
    char = LINE.char_time
    out: list[Chunk] = []
    buf = bytearray()
    due = T0 + every
    for raw, start in frames:
        for k, byte in enumerate(raw):
            end = T0 + start + (k + 1) * char
            while end > due:
                if buf:
                    out.append(Chunk(bytes(buf), due))
                    buf.clear()
                due += every
            buf.append(byte)
    if buf:
        out.append(Chunk(bytes(buf), due))
    return out


# a script: what the master and the slaves send, one exchange a step
STEPS = {
    "read": [READ, ANSWER],
    "read2": [READ_2, ANSWER_2],
    "silent": [SILENT],  # a timeout
    "broadcast": [BROADCAST],
    "write": [WRITE, WRITE],
    "exception": [READ, EXCEPTION],
    "bad": [BAD],
    "noise": [NOISE],
    "retry": [READ, READ, ANSWER],  # the master repeats a request left unanswered
}


# what the tests of windows and segments draw: a script (`scripted`), and how often the
# adapter reads it (`reads_of`)
STEP_LISTS = st.lists(st.sampled_from(sorted(STEPS)), min_size=1, max_size=60)
PAUSE_LISTS = st.lists(st.sampled_from([0.0, 0.001, 0.02, 0.11, 0.6, 2.0]), min_size=1, max_size=5)
READ_EVERY = st.sampled_from([0.0005, 0.004, 0.016, 0.1])


def scripted(steps: list[str], pauses: list[float]) -> list[tuple[bytes, float]]:
    char = LINE.char_time
    frames: list[tuple[bytes, float]] = []
    t = 0.0
    for k, step in enumerate(steps):
        for raw in STEPS[step]:
            frames.append((raw, t))
            t += len(raw) * char + 0.004
        t += pauses[k % len(pauses)]
    return frames


@pytest.mark.parametrize("batched", [False, True])
def test_a_scripted_bus_in_tiny_windows(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, batched: bool
) -> None:
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    if batched:  # (a segment can then end only where a batch does: here, none)
        monkeypatch.setattr(session_module, "batching", batching)
    steps = ["read", "read2", "write", "silent", "broadcast", "exception", "retry", "bad"]
    steps = steps * 12 + ["noise"] + ["read", "read2"] * 20
    pauses = [0.02, 0.05, 0.3, 0.02, 1.5, 0.0]  # a gap in the polling, now and then
    for every in (0.001, 0.016):
        path = recorded(tmp_path / f"bus-{every}.pcapng", reads_of(scripted(steps, pauses), every))
        whole = replayed([str(path)], None)
        assert "poll cycle" in whole[0] and "gap at" in whole[0] and whole[2] == 0
        for window in (1, 2, 3, 5, 16):
            Counted.cuts = 0
            assert replayed([str(path)], window) == whole, (every, window)
            assert batched or Counted.cuts >= 3


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    steps=STEP_LISTS,
    pauses=PAUSE_LISTS,
    every=READ_EVERY,
    window=st.integers(1, 12),
    timeout=st.sampled_from([None, "0.05"]),
)
def test_random_buses_are_counted_alike_in_windows(
    tmp_path_factory: pytest.TempPathFactory,
    monkeypatch: pytest.MonkeyPatch,
    steps: list[str],
    pauses: list[float],
    every: float,
    window: int,
    timeout: str | None,
) -> None:
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    path = recorded(
        tmp_path_factory.mktemp("bus") / "bus.pcapng", reads_of(scripted(steps, pauses), every)
    )
    argv = [str(path)] + (["--timeout", timeout] if timeout else [])
    assert replayed(argv, window) == replayed(argv, None)


def test_a_polling_master_spanning_many_segments(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    frames = [(f.raw, f.t) for f in polling_frames(6000, line=LINE)]
    path = recorded(tmp_path / "poll.pcapng", reads_of(frames, 0.016))
    whole = replayed([str(path)], None)
    for window in (7, 500):
        Counted.cuts = 0
        assert replayed([str(path)], window) == whole
        assert Counted.cuts >= 5


def _captures() -> list[Path]:
    found = sorted((ROOT / "captures").glob("*.*"))
    found += sorted(p for p in (ROOT / "tests" / "captures").rglob("*") if p.is_file())
    return [p for p in found if p.suffix not in (".md", ".toml")]


@pytest.mark.parametrize("path", _captures(), ids=lambda p: p.name)
def test_every_bundled_capture_in_tiny_windows(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    argv = [str(path)]
    try:
        whole = replayed(argv, None)
    except UserError as exc:  # a logic capture with several probes: name them
        names = re.findall(r"probe\d+='([^']*)'", str(exc))[:2]
        assert len(names) == 2, exc
        argv += ["--probe", names[0], "--probe", names[1]]
        whole = replayed(argv, None)
    for window in (1, 3, 50):
        assert replayed(argv, window) == whole, window


def test_the_demo_in_tiny_windows(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    whole = replayed([], None)
    for window in (1, 2, 3, 7, 64):
        Counted.cuts = 0
        assert replayed([], window) == whole
        assert Counted.cuts > 1000 // window // 4


def _sidecar_of(path: Path) -> Path:
    return Path(str(path) + index.SUFFIX)


@pytest.mark.parametrize("reserve", [index.RESERVE, 64])
def test_the_sidecar_written_and_read_a_segment_at_a_time(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, reserve: int
) -> None:
    """A windowed replay writes the sidecar a whole store would (but where its blocks
    end); read back a block at a time it gives the same output, and read whole (the TUI,
    the listings) the rows indexing gives. (With too little room for the header, it is
    written in front of a copy of the blocks.)"""
    monkeypatch.delenv("MODSCOPE_NO_INDEX", raising=False)
    monkeypatch.setattr(index, "MIN_SIZE", 0)
    monkeypatch.setattr(index, "pays", lambda capture, mode: True)  # (serial pcapng too)
    monkeypatch.setattr(index, "RESERVE", reserve)
    monkeypatch.setattr(index, "BLOCK", 40)  # several blocks a segment, too
    steps = ["read", "read2", "write", "silent", "broadcast", "exception", "retry"] * 30
    path = recorded(tmp_path / "bus.pcapng", reads_of(scripted(steps, [0.02, 0.4]), 0.004))
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    whole = replayed([str(path)], None)
    fresh, capture = open_session(path, index=False)
    fresh.ingest(capture.chunks())
    monkeypatch.delenv("MODSCOPE_NO_INDEX")
    for window in (3, 100):
        _sidecar_of(path).unlink(missing_ok=True)
        assert replayed([str(path)], window) == whole  # indexed, the sidecar written
        header = _header(_sidecar_of(path))
        assert len(header["blocks"]) > len(fresh.store) // 100
        assert sorted(p.name for p in tmp_path.iterdir()) == [
            "bus.pcapng",
            "bus.pcapng" + index.SUFFIX,
        ]
        session, capture = open_session(path)
        session.ingest(capture.chunks())  # read whole, as the TUI and the listings do
        assert session.indexed_from is not None
        for name in COLUMNS:
            assert getattr(session.store, name) == getattr(fresh.store, name), name
        assert session.store.streams == fresh.store.streams
        assert session.store.notes == fresh.store.notes
        assert session.stats.table() == fresh.stats.table()
        assert (session.warnings, session.notes) == (fresh.warnings, fresh.notes)
        Counted.cuts = 0
        assert replayed([str(path)], window) == whole  # read back a block at a time
        assert Counted.cuts == 0  # (blocks dropped, nothing framed)


def _header(side: Path) -> dict[str, Any]:
    data = side.read_bytes()
    size: int = index._PREFIX.unpack_from(data, len(index.MAGIC))[0]
    start = len(index.MAGIC) + index._PREFIX.size
    found: dict[str, Any] = json.loads(data[start : start + size])
    return found


def test_a_sidecar_damaged_after_blocks_were_counted_is_indexed_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(index, "MIN_SIZE", 0)
    monkeypatch.setattr(index, "pays", lambda capture, mode: True)  # (serial pcapng too)
    monkeypatch.setattr(index, "BLOCK", 40)
    steps = ["read", "read2", "silent", "broadcast", "retry"] * 30
    path = recorded(tmp_path / "bus.pcapng", reads_of(scripted(steps, [0.02, 0.4]), 0.004))
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    whole = replayed([str(path)], None)
    monkeypatch.delenv("MODSCOPE_NO_INDEX")
    assert replayed([str(path)], 5) == whole
    side = _sidecar_of(path)
    data = bytearray(side.read_bytes())
    header = _header(side)
    blocks = header["blocks"]
    assert isinstance(blocks, list) and len(blocks) > 4
    start = len(index.MAGIC) + index._PREFIX.size
    at = start + index._PREFIX.unpack_from(data, len(index.MAGIC))[0]
    for _count, _pieces, _crc, length in blocks[: len(blocks) // 2]:
        at += int(length)
    data[at + 10] ^= 0xFF  # a block halfway: the blocks before it were counted
    side.write_bytes(bytes(data))
    assert replayed([str(path)], 5) == whole  # counted again from the capture
    assert side.read_bytes() != bytes(data)  # and the sidecar written anew
    session, capture = open_session(path)
    session.ingest(capture.chunks())
    assert session.indexed_from is not None


@pytest.mark.parametrize("seed", range(12))
def test_the_baud_check_counted_in_parts_is_that_of_the_whole(seed: int) -> None:
    rng = random.Random(seed)
    store = random_store(rng, 600, channels=1 + seed % 2)
    if seed % 3:  # no valid frame at all, mostly noise: the counts decide
        for i in range(len(store)):
            store.flags[i] |= int(Flag.CHECK_BAD)
            if store.kind[i] != Kind.EVENT and rng.random() < 0.8:
                store.kind[i] = Kind.NOISE
    cuts = sorted(rng.sample(range(1, len(store)), rng.randrange(1, 30)))
    for min_bytes in (1, 64, 5000):
        check = SpeedCheck()
        for a in [0, *cuts]:
            check.add(store, a) if a == cuts[-1] else check.add(_rows(store, a, cuts), 0)
        assert check.warning(min_bytes) == wrong_speed(store, min_bytes)
    assert seed % 3 == 0 or wrong_speed(store, 1) is not None


def _rows(store: FrameStore, a: int, cuts: list[int]) -> FrameStore:
    """Rows `a` up to the next cut in a store of their own."""
    b = next(c for c in cuts if c > a)
    part = FrameStore(store.streams)
    for name in COLUMNS:
        getattr(part, name).extend(getattr(store, name)[a:b])
    return part


def test_the_row_a_source_warning_names_is_numbered_in_the_capture(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A frame labelled against its content, late in a log: the warning names its row in
    the whole capture, not in the segment it was in."""
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    lines = ["Modbus poll log, COM4 19200 8N2"]
    for k in range(60):
        t = f"12:00:{k // 2:02d}.{(k % 2) * 500:03d}"
        request, answer = ("RX", "TX") if k in (41, 50) else ("TX", "RX")
        lines.append(f"{t} {request}: {READ.hex(' ').upper()}")
        lines.append(f"{t[:-3]}{(k % 2) * 500 + 40:03d} {answer}: {ANSWER.hex(' ').upper()}")
    path = tmp_path / "poll.log"
    path.write_text("\n".join(lines) + "\n")
    whole = replayed([str(path)], None)
    assert "labelled against their content (the first is row 82)" in whole[1]
    for window in (1, 3, 10, 90):
        Counted.cuts = 0
        assert replayed([str(path)], window) == whole
        assert Counted.cuts > (10 if window < 10 else 0)


def test_an_interrupted_replay_leaves_no_half_written_sidecar(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("MODSCOPE_NO_INDEX", raising=False)
    monkeypatch.setattr(index, "MIN_SIZE", 0)
    monkeypatch.setattr(index, "pays", lambda capture, mode: True)  # (serial pcapng too)
    steps = ["read", "read2", "silent"] * 40
    path = recorded(tmp_path / "bus.pcapng", reads_of(scripted(steps, [0.02]), 0.004))
    calls = 0
    settled = Session.settled

    def interrupted(self: Session) -> bool:
        # Ctrl-C once a segment went to the sidecar (two settled moments: the one
        # looked for, the one new_segment checks), at the next settled moment
        nonlocal calls
        if not settled(self):
            return False
        calls += 1
        if calls == 3:
            raise KeyboardInterrupt
        return True

    monkeypatch.setattr(Session, "settled", interrupted)
    with pytest.raises(KeyboardInterrupt):
        replayed([str(path)], 2)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bus.pcapng"]


@pytest.mark.parametrize("rows", [0, 1, 5, 4096])
def test_offsets_renumbered_as_one_big_integer(rows: int) -> None:
    rng = random.Random(rows)
    offsets = array("Q", sorted(rng.randrange(1 << 40) for _ in range(rows)))
    for by in (0, 1, 123_456_789, 1 << 41):
        assert index._plus(offsets, by) == array("Q", (o + by for o in offsets)).tobytes()
    least = min(offsets, default=0)
    for by in (least, least // 2):
        local = index._plus(memoryview(offsets), -by)
        assert local == array("Q", (o - by for o in offsets)).tobytes()
