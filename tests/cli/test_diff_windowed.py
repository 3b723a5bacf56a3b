"""`modscope diff A B` counts each capture a segment of rows at a time (`Side`): what it
says must be what comparing the two captures kept whole says, wherever the segments end.

The captures are polling buses (`polling_frames`: reads, writes now and then, exceptions,
silent slaves) one frame per packet at 115200 8N1, read one packet at a time (a batch
of reads, as the pcapng reader passes a run of them, is framed whole before a cut is
tried: these small files would be one batch); B is A's bus on another day: some units
stop answering, some answers carry other values, the master polls a little slower or
faster."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.analysis.diff import Side, diff_stores
from sniffer.cli import diff as diff_cli
from sniffer.cli import main
from sniffer.framing.pairing import CLOCK_STAMPS
from sniffer.model import LineSettings
from sniffer.session import session as session_module
from sniffer.session.session import open_session
from sniffer.sources.pcapng_writer import PcapngWriter, describe_interface
from sniffer.sources.reads import batching
from sniffer.sources.synth import polling_frames

LINE = LineSettings(baud=115200, bytesize=8, parity="N", stopbits=1, mode="rtu")
T0 = 1_760_000_000.0


def _write(path: Path, frames: list[tuple[float, bytes]]) -> Path:
    with path.open("wb") as f:
        writer = PcapngWriter(f)
        port = writer.add_interface(147, name="ttyUSB0", description=describe_interface(LINE))
        for t, raw in frames:
            writer.write_packet(port, T0 + t + len(raw) * LINE.char_time, raw)
    return path


def _bus(seed: int, n: int, day: int) -> list[tuple[float, bytes]]:
    """`n` frames of the bus of `seed` on `day` (0: A; another: B, changed by `day`)."""
    rng = random.Random(seed * 7919 + day)
    silent = {u for u in (3, 7, 11) if day and rng.random() < 0.5}
    pace = 1.0 if not day else rng.choice((0.7, 1.0, 1.6))
    out: list[tuple[float, bytes]] = []
    for f in polling_frames(n, seed=seed, line=LINE, units=(1, 3, 7, 11)):
        raw = f.raw
        if f.role != "request" and raw[0] in silent:
            continue
        if day and f.role == "response" and raw[1] in (3, 4) and rng.random() < 0.2:
            body = bytearray(raw[:-2])
            body[-1] = rng.randrange(256)  # another value than A read there
            raw = with_crc(bytes(body))
        out.append((f.t * pace, raw))
    return out


def _diff(a: Path, b: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(["diff", str(a), str(b)])
    return code, capsys.readouterr().out


@settings(
    max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 10**6), n=st.integers(40, 400), window=st.integers(1, 300))
@example(seed=5, n=400, window=7)  # (always one cut into many segments)
def test_diff_in_segments_says_what_the_whole_captures_say(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    seed: int,
    n: int,
    window: int,
) -> None:
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    a = _write(tmp_path / "a.pcapng", _bus(seed, n, 0))
    b = _write(tmp_path / "b.pcapng", _bus(seed, n, 1 + seed % 5))
    stores = []
    for path in (a, b):
        session, capture = open_session(path)
        session.ingest(capture.chunks())  # every row kept
        stores.append(session.store)
    whole = diff_stores(stores[0], stores[1], str(a), str(b))
    whole_a = Side()
    whole_a.add(stores[0])
    whole_b = Side(before=whole_a)
    whole_b.add(stores[1])
    monkeypatch.setattr(diff_cli, "REPLAY_WINDOW", window)
    segments = []
    sides: list[Side] = []
    counted = Side.add

    def add(side: Side, store: object) -> None:
        segments.append(len(store))  # type: ignore[arg-type]
        if side not in sides:
            sides.append(side)
        counted(side, store)  # type: ignore[arg-type]

    monkeypatch.setattr(Side, "add", add)
    monkeypatch.setattr(session_module, "batching", lambda on: batching(False))
    code, said = _diff(a, b, capsys)
    assert said == whole.text() + "\n"
    assert code == (0 if whole.same else 1)
    # what each side counted, not only what the text shows of it (a latency that did
    # not move enough to be named, say)
    assert len(sides) == 2
    for side, kept in zip(sides, (whole_a, whole_b), strict=True):
        assert side.units == kept.units
        assert side.fared_units == kept.fared_units
        assert side.fared_polls == kept.fared_polls
        assert side.ranges == kept.ranges
        assert side.cycles.cycles() == kept.cycles.cycles()
        assert (side.below, side.unmeasured) == (kept.below, kept.unmeasured)
        assert {u: sorted(v) for u, v in side.latencies.items()} == {
            u: sorted(v) for u, v in kept.latencies.items()
        }
    rows = len(stores[0]) + len(stores[1])
    assert sum(segments) == rows
    # (cut into segments indeed, once the clock has measured the stamps: before that
    # every row is kept, `Session._timed`)
    if window * 4 < min(map(len, stores)) and min(map(len, stores)) > 2 * CLOCK_STAMPS:
        assert len(segments) > 2
