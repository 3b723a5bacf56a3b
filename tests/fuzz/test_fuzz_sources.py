"""Fuzz: every capture reader (pcap, pcapng with link types 147/250/252, sigrok .sr,
socat and hex dumps, the text logs and Saleae exports of tests/captures/logs, raw) over
damaged copies of the test captures, read to the end and framed. Only CaptureError may
escape; every byte a reader gives lands in one row."""

from __future__ import annotations

import io
import struct
import zipfile
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.model import Chunk
from sniffer.outputs.export import PcapExporter
from sniffer.outputs.listing import Lister
from sniffer.session.session import Session
from sniffer.sources import CaptureError, ReadOptions, open_capture
from sniffer.sources.linktypes import (
    LINKTYPE_RTAC_SERIAL,
    LINKTYPE_USER0,
    LINKTYPE_WIRESHARK_UPPER_PDU,
    build_rtac,
)
from sniffer.sources.pcapng_writer import PcapngWriter, upper_pdu_record
from sniffer.sources.synth import polling_frames
from tests.fuzz.harness import CAPTURES, budget, bytes_by_channel, conserved, mutated, no_hang

pytestmark = [pytest.mark.fuzz, pytest.mark.slow]

T0 = 1_750_000_000.0
FRAMES = [f.raw for f in polling_frames(12, seed=9)]


def _pcapng(linktype: int) -> bytes:
    out = io.BytesIO()
    writer = PcapngWriter(out, application="fuzz")
    a = writer.add_interface(linktype, name="a", description="modscope: 19200 8E1 rtu master")
    b = writer.add_interface(linktype, name="b")
    for k, frame in enumerate(FRAMES):
        t = T0 + k * 0.01
        if linktype == LINKTYPE_RTAC_SERIAL:
            data = build_rtac(t - 0.001, frame, 0, 0)
        elif linktype == LINKTYPE_WIRESHARK_UPPER_PDU:
            data = upper_pdu_record(frame)
        else:
            data = frame
        writer.write_packet(a if k % 2 == 0 else b, t, data, flags=1 + k % 2, comment=f"#{k}")
    return out.getvalue()


def _pcap() -> bytes:
    header = struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, LINKTYPE_USER0)
    records = b"".join(
        struct.pack("<IIII", int(T0) + k, 0, len(f), len(f)) + f for k, f in enumerate(FRAMES)
    )
    return header + records


SIGROK = CAPTURES / "sigrok"
SIGROK_SEEDS = {
    SIGROK / "flowmeter" / "flowmeter_graph_tool.sr": ReadOptions(
        baud=9600, parity="N", probes=("RXTX",)
    ),
    SIGROK / "brainchild_io_16do" / "brainchild-io-16do.sr": ReadOptions(
        baud=19200, parity="E", probes=("1", "0"), invert=True
    ),
    SIGROK / "wizmodbus" / "wizmodbus.sr": ReadOptions(baud=9600, parity="N", probes=("RX", "TX")),
}


def _seeds() -> dict[str, list[bytes]]:
    text = sorted((CAPTURES / "hexdump").iterdir())
    return {
        "pcapng": [_pcapng(t) for t in (147, 250, 252)],
        "pcap": [_pcap()],
        "sigrok": [p.read_bytes() for p in SIGROK_SEEDS],
        "text": [p.read_bytes() for p in text if p.suffix in (".txt", ".log")],
        "logs": [p.read_bytes() for p in sorted((CAPTURES / "logs").iterdir())],
        "raw": [b"".join(FRAMES), with_crc(b"\x01\x03\x00\x00\x00\x01") * 3],
    }


SEEDS = _seeds()
OPTIONS = st.sampled_from(
    [
        ReadOptions(),
        ReadOptions(baud=9600, parity="N", mode="rtu"),
        ReadOptions(mode="ascii", bytesize=7),
        *SIGROK_SEEDS.values(),
    ]
)


def read_and_frame(path: Path, options: ReadOptions) -> None:
    # opening is inside the hang limit too: a text reader's first pass (the whole parse)
    # runs there
    try:
        with no_hang():
            capture = open_capture(path, options)
    except CaptureError as exc:
        assert str(exc).startswith(str(path)), str(exc)
        return
    chunks: list[Chunk] = []
    with no_hang():
        for chunk in capture.chunks():
            assert isinstance(chunk.data, bytes)
            chunks.append(chunk)
        session = Session(
            options.line(capture.info.line), exact_timing=capture.info.exact_timing, timeout=0.2
        )
        session.ingest(chunks)
        rows = range(len(session.store))
        Lister(io.StringIO(), "text", session.describer, absolute=True).write(rows)
        PcapExporter(io.BytesIO(), session.describer, session.line).write(rows)
    conserved(session.store, bytes_by_channel(chunks))
    for warning in capture.warnings:
        # `FILE: ...`, or `FILE line 12: ...` where a text reader names the line
        assert warning.startswith((f"{path}: ", f"{path} line ")), warning


def _members(data: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


SIGROK_MEMBERS = [_members(seed) for seed in SEEDS["sigrok"]]


@st.composite
def repacked_sigrok(draw: st.DrawFn) -> tuple[bytes, ReadOptions]:
    """A sigrok session whose metadata or sample data is damaged inside a sound zip, so
    the damage reaches the metadata parser and the UART decoder, not only unzip."""
    index = draw(st.integers(0, len(SIGROK_MEMBERS) - 1))
    members = dict(SIGROK_MEMBERS[index])
    name = draw(st.sampled_from(sorted(members)))
    members[name] = draw(mutated([members[name]]))
    if draw(st.integers(0, 4)) == 0:
        del members[draw(st.sampled_from(sorted(members)))]
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        for member, data in members.items():
            archive.writestr(member, data)
    return out.getvalue(), list(SIGROK_SEEDS.values())[index]


@budget(150)
@given(repacked_sigrok())
def test_damaged_sigrok_sessions_never_raise(
    tmp_path_factory: pytest.TempPathFactory, case: tuple[bytes, ReadOptions]
) -> None:
    data, options = case
    path = tmp_path_factory.getbasetemp() / "session.sr"
    path.write_bytes(data)
    read_and_frame(path, options)


@pytest.mark.parametrize("kind", sorted(SEEDS))
def test_seeds_read_clean(tmp_path: Path, kind: str) -> None:
    options = list(SIGROK_SEEDS.values()) if kind == "sigrok" else [ReadOptions()] * 99
    for k, seed in enumerate(SEEDS[kind]):
        path = tmp_path / f"seed{k}"
        path.write_bytes(seed)
        capture = open_capture(path, options[k])
        assert sum(len(c.data) for c in capture.chunks()) > 0, (kind, k)


@pytest.mark.parametrize("kind", sorted(SEEDS))
def test_damaged_captures_never_raise_and_conserve_bytes(
    tmp_path_factory: pytest.TempPathFactory, kind: str
) -> None:
    folder = tmp_path_factory.mktemp(kind)
    # the logs are damaged line by line, reader by reader, in test_fuzz_logs: here only
    # their bytes, fewer times
    examples = {"sigrok": 150, "pcapng": 1000, "text": 500, "logs": 150, "pcap": 300, "raw": 150}

    @budget(examples[kind])
    @given(mutated(SEEDS[kind]), OPTIONS)
    def run(data: bytes, options: ReadOptions) -> None:
        path = folder / "capture"
        path.write_bytes(data)
        read_and_frame(path, options)

    run()
