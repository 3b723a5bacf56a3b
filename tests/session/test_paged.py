"""The TUI's paged rows (sniffer.session.paged): the same rows, bytes and descriptions as a store
holding every row, however they reached the paged store."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest

from sniffer.framing.store import COLUMNS, FrameStore
from sniffer.meaning.annotate import Annotator, load_bindings
from sniffer.meaning.describe import Describer
from sniffer.meaning.select import row_words
from sniffer.session import index
from sniffer.session.paged import HOT, PagedStore, wanted
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, open_session
from sniffer.session.state import SessionState
from sniffer.tui.feed import FeedProgress, Pacing, feed_capture
from sniffer.tui.model import ViewModel
from sniffer.tui.render import Styles, columns_for
from tests.support.netbus import STEPS, network_bus


@pytest.fixture
def demo(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The demo capture in tmp_path, allowed a sidecar (MIN_SIZE 0) in blocks of 64 rows,
    so that its 1,600 rows come in some 25 segments."""
    monkeypatch.setattr(index, "MIN_SIZE", 0)
    monkeypatch.setattr(index, "pays", lambda capture, mode: True)  # (serial pcapng too)
    monkeypatch.setattr(index, "BLOCK", 64)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv("MODSCOPE_NO_INDEX", raising=False)
    path = tmp_path / "demo.pcapng"
    shutil.copyfile(DEMO_CAPTURE, path)
    return path


def whole(path: Path) -> Session:
    session, capture = open_session(path, bindings=load_bindings(DEMO_BUS), index=False)
    session.ingest(capture.chunks())
    session.store.sync()
    return session


def paged(path: Path, batch: bool = False) -> tuple[Session, PagedStore, list[FeedProgress]]:
    """The capture fed as the TUI feeds a capture that gets a sidecar. A window is cut
    at the end of a chunk at the soonest: `batch` False has the reader pass the demo's
    reads one at a time (many segments), True in the runs it passes a big capture in
    (the demo: two segments)."""
    session, capture = open_session(path, bindings=load_bindings(DEMO_BUS), interactive=True)
    session.batch_reads = batch
    assert wanted(session, live=False, speed=None)
    store = PagedStore()
    published: list[FeedProgress] = []
    feed_capture(session, capture.chunks(), Pacing(), published.append, paged=store)
    return session, store, published


def assert_same_rows(full: Session, session: Session, store: PagedStore) -> None:
    n = len(full.store)
    assert n > 1000 and len(store) == n
    for name in COLUMNS:
        assert list(getattr(store, name)[0:n]) == list(getattr(full.store, name)), name
        assert getattr(store, name)[n - 1] == getattr(full.store, name)[n - 1], name
    assert [store.raw(i) for i in range(n)] == [full.store.raw(i) for i in range(n)]
    assert store.notes == full.store.notes
    assert store.bytes_total == full.store.bytes_total
    assert (store.stamps, store.resolution) == (full.store.stamps, full.store.resolution)
    # what the TUI shows of each row: names, values, units, problems (the annotator's
    # parameter windows and SunSpec scale factors numbered in the whole capture)
    mine = Describer(store, session.annotator)
    theirs = Describer(full.store, full.annotator)
    for i in range(n):
        a, b = mine.detail(i), theirs.detail(i)
        assert row_words(a) == row_words(b), i
        assert a.view == b.view


@pytest.mark.parametrize("batch", [False, True])
def test_rows_written_segment_by_segment_are_those_of_the_whole_store(
    demo: Path, batch: bool
) -> None:
    full = whole(demo)
    session, store, published = paged(demo, batch)
    assert_same_rows(full, session, store)
    assert len(store._blocks) > 20  # many segments or blocks of the sidecar
    assert published[-1].done and published[-1].rows == len(full.store)
    assert [p.rows for p in published] == sorted(p.rows for p in published)
    assert session.indexed_from is None and index.sidecars(demo)[0].exists()
    # only the narrow columns are kept; the others are read from the sidecar
    assert all(isinstance(getattr(store, name), type(full.store.kind)) for name in HOT)
    hot = sum(getattr(full.store, name).itemsize for name in HOT) * len(store)
    assert hot == 13 * len(store)
    assert store.memory_bytes() - store._cached == hot  # the rest: what the cache holds


def test_rows_read_back_from_the_sidecar_block_by_block_are_the_same(demo: Path) -> None:
    full = whole(demo)
    paged(demo)  # writes the sidecar
    session, store, published = paged(demo)
    assert session.indexed_from == index.sidecars(demo)[0]
    assert_same_rows(full, session, store)
    assert published[-1].done and published[-1].rows == len(full.store)
    # the statistics came back from the sidecar with the rows
    assert session.stats.units.keys() == full.stats.units.keys()
    for unit, stats in full.stats.units.items():
        assert list(session.stats.units[unit].latencies) == list(stats.latencies)


def test_with_nowhere_to_write_a_sidecar_the_rows_stay_in_memory(
    demo: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    blocked = tmp_path / "not-a-folder"
    blocked.write_text("a file where the sidecar's folder would be")
    monkeypatch.setattr(index, "sidecars", lambda capture: [blocked / "x.modscope-index"])
    full = whole(demo)
    session, store, _published = paged(demo)
    assert_same_rows(full, session, store)
    assert all(block.columns is not None for block in store._blocks)


def test_a_sidecar_given_up_halfway_keeps_its_rows_and_the_rest_in_memory(
    demo: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    add = index.Writer.add
    calls = [0]

    def add_then_fail(self: index.Writer, state: SessionState) -> None:
        calls[0] += 1
        if calls[0] == 5:  # as if the disk filled up (the demo: some 25 segments)
            self.abandon()
            return
        add(self, state)

    monkeypatch.setattr(index.Writer, "add", add_then_fail)
    full = whole(demo)
    session, store, _published = paged(demo)
    assert_same_rows(full, session, store)
    in_file = [block.columns is None for block in store._blocks]
    assert in_file == sorted(in_file, reverse=True) and True in in_file and False in in_file
    assert not index.sidecars(demo)[0].exists()  # (the file read from was let go of)


def test_a_damaged_block_after_the_first_asks_for_the_capture_again(demo: Path) -> None:
    paged(demo)
    _session, read_back, _published = paged(demo)
    sidecar = index.sidecars(demo)[0]
    data = bytearray(sidecar.read_bytes())
    data[read_back._blocks[5].pos + 3] ^= 0xFF  # a column of the sixth block
    sidecar.write_bytes(bytes(data))
    _session, store, published = paged(demo)
    assert published[-1].reopen and published[-1].done
    assert 0 < published[-1].rows == len(store) == read_back._blocks[5].start


def test_the_paged_columns_index_and_slice_as_arrays(demo: Path) -> None:
    full = whole(demo)
    _session, store, _published = paged(demo)
    n = len(store)
    t, theirs = store.t, full.store.t
    assert t[-1] == theirs[-1] and t[5:300:7] == theirs[5:300:7]
    assert t[n - 10 : n + 10] == theirs[n - 10 :]
    assert len(t) == n and list(t)[:3] == list(theirs[:3])
    with pytest.raises(IndexError):
        t[n]
    # bytes that two blocks carry between them come back whole
    stream = store.streams[0]
    assert stream[0 : len(stream)] == bytes(full.store.streams[0])


def test_rows_are_published_only_once_complete_while_the_feed_runs(demo: Path) -> None:
    """A reader in another thread sees rows below len() with every column complete."""
    session, capture = open_session(demo, bindings=load_bindings(DEMO_BUS))
    store = PagedStore()
    seen: list[int] = []

    def publish(p: FeedProgress) -> None:
        n = p.rows
        assert n <= len(store)
        if n:
            store.view(n - 1)  # every column readable
            seen.append(n)

    feed_capture(session, capture.chunks(), Pacing(), publish, paged=store, first=0.0, every=0.0)
    assert len(seen) > 5 and seen[-1] == len(store)


def test_the_view_model_lists_the_same_lines_paged_or_not(demo: Path) -> None:
    full = whole(demo)
    session, store, _published = paged(demo)
    cols = columns_for(120, False, 60.0, len(store))
    styles: Styles = {}
    plain = ViewModel(full)
    plain.publish(len(full.store))
    plain.shown = len(full.store)
    plain.update_view()
    mine = ViewModel(session, store)
    mine.publish(len(store))
    mine.shown = len(store)
    mine.update_view()
    assert mine.reader is store
    assert [mine.line(k, cols, styles).plain for k in range(len(store))] == [
        plain.line(k, cols, styles).plain for k in range(len(full.store))
    ]
    assert mine.last_answer == plain.last_answer


def test_the_annotator_keeps_its_rows_numbered_in_the_capture(demo: Path) -> None:
    full = whole(demo)
    session, _store, _published = paged(demo)
    mine: Annotator = session.annotator
    assert mine.keep_rows
    for key, track in full.annotator.tracks.items():
        assert mine.tracks[key].rows == track.rows
        assert mine.tracks[key].numbers == track.numbers
    assert any(track.rows for track in full.annotator.tracks.values())


def test_a_small_capture_or_a_replay_at_its_own_speed_is_not_paged(
    demo: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session, _capture = open_session(demo)
    assert wanted(session, live=False, speed=None)
    assert not wanted(session, live=False, speed=1.0)
    assert not wanted(session, live=True, speed=None)
    monkeypatch.setattr(index, "MIN_SIZE", demo.stat().st_size + 1)
    small, _capture = open_session(demo)
    assert not wanted(small, live=False, speed=None)


@pytest.mark.asyncio
async def test_the_app_pages_a_capture_with_a_sidecar_and_shows_every_row(demo: Path) -> None:
    from sniffer.tui.app import ModscopeApp
    from tests.support.tui import ready

    full = whole(demo)
    session, capture = open_session(demo, bindings=load_bindings(DEMO_BUS))
    app = ModscopeApp(session, capture, blink=False)
    async with app.run_test(size=(100, 30)) as pilot:
        await ready(pilot, app)
        assert app.model.paged is not None
        assert app.model.published == len(full.store)
        # the estimate from the file's size counts each read of a batch as its packet
        progress = app.feeding.index_progress()
        assert progress is not None and 0.9 < progress <= 0.99
        await pilot.press("end")
        await pilot.pause()
        last = app.model.describer.detail(len(full.store) - 1)
        assert last.view == full.store.view(len(full.store) - 1)
        await pilot.press("t")  # one row per transaction, over the hot columns
        await pilot.pause(0.3)
        shown: Any = app.model.view
        assert 0 < len(shown) < len(full.store)


def test_a_store_is_a_frame_store() -> None:
    assert isinstance(PagedStore(), FrameStore) and len(PagedStore()) == 0


@pytest.mark.parametrize("pages", [True, False])
def test_the_feed_says_how_far_it_is_through_the_file_or_its_sidecar(
    demo: Path, pages: bool
) -> None:
    size = demo.stat().st_size
    for read in ("the capture", "its sidecar"):
        session, capture = open_session(demo)
        session.batch_reads = False
        published: list[FeedProgress] = []
        feed_capture(
            session,
            capture.chunks(),
            Pacing(),
            published.append,
            paged=PagedStore() if pages else None,
            size=size,
            first=0.0,
            every=0.0,
            breather=0.0,
        )
        shares = [p.share for p in published]
        assert all(s is not None for s in shares), shares
        assert shares == sorted(shares)  # type: ignore[type-var]
        # (the sidecar's share is of its blocks: its header and the demo's are as big)
        assert (0.9 if read == "the capture" else 0.5) < (shares[-1] or 0) <= 0.99
    assert session.indexed_from is not None  # the second pass read the sidecar back


def test_pages_smaller_than_a_block_read_the_same_rows_and_bytes(
    demo: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Columns and bytes are read a page at a time; pages that end inside a frame, a
    block or a slice give the same values."""
    import sniffer.session.paged as paged_module

    monkeypatch.setattr(index, "PIECE", 13)  # bytes packed in pieces of 13
    monkeypatch.setattr(paged_module, "CACHE_BYTES", 200)  # pages come and go
    full = whole(demo)
    for _pass in ("written", "read back"):
        session, store, _published = paged(demo)
        assert_same_rows(full, session, store)
        n = len(store)
        assert store.t[3 : n - 3 : 5] == full.store.t[3 : n - 3 : 5]
        stream = store.streams[0]
        assert stream[5 : len(stream) - 5] == bytes(full.store.streams[0][5:-5])
        assert store._cached <= 200 + 13 * 8


def test_the_first_rows_are_published_once_written_not_at_the_next_progress(
    demo: Path,
) -> None:
    for _pass in ("written", "read back"):
        session, capture = open_session(demo)
        session.batch_reads = False
        store = PagedStore()
        published: list[FeedProgress] = []
        # progress as good as never: only the first rows and the end are published (the
        # ingest's own last progress call too publishes once `every` has passed since the
        # first rows: under load that was 0.25 s, and this test failed)
        feed_capture(
            session,
            capture.chunks(),
            Pacing(),
            published.append,
            paged=store,
            first=3600,
            every=3600,
        )
        assert [p.done for p in published] == [False, True]
        assert 0 < published[0].rows < published[1].rows == len(store)


@pytest.mark.parametrize("again", [False, True])
def test_a_network_capture_pages_with_its_peers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, again: bool
) -> None:
    """A network capture is paged too (cut where no request waits for an answer), and
    its rows keep their senders and servers (`ip:port`), written segment by segment or
    read back from the sidecar (which lost them before its format 4)."""
    monkeypatch.setattr(index, "MIN_SIZE", 0)
    monkeypatch.setattr(index, "pays", lambda capture, mode: True)  # (serial pcapng too)
    monkeypatch.setattr(index, "BLOCK", 64)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv("MODSCOPE_NO_INDEX", raising=False)
    path = tmp_path / "net.pcap"
    path.write_bytes(network_bus([(k % 3, STEPS[k % len(STEPS)]) for k in range(700)]))
    full = whole(path)
    assert full.store.peers and full.store.servers
    if again:
        paged(path)  # writes the sidecar
    session, store, _ = paged(path)
    assert (session.indexed_from is not None) == again
    assert_same_rows(full, session, store)
    assert len(store._blocks) > 10
    assert (store.peers, store.servers) == (full.store.peers, full.store.servers)
