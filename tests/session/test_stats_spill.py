"""A windowed `replay --stats` counts latencies and request times in their bounded form
and hands every value to the sidecar being written (`index.Spill`, a temporary file),
so its memory does not grow with the capture while the sidecar is the one a store
holding every value writes."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

from sniffer.session import index
from sniffer.session.session import Session, open_session
from sniffer.sources.synth import polling_frames
from tests.support.index import LINE, _ingested


@pytest.fixture
def framed(capture: Path) -> Path:
    """1000 frames of a polling bus as a logic analyser's export (Saleae CSV, a line a
    byte with its own time): exact stamps, so latencies are measured (the `capture`
    fixture's 16 ms reads only bound them); sidecars allowed as for it."""
    path = capture.with_name("framed.csv")
    lines = ["Time [s],Value,Parity Error,Framing Error"]
    for f in polling_frames(1000, line=LINE, seed=5):
        for k, byte in enumerate(f.raw):
            lines.append(f"{f.t + k * LINE.char_time:.9f},0x{byte:02X},,")
    path.write_text("\n".join(lines) + "\n")
    return path


def _values(session: Session) -> dict[int, tuple[list[float], list[float]]]:
    return {
        u: (list(st.latencies), list(st.request_times)) for u, st in session.stats.units.items()
    }


def _windowed(capture: Path) -> Session:
    session, source = open_session(capture)
    session.ingest(source.chunks(), window=400, bounded=True)
    return session


# chunks of 3 values in pieces of 4 (neither divides the other), and the real sizes
@pytest.mark.parametrize(("chunk", "piece"), [(3, 4), (8192, 1 << 16)])
def test_the_sidecar_keeps_every_value_the_bounded_statistics_counted(
    framed: Path, monkeypatch: pytest.MonkeyPatch, chunk: int, piece: int
) -> None:
    capture = framed
    monkeypatch.setattr(index.Spill, "CHUNK", chunk)  # 3: many chunks and a rest
    monkeypatch.setattr(index, "TAIL_PIECE", piece)  # 4, 7: many pieces a part
    whole = _ingested(capture, index=False)  # every value kept, no sidecar
    expected = _values(whole)
    assert sum(len(lat) for lat, _ in expected.values()) > 300
    assert sum(len(times) for _, times in expected.values()) > 300

    windowed = _windowed(capture)
    # nothing kept in memory: every unit counted in tallies, its arrays empty
    assert windowed.stats.units.keys() == expected.keys()
    for st in windowed.stats.units.values():
        assert st.tallies is not None and not st.latencies and not st.request_times
    assert windowed.stats.table() == whole.stats.table()

    back = _ingested(capture)  # from the sidecar the windowed replay wrote
    assert back.indexed_from is not None
    assert _values(back) == expected
    assert back.stats.table() == whole.stats.table()


def test_the_sidecar_read_back_by_a_windowed_replay_is_counted_bounded(
    framed: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Counted a piece of the tail at a time (5: pieces of 5 values, each unpacked only
    as it is counted), the statistics are those of every value."""
    piece = 5
    monkeypatch.setattr(index, "TAIL_PIECE", piece)
    unpacked: list[int] = []
    unpack = index._unpack_tail

    def counting(packed: bytes, count: int) -> object:
        unpacked.append(count)
        return unpack(packed, count)

    monkeypatch.setattr(index, "_unpack_tail", counting)
    capture = framed
    whole = _ingested(capture, index=False)
    _ingested(capture)  # writes the sidecar (every row in one store)
    session, source = open_session(capture)
    session.ingest(source.chunks(), window=400, bounded=True)
    assert session.indexed_from is not None
    for st in session.stats.units.values():
        assert st.tallies is not None and not st.latencies
    assert session.stats.table() == whole.stats.table()
    assert max(unpacked) <= piece and sum(unpacked) > 600
    for unit, st in whole.stats.units.items():
        tallies = session.stats.units[unit].tallies
        assert tallies is not None
        assert list(tallies.recent_latencies) == list(
            st.latencies[-len(tallies.recent_latencies) :]
        )
        assert tallies.requests == len(st.request_times)


def test_without_a_temporary_file_the_values_stay_in_memory(
    framed: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    capture = framed

    def refused(*args: object, **kwargs: object) -> None:
        raise OSError(28, os.strerror(28))

    monkeypatch.setattr(index.Spill, "CHUNK", 5)
    monkeypatch.setattr(tempfile, "TemporaryFile", refused)
    expected = _values(_ingested(capture, index=False))
    _windowed(capture)
    assert _values(_ingested(capture)) == expected
