"""Provides helpers shared by tests (moved from test_index.py)."""

from __future__ import annotations

from pathlib import Path

from sniffer.framing.store import COLUMNS
from sniffer.model import LineSettings
from sniffer.session.session import Session, open_session

LINE = LineSettings(baud=115200, bytesize=8, parity="N", stopbits=1, mode="rtu")
T0 = 1_714_564_800.0


def _ingested(path: Path, **kwargs: object) -> Session:
    session, capture = open_session(path, **kwargs)  # type: ignore[arg-type]
    session.ingest(capture.chunks())
    session.warnings.extend(capture.warnings)
    return session


def _same(a: Session, b: Session) -> None:
    for name in COLUMNS:
        assert getattr(a.store, name) == getattr(b.store, name), name
    assert a.store.streams == b.store.streams
    assert a.store.notes == b.store.notes
    assert (a.store.stamps, a.store.resolution) == (b.store.stamps, b.store.resolution)
    assert a.stats.table() == b.stats.table()
    assert (a.warnings, a.notes, a.mode) == (b.warnings, b.notes, b.mode)
