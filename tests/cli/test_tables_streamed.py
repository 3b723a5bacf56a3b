"""`export --what transactions|registers` (CSV, JSONL) and every Parquet table write a
serial capture a segment at a time too (issue #29, `sniffer.session.streamed`), as the
frame listings do: their bytes (Parquet: their rows) must be those of the table of one
store of every row, whatever the windows, the filter and -c, rows numbered in the whole
capture and named as after every row; and the rows kept must not grow with the capture.

The windows are a few rows and the reads come one by one, as in test_listing_streamed."""

from __future__ import annotations

import argparse
import io
import json
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sniffer.cli import build_parser
from sniffer.cli.filtering import Selection, query_of
from sniffer.cli.options import bindings_for, read_options
from sniffer.outputs import parquet
from sniffer.outputs.export import (
    REGISTER_COLUMNS,
    TRANSACTION_COLUMNS,
    register_records,
    transaction_records,
    write_table,
)
from sniffer.session import streamed
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, open_session
from sniffer.sources.synth import polling_frames
from tests.cli.test_listing_streamed import Kept, _bundled, _one_by_one
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

__all__ = ["_one_by_one"]  # (the module's autouse fixture: reads one by one, cuts counted)

DEMO = [str(DEMO_CAPTURE), "--bus", str(DEMO_BUS)]
TABLES = [(what, fmt) for what in ("transactions", "registers") for fmt in ("csv", "jsonl")]


def _session(argv: list[str]) -> tuple[argparse.Namespace, Session]:
    args = build_parser().parse_args(["export", *argv, "-o", "x.csv"])
    session, capture = open_session(
        Path(args.file), read_options(args), bindings=bindings_for(args), index=False
    )
    session.ingest(capture.chunks())
    return args, session


def whole(argv: list[str], what: str, fmt: str) -> str:
    """The table of one store holding every row, as before (CSV or JSONL)."""
    args, session = _session(argv)
    rows = Selection(session, query_of(args), args.count).take(len(session.store), final=True)
    maker = transaction_records if what == "transactions" else register_records
    columns = TRANSACTION_COLUMNS if what == "transactions" else REGISTER_COLUMNS
    out = io.StringIO()
    write_table(out, fmt, columns, maker(session.describer, rows), raw_csv=False)
    return out.getvalue()


def exported(
    argv: list[str],
    target: Path,
    monkeypatch: pytest.MonkeyPatch,
    learn: int,
    window: int,
) -> tuple[bytes, str]:
    """The bytes `modscope export ARGV -o TARGET` writes and its stderr, the first pass
    keeping `learn` rows, the second `window` (a capture with lines skipped exits 1, one
    of noise alone 2, and the table is written all the same)."""
    monkeypatch.setattr(streamed, "LEARN_WINDOW", learn)
    monkeypatch.setattr(streamed, "LIST_WINDOW", window)
    args = build_parser().parse_args(["export", *argv, "-o", str(target), "--jobs", "1"])
    err = io.StringIO()
    assert args.func(args, io.StringIO(), err) in (0, 1, 2), err.getvalue()
    return target.read_bytes(), err.getvalue()


def _same(
    argv: list[str],
    what: str,
    fmt: str,
    tmp: Path,
    monkeypatch: pytest.MonkeyPatch,
    windows: list[tuple[int, int]],
) -> str:
    reference = whole(argv, what, fmt)
    target = tmp / f"out.{fmt}"
    for learn, window in [(1 << 30, 1 << 30), *windows]:
        got, err = exported([*argv, "--what", what], target, monkeypatch, learn, window)
        assert got.decode("utf-8") == reference, (what, fmt, learn, window)
        count = len(reference.splitlines()) - (fmt == "csv")
        assert f": {count} {what} ({fmt})" in err
    return reference


# a filter, -c, and a filter nothing passes (a CSV table of its header alone); one
# format each (the tables are written alike in both: `write_table`)
EXTRAS = {
    ("transactions", "csv"): [["--filter", "reg:Voltage or fc:16"], ["--filter", "unit:99"]],
    ("registers", "jsonl"): [["--filter", "reg:Voltage or fc:16", "-c", "40"], ["-c", "9"]],
}


@pytest.mark.parametrize(("what", "fmt"), list(EXTRAS))
def test_the_demo_tables_in_segments(
    what: str, fmt: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The demo's bus file names registers through parameter windows and scales: a
    segment must name them as one store does; a transaction's answer is in its request's
    segment (segments end only when no request is open)."""
    table = _same(DEMO, what, fmt, tmp_path, monkeypatch, [(1, 1)])
    assert Kept.cuts > 100
    if fmt == "jsonl":  # numbered in the whole capture, to the last record
        last = json.loads(table.splitlines()[-1])
        key = "request" if what == "transactions" else "index"
        assert last[key] > 1000
    for extra in EXTRAS[(what, fmt)]:
        _same([*DEMO, *extra], what, fmt, tmp_path, monkeypatch, [(3, 2)])


@needs_models
def test_registers_named_by_models_found_later(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The master polls a SunSpec device's values before it reads the models: one store
    names the first polls' registers with the models found later, and so must each
    segment."""
    reg = device_image()
    polls = [(40072, 50), (40124, 53)]
    reads = [*polls * 6, *discovery(reg, 40000), *polls * 6]
    capture = write_capture(tmp_path / "sunspec.pcapng", frames_of(reg, reads))
    table = _same([str(capture)], "registers", "jsonl", tmp_path, monkeypatch, [(2, 3), (7, 2)])
    first = json.loads(table.splitlines()[0])
    assert first["index"] == 1 and first["name"]  # the first poll's answer, named


@settings(
    max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    steps=STEP_LISTS,
    pauses=PAUSE_LISTS,
    every=READ_EVERY,
    window=st.integers(1, 12),
    table=st.sampled_from(TABLES),
    selection=st.sampled_from([[], ["-c", "5"], ["--filter", "status:timeout or kind:exception"]]),
)
def test_random_buses_tabled_alike_in_segments(
    tmp_path_factory: pytest.TempPathFactory,
    monkeypatch: pytest.MonkeyPatch,
    steps: list[str],
    pauses: list[float],
    every: float,
    window: int,
    table: tuple[str, str],
    selection: list[str],
) -> None:
    """Open requests, timeouts, exceptions, noise and echoes next to the cuts."""
    tmp = tmp_path_factory.mktemp("bus")
    path = recorded(tmp / "bus.pcapng", reads_of(scripted(steps, pauses), every))
    what, fmt = table
    _same([str(path), *selection], what, fmt, tmp, monkeypatch, [(window, window), (3, 1)])


@pytest.mark.parametrize("path", _bundled(), ids=lambda p: p.name)
def test_every_bundled_capture_tabled_in_segments(
    path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every format modscope reads (logs, hex dumps, sigrok, pcap of serial and network
    captures, ASCII), both tables."""
    for what, fmt in (("transactions", "csv"), ("registers", "jsonl")):
        _same([str(path)], what, fmt, tmp_path, monkeypatch, [(3, 2)])


def _parquet_rows(path: Path) -> list[dict[str, Any]]:
    import pyarrow.parquet as pq

    rows: list[dict[str, Any]] = pq.read_table(path).to_pylist()
    return rows


@pytest.mark.parametrize("what", ["frames", "transactions", "registers"])
def test_parquet_in_segments(what: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A Parquet table is written as its row groups fill, across segments: the rows are
    those of the table of one store, numbered in the whole capture."""
    pytest.importorskip("pyarrow")
    monkeypatch.setattr(parquet, "ROW_GROUP", 50)  # row groups across segments' ends
    _args, session = _session(DEMO)
    reference = tmp_path / "whole.parquet"
    parquet.write_parquet(reference, what, session.describer, range(len(session.store)))
    expected = _parquet_rows(reference)
    assert len(expected) > 200
    target = tmp_path / "x.parquet"
    for learn, window in [(1, 1)]:
        _bytes, err = exported([*DEMO, "--what", what], target, monkeypatch, learn, window)
        assert _parquet_rows(target) == expected, (what, learn, window)
        assert f": {len(expected)} {what} (parquet)" in err
    assert Kept.cuts > 100


def test_a_table_keeps_rows_flat_in_the_capture(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each pass keeps about its window of rows, not every row: counted through the
    store's size when a segment is cut, for a capture of 80 times the window."""
    frames = [(f.raw, f.t) for f in polling_frames(2000, line=LINE)]
    path = recorded(tmp_path / "poll.pcapng", reads_of(frames, 0.016))
    out, _err = exported(
        [str(path), "--what", "registers"], tmp_path / "r.jsonl", monkeypatch, 12, 25
    )
    records = out.decode().splitlines()
    assert len(records) > 2000 and json.loads(records[-1])["index"] > 1900
    assert Kept.cuts > 100
    assert 12 <= Kept.rows <= 8 * 25
    assert out.decode() == whole([str(path)], "registers", "jsonl")


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_the_second_pass_shows_its_progress(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On a terminal, the second pass says how far it wrote (the first says how far it
    read), and the line is cleared before the summary."""
    frames = [(f.raw, f.t) for f in polling_frames(2000, line=LINE)]
    path = recorded(tmp_path / "poll.pcapng", reads_of(frames, 0.016))
    clock = [100.0]

    def ticking() -> float:
        clock[0] += 0.3  # every look at the clock a while later: each update is due
        return clock[0]

    monkeypatch.setattr("sniffer.cli.progress.time.monotonic", ticking)
    monkeypatch.setattr(streamed, "LEARN_WINDOW", 200)
    monkeypatch.setattr(streamed, "LIST_WINDOW", 300)
    target = tmp_path / "t.csv"
    args = build_parser().parse_args(
        ["export", str(path), "--what", "transactions", "-o", str(target)]
    )
    err = _Terminal()
    assert args.func(args, io.StringIO(), err) == 0
    said = err.getvalue()
    shares = [int(p.split("%")[0]) for p in said.split("writing poll.pcapng: ")[1:]]
    assert len(shares) >= 3 and shares == sorted(shares) and shares[-1] >= 80
    last = said.rsplit("\r\x1b[K", 1)[1]  # after the line was cleared: the summary alone
    assert last == f"{target}: {len(target.read_text().splitlines()) - 1} transactions (csv)\n"
