"""The sidecar index: a capture indexed once reads back to the same rows, listing and stats,
and a sidecar that no longer fits (changed capture, other settings, damage) is not used."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from sniffer.cli import main
from sniffer.framing.store import COLUMNS
from sniffer.model import LineSettings
from sniffer.session import index
from sniffer.session.session import Session, open_session
from sniffer.sources import ReadOptions
from sniffer.sources.linktypes import LINKTYPE_RTAC_SERIAL
from sniffer.sources.pcapng_writer import (
    EPB_FLAG_INBOUND,
    PcapngWriter,
    describe_interface,
    rtac_record,
)
from sniffer.sources.synth import polling_frames

LINE = LineSettings(baud=115200, bytesize=8, parity="N", stopbits=1, mode="rtu")
T0 = 1_714_564_800.0


@pytest.fixture
def capture(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A recording of 3000 frames in 16 ms reads, with a CRC error and stray bytes, and
    sidecars allowed for it (MIN_SIZE 0, the cache folder in tmp_path), in blocks of 500
    rows."""
    monkeypatch.setattr(index, "MIN_SIZE", 0)
    monkeypatch.setattr(index, "BLOCK", 500)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv("MODSCOPE_NO_INDEX", raising=False)
    frames = polling_frames(3000, line=LINE, seed=3)
    path = tmp_path / "bus.pcapng"
    with path.open("wb") as out:
        writer = PcapngWriter(out)
        iface = writer.add_interface(
            LINKTYPE_RTAC_SERIAL, name="ttyUSB0", description=describe_interface(LINE)
        )
        buf, t_read = bytearray(), 0.016
        for k, f in enumerate(frames):
            if f.t >= t_read and buf:
                t = T0 + t_read
                data = bytes(buf)
                packet = rtac_record(t - len(data) * LINE.char_time, data)
                writer.write_packet(iface, t, packet, flags=EPB_FLAG_INBOUND)
                buf.clear()
                while t_read <= f.t:
                    t_read += 0.016
            raw = bytearray(f.raw)
            if k == 100:
                raw[-1] ^= 0xFF  # a CRC error
            if k == 200:
                buf += b"\x00\xff"  # stray bytes
            buf += raw
        t = T0 + t_read
        writer.write_packet(iface, t, rtac_record(t - 0.001, bytes(buf)), flags=EPB_FLAG_INBOUND)
    return path


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
