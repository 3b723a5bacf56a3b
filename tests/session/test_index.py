"""The sidecar index: a capture indexed once reads back to the same rows, listing and stats,
and a sidecar that no longer fits (changed capture, other settings, damage) is not used."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from sniffer.cli import main
from sniffer.framing.store import COLUMNS
from sniffer.session import index
from sniffer.sources import ReadOptions
from tests.support.index import _ingested, _same


def test_an_indexed_capture_reads_back_to_the_same_rows_and_listing(
    capture: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fresh = _ingested(capture, index=False)
    assert not Path(str(capture) + index.SUFFIX).exists()
    first = _ingested(capture)
    assert first.indexed_from is None
    assert Path(str(capture) + index.SUFFIX).exists()
    again = _ingested(capture)
    assert again.indexed_from == Path(str(capture) + index.SUFFIX).resolve()
    _same(fresh, first)
    _same(fresh, again)
    # the listing and the statistics, byte for byte, with and without the sidecar
    outputs = []
    for env in ("1", "0"):
        os.environ["MODSCOPE_NO_INDEX"] = env
        try:
            for argv in (["--format", "jsonl"], ["--stats"]):
                main(["replay", str(capture), *argv])
                outputs.append(capsys.readouterr())
        finally:
            del os.environ["MODSCOPE_NO_INDEX"]
    assert outputs[:2] == outputs[2:]
    assert outputs[0].out.count("\n") == len(fresh.store)


def test_a_changed_capture_or_other_settings_are_indexed_again(capture: Path) -> None:
    _ingested(capture)
    assert _ingested(capture).indexed_from is not None
    # other settings the rows depend on
    assert _ingested(capture, timeout=0.05).indexed_from is None
    assert _ingested(capture, options=ReadOptions(baud=9600)).indexed_from is None
    # the capture grew (a recording still being written)
    with capture.open("ab") as out:
        out.write(b"\0" * 8)
    grown = _ingested(capture)
    assert grown.indexed_from is None
    _same(grown, _ingested(capture, index=False))
    assert _ingested(capture).indexed_from is not None  # rewritten for the new content


@pytest.mark.parametrize(
    "damage",
    [
        lambda b: b[: len(b) // 2],  # cut short
        lambda b: b + b"more",  # longer than its header says
        lambda b: b[:30] + b"{" + b[31:],  # broken header
        lambda b: b"not an index at all",
        lambda b: b[:-5000] + bytes(5000),  # zeroed statistics and bytes: same length
    ],
)
def test_a_damaged_sidecar_is_ignored_and_rewritten(capture: Path, damage: object) -> None:
    fresh = _ingested(capture, index=False)
    _ingested(capture)
    side = Path(str(capture) + index.SUFFIX)
    assert callable(damage)
    side.write_bytes(damage(side.read_bytes()))
    again = _ingested(capture)
    _same(fresh, again)


def test_rows_pointing_outside_their_bytes_or_rows_are_refused(capture: Path) -> None:
    # a sidecar can be made by anyone (its checksum too): rows are checked before use
    session = _ingested(capture, index=False)
    store = session.store
    columns = {name: getattr(store, name) for name in COLUMNS}
    n = len(store)
    lengths = {ch: len(data) for ch, data in store.streams.items()}
    assert index._consistent(columns, lengths, n)
    for name, row, value in [
        ("offset", n - 1, len(store.streams[0])),
        ("length", n - 1, 600),  # past the end of the bytes
        ("partner", 5, n),
        ("partner", 5, -2),
        ("channel", 7, 3),
        ("kind", 9, 200),
    ]:
        bad = {k: type(v)(v.typecode, v) for k, v in columns.items()}
        bad[name][row] = value
        assert not index._consistent(bad, lengths, n), name


def test_a_folder_that_cannot_take_the_sidecar_sends_it_to_the_cache(
    capture: Path, tmp_path: Path
) -> None:
    Path(str(capture) + index.SUFFIX).mkdir()  # the place beside it is taken
    _ingested(capture)
    cached = list((tmp_path / "cache" / "modscope" / "index").glob("*" + index.SUFFIX))
    assert len(cached) == 1
    assert _ingested(capture).indexed_from == cached[0]


def test_no_index_neither_reads_nor_writes(capture: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    _ingested(capture)
    _ingested(capture)
    assert not Path(str(capture) + index.SUFFIX).exists()
    assert not (capture.parent / "cache").exists()


def test_small_captures_get_no_sidecar(capture: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(index, "MIN_SIZE", capture.stat().st_size + 1)
    _ingested(capture)
    assert not Path(str(capture) + index.SUFFIX).exists()
