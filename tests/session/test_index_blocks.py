"""The sidecar index read a block at a time: rows handed out after each block are those
indexing gives, a damaged block is found before its rows join the store, and the TUI
starts over from the capture when rows it showed came from a damaged sidecar."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sniffer.framing.store import COLUMNS
from sniffer.session import index
from sniffer.session.session import Session, open_session
from sniffer.tui.feed import FeedProgress, Pacing, feed_capture
from tests.support.index import (
    _ingested,
    _same,
)


def _block_start(side: Path, k: int) -> int:
    """Where block `k` of a sidecar starts."""
    data = side.read_bytes()
    size: int = index._PREFIX.unpack_from(data, len(index.MAGIC))[0]
    start = len(index.MAGIC) + index._PREFIX.size
    header = json.loads(data[start : start + size])
    at = start + size
    for _count, _pieces, _crc, length in header["blocks"][:k]:
        at += int(length)
    return at


def _damage(side: Path, k: int) -> None:
    data = bytearray(side.read_bytes())
    data[_block_start(side, k) + 10] ^= 0xFF
    side.write_bytes(bytes(data))


def test_rows_come_a_block_at_a_time_and_are_those_indexing_gives(capture: Path) -> None:
    fresh = _ingested(capture, index=False)
    _ingested(capture)  # writes the sidecar
    session, cap = open_session(capture)
    seen: list[int] = []

    def progress(done: int, rows: int) -> None:
        seen.append(rows)
        store = session.store
        assert len(store) == rows
        for name in COLUMNS:  # every column of the rows handed out, as indexing has them
            assert getattr(store, name) == getattr(fresh.store, name)[:rows], name
        assert session.annotator.next == rows  # the annotator has seen them
        for ch, data in store.streams.items():
            assert fresh.store.streams[ch].startswith(data)
        assert 0 < done <= capture.stat().st_size

    session.ingest(cap.chunks(), progress, shown=True)
    session.warnings.extend(cap.warnings)
    assert session.indexed_from is not None
    n = len(fresh.store)
    assert seen == [*range(index.BLOCK, n, index.BLOCK), n]
    _same(fresh, session)


def test_a_damaged_block_takes_its_rows_back_and_the_capture_is_indexed(capture: Path) -> None:
    fresh = _ingested(capture, index=False)
    _ingested(capture)
    side = Path(str(capture) + index.SUFFIX)
    _damage(side, 3)
    again = _ingested(capture)
    assert again.indexed_from is None
    _same(fresh, again)
    assert _ingested(capture).indexed_from is not None  # rewritten


def test_rows_shown_from_a_damaged_sidecar_are_not_taken_back(capture: Path) -> None:
    fresh = _ingested(capture, index=False)
    _ingested(capture)
    side = Path(str(capture) + index.SUFFIX)
    _damage(side, 3)
    session, cap = open_session(capture)
    with pytest.raises(index.DamagedError):
        session.ingest(cap.chunks(), lambda done, rows: None, shown=True)
    assert len(session.store) == 3 * index.BLOCK  # the rows before the damaged block stay
    for name in COLUMNS:
        assert getattr(session.store, name) == getattr(fresh.store, name)[: 3 * index.BLOCK]
    # opened again (as the TUI does), the damaged sidecar is not read: the capture is
    again = _ingested(capture)
    assert again.indexed_from is None
    _same(fresh, again)


def test_the_tui_feed_asks_to_start_over_on_a_damaged_sidecar(capture: Path) -> None:
    _ingested(capture)
    _damage(Path(str(capture) + index.SUFFIX), 2)
    session, cap = open_session(capture)
    seen: list[FeedProgress] = []
    feed_capture(session, cap.chunks(), Pacing(), seen.append, every=0.0)
    assert seen[0].rows == index.BLOCK and not seen[0].done
    assert seen[-1].done and seen[-1].reopen and "damaged" in seen[-1].error


def test_a_damaged_first_block_is_found_before_any_row_is_shown(capture: Path) -> None:
    fresh = _ingested(capture, index=False)
    _ingested(capture)
    _damage(Path(str(capture) + index.SUFFIX), 0)
    session, cap = open_session(capture)
    seen: list[FeedProgress] = []
    feed_capture(session, cap.chunks(), Pacing(), seen.append, every=0.0)
    assert seen[-1].done and not seen[-1].reopen and not seen[-1].error
    assert session.indexed_from is None
    session.warnings.extend(cap.warnings)
    _same(fresh, session)


def test_a_replay_at_the_original_speed_reads_the_capture(capture: Path) -> None:
    _ingested(capture)
    session, cap = open_session(capture)
    session.ingest(cap.chunks(), index=False)
    assert session.indexed_from is None


def test_a_sidecar_of_the_older_format_is_indexed_again(
    capture: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with monkeypatch.context() as m:
        m.setattr(index, "FORMAT", 1)
        _ingested(capture)
    assert _ingested(capture).indexed_from is None
    assert _ingested(capture).indexed_from is not None


def test_an_empty_store_has_one_block(capture: Path) -> None:
    session = Session(_ingested(capture, index=False).line)
    blocks = index._blocks(session.store, 0)
    assert blocks == [(0, 0, [])]


@pytest.mark.asyncio
async def test_the_tui_starts_over_from_the_capture_on_a_damaged_sidecar(capture: Path) -> None:
    from sniffer.tui.app import ModscopeApp

    fresh = _ingested(capture, index=False)
    _ingested(capture)
    _damage(Path(str(capture) + index.SUFFIX), 2)
    session, cap = open_session(capture)
    app = ModscopeApp(session, cap, blink=False)
    async with app.run_test(size=(120, 36)) as pilot:
        for _ in range(1000):
            if app.indexed.is_set() and app.session is not session:
                break
            await pilot.pause(0.01)
        await pilot.pause()
        assert app.session is not session and app.session.indexed_from is None
        assert app.model.published == app.frames.count == len(fresh.store)
        assert any("indexing the capture again" in said for said in app.said)
