"""Cut, empty and meaningless capture files say so, naming the file and the offset, and
the read gets a verdict the CLI can exit with (issue 15, item 8)."""

from __future__ import annotations

import io
import random
import struct
from pathlib import Path

import pytest

from dissectors.checks import with_crc
from sniffer.outputs.export import PcapExporter
from sniffer.outputs.listing import Lister
from sniffer.session.session import open_session
from sniffer.session.verdict import ALL_READ, NOTHING_USABLE, READ_WITH_WARNINGS, read_verdict
from sniffer.sources import open_capture
from sniffer.sources.pcapng_writer import PcapngWriter
from sniffer.vocab import Kind

REQUEST = with_crc(bytes.fromhex("010300000002"))
ANSWER = with_crc(bytes.fromhex("01030400640065"))


def pcapng_bytes(tmp_path: Path) -> bytes:
    path = tmp_path / "whole.pcapng"
    with path.open("wb") as handle:
        writer = PcapngWriter(handle, application="test")
        iface = writer.add_interface(147, name="ttyUSB0")
        writer.write_packet(iface, 1_750_000_000.0, REQUEST)
        writer.write_packet(iface, 1_750_000_000.02, ANSWER)
    return path.read_bytes()


def verdict_of(path: Path) -> tuple[int, list[str]]:
    session, capture = open_session(path, None)
    session.ingest(capture.chunks())
    verdict = read_verdict(capture, session)
    return verdict.status, [*capture.warnings, verdict.reason]


@pytest.mark.parametrize("size", range(1, 12))
def test_pcapng_cut_inside_its_first_header_warns_not_noise(tmp_path: Path, size: int) -> None:
    path = tmp_path / "cut.pcapng"
    path.write_bytes(pcapng_bytes(tmp_path)[:size])
    capture = open_capture(path)
    assert capture.info.format == "pcapng"
    assert list(capture.chunks()) == []
    assert capture.warnings[0].startswith(f"{path}: truncated pcapng")
    assert "byte offset 0" in capture.warnings[0]
    assert capture.empty
    status, texts = verdict_of(path)
    assert status == NOTHING_USABLE
    assert all(text.startswith(f"{path}:") for text in texts)


@pytest.mark.parametrize("size", [4, 10, 23])
def test_pcap_cut_inside_its_file_header_warns(tmp_path: Path, size: int) -> None:
    header = struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 147)
    path = tmp_path / "cut.pcap"
    path.write_bytes(header[:size])
    capture = open_capture(path)
    assert capture.info.format == "pcap"
    assert list(capture.chunks()) == []
    assert capture.warnings[0] == (
        f"{path}: truncated pcap file header at byte offset 0: {size} of 24 bytes"
    )


def test_every_warning_names_its_file(tmp_path: Path) -> None:
    data = pcapng_bytes(tmp_path)
    path = tmp_path / "cut.pcapng"
    path.write_bytes(data[:-5])
    capture = open_capture(path)
    chunks = list(capture.chunks())
    assert [c.data for c in chunks] == [REQUEST]
    assert len(capture.warnings) == 1
    assert capture.warnings[0].startswith(f"{path}: truncated pcapng block at byte offset ")
    status, _ = verdict_of(path)
    assert status == READ_WITH_WARNINGS


def test_a_whole_capture_reads_clean(tmp_path: Path) -> None:
    path = tmp_path / "whole.pcapng"
    path.write_bytes(pcapng_bytes(tmp_path))
    assert verdict_of(path) == (ALL_READ, [""])


def test_random_bytes_with_no_frame_are_nothing_usable(tmp_path: Path) -> None:
    path = tmp_path / "random.bin"
    path.write_bytes(random.Random(7).randbytes(3000))
    session, capture = open_session(path, None)
    session.ingest(capture.chunks())
    verdict = read_verdict(capture, session)
    assert verdict.status == NOTHING_USABLE
    assert verdict.reason.startswith(f"{path}: 3,000 bytes read and not one Modbus frame")


def test_hexdump_warnings_name_the_file(tmp_path: Path) -> None:
    path = tmp_path / "dump.txt"
    # the second line's offset should be 0x0008: the reader warns that the packet ends
    path.write_text("0000  01 03 00 00 00 02 c4 0b\n0010  01 03\n", encoding="ascii")
    capture = open_capture(path, None)
    list(capture.chunks())
    assert capture.warnings
    assert all(w.startswith(f"{path}: ") for w in capture.warnings)


def test_pcapng_with_more_interfaces_than_channels_reads_the_first_128(tmp_path: Path) -> None:
    # found by the fuzz harness: interface 256 overflowed the frame store's channel byte
    path = tmp_path / "many.pcapng"
    with path.open("wb") as handle:
        writer = PcapngWriter(handle, application="test")
        ids = [writer.add_interface(147, name=f"i{k}") for k in range(300)]
        for k in ids:
            writer.write_packet(k, 1_750_000_000.0 + k, REQUEST)
    session, capture = open_session(path, None)
    session.ingest(capture.chunks())
    assert len(session.store) == 128
    assert len(capture.warnings) == 1
    assert capture.warnings[0].startswith(f"{path}: interface description at byte offset ")
    assert capture.warnings[0].endswith(
        "is the 129th; modscope reads 128 interfaces at most, the packets of the others are skipped"
    )


@pytest.mark.parametrize("absolute", [False, True])
def test_impossible_times_are_kept_in_order_with_a_warning(tmp_path: Path, absolute: bool) -> None:
    # found by the fuzz harness: `--time abs` and the pcapng export crashed on a time
    # past the year 9999 (a hex dump's "1e37" seconds, a pcapng tick count near 2**64)
    path = tmp_path / "dump.txt"
    path.write_text(
        f"O 99999999999999999999999.5\n0000  {REQUEST.hex(' ')}\n"
        f"I 9999999999999999999999999999999999999.5\n0000  {ANSWER.hex(' ')}\n",
        encoding="ascii",
    )
    session, capture = open_session(path, None)
    session.ingest(capture.chunks())
    kinds = [session.store.kind[i] for i in range(len(session.store))]
    assert kinds == [Kind.REQUEST, Kind.RESPONSE]
    assert len(capture.warnings) == 1
    assert capture.warnings[0].startswith(f"{path}: 2 record(s) had a time outside 1970-2286")
    rows = range(len(session.store))
    out = io.StringIO()
    assert Lister(out, "text", session.describer, absolute=absolute).write(rows) == 2
    exported = io.BytesIO()
    assert PcapExporter(exported, session.describer, session.line).write(rows) == 2
