"""Tests the pcap/pcapng readers on hand-built files and the pcapng writer against tshark."""

from __future__ import annotations

import io
import itertools
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from dissectors.checks import crc16, with_crc
from sniffer.model import Chunk, Direction, LineSettings
from sniffer.sources import Capture, ReadOptions, open_capture
from sniffer.sources.linktypes import (
    describe_interface,
    parse_interface_description,
    parse_rtac,
    parse_upper_pdu,
)
from sniffer.sources.pcap import packet_direction
from sniffer.sources.pcapng_writer import (
    EPB_FLAG_CRC_ERROR,
    EPB_FLAG_INBOUND,
    EPB_FLAG_OUTBOUND,
    LINKTYPE_RTAC_SERIAL,
    LINKTYPE_USER0,
    LINKTYPE_WIRESHARK_UPPER_PDU,
    RTAC_CAPTURE_DATA_LOST,
    RTAC_DATA_RX_START,
    RTAC_DATA_TX_START,
    RTAC_FRAMING_ERROR,
    RTAC_PARITY_ERROR,
    RTAC_STATUS_CHANGE,
    PcapngWriter,
    rtac_record,
    upper_pdu_record,
)

T0 = 1_714_564_800.0  # 2024-05-01 12:00:00 UTC
REQUEST = with_crc(bytes.fromhex("010300000002"))
RESPONSE = with_crc(bytes.fromhex("01030400010002"))
WRITE = with_crc(bytes.fromhex("010600010003"))
FRAMES = [REQUEST, RESPONSE, WRITE, WRITE]


# ---------------------------------------------------------------- hand-built pcapng


def opt(order: str, code: int, value: bytes) -> bytes:
    return struct.pack(order + "HH", code, len(value)) + value + b"\0" * (-len(value) % 4)


def opts(order: str, *items: bytes) -> bytes:
    return b"".join(items) + struct.pack(order + "HH", 0, 0) if items else b""


def block(order: str, block_type: int, body: bytes) -> bytes:
    total = 12 + len(body)
    return struct.pack(order + "II", block_type, total) + body + struct.pack(order + "I", total)


def shb(order: str) -> bytes:
    body = struct.pack(order + "IHHq", 0x1A2B3C4D, 1, 0, -1) + opts(
        order, opt(order, 4, b"hand-built")
    )
    return block(order, 0x0A0D0D0A, body)


def idb(order: str, linktype: int, *options: bytes) -> bytes:
    return block(order, 1, struct.pack(order + "HHI", linktype, 0, 0) + opts(order, *options))


def epb(
    order: str, interface: int, ticks: int, data: bytes, *options: bytes, caplen: int = -1
) -> bytes:
    length = len(data) if caplen < 0 else caplen
    body = struct.pack(order + "IIIII", interface, ticks >> 32, ticks & 0xFFFFFFFF, length, length)
    body += data + b"\0" * (-len(data) % 4) + opts(order, *options)
    return block(order, 6, body)


def spb(order: str, data: bytes) -> bytes:
    return block(order, 3, struct.pack(order + "I", len(data)) + data + b"\0" * (-len(data) % 4))


def pb(order: str, interface: int, ticks: int, data: bytes, flags: int) -> bytes:
    body = struct.pack(
        order + "HHIIII", interface, 0, ticks >> 32, ticks & 0xFFFFFFFF, len(data), len(data)
    )
    body += (
        data
        + b"\0" * (-len(data) % 4)
        + opts(order, opt(order, 2, struct.pack(order + "I", flags)))
    )
    return block(order, 2, body)


def flags_opt(order: str, flags: int) -> bytes:
    return opt(order, 2, struct.pack(order + "I", flags))


def read(path: Path, options: ReadOptions | None = None) -> tuple[Capture, list[Chunk]]:
    capture = open_capture(path, options)
    return capture, list(capture.chunks())


@pytest.mark.parametrize("order", ["<", ">"])
def test_pcapng_interfaces_resolutions_blocks(tmp_path: Path, order: str) -> None:
    us = int(T0 * 1_000_000)
    ns = int(T0) * 1_000_000_000
    binary = int(T0) << 20  # if_tsresol 0x94: 2^-20 s
    data = (
        shb(order)
        + idb(order, LINKTYPE_USER0, opt(order, 2, b"ttyUSB0"))  # microseconds by default
        + idb(order, LINKTYPE_USER0, opt(order, 2, b"ttyUSB1"), opt(order, 9, b"\x09"))
        + idb(order, LINKTYPE_USER0, opt(order, 9, b"\x94"))
        + idb(
            order,
            LINKTYPE_USER0,
            opt(order, 9, b"\x03"),
            opt(order, 14, struct.pack(order + "q", 1_000_000_000)),
        )
        + block(order, 4, b"\0\0\0\0")  # a name resolution block: skipped
        + epb(order, 0, us + 500, b"\x01\x03", opt(order, 1, b"first read"))
        + epb(order, 1, ns + 750_000_000, b"\x00\x00", flags_opt(order, EPB_FLAG_OUTBOUND))
        + epb(order, 2, binary + (1 << 19), b"\x00\x02")
        + epb(order, 3, 714_564_800_250, b"\xc4")  # ms after 1,000,000,000 s
        + spb(order, b"\x0b")
        + pb(order, 1, ns + 900_000_000, b"\x99", EPB_FLAG_INBOUND)
    )
    path = tmp_path / "multi.pcapng"
    path.write_bytes(data)
    capture, chunks = read(path)
    assert capture.info.format == "pcapng"
    assert capture.warnings == []
    assert capture.info.channels == {
        0: "ttyUSB0 (USER0 raw serial)",
        1: "ttyUSB1 (USER0 raw serial)",
        2: "interface 2 (USER0 raw serial)",
        3: "interface 3 (USER0 raw serial)",
    }
    assert [c.data for c in chunks] == [
        b"\x01\x03",
        b"\x00\x00",
        b"\x00\x02",
        b"\xc4",
        b"\x0b",
        b"\x99",
    ]
    assert [c.channel for c in chunks] == [0, 1, 2, 3, 0, 1]
    assert chunks[0].t_end == pytest.approx(T0 + 0.0005, abs=1e-7)
    assert chunks[0].note == "first read"
    assert chunks[1].t_end == pytest.approx(T0 + 0.75, abs=1e-7)
    assert chunks[2].t_end == pytest.approx(T0 + 0.5, abs=1e-7)
    assert chunks[3].t_end == pytest.approx(T0 + 0.25, abs=1e-7)
    # an SPB has no time: one character time after the interface's previous packet
    assert chunks[4].t_end == pytest.approx(chunks[0].t_end + LineSettings().char_time)
    assert chunks[5].t_end == pytest.approx(T0 + 0.9, abs=1e-7)
    assert [c.direction for c in chunks] == [
        Direction.UNKNOWN,
        Direction.MASTER,  # outbound on a raw port: the capturing host sent it
        Direction.UNKNOWN,
        Direction.UNKNOWN,
        Direction.UNKNOWN,
        Direction.UNKNOWN,  # inbound on a raw port: everything a tap sees
    ]
    assert all(c.t_start is None for c in chunks)


def test_pcapng_sections_of_both_byte_orders(tmp_path: Path) -> None:
    data = (
        shb("<")
        + idb("<", LINKTYPE_USER0)
        + epb("<", 0, int(T0 * 1e6), b"\x01")
        + shb(">")
        + idb(">", LINKTYPE_USER0)
        + epb(">", 0, int(T0 * 1e6) + 1, b"\x02")
    )
    path = tmp_path / "two.pcapng"
    path.write_bytes(data)
    capture, chunks = read(path)
    assert capture.warnings == []
    assert [(c.data, c.channel) for c in chunks] == [(b"\x01", 0), (b"\x02", 1)]


def test_pcapng_line_settings_and_role_from_description(tmp_path: Path) -> None:
    description = b"modscope 9600 8N2 rtu slave"
    data = (
        shb("<")
        + idb("<", LINKTYPE_USER0, opt("<", 3, description))
        + epb("<", 0, int(T0 * 1e6), b"\x01\x02")
    )
    path = tmp_path / "line.pcapng"
    path.write_bytes(data)
    capture, chunks = read(path)
    assert capture.info.line == LineSettings(9600, 8, "N", 2, "rtu")
    assert chunks[0].direction == Direction.SLAVE
    capture, _ = read(path, ReadOptions(baud=38400))
    assert capture.info.line == LineSettings(38400, 8, "N", 2, "rtu")


@pytest.mark.parametrize(
    ("text", "line", "role"),
    [
        ("modscope 19200 8E1 rtu", LineSettings(19200, 8, "E", 1, "rtu"), Direction.UNKNOWN),
        (
            "modscope ascii 7O2 9600 master",
            LineSettings(9600, 7, "O", 2, "ascii"),
            Direction.MASTER,
        ),
        ("modscope responses", None, Direction.SLAVE),
        ("modscope 115200", LineSettings(115200, 8, "E", 1, "auto"), Direction.UNKNOWN),
        ("USB serial port", None, Direction.UNKNOWN),
        ("", None, Direction.UNKNOWN),
    ],
)
def test_interface_description(text: str, line: LineSettings | None, role: Direction) -> None:
    note = parse_interface_description(text)
    assert note.line == line
    assert note.role == role


def test_describe_interface_round_trip() -> None:
    line = LineSettings(9600, 8, "N", 1, "rtu")
    text = describe_interface(line, Direction.MASTER)
    assert text == "modscope 9600 8N1 rtu master"
    note = parse_interface_description(text)
    assert (note.line, note.role) == (line, Direction.MASTER)


@pytest.mark.parametrize(
    ("linktype", "role", "flags", "expected"),
    [
        (LINKTYPE_WIRESHARK_UPPER_PDU, Direction.UNKNOWN, EPB_FLAG_OUTBOUND, Direction.MASTER),
        (LINKTYPE_WIRESHARK_UPPER_PDU, Direction.UNKNOWN, EPB_FLAG_INBOUND, Direction.SLAVE),
        (LINKTYPE_WIRESHARK_UPPER_PDU, Direction.UNKNOWN, None, Direction.UNKNOWN),
        (LINKTYPE_WIRESHARK_UPPER_PDU, Direction.UNKNOWN, EPB_FLAG_CRC_ERROR, Direction.UNKNOWN),
        (LINKTYPE_USER0, Direction.UNKNOWN, EPB_FLAG_INBOUND, Direction.UNKNOWN),
        (LINKTYPE_USER0, Direction.UNKNOWN, EPB_FLAG_OUTBOUND, Direction.MASTER),
        (LINKTYPE_RTAC_SERIAL, Direction.UNKNOWN, EPB_FLAG_INBOUND, Direction.UNKNOWN),
        (LINKTYPE_RTAC_SERIAL, Direction.SLAVE, EPB_FLAG_INBOUND, Direction.SLAVE),
        (LINKTYPE_USER0, Direction.MASTER, EPB_FLAG_INBOUND, Direction.MASTER),
        (LINKTYPE_WIRESHARK_UPPER_PDU, Direction.SLAVE, EPB_FLAG_OUTBOUND, Direction.SLAVE),
    ],
)
def test_direction_mapping(
    linktype: int, role: Direction, flags: int | None, expected: Direction
) -> None:
    assert packet_direction(linktype, role, flags) == expected


def test_rtac_events(tmp_path: Path) -> None:
    with (tmp_path / "rtac.pcapng").open("wb") as stream:
        writer = PcapngWriter(stream)
        port = writer.add_interface(LINKTYPE_RTAC_SERIAL, name="ttyS0")
        writer.write_packet(port, T0 + 0.010, rtac_record(T0 + 0.006, REQUEST))
        writer.write_packet(
            port, T0 + 0.020, rtac_record(T0 + 0.020, b"\x55", event=RTAC_FRAMING_ERROR)
        )
        writer.write_packet(port, T0 + 0.030, rtac_record(T0 + 0.030, b"", event=RTAC_PARITY_ERROR))
        writer.write_packet(
            port, T0 + 0.040, rtac_record(T0 + 0.040, b"", event=RTAC_CAPTURE_DATA_LOST)
        )
        writer.write_packet(
            port,
            T0 + 0.050,
            rtac_record(T0 + 0.050, b"", event=RTAC_STATUS_CHANGE, control_lines=0x09),
        )
        writer.write_packet(
            port, T0 + 0.060, rtac_record(T0 + 0.058, WRITE, event=RTAC_DATA_TX_START)
        )
        writer.write_packet(port, T0 + 0.070, b"\x01\x02")  # too short for the header
    capture, chunks = read(tmp_path / "rtac.pcapng")
    assert [(c.data, c.event) for c in chunks] == [
        (REQUEST, ""),
        (b"\x55", ""),
        (b"", "framing error"),
        (b"", "parity error"),
        (b"", "data lost"),
        (b"", "control lines"),
        (WRITE, ""),
    ]
    assert chunks[0].t_start == pytest.approx(T0 + 0.006, abs=1e-6)
    assert chunks[0].t_end == pytest.approx(T0 + 0.010, abs=1e-6)
    assert chunks[1].t_start is None  # header time equal to packet time: no lead to trust
    assert chunks[5].note == "CTS /DCD /DSR RTS /DTR /RING /MBOK"
    assert chunks[0].direction == Direction.UNKNOWN
    assert chunks[6].direction == Direction.MASTER  # TX: the capturing device sent it
    assert len(capture.warnings) == 1
    assert "shorter than its 12-byte header" in capture.warnings[0]


def test_upper_pdu_frames_are_kept_apart(tmp_path: Path) -> None:
    line = LineSettings(19200, 8, "E", 1, "rtu")
    with (tmp_path / "export.pcapng").open("wb") as stream:
        writer = PcapngWriter(stream)
        port = writer.add_interface(
            LINKTYPE_WIRESHARK_UPPER_PDU, description=describe_interface(line)
        )
        # the response stamped 1 ms after the request ends: closer than t3.5 (2 ms)
        writer.write_packet(port, T0, upper_pdu_record(REQUEST), flags=EPB_FLAG_OUTBOUND)
        writer.write_packet(port, T0 + 0.001, upper_pdu_record(RESPONSE), flags=EPB_FLAG_INBOUND)
        writer.write_packet(port, T0 + 0.5, upper_pdu_record(WRITE, "mbtcp"))
        writer.write_packet(port, T0 + 0.6, b"\x00\x0c\x00\x10")  # tag runs past the end
    capture, chunks = read(tmp_path / "export.pcapng")
    assert [c.data for c in chunks] == [REQUEST, RESPONSE, WRITE]
    assert chunks[0].t_end == pytest.approx(T0, abs=1e-6)
    assert chunks[0].t_start == pytest.approx(T0 - len(REQUEST) * line.char_time, abs=1e-6)
    for before, after in itertools.pairwise(chunks):
        assert after.t_start is not None
        assert after.t_start - before.t_end >= line.t35
        assert after.t_end >= after.t_start
    assert chunks[2].t_end == pytest.approx(T0 + 0.5, abs=1e-6)
    assert [c.direction for c in chunks] == [Direction.MASTER, Direction.SLAVE, Direction.UNKNOWN]
    assert len(capture.warnings) == 2
    assert "'mbtcp'" in capture.warnings[0]
    assert "broken tags" in capture.warnings[1]


def test_unknown_linktype_and_interface_are_skipped(tmp_path: Path) -> None:
    data = (
        shb("<")
        + idb("<", 105)  # IEEE 802.11 (Ethernet-family types are read: test_sources_ethernet)
        + epb("<", 0, int(T0 * 1e6), b"\xff" * 14)
        + epb("<", 0, int(T0 * 1e6), b"\xff" * 14)
        + epb("<", 5, int(T0 * 1e6), b"\x01")
    )
    path = tmp_path / "ether.pcapng"
    path.write_bytes(data)
    capture, chunks = read(path)
    assert chunks == []
    assert len(capture.warnings) == 3
    assert "link type 105 is not serial data" in capture.warnings[0]
    assert "interface 5" in capture.warnings[1]
    assert "no serial data" in capture.warnings[2] and capture.empty


def _three_packets() -> tuple[bytes, list[int]]:
    parts = [shb("<"), idb("<", LINKTYPE_USER0)]
    starts = []
    for k, frame in enumerate(FRAMES[:3]):
        starts.append(sum(map(len, parts)))
        parts.append(epb("<", 0, int(T0 * 1e6) + k, frame))
    return b"".join(parts), starts


@pytest.mark.parametrize("cut", [1, 7, 20, 31])
def test_truncated_pcapng_keeps_complete_blocks(tmp_path: Path, cut: int) -> None:
    data, starts = _three_packets()
    path = tmp_path / "cut.pcapng"
    path.write_bytes(data[: len(data) - cut])
    capture, chunks = read(path)
    assert [c.data for c in chunks] == FRAMES[:2]
    assert len(capture.warnings) == 1
    assert "truncated pcapng block" in capture.warnings[0]
    assert f"byte offset {starts[2]}" in capture.warnings[0]


def test_corrupt_pcapng_trailer(tmp_path: Path) -> None:
    data, starts = _three_packets()
    broken = bytearray(data)
    broken[starts[2] - 4 : starts[2]] = b"\x10\x00\x00\x00"  # trailing length of block 2
    path = tmp_path / "bad.pcapng"
    path.write_bytes(bytes(broken))
    capture, chunks = read(path)
    assert [c.data for c in chunks] == FRAMES[:1]
    assert f"corrupt pcapng block at byte offset {starts[1]}" in capture.warnings[0]


def test_pcapng_packet_longer_than_block_is_skipped(tmp_path: Path) -> None:
    data = shb("<") + idb("<", LINKTYPE_USER0) + epb("<", 0, 0, b"\x01\x02", caplen=99)
    data += epb("<", 0, 1, b"\x03")
    path = tmp_path / "caplen.pcapng"
    path.write_bytes(data)
    capture, chunks = read(path)
    assert [c.data for c in chunks] == [b"\x03"]
    assert "99 bytes announced" in capture.warnings[0]


# ---------------------------------------------------------------- pcap


def pcap_file(
    order: str,
    nanoseconds: bool,
    linktype: int,
    packets: list[tuple[float, bytes]],
    modified: bool = False,
) -> bytes:
    magic = 0xA1B2CD34 if modified else 0xA1B23C4D if nanoseconds else 0xA1B2C3D4
    out = struct.pack(order + "IHHiIII", magic, 2, 4, 0, 0, 65535, linktype)
    per_second = 1_000_000_000 if nanoseconds else 1_000_000
    for t, data in packets:
        secs = int(t)
        frac = round((t - secs) * per_second)
        out += struct.pack(order + "IIII", secs, frac, len(data), len(data))
        if modified:
            out += struct.pack(order + "IHBB", 0, 0, 0, 0)
        out += data
    return out


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("nanoseconds", [False, True])
def test_pcap_magics(tmp_path: Path, order: str, nanoseconds: bool) -> None:
    packets = [(T0 + 0.25, REQUEST), (T0 + 0.5, RESPONSE)]
    path = tmp_path / "a.pcap"
    path.write_bytes(pcap_file(order, nanoseconds, LINKTYPE_USER0, packets))
    capture, chunks = read(path)
    assert capture.info.format == "pcap"
    assert capture.warnings == []
    assert [c.data for c in chunks] == [REQUEST, RESPONSE]
    assert [c.t_end for c in chunks] == pytest.approx([T0 + 0.25, T0 + 0.5], abs=1e-6)


def test_modified_pcap(tmp_path: Path) -> None:
    path = tmp_path / "m.pcap"
    path.write_bytes(pcap_file("<", False, LINKTYPE_USER0, [(T0, REQUEST)], modified=True))
    _capture, chunks = read(path)
    assert [c.data for c in chunks] == [REQUEST]


def test_pcap_252_and_truncated_record(tmp_path: Path) -> None:
    packets = [(T0 + k, upper_pdu_record(frame)) for k, frame in enumerate(FRAMES)]
    data = pcap_file("<", False, LINKTYPE_WIRESHARK_UPPER_PDU, packets)
    last = len(data) - 16 - len(packets[-1][1])
    path = tmp_path / "cut.pcap"
    path.write_bytes(data[:-3])
    capture, chunks = read(path)
    assert [c.data for c in chunks] == FRAMES[:3]
    assert capture.warnings == [
        f"{path}: truncated pcap record at byte offset {last}: {len(packets[-1][1])} bytes "
        f"announced, {len(packets[-1][1]) - 3} present; reading stopped there"
    ]
    path.write_bytes(data[: last + 9])
    capture, chunks = read(path)
    assert len(chunks) == 3
    assert f"truncated pcap record header at byte offset {last}" in capture.warnings[0]


# ---------------------------------------------------------------- writer


def test_writer_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "round.pcapng"
    times = [T0 + 0.123456789, T0 + 0.2, T0 + 1.000001, T0 + 2.5]
    with path.open("wb") as stream:
        writer = PcapngWriter(stream, application="modscope test")
        raw_ns = writer.add_interface(LINKTYPE_USER0, name="ttyUSB0")
        raw_us = writer.add_interface(LINKTYPE_USER0, name="ttyUSB1", tsresol_ns=False)
        rtac = writer.add_interface(LINKTYPE_RTAC_SERIAL, description="modscope 9600 8N1 rtu")
        export = writer.add_interface(LINKTYPE_WIRESHARK_UPPER_PDU, name="frames")
        assert (raw_ns, raw_us, rtac, export) == (0, 1, 2, 3)
        for k, (t, frame) in enumerate(zip(times, FRAMES, strict=True)):
            flags = EPB_FLAG_OUTBOUND if k % 2 == 0 else EPB_FLAG_INBOUND
            writer.write_packet(raw_ns, t, frame, flags=flags, comment=f"packet {k}")
            writer.write_packet(raw_us, t, frame)
            writer.write_packet(rtac, t, rtac_record(t - 0.005, frame))
            writer.write_packet(
                export, t, upper_pdu_record(frame), flags=flags | EPB_FLAG_CRC_ERROR
            )
    capture, chunks = read(path)
    assert capture.warnings == []
    assert capture.info.line == LineSettings(9600, 8, "N", 1, "rtu")
    assert set(capture.info.channels) == {0, 1, 2, 3}
    for channels, tolerance in (({0}, 1e-6), ({1}, 1e-6), ({2}, 1e-6), ({3}, 1e-6)):
        mine = [c for c in chunks if c.channel in channels]
        assert [c.data for c in mine] == FRAMES
        assert [c.t_end for c in mine] == pytest.approx(times, abs=tolerance)
    ns = [c for c in chunks if c.channel == 0]
    assert [c.direction for c in ns] == [Direction.MASTER, Direction.UNKNOWN] * 2
    assert [c.note for c in ns] == [f"packet {k}" for k in range(4)]
    # exported frames: requests and answers on the interface's channel, in file order
    exported = [c for c in chunks if c.channel == 3]
    assert [c.direction for c in exported] == [Direction.MASTER, Direction.SLAVE] * 2
    rtac_chunks = [c for c in chunks if c.channel == 2]
    assert [c.t_start for c in rtac_chunks] == pytest.approx([t - 0.005 for t in times], abs=1e-6)
    # microsecond interface: times come back exactly to the microsecond
    us = [c.t_end for c in chunks if c.channel == 1]
    assert [round(t * 1e6) for t in us] == [round(t * 1e6) for t in times]


def test_writer_flushes_every_block() -> None:
    class Counting(io.BytesIO):
        flushes = 0

        def flush(self) -> None:
            self.flushes += 1
            super().flush()

    stream = Counting()
    writer = PcapngWriter(stream)
    port = writer.add_interface(LINKTYPE_USER0)
    writer.write_packet(port, T0, b"\x01")
    assert stream.flushes == 3
    with pytest.raises(ValueError, match="no interface 4"):
        writer.write_packet(4, T0, b"")


def test_payload_builders() -> None:
    record = rtac_record(T0 + 0.25, b"\x01\x02", event=RTAC_DATA_RX_START, control_lines=3)
    assert record[:12] == struct.pack(">IIBBH", int(T0), 250_000, 2, 3, 0)
    parsed = parse_rtac(record)
    assert parsed is not None
    assert (parsed.seconds, parsed.event, parsed.control_lines, parsed.data) == (
        T0 + 0.25,
        2,
        3,
        b"\x01\x02",
    )
    pdu = upper_pdu_record(REQUEST)
    assert pdu == b"\x00\x0c\x00\x08mbrtu\0\0\0\x00\x00\x00\x00" + REQUEST
    upper = parse_upper_pdu(pdu)
    assert upper is not None
    assert (upper.dissector, upper.pdu) == ("mbrtu", REQUEST)


# ---------------------------------------------------------------- tshark

needs_tshark = pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark not installed")


def tshark(path: Path, *args: str) -> list[list[str]]:
    result = subprocess.run(
        ["tshark", "-r", str(path), *args], check=True, capture_output=True, text=True
    )
    return [line.split("\t") for line in result.stdout.splitlines()]


def _valid_frames() -> list[bytes]:
    frames = [
        REQUEST,
        RESPONSE,
        WRITE,
        WRITE,
        with_crc(bytes.fromhex("0a10000a0002040102a0b1")),
        with_crc(bytes.fromhex("0a10000a0002")),
    ]
    assert all(crc16(frame) == 0 for frame in frames)
    return frames


@pytest.mark.peer
@needs_tshark
def test_tshark_dissects_252_as_modbus_rtu(tmp_path: Path) -> None:
    path = tmp_path / "export.pcapng"
    frames = _valid_frames()
    with path.open("wb") as stream:
        writer = PcapngWriter(stream)
        port = writer.add_interface(LINKTYPE_WIRESHARK_UPPER_PDU, name="modbus")
        for k, frame in enumerate(frames):
            flags = EPB_FLAG_OUTBOUND if k % 2 == 0 else EPB_FLAG_INBOUND
            writer.write_packet(port, T0 + k * 0.1, upper_pdu_record(frame), flags=flags)
    rows = tshark(
        path,
        "-T",
        "fields",
        "-e",
        "frame.protocols",
        "-e",
        "mbrtu.unit_id",
        "-e",
        "modbus.func_code",
        "-e",
        "_ws.malformed",
    )
    assert rows == [
        ["exported_pdu:mbrtu:modbus", str(frame[0]), str(frame[1]), ""] for frame in frames
    ]
    verbose = subprocess.run(
        ["tshark", "-r", str(path), "-V"], check=True, capture_output=True, text=True
    ).stdout
    assert "Malformed" not in verbose
    assert verbose.count("Modbus RTU") == len(frames)
    assert "CRC" in verbose


@pytest.mark.peer
@needs_tshark
def test_tshark_reads_rtac_serial(tmp_path: Path) -> None:
    path = tmp_path / "rtac.pcapng"
    frames = _valid_frames()
    with path.open("wb") as stream:
        writer = PcapngWriter(stream)
        port = writer.add_interface(LINKTYPE_RTAC_SERIAL, name="ttyS0")
        for k, frame in enumerate(frames):
            t = T0 + k * 0.1
            writer.write_packet(port, t, rtac_record(t - 0.004, frame), flags=EPB_FLAG_INBOUND)
        writer.write_packet(port, T0 + 1, rtac_record(T0 + 1, b"", event=RTAC_PARITY_ERROR))
    rows = tshark(
        path, "-T", "fields", "-e", "frame.protocols", "-e", "rtacser.eventtype", "-e", "data.data"
    )
    assert rows[:-1] == [["rtacser:data", "0x02", frame.hex()] for frame in frames]
    assert rows[-1] == ["rtacser", "0x08", ""]
    text = subprocess.run(
        ["tshark", "-r", str(path)], check=True, capture_output=True, text=True
    ).stdout
    assert "RTAC Serial" in text
    assert "DATA_RX_START" in text


@pytest.mark.peer
@needs_tshark
def test_tshark_reads_user0(tmp_path: Path) -> None:
    path = tmp_path / "raw.pcapng"
    frames = _valid_frames()
    with path.open("wb") as stream:
        writer = PcapngWriter(stream)
        port = writer.add_interface(LINKTYPE_USER0, name="ttyUSB0", tsresol_ns=False)
        for k, frame in enumerate(frames):
            writer.write_packet(port, T0 + k * 0.1, frame, comment="hi" if k == 0 else None)
    rows = tshark(
        path, "-T", "fields", "-e", "frame.encap_type", "-e", "data.data", "-e", "frame.time_epoch"
    )
    assert [row[1] for row in rows] == [frame.hex() for frame in frames]
    assert {row[0] for row in rows} == {"45"}  # WTAP_ENCAP_USER0
    assert [float(row[2]) for row in rows] == pytest.approx(
        [T0 + k * 0.1 for k in range(len(frames))], abs=1e-6
    )
