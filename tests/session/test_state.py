"""Tests the session's state (`sniffer.session.state`): the rows and counts a session keeps
are its state's, and a sidecar read back leaves the state that reading the capture left."""

from __future__ import annotations

from pathlib import Path

from sniffer.analysis.stats import Stats
from sniffer.framing.store import FrameStore
from sniffer.model import LineSettings
from sniffer.session.session import Session, open_session
from sniffer.session.state import SessionState
from sniffer.vocab import Kind


def test_a_sessions_rows_and_counts_are_its_states() -> None:
    session = Session(LineSettings())
    state = session.state
    assert isinstance(state, SessionState)
    assert session.store is state.store and session.pipeline is state.pipeline
    assert session.annotator is state.annotator and session.stats is state.stats
    assert session.pipeline.store is session.store  # one store, framed into and kept
    session.warnings.append("a warning")
    session.chunks += 3
    session.stream_base[1] = 40
    assert (state.warnings, state.chunks, state.stream_base) == (["a warning"], 3, {1: 40})
    merged = FrameStore()  # as several files replayed together replace the rows
    session.store, session.stats = merged, Stats(merged)
    assert state.store is merged and state.stats.store is merged


def _frames(store: FrameStore) -> int:
    kinds = store.kind.tobytes()
    return len(kinds) - kinds.count(Kind.NOISE) - kinds.count(Kind.EVENT)


def _bytes(state: SessionState) -> dict[int, int]:
    """Each channel's bytes in the whole capture."""
    streams = state.store.streams
    return {ch: state.stream_base.get(ch, 0) + len(data) for ch, data in streams.items()}


def _read(capture: Path, window: int | None = None) -> Session:
    session, opened = open_session(capture)
    session.ingest(opened.chunks(), window=window, segment=lambda s: None)
    return session


def test_a_sidecar_read_back_leaves_the_state_reading_left(capture: Path) -> None:
    for window in (None, 700):  # whole, and windowed (the sidecar read back in blocks)
        first = _read(capture, window)
        assert first.indexed_from is None
        again = _read(capture, window)
        assert again.indexed_from is not None, window
        a, b = first.state, again.state
        assert (b.warnings, b.notes, b.chunks) == (a.warnings, a.notes, a.chunks)
        # where the rows stand in the whole capture (read back windowed, each block is
        # a segment: the segments may fall elsewhere, the totals may not)
        assert b.base + len(b.store) == a.base + len(a.store)
        assert b.frames_before + _frames(b.store) == a.frames_before + _frames(a.store)
        assert _bytes(b) == _bytes(a)
        if window is None:
            assert (b.base, b.stream_base, b.frames_before) == (0, {}, 0)
            assert b.store.kind == a.store.kind
        else:
            assert b.base > 0  # blocks were read back and dropped
        assert b.pipeline.mode == a.pipeline.mode
        assert b.pipeline.pairer.next == len(b.store)  # taken as paired already
        assert b.stats.table({}) == a.stats.table({})
        assert a.stats.units and b.stats.units.keys() == a.stats.units.keys()
        for unit in a.stats.units:
            ours, theirs = a.stats.units[unit], b.stats.units[unit]
            assert (theirs.requests, theirs.responses) == (ours.requests, ours.responses)
            assert theirs.latencies == ours.latencies
        for path in capture.parent.glob("*.modscope-index"):
            path.unlink()
