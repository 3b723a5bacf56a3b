"""`export -o x.pcapng` writes a serial capture a segment at a time (issue #29, as the
listings: `sniffer.session.streamed`): the first pass also finds what the interface
block says the times are worth over the whole capture (`Moves`), the second writes each
segment's packets, their transaction ids numbered in the whole capture
(`PcapExporter.base`). Its bytes must be those of the export of one store of every row
(the path network captures still take), with either core, whatever the windows, the
style, the filter, -c, --jobs and a sidecar read back.

The windows are a few rows, so that segments are cut next to open requests, timeouts,
noise and frames squeezed closer than t3.5; the reads come one by one (a batch of reads
is framed whole before a cut is tried)."""

from __future__ import annotations

import io
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sniffer import core
from sniffer.cli import build_parser
from sniffer.cli.filtering import Selection, query_of
from sniffer.cli.options import bindings_for, read_options
from sniffer.outputs.export import PcapExporter
from sniffer.outputs.parallel import MIN_ROWS_ENV
from sniffer.session import index, streamed
from sniffer.session import session as session_module
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, open_session
from sniffer.sources.reads import batching
from sniffer.sources.synth import polling_frames
from tests.meaning.test_sunspec import write_capture
from tests.session.test_replay_window import LINE, STEPS, reads_of, recorded, scripted
from tests.support.core import running
from tests.support.sunspec import device_image, discovery, frames_of


class Cut:
    segments = 0  # segments cut (both passes)


@pytest.fixture(autouse=True)
def _one_by_one(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    monkeypatch.setattr(session_module, "batching", lambda on: batching(False))
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    new_segment = Session.new_segment

    def counting(self: Session) -> bool:
        done = new_segment(self)
        Cut.segments += done
        return done

    monkeypatch.setattr(Session, "new_segment", counting)
    Cut.segments = 0
    yield


def whole(argv: list[str]) -> bytes:
    """The export of one store holding every row, as before #29 (one process)."""
    args = build_parser().parse_args(["export", *argv, "-o", "x.pcapng"])
    path = Path(args.file)
    bindings = bindings_for(args)
    session, capture = open_session(
        path, read_options(args), bindings=bindings, timeout=args.timeout, index=False
    )
    session.ingest(capture.chunks())
    rows = Selection(session, query_of(args), args.count).take(len(session.store), final=True)
    out = io.BytesIO()
    exporter = PcapExporter(out, session.describer, session.line, name=path.name, style=args.style)
    exporter.write(rows)
    return out.getvalue()


def exported(
    argv: list[str], target: Path, monkeypatch: pytest.MonkeyPatch, learn: int, window: int
) -> bytes:
    """The bytes `modscope export ARGV -o TARGET` writes, the first pass keeping `learn`
    rows, the second `window`."""
    monkeypatch.setattr(streamed, "LEARN_WINDOW", learn)
    monkeypatch.setattr(streamed, "LIST_WINDOW", window)
    args = build_parser().parse_args(["export", *argv, "-o", str(target)])
    err = io.StringIO()
    args.func(args, io.StringIO(), err)  # (1 or 2 for a capture of noise: the bytes count)
    assert "packets (link type 252" in err.getvalue()
    return target.read_bytes()


SELECTIONS = [[], ["-c", "7"], ["--filter", "status:timeout or kind:exception or t:0.5-3"]]


@settings(
    max_examples=10, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    steps=st.lists(st.sampled_from(sorted(STEPS)), min_size=1, max_size=40),
    pauses=st.lists(st.sampled_from([0.0, 0.001, 0.02, 0.6, 2.0]), min_size=1, max_size=4),
    every=st.sampled_from([0.0005, 0.004, 0.016]),
    window=st.integers(1, 9),
    style=st.sampled_from(["modbus-tcp", "rtu"]),
    selection=st.sampled_from(SELECTIONS),
)
def test_random_buses_export_alike_in_segments(
    tmp_path_factory: pytest.TempPathFactory,
    monkeypatch: pytest.MonkeyPatch,
    steps: list[str],
    pauses: list[float],
    every: float,
    window: int,
    style: str,
    selection: list[str],
) -> None:
    folder = tmp_path_factory.mktemp("bus")
    path = recorded(folder / "bus.pcapng", reads_of(scripted(steps, pauses), every))
    argv = [str(path), "--as", style, "--jobs", "1", *selection]
    reference = whole(argv)
    for fast in (None, core.FAST):
        with running(fast):
            got = exported(argv, folder / "out.pcapng", monkeypatch, window, window)
        assert got == reference, (fast, window)


def test_the_demo_in_segments(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The demo binds devices with parameter windows and timing rules: the rows of those
    units and the slow answers go by the Python path (`PcapExporter._rows`) even with
    the compiled core, their transaction ids too."""
    argv = [str(DEMO_CAPTURE), "--bus", str(DEMO_BUS), "--jobs", "1"]
    got = exported(argv, tmp_path / "x.pcapng", monkeypatch, 24, 16)
    assert got == whole(argv) and Cut.segments > 60


def test_jobs_share_each_segment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Workers forked for each segment's rows write what one process writes; the
    transaction ids count on from one segment to the next."""
    frames = [(f.raw, f.t) for f in polling_frames(1000, line=LINE)]
    path = recorded(tmp_path / "poll.pcapng", reads_of(frames, 0.016))
    monkeypatch.setenv(MIN_ROWS_ENV, "1")  # workers however few the rows
    one = exported([str(path), "--jobs", "1"], tmp_path / "1.pcapng", monkeypatch, 150, 200)
    assert one == whole([str(path)])
    three = exported([str(path), "--jobs", "3"], tmp_path / "3.pcapng", monkeypatch, 150, 200)
    assert three == one and Cut.segments > 8


def test_a_sidecar_read_back_in_both_passes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With a sidecar (written by the first run, read back by the next, a block at a
    time: the moves are found over its blocks), the export is the same, and neither pass
    frames the capture. So it is with the sidecar of one store, whose blocks of 51 rows
    end between requests and their answers (a block joins the next where they pair:
    `sniffer.session.index.load`): a block that began with the answer to a read of a
    unit with no dictionary once had the first pass learn again from the capture."""
    monkeypatch.delenv("MODSCOPE_NO_INDEX")
    monkeypatch.setattr(index, "MIN_SIZE", 0)
    monkeypatch.setattr(index, "pays", lambda capture, mode: True)  # (serial pcapng too)
    monkeypatch.setattr(index, "BLOCK", 51)  # (odd: blocks of one store cut pairs)
    reg = device_image()
    reads = [*[(40072, 50), (40124, 53)] * 60, *discovery(reg, 40000), (40072, 50)]
    path = write_capture(tmp_path / "sunspec.pcapng", frames_of(reg, reads))
    first = exported([str(path)], tmp_path / "1.pcapng", monkeypatch, 7, 5)
    assert Path(str(path) + index.SUFFIX).exists()
    assert Cut.segments > 0  # (the capture framed: both passes)
    Cut.segments = 0
    assert exported([str(path)], tmp_path / "2.pcapng", monkeypatch, 7, 5) == first
    assert Cut.segments == 0  # (read back: both passes)
    session, capture = open_session(path)  # the sidecar of one store, in its blocks
    Path(str(path) + index.SUFFIX).unlink()
    session.ingest(capture.chunks())
    passes: list[bool] = []
    learn = streamed.learn

    def counted(*args: Any, **kwargs: Any) -> streamed.Learnt:
        learnt = learn(*args, **kwargs)
        passes.append(learnt.indexed)
        return learnt

    monkeypatch.setattr("sniffer.cli.replaying.learn", counted)
    assert exported([str(path)], tmp_path / "2.pcapng", monkeypatch, 7, 5) == first
    assert passes == [True] and Cut.segments == 0
    assert first == whole([str(path)])
