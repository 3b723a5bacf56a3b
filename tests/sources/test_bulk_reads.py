"""The bulk pcapng and pcap walks and batches of reads give what the block-by-block walk
gives.

`Session.ingest` lets the pcapng and pcap readers pass runs of link type 250 and 147 reads
as one `sniffer.sources.reads.Reads`; everything else reads a capture one chunk per read.
Both must agree on every chunk, warning and row, for clean, odd and damaged files alike.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from sniffer.errors import CaptureError
from sniffer.model import Chunk
from sniffer.session.session import Session, open_session
from sniffer.sources import open_capture, pcap
from sniffer.sources.linktypes import (
    LINKTYPE_RTAC_SERIAL,
    LINKTYPE_USER0,
)
from sniffer.sources.reads import MAX_BATCH_SPAN, Reads, batching
from tests.support.reads import (
    COLUMNS,
    FRAMES,
    LINE,
    LINKTYPE_MIXES,
    PCAP_MAGIC,
    SHAPES,
    T0,
    _capture,
    _recording,
    damage,
    hurt_file,
    packet,
    pcap_capture,
)


def _chunks(path: Path, batched: bool) -> tuple[list[Chunk], list[str], int]:
    """What a walk reads of `path`; a file the damage made no capture at all (its magic
    overwritten: `PK\\3\\4` reads as a ZIP) is refused, and both walks must refuse it alike."""
    try:
        capture = open_capture(path)
    except CaptureError as exc:
        return [], [f"refused: {exc}"], 0
    with batching(batched):
        got: list[Chunk] = []
        for chunk in capture.chunks():
            got.extend(chunk.split() if isinstance(chunk, Reads) else [chunk])
    return got, capture.warnings, capture.data_bytes


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    order=st.sampled_from(["<", ">"]),
    linktypes=st.sampled_from(LINKTYPE_MIXES),
    packets=st.lists(packet, max_size=40),
    second_section=st.integers(-1, 40),
    hurt=damage,
)
def test_bulk_walk_gives_the_chunks_and_warnings_of_the_block_walk(
    tmp_path_factory: pytest.TempPathFactory,
    order: str,
    linktypes: list[int],
    packets: list[tuple[int, str, int | None, str, int, int, float, float]],
    second_section: int,
    hurt: tuple[object, ...] | None,
) -> None:
    data = hurt_file(_capture(order, linktypes, packets, second_section), hurt)
    path = tmp_path_factory.mktemp("bulk") / "c.pcapng"
    path.write_bytes(data)
    plain = _chunks(path, False)
    batched = _chunks(path, True)
    assert batched == plain


def _read_the_same_in_pieces(path: Path, piece: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """The bulk walk reading `path` `piece` bytes at a time (`BULK_READ`) gives the
    chunks and warnings of the block or record walk (the patch undone after)."""
    plain = _chunks(path, False)
    with monkeypatch.context() as m:
        m.setattr(pcap, "BULK_READ", piece)
        batched = _chunks(path, True)
    assert batched == plain


@settings(
    max_examples=60,
    deadline=None,
    # the monkeypatch is undone after every example (its context below)
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(
    order=st.sampled_from(["<", ">"]),
    linktypes=st.sampled_from(LINKTYPE_MIXES),
    packets=st.lists(packet, min_size=1, max_size=30),
    piece=st.sampled_from([12, 13, 40, 64, 100, 333]),
    hurt=damage,
)
@example(  # the magic overwritten with a ZIP's: no capture at all, refused alike
    order="<",
    linktypes=LINKTYPE_MIXES[0],
    packets=[(0, "data", None, "", 0, 1, 0.004, 0.01)],
    piece=12,
    hurt=("poke", 0, b"PK\x03\x04"),
)
def test_bulk_walk_reads_the_same_in_small_pieces(
    tmp_path_factory: pytest.TempPathFactory,
    monkeypatch: pytest.MonkeyPatch,
    order: str,
    linktypes: list[int],
    packets: list[tuple[int, str, int | None, str, int, int, float, float]],
    piece: int,
    hurt: tuple[object, ...] | None,
) -> None:
    """Read in pieces smaller than a block (`BULK_READ`), so that every refill keeps the
    rest of a block and reads behind it, and some blocks need a bigger buffer: the
    chunks and warnings are those of the block walk."""
    data = hurt_file(_capture(order, linktypes, packets, -1), hurt)
    path = tmp_path_factory.mktemp("pieces") / "c.pcapng"
    path.write_bytes(data)
    _read_the_same_in_pieces(path, piece, monkeypatch)


def test_bulk_walk_ends_when_the_file_is_shorter_than_it_was(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A file that shrinks while it is read (its size was taken when it was opened) and
    now ends inside a block: the bulk walk stops at that block rather than waiting for
    bytes that will not come, and the block walk reads what is there, as without the
    bulk walk."""
    packets: list[tuple[int, str, int | None, str, int, int, float, float]] = [
        (0, "data", None, "", k, 1, 0.004, 0.01) for k in range(20)
    ]
    data = _capture("<", [LINKTYPE_RTAC_SERIAL], packets, -1)
    path = tmp_path / "c.pcapng"
    path.write_bytes(data[:-10])  # the last block cut
    real = pcap._file_size
    monkeypatch.setattr(pcap, "_file_size", lambda handle: real(handle) + 4096)
    monkeypatch.setattr(pcap, "BULK_READ", 64)
    chunks, warnings, _ = _chunks(path, True)
    assert b"".join(c.data for c in chunks) == b"".join(FRAMES[:19])
    assert any("the file shrank while it was read" in w for w in warnings)
    assert (chunks, warnings) == _chunks(path, False)[:2]


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    order=st.sampled_from(["<", ">"]),
    layout=st.sampled_from(list(PCAP_MAGIC)),  # nanoseconds, modified record header
    linktype=st.sampled_from([LINKTYPE_RTAC_SERIAL, LINKTYPE_USER0]),
    packets=st.lists(packet, max_size=40),
    hurt=damage,
)
def test_bulk_pcap_walk_gives_the_chunks_and_warnings_of_the_record_walk(
    tmp_path_factory: pytest.TempPathFactory,
    order: str,
    layout: tuple[bool, bool],
    linktype: int,
    packets: list[tuple[int, str, int | None, str, int, int, float, float]],
    hurt: tuple[object, ...] | None,
) -> None:
    data = hurt_file(pcap_capture(order, *layout, linktype, packets), hurt)
    path = tmp_path_factory.mktemp("bulkpcap") / "c.pcap"
    path.write_bytes(data)
    plain = _chunks(path, False)
    batched = _chunks(path, True)
    assert batched == plain


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(
    order=st.sampled_from(["<", ">"]),
    layout=st.sampled_from(list(PCAP_MAGIC)),
    linktype=st.sampled_from([LINKTYPE_RTAC_SERIAL, LINKTYPE_USER0]),
    packets=st.lists(packet, min_size=1, max_size=30),
    piece=st.sampled_from([16, 17, 40, 64, 100, 333]),
    hurt=damage,
)
def test_bulk_pcap_walk_reads_the_same_in_small_pieces(
    tmp_path_factory: pytest.TempPathFactory,
    monkeypatch: pytest.MonkeyPatch,
    order: str,
    layout: tuple[bool, bool],
    linktype: int,
    packets: list[tuple[int, str, int | None, str, int, int, float, float]],
    piece: int,
    hurt: tuple[object, ...] | None,
) -> None:
    """As `test_bulk_walk_reads_the_same_in_small_pieces`, for a classic pcap file."""
    data = hurt_file(pcap_capture(order, *layout, linktype, packets), hurt)
    path = tmp_path_factory.mktemp("pcappieces") / "c.pcap"
    path.write_bytes(data)
    _read_the_same_in_pieces(path, piece, monkeypatch)


@pytest.mark.parametrize("batched", [True, False])
def test_pcap_walks_end_when_the_file_is_shorter_than_it_was(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, batched: bool
) -> None:
    """As `test_bulk_walk_ends_when_the_file_is_shorter_than_it_was`, for a classic pcap
    file: the record cut short is said, not read as a shorter packet."""
    packets: list[tuple[int, str, int | None, str, int, int, float, float]] = [
        (0, "data", None, "", k, 1, 0.004, 0.01) for k in range(20)
    ]
    path = tmp_path / "c.pcap"
    path.write_bytes(pcap_capture("<", False, False, LINKTYPE_RTAC_SERIAL, packets)[:-3])
    real = pcap._file_size
    monkeypatch.setattr(pcap, "_file_size", lambda handle: real(handle) + 4096)
    monkeypatch.setattr(pcap, "BULK_READ", 64)
    chunks, warnings, _ = _chunks(path, batched)
    assert b"".join(c.data for c in chunks) == b"".join(FRAMES[:19])
    assert any("the file shrank while it was read" in w for w in warnings)


def test_data_packets_of_every_shape_come_in_batches(tmp_path: Path) -> None:
    """The batches are real: a clean capture's reads come as few `Reads`, cut at
    MAX_BATCH_SPAN seconds (300 reads over 12 spans)."""
    gap = MAX_BATCH_SPAN / 25
    reads = [(FRAMES[k % 50], T0 + k * gap) for k in range(300)]
    for shape in SHAPES:
        path = tmp_path / f"{shape.replace(' ', '')}.cap"
        _recording(path, reads, shape)
        with batching(True):
            chunks = list(open_capture(path).chunks())
        assert 1 < len(chunks) < 30
        assert all(isinstance(c, Reads) for c in chunks)
        assert sum(len(c) for c in chunks if isinstance(c, Reads)) == 300


def _store_of(path: Path, batched: bool) -> Session:
    session, capture = open_session(path)
    session.batch_reads = batched
    session.ingest(capture.chunks())
    return session


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    cuts=st.lists(st.integers(1, 90), min_size=1, max_size=400),
    noise=st.lists(st.tuples(st.integers(0, 5000), st.binary(max_size=3)), max_size=8),
    lag=st.floats(0.0, 0.02),
    shape=st.sampled_from(SHAPES),
)
# more than READ_GAPS reads: the read resolution is estimated from the same first gaps
@example(cuts=[2, 1], noise=[], lag=0.0, shape="pcapng 250")
def test_batches_frame_pair_and_count_as_the_reads_one_by_one(
    tmp_path_factory: pytest.TempPathFactory,
    cuts: list[int],
    noise: list[tuple[int, bytes]],
    lag: float,
    shape: str,
) -> None:
    stream = bytearray(b"".join(FRAMES))
    for at, junk in sorted(noise, reverse=True):
        stream[at:at] = junk
    reads: list[tuple[bytes, float]] = []
    pos, t, k = 0, T0, 0
    while pos < len(stream):
        n = cuts[k % len(cuts)]
        k += 1
        t += n * LINE.char_time + (lag if k % 3 == 0 else 0.0)
        reads.append((bytes(stream[pos : pos + n]), t))
        pos += n
    path = tmp_path_factory.mktemp("rec") / "r.pcapng"
    _recording(path, reads, shape)
    one, many = _store_of(path, False), _store_of(path, True)
    for name in COLUMNS:
        assert getattr(many.store, name) == getattr(one.store, name), name
    assert many.store.streams == one.store.streams
    assert many.store.resolution == one.store.resolution
    assert many.stats.table() == one.stats.table()
    assert (many.warnings, many.notes) == (one.warnings, one.notes)
    # every byte is in the store, and the framer found the frames the stream holds
    assert bytes(one.store.streams[0]) == bytes(stream)
    assert len(one.store) > 0
