"""Export: pcapng for Wireshark as RTU (`--as rtu`: link type 252, mbrtu; direction and
CRC-error flags, problems in comments, noise as data, ASCII as the equivalent RTU frame),
and CSV/JSONL tables of frames, transactions and register values."""

from __future__ import annotations

import csv
import io
import json
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from dissectors.checks import ascii_frame, with_crc
from sniffer.cli import main
from sniffer.cli.export import output_format
from sniffer.live.port import PortSpec
from sniffer.live.recorder import Recorder
from sniffer.model import Chunk, LineSettings
from sniffer.outputs.export import (
    PcapExporter,
    packet_for,
    register_records,
    transaction_records,
)
from sniffer.session.session import Session
from sniffer.sources import open_capture
from sniffer.sources.linktypes import (
    EPB_FLAG_CRC_ERROR,
    EPB_FLAG_INBOUND,
    EPB_FLAG_OUTBOUND,
    parse_upper_pdu,
)
from sniffer.vocab import Kind

RTU = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
ASCII = LineSettings(baud=9600, parity="E", stopbits=1, bytesize=7, mode="ascii")
T0 = 1_750_000_000.0
TSHARK = shutil.which("tshark")

REQUEST = with_crc(bytes.fromhex("010300000002"))
ANSWER = with_crc(bytes.fromhex("01030400640065"))
BAD_CRC = bytes.fromhex("01030400640065") + b"\x00\x00"
WRITE = with_crc(bytes.fromhex("020600050007"))
EXCEPTION_REQ = with_crc(bytes.fromhex("030300640001"))
EXCEPTION = with_crc(bytes.fromhex("038302"))
SILENT = with_crc(bytes.fromhex("090300000001"))
NOISE = b"\xff\xfe\x00"


def rtu_session(frames: list[bytes]) -> Session:
    """Frames on the wire with exact timing (so a bad CRC is a frame, not noise)."""
    s = Session(RTU, exact_timing=True, timeout=0.1)
    t = T0
    for f in frames:
        s.feed(Chunk(f, t + len(f) * RTU.char_time, t_start=t))
        t += 0.03 if f != SILENT else 0.5
    s.feed(Chunk(b"", t, event="reconnect", note="/dev/ttyUSB0: back after 1.0 s"))
    s.finish()
    return s


def mixed() -> Session:
    return rtu_session(
        [REQUEST, ANSWER, REQUEST, BAD_CRC, WRITE, WRITE, EXCEPTION_REQ, EXCEPTION, SILENT, NOISE]
    )


def ascii_session() -> Session:
    frames = [
        ascii_frame(bytes.fromhex("010300000002")),
        ascii_frame(bytes.fromhex("01030400640065")),
        b":010300000002FB\r\n",  # LRC wrong (FA is right)
        b":01030400640065\r\n",  # the LRC is missing: the check fails
    ]
    s = Session(ASCII)
    for k, f in enumerate(frames):
        s.feed(Chunk(f, T0 + k * 0.1))
    s.finish()
    return s


def export_bytes(s: Session, style: str = "rtu") -> bytes:
    """The `--as rtu` export (the default one: tests/outputs/test_wireshark_export.py)."""
    buf = io.BytesIO()
    PcapExporter(buf, s.describer, s.line, style=style).write(range(len(s.store)))
    return buf.getvalue()


# -- packets -------------------------------------------------------------------------------


def test_requests_go_out_answers_come_in_and_bad_crcs_are_flagged() -> None:
    s = mixed()
    details = [s.describer.detail(i) for i in range(len(s.store))]
    by_kind = {Kind(d.view.kind) for d in details}
    assert {Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION, Kind.NOISE, Kind.EVENT} <= by_kind
    for d in details:
        packet, flags, comment = packet_for(d)
        pdu = parse_upper_pdu(packet)
        assert pdu is not None
        kind = Kind(d.view.kind)
        if kind == Kind.REQUEST:
            assert flags & 3 == EPB_FLAG_OUTBOUND
        elif kind in (Kind.RESPONSE, Kind.EXCEPTION):
            assert flags & 3 == EPB_FLAG_INBOUND
        else:
            assert flags & 3 == 0
        if kind in (Kind.NOISE, Kind.EVENT):
            assert pdu.dissector == "data"
            assert comment
        else:
            assert (pdu.dissector, pdu.pdu) == ("mbrtu", d.view.raw)
        assert bool(flags & EPB_FLAG_CRC_ERROR) == (d.view.raw == BAD_CRC)
        if d.view.raw == BAD_CRC:
            assert "CRC 00 00 wrong, expected" in comment
        if d.view.raw == SILENT:
            assert "no answer (timeout)" in comment


def test_ascii_frames_become_rtu_frames_with_a_note() -> None:
    s = ascii_session()
    out = [packet_for(s.describer.detail(i)) for i in range(len(s.store))]
    first = parse_upper_pdu(out[0][0])
    assert first is not None
    assert first.pdu == REQUEST
    assert out[0][2].startswith("carried as Modbus ASCII with LRC FA (right)")
    second = parse_upper_pdu(out[1][0])
    assert second is not None and second.pdu == ANSWER
    assert out[2][1] & EPB_FLAG_CRC_ERROR
    assert "LRC FB (wrong, expected FA)" in out[2][2]


def test_export_reads_back_as_the_same_frames(tmp_path: Path) -> None:
    s = mixed()
    path = tmp_path / "out.pcapng"
    path.write_bytes(export_bytes(s))
    capture = open_capture(path)
    assert capture.info.line == RTU
    got = [(c.data, c.direction) for c in capture.chunks() if c.data]
    sent = [
        (s.store.raw(i), s.describer.detail(i).direction)
        for i in range(len(s.store))
        if s.store.kind[i] != Kind.EVENT
    ]
    names = {1: "M>S", 2: "S>M", 0: "?"}
    assert [(data, names[d]) for data, d in got] == sent


def tshark(path: Path, *args: str) -> str:
    assert TSHARK is not None
    result = subprocess.run(
        [TSHARK, "-r", str(path), *args], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    return result.stdout


@pytest.mark.peer
@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed")
def test_tshark_decodes_every_frame_as_modbus_rtu(tmp_path: Path) -> None:
    s = mixed()
    path = tmp_path / "out.pcapng"
    path.write_bytes(export_bytes(s))
    assert tshark(path, "-Y", "_ws.malformed") == ""
    fields = tshark(
        path,
        "-T",
        "fields",
        "-E",
        "separator=;",
        "-e",
        "mbrtu.unit_id",
        "-e",
        "modbus.func_code",
        "-e",
        "frame.p2p_dir",
        "-e",
        "frame.comment",
    ).splitlines()
    assert len(fields) == len(s.store)
    for i, line in enumerate(fields):
        unit, fc, p2p, _comment = line.split(";", 3)
        v = s.store.view(i)
        if v.kind in (Kind.NOISE, Kind.EVENT):
            assert (unit, fc) == ("", "")
            continue
        assert int(unit) == v.unit
        assert int(fc) == v.function
        assert p2p == ("0" if v.kind == Kind.REQUEST else "1")
    crc_flagged = tshark(path, "-Y", "frame.packet_flags_crc_error == 1", "-T", "fields", "-e",
                         "frame.number")  # fmt: skip
    bad = [i + 1 for i in range(len(s.store)) if s.store.raw(i) == BAD_CRC]
    assert [int(n) for n in crc_flagged.split()] == bad
    values = tshark(path, "-T", "fields", "-e", "modbus.regval_uint16")
    assert values.split() == ["100,101", "100,101"]  # the second one with its bad CRC


@pytest.mark.peer
@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed")
def test_tshark_decodes_ascii_frames_exported_as_rtu(tmp_path: Path) -> None:
    s = ascii_session()
    path = tmp_path / "ascii.pcapng"
    path.write_bytes(export_bytes(s))
    assert tshark(path, "-Y", "_ws.malformed") == ""
    units = tshark(path, "-T", "fields", "-e", "mbrtu.unit_id", "-e", "modbus.func_code")
    assert units.splitlines()[:2] == ["1\t3", "1\t3"]


# -- tables --------------------------------------------------------------------------------


def test_transactions_one_row_per_request_with_its_answer() -> None:
    s = mixed()
    recs = list(transaction_records(s.describer, range(len(s.store))))
    statuses = [(r["unit"], r["function"], r["status"]) for r in recs]
    assert statuses == [
        (1, 3, "ok"),
        (1, 3, "bad answer"),  # its answer had a bad CRC
        (2, 6, "ok"),
        (3, 3, "exception"),
        (9, 3, "timeout"),
    ]
    first = recs[0]
    assert first["response"] == 1 and first["latency_ms"] is not None
    assert first["request_raw"] == REQUEST.hex() and first["response_raw"] == ANSWER.hex()
    assert recs[3]["exception_code"] == 2
    assert recs[4]["response"] is None


def test_registers_one_row_per_value() -> None:
    s = mixed()
    recs = list(register_records(s.describer, range(len(s.store))))
    got = [(r["unit"], r["access"], r["table"], r["address"], r["value"]) for r in recs]
    assert (1, "read", "holding_registers", 0, 100) in got
    assert (1, "read", "holding_registers", 1, 101) in got
    assert (2, "write", "holding_registers", 5, 7) in got


def test_export_command_picks_the_format_from_the_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rec = tmp_path / "rec.pcapng"
    recorder = Recorder(rec, [PortSpec("/dev/ttyUSB0", RTU)])
    t = T0
    for f in (REQUEST, ANSWER, WRITE, WRITE):
        recorder.write(Chunk(f, t))
        t += 0.05
    recorder.close()
    out_csv = tmp_path / "tx.csv"
    assert main(["export", str(rec), "-o", str(out_csv), "--what", "transactions"]) == 0
    rows = list(csv.DictReader(out_csv.open()))
    assert [(r["unit"], r["function"], r["status"]) for r in rows] == [
        ("1", "3", "ok"),
        ("2", "6", "ok"),
    ]
    out_jsonl = tmp_path / "regs.jsonl"
    assert main(["export", str(rec), "-o", str(out_jsonl), "--what", "registers"]) == 0
    regs = [json.loads(line) for line in out_jsonl.read_text().splitlines()]
    assert [r["value"] for r in regs if r["access"] == "read"] == [100, 101]
    out_pcap = tmp_path / "ws.pcapng"
    assert main(["export", str(rec), "-o", str(out_pcap)]) == 0
    capture = open_capture(out_pcap)
    assert [c.data for c in capture.chunks()] == [REQUEST, ANSWER, WRITE, WRITE]
    capsys.readouterr()
    assert main(["export", str(rec), "-o", "-", "--format", "jsonl"]) == 0
    listing = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [r["kind"] for r in listing] == ["request", "response", "request", "response"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["-o", "x.pcapng", "--what", "transactions"], "needs csv or jsonl"),
        (["-o", "x.txt", "--what", "registers"], "write it as csv or jsonl"),
        (["-o", "-"], "needs --format"),
        (["-o", "x.bin"], "cannot tell the format"),
    ],
)
def test_export_usage_errors(
    tmp_path: Path, args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    rec = tmp_path / "rec.pcapng"
    Recorder(rec, [PortSpec("/dev/ttyUSB0", RTU)]).close()
    assert main(["export", str(rec), *args]) == 2
    assert message in capsys.readouterr().err


def test_output_format() -> None:
    assert output_format("a.PCAPNG", None) == "pcapng"
    assert output_format("a.ndjson", None) == "jsonl"
    assert output_format("a.bin", "csv") == "csv"


def test_pcapng_header_names_modscope_and_the_line() -> None:
    raw = export_bytes(mixed())
    assert struct.unpack_from("<I", raw)[0] == 0x0A0D0D0A
    assert b"modscope" in raw[:200] and b"modscope 19200 8N2 rtu" in raw[:400]
