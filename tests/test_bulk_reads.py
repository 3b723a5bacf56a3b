"""The bulk pcapng and pcap walks and batches of reads give what the block-by-block walk
gives.

`Session.ingest` lets the pcapng and pcap readers pass runs of link type 250 and 147 reads
as one `sniffer.sources.reads.Reads`; everything else reads a capture one chunk per read.
Both must agree on every chunk, warning and row, for clean, odd and damaged files alike.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from sniffer.model import Chunk, LineSettings
from sniffer.session.session import Session, open_session
from sniffer.sources import open_capture, pcap
from sniffer.sources.linktypes import (
    LINKTYPE_RTAC_SERIAL,
    LINKTYPE_USER0,
    LINKTYPE_WIRESHARK_UPPER_PDU,
    RTAC_CAPTURE_DATA_LOST,
    RTAC_DATA_RX_START,
    RTAC_DATA_TX_START,
    RTAC_FRAMING_ERROR,
)
from sniffer.sources.pcapng_writer import describe_interface, rtac_record
from sniffer.sources.reads import MAX_BATCH_SPAN, Reads, batching
from sniffer.sources.synth import polling_frames

T0 = 1_714_564_800.0
LINE = LineSettings(baud=19200, bytesize=8, parity="E", stopbits=1, mode="rtu")
FRAMES = [f.raw for f in polling_frames(400, line=LINE, seed=7)]


def _opt(order: str, code: int, value: bytes) -> bytes:
    return struct.pack(order + "HH", code, len(value)) + value + b"\0" * (-len(value) % 4)


def _opts(order: str, items: list[bytes]) -> bytes:
    return b"".join(items) + struct.pack(order + "HH", 0, 0) if items else b""


def _block(order: str, block_type: int, body: bytes) -> bytes:
    total = 12 + len(body)
    return struct.pack(order + "II", block_type, total) + body + struct.pack(order + "I", total)


def _shb(order: str) -> bytes:
    return _block(order, 0x0A0D0D0A, struct.pack(order + "IHHq", 0x1A2B3C4D, 1, 0, -1))


def _idb(order: str, linktype: int, described: bool) -> bytes:
    options = [_opt(order, 9, bytes([9]))]  # nanosecond stamps, as the recorder writes
    if described:
        options.append(_opt(order, 3, describe_interface(LINE).encode()))
    return _block(order, 1, struct.pack(order + "HHI", linktype, 0, 0) + _opts(order, options))


def _epb(order: str, iface: int, t: float, data: bytes, options: list[bytes]) -> bytes:
    ticks = round(t * 1e9)
    body = struct.pack(
        order + "IIIII", iface, ticks >> 32, ticks & 0xFFFFFFFF, len(data), len(data)
    )
    return _block(order, 6, body + data + b"\0" * (-len(data) % 4) + _opts(order, options))


# one packet: interface, what (data, event, sent data), EPB flags, comment, bytes, the
# header's lead over the packet time (negative: a header after the packet), time step
packet = st.tuples(
    st.integers(0, 2),
    st.sampled_from(["data", "data", "data", "event", "sent", "lost"]),
    st.sampled_from([None, None, 1, 2, 3]),
    st.sampled_from(["", "", "", "a note"]),
    st.integers(0, len(FRAMES) - 1),
    st.integers(1, 3),
    st.sampled_from([0.004, 0.004, 0.0, -0.5, 90.0]),
    st.floats(0.0, 0.3),
)


def _capture(
    order: str,
    linktypes: list[int],
    packets: list[tuple[int, str, int | None, str, int, int, float, float]],
    second_section: int,
) -> bytes:
    out = bytearray(_shb(order))
    for k, lt in enumerate(linktypes):
        out += _idb(order, lt, k == 0)
    t = T0
    for n, (iface, what, flags, comment, start, count, lead, step) in enumerate(packets):
        if n == second_section:
            out += _shb(order)
            for k, lt in enumerate(linktypes):
                out += _idb(order, lt, k == 0)
        t += step
        data = b"".join(FRAMES[start : start + count])
        event = {"data": RTAC_DATA_RX_START, "sent": RTAC_DATA_TX_START}.get(what)
        if event is None:
            event = RTAC_FRAMING_ERROR if what == "event" else RTAC_CAPTURE_DATA_LOST
            data = b""
        options = []
        if comment:
            options.append(_opt(order, 1, comment.encode()))
        if flags is not None:
            options.append(_opt(order, 2, struct.pack(order + "I", flags)))
        body = rtac_record(max(t - lead, 0.0), data, event=event)
        if linktypes[iface % len(linktypes)] != LINKTYPE_RTAC_SERIAL:
            body = data
        out += _epb(order, iface % (len(linktypes) + 1), t, body, options)
    return bytes(out)


def _chunks(path: Path, batched: bool) -> tuple[list[Chunk], list[str], int]:
    capture = open_capture(path)
    with batching(batched):
        got: list[Chunk] = []
        for chunk in capture.chunks():
            got.extend(chunk.split() if isinstance(chunk, Reads) else [chunk])
    return got, capture.warnings, capture.data_bytes


# the interfaces of a pcapng capture: data records, plain reads, both, and a link type that
# is not batched (252, whose packets are not interpreted as reads here)
LINKTYPE_MIXES = [
    [LINKTYPE_RTAC_SERIAL],
    [LINKTYPE_RTAC_SERIAL] * 2,
    [LINKTYPE_RTAC_SERIAL, LINKTYPE_USER0],
    [LINKTYPE_USER0],
    [LINKTYPE_USER0] * 2,
    [LINKTYPE_USER0, LINKTYPE_WIRESHARK_UPPER_PDU],
]

damage = st.one_of(
    st.none(),
    st.tuples(st.just("cut"), st.integers(0, 10**6)),
    st.tuples(st.just("poke"), st.integers(0, 10**6), st.binary(min_size=1, max_size=4)),
)


def hurt_file(data: bytes, hurt: tuple[object, ...] | None) -> bytes:
    """The file cut short or with a few bytes overwritten, as `damage` drew."""
    out = bytearray(data)
    if hurt is not None and hurt[0] == "cut":
        del out[max(1, int(str(hurt[1])) % (len(out) + 1)) :]  # an empty file is refused
    elif hurt is not None:
        at = int(str(hurt[1])) % len(out)
        poke = hurt[2]
        assert isinstance(poke, bytes)
        out[at : at + len(poke)] = poke
    return bytes(out)


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


PCAP_MAGIC = {(False, False): 0xA1B2C3D4, (True, False): 0xA1B23C4D, (False, True): 0xA1B2CD34}


def pcap_capture(
    order: str,
    nanoseconds: bool,
    modified: bool,
    linktype: int,
    packets: list[tuple[int, str, int | None, str, int, int, float, float]],
) -> bytes:
    """A classic pcap file of the `packet` draws (one interface: no flags, no comments)."""
    magic = PCAP_MAGIC[nanoseconds, modified]
    out = bytearray(struct.pack(order + "IHHiIII", magic, 2, 4, 0, 0, 65535, linktype))
    t = T0
    for _iface, what, _flags, _comment, start, count, lead, step in packets:
        t += step
        data = b"".join(FRAMES[start : start + count])
        event = {"data": RTAC_DATA_RX_START, "sent": RTAC_DATA_TX_START}.get(what)
        if event is None:
            event = RTAC_FRAMING_ERROR if what == "event" else RTAC_CAPTURE_DATA_LOST
            data = b""
        body = rtac_record(max(t - lead, 0.0), data, event=event)
        if linktype != LINKTYPE_RTAC_SERIAL:
            body = data
        ticks = round(t * (1e9 if nanoseconds else 1e6))
        secs, frac = divmod(ticks, 10**9 if nanoseconds else 10**6)
        fields = (secs, frac, len(body), len(body)) + ((0, 0, 0, 0) if modified else ())
        out += struct.pack(order + ("IIIIIHBB" if modified else "IIII"), *fields) + body
    return bytes(out)


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


# the shapes a recording of reads is written in: pcapng link type 250 (RTAC records with
# the first byte's time) or 147 (the bytes alone), classic pcap of either
SHAPES = ["pcapng 250", "pcapng 147", "pcap 250", "pcap 147"]


def _recording(path: Path, reads: list[tuple[bytes, float]], shape: str = "pcapng 250") -> None:
    order = "<"
    linktype = LINKTYPE_RTAC_SERIAL if shape.endswith("250") else LINKTYPE_USER0
    if shape.startswith("pcap "):
        out = bytearray(struct.pack("<IHHiIII", PCAP_MAGIC[True, False], 2, 4, 0, 0, 0, linktype))
        for data, t in reads:
            body = data
            if linktype == LINKTYPE_RTAC_SERIAL:
                body = rtac_record(t - len(data) * LINE.char_time, data)
            secs, frac = divmod(round(t * 1e9), 10**9)
            out += struct.pack("<IIII", secs, frac, len(body), len(body)) + body
        path.write_bytes(bytes(out))
        return
    out = bytearray(_shb(order) + _idb(order, linktype, True))
    for data, t in reads:
        body = data
        if linktype == LINKTYPE_RTAC_SERIAL:
            body = rtac_record(t - len(data) * LINE.char_time, data)
        out += _epb(order, 0, t, body, [_opt(order, 2, b"\1\0\0\0")])
    path.write_bytes(bytes(out))


def _store_of(path: Path, batched: bool) -> Session:
    session, capture = open_session(path)
    session.batch_reads = batched
    session.ingest(capture.chunks())
    return session


COLUMNS = [
    "offset",
    "length",
    "t",
    "t_end",
    "kind",
    "unit",
    "fc",
    "flags",
    "channel",
    "partner",
    "status",
]


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
