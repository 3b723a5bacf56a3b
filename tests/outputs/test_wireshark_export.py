"""The default Wireshark export (issue 10): each frame's PDU for Wireshark's Modbus/TCP
dissector, so every function code opens classified and paired with no preferences; the
line's bytes and the check's verdict in the comment; read back by modscope as the same
frames. `--as rtu` keeps the byte-exact RTU export (tests/outputs/test_export.py)."""

from __future__ import annotations

import io
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from dissectors.checks import ascii_frame, with_crc
from sniffer.cli import main
from sniffer.framing.tcp import NetPipeline
from sniffer.meaning.annotate import Annotator
from sniffer.meaning.describe import Describer
from sniffer.model import Chunk, LineSettings
from sniffer.outputs.export import PcapExporter, tcp_packet_for
from sniffer.session.session import Session, open_session
from sniffer.sources import open_capture
from sniffer.sources.base import ReadOptions
from sniffer.sources.linktypes import (
    EPB_FLAG_CRC_ERROR,
    EPB_FLAG_INBOUND,
    EPB_FLAG_OUTBOUND,
    MBAP_HEADER,
    parse_upper_pdu,
)
from sniffer.vocab import STATUS_NAMES, Kind
from tests.support.netbuild import Conversation, pcap

TSHARK = shutil.which("tshark")
RTU = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
ASCII = LineSettings(baud=9600, parity="E", stopbits=1, bytesize=7, mode="ascii")
T0 = 1_750_000_000.0

# (request, answer) as unit + PDU in hex; None: no answer. Every public function code of
# the serial line, FC 5/6/8/21/22 echoes, an exception, a timeout and two broadcasts.
PAIRS: list[tuple[str, str | None]] = [
    ("01 01 0000 000a", "01 01 02 5501"),
    ("01 02 0000 0008", "01 02 01 a5"),
    ("01 03 0000 0002", "01 03 04 0064 0065"),
    ("01 04 0001 0001", "01 04 02 00ff"),
    ("01 05 0003 ff00", "01 05 0003 ff00"),
    ("01 06 0005 0007", "01 06 0005 0007"),
    ("01 07", "01 07 6d"),
    ("01 08 0000 a537", "01 08 0000 a537"),
    ("01 0b", "01 0b ffff 0108"),
    ("01 0c", "01 0c 08 0000 0108 0121 2000"),
    ("01 0f 0013 000a 02 cd01", "01 0f 0013 000a"),
    ("01 10 0001 0002 04 000a 0102", "01 10 0001 0002"),
    ("01 11", "01 11 05 01 ff 414243"),
    ("01 14 07 06 0004 0001 0002", "01 14 06 05 06 0df8 46e0"),
    ("01 15 0d 06 0004 0007 0003 06af 04be 100d", "01 15 0d 06 0004 0007 0003 06af 04be 100d"),
    ("01 16 0004 00f2 0025", "01 16 0004 00f2 0025"),
    ("01 17 0003 0006 000e 0003 06 00ff 00ff 00ff", "01 17 0c 000000000000000000000000"),
    ("01 18 04de", "01 18 0006 0002 01b8 1284"),
    ("01 2b 0e 01 00", "01 2b 0e 01 01 00 00 03 00 06 56656e646f72 01 04 50313233 02 03 312e30"),
    ("01 03 0064 0001", "01 83 02"),
    ("01 06 0001 0003", None),
    ("00 06 0001 0003", None),
    ("00 10 0001 0001 02 0007", None),
]
BAD_CRC = bytes.fromhex("01030400640065") + b"\x00\x00"


def hexbytes(text: str) -> bytes:
    return bytes.fromhex(text.replace(" ", ""))


def every_function() -> Session:
    """The PAIRS on the wire with exact timing, then a request whose answer's CRC is bad."""
    s = Session(RTU, exact_timing=True, timeout=0.1)
    t = T0
    frames: list[bytes | None] = []
    for q, a in PAIRS:
        frames += [with_crc(hexbytes(q)), None if a is None else with_crc(hexbytes(a))]
    frames += [with_crc(hexbytes("01 03 0000 0002")), BAD_CRC]
    for raw in frames:
        if raw is None:
            t += 0.3
            continue
        s.feed(Chunk(raw, t + len(raw) * RTU.char_time, t_start=t))
        t += 0.03
    s.finish()
    return s


def ascii_session() -> Session:
    frames = [
        ascii_frame(hexbytes("01 03 0000 0002")),
        ascii_frame(hexbytes("01 03 04 0064 0065")),
        ascii_frame(hexbytes("01 05 0003 ff00")),
        ascii_frame(hexbytes("01 05 0003 ff00")),
        b":010300000002FB\r\n",  # LRC wrong (FA is right)
    ]
    s = Session(ASCII)
    for k, f in enumerate(frames):
        s.feed(Chunk(f, T0 + k * 0.1))
    s.finish()
    return s


def export_to(s: Session, path: Path) -> Path:
    buf = io.BytesIO()
    PcapExporter(buf, s.describer, s.line).write(range(len(s.store)))
    path.write_bytes(buf.getvalue())
    return path


def rows_of(s: Session) -> list[tuple[bytes, int, str]]:
    return [
        (s.store.raw(i), s.store.kind[i], STATUS_NAMES[s.store.status[i]])
        for i in range(len(s.store))
    ]


def test_the_table_frames_as_intended() -> None:
    s = every_function()
    kinds = [Kind(k) for k in s.store.kind]
    assert kinds.count(Kind.REQUEST) == len(PAIRS) + 1
    assert kinds.count(Kind.RESPONSE) + kinds.count(Kind.EXCEPTION) == 21
    assert {s.store.view(i).function for i in range(len(s.store))} >= {
        1, 2, 3, 4, 5, 6, 7, 8, 11, 12, 15, 16, 17, 20, 21, 22, 23, 24, 43,
    }  # fmt: skip


def test_packets_carry_mbap_with_the_request_row_as_transaction_id() -> None:
    s = every_function()
    for i in range(len(s.store)):
        d = s.describer.detail(i)
        packet, flags, comment = tcp_packet_for(d)
        record = parse_upper_pdu(packet)
        assert record is not None and record.dissector == "mbtcp"
        tid, protocol, length, unit = MBAP_HEADER.unpack_from(record.pdu)
        raw = d.view.raw
        assert (protocol, length, unit) == (0, len(raw) - 2, raw[0])
        assert record.pdu[7:] == raw[1:-2]
        request = i if d.view.kind == Kind.REQUEST else d.view.partner
        assert tid == request
        direction = EPB_FLAG_OUTBOUND if d.view.kind == Kind.REQUEST else EPB_FLAG_INBOUND
        assert flags & 3 == direction
        assert comment.startswith(f"RTU {raw.hex(' ')}; ")
        if raw == BAD_CRC:
            assert flags & EPB_FLAG_CRC_ERROR
            assert comment.count("CRC 00 00 wrong, expected") == 1
        else:
            assert not flags & EPB_FLAG_CRC_ERROR
            assert f"; CRC {raw[-2]:02x} {raw[-1]:02x} right" in comment


def test_the_export_reads_back_as_the_same_frames(tmp_path: Path) -> None:
    s = every_function()
    path = export_to(s, tmp_path / "every.pcapng")
    again, capture = open_session(path, None)
    again.ingest(capture.chunks())
    assert capture.warnings == []
    assert rows_of(again) == rows_of(s)


def test_ascii_frames_go_out_decoded_and_come_back_as_ascii(tmp_path: Path) -> None:
    s = ascii_session()
    details = [s.describer.detail(i) for i in range(len(s.store))]
    first = tcp_packet_for(details[0])
    assert first[2].startswith('ASCII ":010300000002FA\\r\\n"; LRC FA right')
    record = parse_upper_pdu(first[0])
    assert record is not None and record.pdu[6:] == hexbytes("01 03 0000 0002")
    bad = tcp_packet_for(details[4])
    assert bad[1] & EPB_FLAG_CRC_ERROR
    assert "LRC 0xFB wrong, expected 0xFA" in bad[2]
    path = export_to(s, tmp_path / "ascii.pcapng")
    again, capture = open_session(path, None)
    again.ingest(capture.chunks())
    assert rows_of(again) == rows_of(s)
    assert again.line.mode == "ascii"


def test_a_packet_that_is_not_mbap_is_passed_on_with_a_warning(tmp_path: Path) -> None:
    from sniffer.sources.pcapng_writer import PcapngWriter, upper_pdu_record

    path = tmp_path / "odd.pcapng"
    with path.open("wb") as handle:
        writer = PcapngWriter(handle)
        iface = writer.add_interface(252)
        # an RTU frame handed to mbtcp: protocol id 0x0006 is not Modbus/TCP's 0
        writer.write_packet(
            iface, T0, upper_pdu_record(with_crc(hexbytes("0106 0005 0007")), "mbtcp")
        )
    session, capture = open_session(path, None)
    session.ingest(capture.chunks())
    assert session.store.raw(0) == with_crc(hexbytes("0106 0005 0007"))
    assert any("is not one Modbus/TCP frame" in w for w in capture.warnings)


def test_cli_default_is_modbus_tcp_and_as_rtu_is_byte_exact(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = export_to(every_function(), tmp_path / "in.pcapng")
    assert main(["export", str(source), "-o", str(tmp_path / "tcp.pcapng")]) == 0
    assert main(["export", str(source), "-o", str(tmp_path / "rtu.pcapng"), "--as", "rtu"]) == 0
    err = capsys.readouterr().err
    assert "Modbus/TCP" in err and "Modbus RTU byte for byte" in err
    assert b"mbtcp" in (tmp_path / "tcp.pcapng").read_bytes()
    rtu = (tmp_path / "rtu.pcapng").read_bytes()
    assert b"mbtcp" not in rtu and BAD_CRC in rtu
    assert main(["export", str(source), "-o", str(tmp_path / "x.csv"), "--as", "rtu"]) == 2
    assert "--as does not apply to a CSV export" in capsys.readouterr().err


def tshark(path: Path, *args: str) -> str:
    assert TSHARK is not None
    result = subprocess.run(
        [TSHARK, "-r", str(path), *args], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    return result.stdout


@pytest.mark.peer
@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed")
@pytest.mark.parametrize("session", [every_function, ascii_session])
def test_tshark_classifies_and_pairs_every_frame(tmp_path: Path, session: object) -> None:
    assert callable(session)
    s: Session = session()
    path = export_to(s, tmp_path / "out.pcapng")
    assert tshark(path, "-Y", "_ws.malformed || _ws.expert.severity >= error") == ""
    fields = tshark(
        path, "-T", "fields", "-E", "separator=;",
        "-e", "mbtcp.trans_id", "-e", "mbtcp.unit_id", "-e", "modbus.func_code",
        "-e", "modbus.request_frame", "-e", "_ws.col.Info",
    ).splitlines()  # fmt: skip
    assert len(fields) == len(s.store)
    for i, line in enumerate(fields):
        tid, unit, fc, request_frame, info = line.split(";", 4)
        v = s.store.view(i)
        assert int(unit) == v.unit and int(fc) == v.function
        if v.kind == Kind.REQUEST:
            assert info.lstrip().startswith("Query:"), line
            assert (int(tid), request_frame) == (i, "")
        else:
            assert info.lstrip().startswith("Response:"), line
            assert int(tid) == v.partner
            if v.kind == Kind.EXCEPTION:  # tshark 4.0 links no exception to its request
                assert request_frame in ("", str(v.partner + 1))
            else:
                assert int(request_frame) == v.partner + 1  # Wireshark counts from 1


def test_exported_pdu_tags_name_mbtcp_and_port_502() -> None:
    s = every_function()
    packet, _flags, _comment = tcp_packet_for(s.describer.detail(0))
    # tag 12 "mbtcp", then IPv4 src/dst (20, 21), port type (24), ports (25, 26)
    assert packet[:12] == struct.pack(">HH", 12, 8) + b"mbtcp\0\0\0"
    tags = {}
    offset = 12
    while True:
        tag, length = struct.unpack_from(">HH", packet, offset)
        offset += 4
        if tag == 0:
            break
        tags[tag] = packet[offset : offset + length]
        offset += length
    assert struct.unpack(">I", tags[26])[0] == 502  # a request goes to the server port
    answer = tcp_packet_for(s.describer.detail(1))[0]
    assert struct.pack(">HHI", 25, 4, 502) in answer


def modbus_tcp_capture(path: Path) -> Path:
    """A Modbus TCP connection on Ethernet: two transactions with their own MBAP ids."""
    conv = Conversation()
    adus = [
        (True, bytes.fromhex("0007 0000 0006 01 03 0000 0002")),
        (False, bytes.fromhex("0007 0000 0007 01 03 04 0064 0065")),
        (True, bytes.fromhex("0008 0000 0006 01 06 0005 0007")),
        (False, bytes.fromhex("0008 0000 0006 01 06 0005 0007")),
    ]
    packets = [*conv.handshake()]
    packets += [conv.client(adu) if client else conv.server(adu) for client, adu in adus]
    path.write_bytes(pcap(1, [(T0 + 0.01 * k, p) for k, p in enumerate(packets)]))
    return path


def test_modbus_tcp_rows_go_out_with_their_header_in_the_comment(tmp_path: Path) -> None:
    path = modbus_tcp_capture(tmp_path / "tcp.pcap")
    capture = open_capture(path, ReadOptions())
    pipeline = NetPipeline(RTU, channels=capture.info.channels)
    pipeline.feed_all(capture.chunks())
    pipeline.finish()
    store = pipeline.store
    describer = Describer(store, Annotator({}))
    rows = [i for i in range(len(store)) if store.kind[i] != Kind.EVENT]
    assert [Kind(store.kind[i]) for i in rows] == [Kind.REQUEST, Kind.RESPONSE] * 2
    for i in rows:
        packet, _flags, comment = tcp_packet_for(describer.detail(i))
        record = parse_upper_pdu(packet)
        assert record is not None and record.dissector == "mbtcp"
        assert record.pdu[6:] == store.raw(i)[6:]  # unit and PDU
        assert comment.startswith("Modbus/TCP " + store.raw(i).hex(" "))
    out = io.BytesIO()
    PcapExporter(out, describer, RTU).write(rows)
    exported = tmp_path / "out.pcapng"
    exported.write_bytes(out.getvalue())
    if TSHARK is not None:
        info = tshark(exported, "-T", "fields", "-e", "_ws.col.Info").splitlines()
        assert [line.split(":")[0].strip() for line in info] == ["Query", "Response"] * 2
