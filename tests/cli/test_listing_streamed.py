"""`replay --format` lists a serial capture a segment at a time (issue #29,
`sniffer.session.streamed`): a first pass keeping a window of rows learns what is said
before the rows and what the annotator finds in every row, a second lists each segment
as it drops it. Its output must be byte for byte the listing of one store of every row
(`write_listing` after a whole ingest, the path several files and network captures
still take), whatever the windows, the format, the filter, -c and --jobs; and the rows
it keeps must not grow with the capture.

The windows here are a few rows, so that segments are cut next to open requests,
timeouts, noise, SunSpec discovery and parameter-window selections; the reads come one
by one (a batch of reads is framed whole before a cut is tried)."""

from __future__ import annotations

import io
import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sniffer.cli import build_parser
from sniffer.cli.filtering import query_of
from sniffer.cli.options import bindings_for, read_options
from sniffer.cli.replaying import write_listing
from sniffer.outputs.parallel import MIN_ROWS_ENV
from sniffer.session import index, streamed
from sniffer.session import session as session_module
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, open_session
from sniffer.sources.reads import batching
from sniffer.sources.synth import polling_frames
from tests.meaning.test_sunspec import needs_models, write_capture
from tests.session.test_replay_window import (
    LINE,
    PAUSE_LISTS,
    READ_EVERY,
    STEP_LISTS,
    reads_of,
    recorded,
    scripted,
)
from tests.support.sunspec import device_image, discovery, frames_of

ROOT = Path(__file__).resolve().parent.parent.parent


class Kept:
    """The most rows a store held when a segment but the first was cut, and the segments
    cut."""

    rows = 0
    cuts = 0


@pytest.fixture(autouse=True)
def _one_by_one(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    monkeypatch.setattr(session_module, "batching", lambda on: batching(False))
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    new_segment = Session.new_segment

    def counting(self: Session) -> bool:
        if self.base:  # (the first segment waits for the stamps' clock: Session._timed)
            Kept.rows = max(Kept.rows, len(self.store))
        done = new_segment(self)
        Kept.cuts += done
        return done

    monkeypatch.setattr(Session, "new_segment", counting)
    Kept.rows = Kept.cuts = 0
    yield


def whole(argv: list[str]) -> str:
    """The listing of one store holding every row, as before #29."""
    args = build_parser().parse_args(["replay", *argv])
    path = Path(args.file[0]) if args.file else DEMO_CAPTURE
    bindings = bindings_for(args, DEMO_BUS if not args.file else None)
    session, capture = open_session(
        path, read_options(args), bindings=bindings, timeout=args.timeout, index=False
    )
    session.ingest(capture.chunks())
    out = io.StringIO()
    write_listing(out, args, session, query_of(args))
    return out.getvalue()


def listed(
    argv: list[str], monkeypatch: pytest.MonkeyPatch, learn: int, window: int
) -> tuple[str, str, int]:
    """stdout, stderr and status of `modscope replay ARGV`, the first pass keeping
    `learn` rows, the second `window`."""
    monkeypatch.setattr(streamed, "LEARN_WINDOW", learn)
    monkeypatch.setattr(streamed, "LIST_WINDOW", window)
    args = build_parser().parse_args(["replay", *argv])
    out, err = io.StringIO(), io.StringIO()
    status = args.func(args, out, err)
    return out.getvalue(), err.getvalue(), status


FORMATS = [["--format", f] for f in ("text", "jsonl", "csv")]
SELECTIONS = [
    [],
    ["-c", "7"],
    ["--filter", "status:timeout or kind:exception"],
    ["--filter", "t:0.5-3", "-c", "3"],
]


def _same(argv: list[str], monkeypatch: pytest.MonkeyPatch, windows: list[tuple[int, int]]) -> None:
    reference = whole(argv)
    first = listed(argv, monkeypatch, 1 << 30, 1 << 30)  # one segment each pass
    assert first[0] == reference
    for learn, window in windows:
        assert listed(argv, monkeypatch, learn, window) == first, (argv, learn, window)


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    steps=STEP_LISTS,
    pauses=PAUSE_LISTS,
    every=READ_EVERY,
    window=st.integers(1, 12),
    fmt=st.sampled_from(FORMATS),
    selection=st.sampled_from(SELECTIONS),
)
def test_random_buses_list_alike_in_segments(
    tmp_path_factory: pytest.TempPathFactory,
    monkeypatch: pytest.MonkeyPatch,
    steps: list[str],
    pauses: list[float],
    every: float,
    window: int,
    fmt: list[str],
    selection: list[str],
) -> None:
    path = recorded(
        tmp_path_factory.mktemp("bus") / "bus.pcapng", reads_of(scripted(steps, pauses), every)
    )
    _same([str(path), *fmt, *selection], monkeypatch, [(window, window), (3, 1)])


@pytest.mark.parametrize("fmt", FORMATS, ids=lambda f: f[1])
def test_the_demo_in_segments(fmt: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """The demo's bus file binds devices with parameter windows (a later read of the
    window's value is named after the parameter selected before it) and timing rules."""
    _same(fmt, monkeypatch, [(1, 1), (64, 7)])
    assert Kept.cuts > 100
    _same([*fmt, "--filter", "reg:Voltage or fc:16"], monkeypatch, [(3, 2)])


@needs_models
@pytest.mark.parametrize("fmt", FORMATS, ids=lambda f: f[1])
def test_sunspec_found_after_the_rows_that_show_it(
    tmp_path: Path, fmt: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The master polls the device's values before it reads the marker and the models:
    one store names those first polls with the models found later, and so must each
    segment; a scale factor's value is the one read before the row."""
    reg = device_image()
    polls = [(40072, 50), (40124, 53)]
    reads = [*polls * 6, *discovery(reg, 40000), *polls * 6]
    capture = write_capture(tmp_path / "sunspec.pcapng", frames_of(reg, reads))
    out = listed([str(capture), *fmt], monkeypatch, 2, 3)[0]
    assert "Amps = 12.34 A" in "".join(out.splitlines()[:4])  # the first poll, named
    _same([str(capture), *fmt], monkeypatch, [(1, 1), (2, 3), (7, 2)])
    _same([str(capture), *fmt, "--filter", "reg:Watts"], monkeypatch, [(2, 2)])


def _bundled() -> list[Path]:
    found = sorted((ROOT / "captures").glob("*.*"))
    found += sorted(p for p in (ROOT / "tests" / "captures").rglob("*") if p.is_file())
    return [p for p in found if p.suffix not in (".md", ".toml", ".csv", ".sr", ".json")]


@pytest.mark.parametrize("path", _bundled(), ids=lambda p: p.name)
def test_every_bundled_capture_in_segments(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _same([str(path), "--format", "jsonl"], monkeypatch, [(3, 2)])


def test_jobs_share_each_segment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    frames = [(f.raw, f.t) for f in polling_frames(3000, line=LINE)]
    path = recorded(tmp_path / "poll.pcapng", reads_of(frames, 0.016))
    monkeypatch.setenv(MIN_ROWS_ENV, "1")  # workers however few the rows
    for fmt in FORMATS:
        argv = [str(path), *fmt]
        one = listed([*argv, "--jobs", "1"], monkeypatch, 500, 700)
        assert one[0] == whole(argv)
        assert listed([*argv, "--jobs", "3"], monkeypatch, 500, 700) == one


def test_the_rows_kept_do_not_grow_with_the_capture(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each pass keeps about its window of rows (a segment ends at the next settled
    moment), not every row of the capture: counted through the store's size when a
    segment is cut, for a capture of 80 times the window."""
    frames = [(f.raw, f.t) for f in polling_frames(8000, line=LINE)]
    path = recorded(tmp_path / "poll.pcapng", reads_of(frames, 0.016))
    seen: list[int] = []
    write_listing_rows = streamed.segments

    def watching(session: Session, *a: object, **kw: object) -> None:
        write_listing_rows(session, *a, **kw)  # type: ignore[arg-type]
        seen.append(session.base + len(session.store))

    monkeypatch.setattr("sniffer.cli.replaying.segments", watching)
    out, _err, status = listed([str(path), "--format", "jsonl"], monkeypatch, 50, 100)
    rows = out.splitlines()
    assert status == 0 and len(rows) == seen[0] and len(rows) >= 80 * 100
    assert json.loads(rows[-1])["index"] == len(rows) - 1  # numbered in the whole capture
    assert Kept.cuts > 100  # (both passes)
    # the window, and the rows until a settled moment (at most a few hundred on this
    # bus, whose master does not always wait for an answer): never the capture
    assert 50 <= Kept.rows <= 8 * 100 <= len(rows) / 10


@pytest.mark.parametrize("selection", [[], *SELECTIONS[1:]])
@pytest.mark.parametrize("fmt", FORMATS, ids=lambda f: f[1])
def test_a_sidecar_read_back_in_both_passes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fmt: list[str], selection: list[str]
) -> None:
    """With a sidecar (written by the first run, read back by the next, a block at a
    time, in both passes: nothing framed), the listing is the same, -c and filters too."""
    monkeypatch.delenv("MODSCOPE_NO_INDEX")
    monkeypatch.setattr(index, "MIN_SIZE", 0)
    monkeypatch.setattr(index, "pays", lambda capture, mode: True)  # (serial pcapng too)
    monkeypatch.setattr(index, "BLOCK", 50)
    reg = device_image()
    reads = [*[(40072, 50), (40124, 53)] * 60, *discovery(reg, 40000), (40072, 50)]
    path = write_capture(tmp_path / "sunspec.pcapng", frames_of(reg, reads))
    argv = [str(path), *fmt, *selection]
    first = listed(argv, monkeypatch, 7, 5)
    assert Path(str(path) + index.SUFFIX).exists() and Kept.cuts > 0
    Kept.cuts = 0
    assert listed(argv, monkeypatch, 7, 5) == first
    assert Kept.cuts == 0
    assert first[0] == whole(argv)


@pytest.mark.parametrize("fmt", ["text", "jsonl", "csv"])
def test_export_of_frames_in_segments(
    tmp_path: Path, fmt: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`export -o x.jsonl` (text, csv) writes the listing replay writes, a segment at a
    time too."""
    frames = [(f.raw, f.t) for f in polling_frames(1500, line=LINE)]
    path = recorded(tmp_path / "poll.pcapng", reads_of(frames, 0.016))
    monkeypatch.setattr(streamed, "LEARN_WINDOW", 40)
    monkeypatch.setattr(streamed, "LIST_WINDOW", 60)
    target = tmp_path / f"out.{'txt' if fmt == 'text' else fmt}"
    args = build_parser().parse_args(["export", str(path), "-o", str(target), "--jobs", "1"])
    err = io.StringIO()
    assert args.func(args, io.StringIO(), err) == 0
    assert target.read_bytes().decode("utf-8") == whole([str(path), "--format", fmt])
    assert Kept.cuts > 20 and f": 1500 frames ({fmt})" in err.getvalue()
