"""Tests Modbus TCP through `modscope replay`: MBAP rows listed, dissected and checked
through the MBAP envelope, with channel and peer; `--carrier`, `--port`, standard input;
several files replayed together with both sides of a gateway linked (JSONL `gateway`,
`--stats`, `--offset`, the estimate); `p` in the TUI across the link; tshark's reading
of the same capture through the command line."""

from __future__ import annotations

import io
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from dissectors.checks import with_crc
from dissectors.envelope import open_mbap
from sniffer.cli import main
from sniffer.framing.store import FrameView
from sniffer.meaning.problems import frame_problems
from sniffer.vocab import Flag, Kind
from tests.support import gateway as gw
from tests.support.netbuild import Conversation, pcap

T0 = 1_750_000_000.0


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str], str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out.splitlines(), err


def jsonl(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[list[dict[str, Any]], str]:
    code, lines, err = run([*args, "--format", "jsonl"], capsys)
    assert code in (0, 1), err
    return [json.loads(line) for line in lines], err


def eth_capture(tmp_path: Path) -> Path:
    """Two connections to two servers; the second polls unit 7 and gets an exception."""
    one = Conversation()
    two = Conversation(client_port=50300, server_ip="192.168.1.30", server_port=503)
    packets = [*one.handshake(), *two.handshake()]
    packets += [
        one.client(gw.mbap_frame(1, bytes.fromhex("0103000a0002"))),
        two.client(gw.mbap_frame(1, bytes.fromhex("070400000001"))),
        one.server(gw.mbap_frame(1, bytes.fromhex("01030400010002"))),
        two.server(gw.mbap_frame(1, bytes.fromhex("078402"))),
    ]
    path = tmp_path / "eth.pcap"
    path.write_bytes(pcap(1, [(T0 + k * 0.01, p) for k, p in enumerate(packets)]))
    return path


# ------------------------------------------------------------------ one network capture


def test_modbus_tcp_rows_are_listed_with_channel_and_peer(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rows, _ = jsonl(["replay", str(eth_capture(tmp_path))], capsys)
    frames = [r for r in rows if r["kind"] != "event"]
    assert [(r["kind"], r["unit"], r["function"]) for r in frames] == [
        ("request", 1, 3),
        ("request", 7, 4),
        ("response", 1, 3),
        ("exception", 7, 4),
    ]
    assert all(r["mode"] == "tcp" and r["check_ok"] for r in frames)
    assert [r["peer"] for r in frames] == [
        "192.168.1.10:50211",
        "192.168.1.10:50300",
        "192.168.1.20:502",
        "192.168.1.30:503",
    ]
    assert [r["channel"] for r in frames] == [0, 2, 1, 3]
    # the body went to the same dissector as an RTU frame's: fields, spans in the body
    assert frames[0]["summary"] == "read 2 holding registers from 0x000A"
    assert frames[2]["fields"][1]["value"] == [1, 2]
    assert frames[2]["transaction"]["partner"] == frames[0]["index"]
    assert frames[3]["transaction"]["status"] == "exception"


def test_stats_per_server_and_unit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, lines, _ = run(["replay", str(eth_capture(tmp_path)), "--stats"], capsys)
    assert code == 0
    text = "\n".join(lines)
    assert "per server and unit" in text
    row = next(x for x in lines if x.startswith("192.168.1.30:503"))
    assert row.split()[1:6] == ["7", "1", "1", "1", "0"]  # unit, req, resp, exc, t/o
    assert any(x.startswith("192.168.1.20:502") for x in lines)


def test_text_and_csv_name_the_peer(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = str(eth_capture(tmp_path))
    _, lines, _ = run(["replay", path, "--format", "text"], capsys)
    assert sum("192.168.1.10:50211" in x and "u1" in x for x in lines) == 1
    _, lines, _ = run(["replay", path, "--format", "csv"], capsys)
    head = lines[0].split(",")
    assert head[-2:] == ["channel", "peer"]
    assert lines[-1].split(",")[-2:] == ["3", "192.168.1.30:503"]


def test_standard_input_reads_a_pcap(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """`tcpdump -U -w - | modscope replay -`: the pcap comes on standard input."""
    data = eth_capture(tmp_path).read_bytes()
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))
    rows, _ = jsonl(["replay", "-"], capsys)
    assert [r["unit"] for r in rows if r["kind"] == "request"] == [1, 7]


def test_port_leaves_other_servers_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rows, err = jsonl(["replay", str(eth_capture(tmp_path)), "--port", "503"], capsys)
    assert {r["peer"] for r in rows} == {"192.168.1.10:50300", "192.168.1.30:503"}
    assert "not on port 503" in err
    code, _, err = run(["replay", str(eth_capture(tmp_path)), "--port", "70000"], capsys)
    assert code == 2 and "--port must be" in err


def test_carrier_reads_rtu_over_tcp(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    conv = Conversation(server_port=4001)
    request, answer = with_crc(bytes.fromhex("110300000001")), with_crc(bytes.fromhex("1103020007"))
    packets = [*conv.handshake(), conv.client(request), conv.server(answer)]
    path = tmp_path / "nport.pcap"
    path.write_bytes(pcap(1, [(T0 + k * 0.01, p) for k, p in enumerate(packets)]))
    rows, _ = jsonl(["replay", str(path), "--carrier", "rtu-over-tcp"], capsys)
    frames = [r for r in rows if r["kind"] != "event"]
    assert [(r["mode"], r["kind"], r["unit"], r["raw"]) for r in frames] == [
        ("rtu", "request", 17, request.hex()),
        ("rtu", "response", 17, answer.hex()),
    ]
    assert frames[0]["peer"] == "192.168.1.10:50211"
    # read as Modbus TCP, the same bytes are no frame at all: nothing usable, exit 2
    code, out, err = run(["replay", str(path), "--carrier", "tcp", "--format", "jsonl"], capsys)
    assert code == 2 and "not one Modbus frame" in err
    assert {json.loads(line)["kind"] for line in out} <= {"noise", "event"}


def test_a_bad_mbap_header_is_a_problem_said_through_the_envelope() -> None:
    raw = bytes.fromhex("000100010006010300000001")  # protocol id 1
    view = FrameView(
        0, raw, 0.0, 0.0, Kind.REQUEST, 1, 3, False, Flag.MBAP | Flag.ENVELOPE_BAD, 0, -1, 0
    )
    assert view.body() == raw[6:] and not view.check_ok
    problems = frame_problems(view)
    assert [p.kind for p in problems] == ["mbap-header"]
    assert "protocol id 1 (0x0001) is not 0" in problems[0].text
    envelope = open_mbap(raw)
    assert envelope.unit == 1 and envelope.pdu == raw[7:] and not envelope.check_ok
    assert dict(envelope.spans)["pdu"] == (7, 12)
    good = open_mbap(bytes.fromhex("000100000006010300000001"))
    assert good.check_ok and good.check_text == "" and good.transaction == 1


# ------------------------------------------------------------------ both sides of a gateway


def gateway_files(tmp_path: Path) -> tuple[Path, Path]:
    """The nine fates of tests/analysis/test_gateway.py as a TCP pcap and a serial pcap (link type
    147), whose clock is 100 s behind."""
    conv = Conversation()
    packets = [(1000.0 + k * 0.001, p) for k, p in enumerate(conv.handshake())]
    serial: list[tuple[float, bytes]] = []
    for k, (_, tcp_answer, sent, rtu_answer) in enumerate(gw.CASES):
        t = 1001.0 + k
        request = gw.read_request(10 + k)
        packets.append((t, conv.client(gw.mbap_frame(k + 1, request))))
        serial_end = t + gw.DELAY_IN + gw.RTU_TIME
        if sent:
            serial.append((serial_end + gw.SERIAL_CLOCK, with_crc(request)))
        answer_end = serial_end + 0.02 + gw.RTU_TIME
        if rtu_answer is not None:
            serial.append((answer_end + gw.SERIAL_CLOCK, with_crc(rtu_answer)))
        if tcp_answer is not None:
            late = 0.5 * (rtu_answer is None)
            frame = gw.mbap_frame(k + 1, tcp_answer)
            packets.append((answer_end + gw.DELAY_OUT + late, conv.server(frame)))
    tcp_path, serial_path = tmp_path / "tcp.pcap", tmp_path / "serial.pcap"
    tcp_path.write_bytes(pcap(1, packets))
    serial_path.write_bytes(pcap(147, serial))
    return tcp_path, serial_path


LINE = ["-b", "19200", "-P", "N", "--stopbits", "2"]
# from the TCP request's end to the serial request's start: the serial request ends 4 ms
# + 10 ms after, and started its 8 bytes (11 bits each at 19200 baud) before that
DELAY_IN_TRUE = gw.DELAY_IN + gw.RTU_TIME - 8 * 11 / 19200
EXPECTED = [v.value for v in gw.EXPECTED]


def test_both_sides_are_linked_with_the_offset_estimated(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tcp, serial = gateway_files(tmp_path)
    rows, err = jsonl(["replay", str(tcp), str(serial), *LINE], capsys)
    assert "serial.pcap: clock offset +99.99" in err and "estimated from 4" in err
    assert [r["t"] for r in rows] == sorted(r["t"] for r in rows)  # merged by time
    requests = [r for r in rows if r["mode"] == "tcp" and r["kind"] == "request"]
    assert [r["gateway"]["verdict"] for r in requests] == EXPECTED
    serial_rows = [r for r in rows if r["mode"] == "rtu" and r["kind"] != "event"]
    assert {r["channel"] for r in serial_rows} == {2}  # the second file's own channel
    assert all("peer" not in r for r in serial_rows)
    first = requests[0]["gateway"]
    other = rows[first["peer"]]
    assert other["raw"] == with_crc(gw.read_request(10)).hex()
    assert other["gateway"]["peer"] == requests[0]["index"]
    assert first["delay_ms"] == pytest.approx(other["gateway"]["delay_ms"])
    # the answer leg: the TCP answer points at the serial answer, with the delay out
    answer = rows[requests[0]["transaction"]["partner"]]
    assert rows[answer["gateway"]["peer"]]["raw"] == with_crc(gw.read_answer(10)).hex()
    # an estimated offset splits the gateway's time evenly between the two legs: their
    # sum is what it is
    in_out = first["delay_ms"] + answer["gateway"]["delay_ms"]
    assert in_out == pytest.approx((DELAY_IN_TRUE + gw.DELAY_OUT) * 1000, abs=0.5)


def test_a_given_offset_is_used_and_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tcp, serial = gateway_files(tmp_path)
    rows, err = jsonl(
        ["replay", str(tcp), str(serial), *LINE, "--offset", "serial.pcap=100"], capsys
    )
    assert "serial.pcap: clock offset +100.000000 s (given)" in err
    requests = [r for r in rows if r["mode"] == "tcp" and r["kind"] == "request"]
    assert [r["gateway"]["verdict"] for r in requests] == EXPECTED
    # with the true offset each leg's delay is the gateway's own
    first = requests[0]["gateway"]
    answer = rows[requests[0]["transaction"]["partner"]]
    assert first["delay_ms"] == pytest.approx(DELAY_IN_TRUE * 1000, abs=0.5)
    assert answer["gateway"]["delay_ms"] == pytest.approx(gw.DELAY_OUT * 1000, abs=0.5)
    # an offset far off: nothing links, every request is not-sent or a gateway exception
    rows, _ = jsonl(["replay", str(tcp), str(serial), *LINE, "--offset", "serial.pcap=50"], capsys)
    verdicts = {
        r["gateway"]["verdict"] for r in rows if r["mode"] == "tcp" and r["kind"] == "request"
    }
    assert verdicts == {"not-sent", "gateway-exception"}
    code, _, err = run(["replay", str(tcp), str(serial), "--offset", "other.pcap=1"], capsys)
    assert code == 2 and "not one of the files given" in err
    code, _, err = run(["replay", str(tcp), "--offset", "tcp.pcap=1"], capsys)
    assert code == 2 and "several files" in err


def test_stats_have_a_gateway_section(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tcp, serial = gateway_files(tmp_path)
    given = ["--offset", "serial.pcap=100"]
    code, lines, _ = run(["replay", str(tcp), str(serial), *LINE, *given, "--stats"], capsys)
    assert code == 0
    counts = {
        x.split()[0]: int(x.split()[1])
        for x in lines
        if x.startswith("  ") and x.split()[1].isdigit()
    }
    assert counts["ok"] == 2 and counts["not-sent"] == 1 and counts["gateway-exception"] == 2
    assert counts["gateway-fault"] == 1 and counts["mismatch"] == 1
    delay_in = next(x for x in lines if x.strip().startswith("request in")).split()
    # n, min, median: the serial request starts 4 ms + 10 ms - its own 7 characters after
    assert int(delay_in[2]) == 7
    assert float(delay_in[4]) == pytest.approx(DELAY_IN_TRUE * 1000, abs=0.5)
    assert any(
        x.startswith("file ") and "serial.pcap" in x and "channels from 2" in x for x in lines
    )


@pytest.mark.asyncio
async def test_p_jumps_across_the_gateway_link(tmp_path: Path) -> None:
    from sniffer.session.multifile import align, link_files, merge
    from sniffer.session.session import replay_file
    from sniffer.sources import ReadOptions
    from sniffer.tui.app import ModscopeApp

    tcp, serial = gateway_files(tmp_path)
    options = ReadOptions(baud=19200, parity="N", stopbits=2)
    sessions = [replay_file(tcp, options), replay_file(serial, options)]
    names = [str(tcp), str(serial)]
    merged, parts, _ = merge(names, sessions, [a.offset for a in align(names, sessions, {})])
    links = link_files(merged, parts)
    request = links[0].tcp.request
    across = merged.store.links[request]["peer"]
    assert isinstance(across, int)
    app = ModscopeApp(merged)
    async with app.run_test(size=(120, 36)) as pilot:
        deadline = time.monotonic() + 10
        while not app.indexed.is_set():
            assert time.monotonic() < deadline
            await pilot.pause(0.02)
        await pilot.pause()
        app.frames.go_to_row(request)
        await pilot.pause()
        assert "gateway: ok" in str(app.main.detail.query_one("#detail-title").render())
        await pilot.press("p")
        await pilot.pause()
        assert app.frames.cursor_row == across
        await pilot.press("p")
        await pilot.pause()
        assert app.frames.cursor_row == request


# ------------------------------------------------------------------ tshark, end to end


@pytest.mark.peer
@pytest.mark.slow
@pytest.mark.skipif(
    not (shutil.which("dumpcap") and shutil.which("tshark")), reason="needs dumpcap and tshark"
)
def test_replay_lists_what_tshark_dissects(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`modscope replay eth.pcap --format jsonl` on pymodbus traffic captured by dumpcap:
    every Modbus TCP frame, with tshark's unit and function, in tshark's order."""
    pytest.importorskip("pymodbus")
    from tests.sources.test_sources_ethernet import _exchange, _TcpPeer

    path = tmp_path / "eth.pcapng"
    with _TcpPeer(path) as peer:
        sent = _exchange([peer.client(), peer.client()])
    rows, _ = jsonl(["replay", str(path)], capsys)
    ours = [(r["unit"], r["function"]) for r in rows if r["mode"] == "tcp" and r["kind"] != "noise"]
    fields = ["-T", "fields", "-e", "mbtcp.unit_id", "-e", "modbus.func_code"]
    result = subprocess.run(
        ["tshark", "-r", str(path), "-d", f"tcp.port=={peer.port},mbtcp", "-Y", "mbtcp", *fields],
        capture_output=True,
        text=True,
        check=True,
    )
    theirs = [tuple(int(x) for x in line.split("\t")) for line in result.stdout.splitlines()]
    assert ours == theirs
    assert len(ours) == 2 * sent
    assert {r["peer"].split(":")[0] for r in rows if r["kind"] != "event"} == {"127.0.0.1"}


@pytest.mark.peer
@pytest.mark.skipif(not shutil.which("tshark"), reason="needs tshark")
def test_wireshark_export_hands_mbap_frames_to_mbtcp(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The export hands Modbus TCP frames to Wireshark's `mbtcp`: units and functions as
    captured, each answer under its request's transaction id (the export numbers
    transactions by row, as for serial frames; the captured header is in the comment)."""
    out = tmp_path / "out.pcapng"
    code, _, err = run(["export", str(eth_capture(tmp_path)), "-o", str(out)], capsys)
    assert code == 0, err
    fields = ["-T", "fields", "-e", "mbtcp.trans_id", "-e", "mbtcp.unit_id"]
    result = subprocess.run(
        ["tshark", "-r", str(out), "-Y", "mbtcp", *fields, "-e", "modbus.func_code"],
        capture_output=True,
        text=True,
        check=True,
    )
    rows = [line.split("\t") for line in result.stdout.splitlines()]
    assert [r[1:] for r in rows] == [["1", "3"], ["7", "4"], ["1", "3"], ["7", "4"]]
    ids = [r[0] for r in rows]
    assert len(set(ids)) == 2 and ids[0] != ids[1]


def test_export_and_diff_take_the_network_options(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    conv = Conversation(server_port=4001)
    request, answer = with_crc(bytes.fromhex("110300000001")), with_crc(bytes.fromhex("1103020007"))
    packets = [*conv.handshake(), conv.client(request), conv.server(answer)]
    path = tmp_path / "nport.pcap"
    path.write_bytes(pcap(1, [(T0 + k * 0.01, p) for k, p in enumerate(packets)]))
    out = tmp_path / "frames.jsonl"
    code, _, err = run(
        ["export", str(path), "-o", str(out), "--carrier", "rtu-over-tcp", "--port", "4001"],
        capsys,
    )
    assert code == 0, err
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["raw"] for r in rows if r["kind"] != "event"] == [request.hex(), answer.hex()]
    code, _, err = run(["diff", str(path), str(path), "--carrier", "rtu-over-tcp"], capsys)
    assert code == 0, err


def test_an_answer_garbled_on_the_serial_line_is_a_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The device answers, its CRC garbled on the RS-485 side; the gateway answers 0x0B.
    The gateway did right: the verdict blames the serial line, not the gateway."""
    conv = Conversation()
    packets = [(1000.0 + k * 0.001, p) for k, p in enumerate(conv.handshake())]
    serial: list[tuple[float, bytes]] = []
    for k in range(4):
        t = 1001.0 + k
        request = gw.read_request(10 + k)
        packets.append((t, conv.client(gw.mbap_frame(k + 1, request))))
        serial_end = t + gw.DELAY_IN + gw.RTU_TIME
        serial.append((serial_end, with_crc(request)))
        answer = with_crc(gw.read_answer(20 + k))
        garbled = k == 2
        if garbled:
            answer = answer[:-2] + answer[-1:] + answer[-2:-1]
        answer_end = serial_end + 0.02 + gw.RTU_TIME
        serial.append((answer_end, answer))
        reply = gw.EXC_0B if garbled else gw.read_answer(20 + k)
        packets.append((answer_end + gw.DELAY_OUT, conv.server(gw.mbap_frame(k + 1, reply))))
    tcp_path, serial_path = tmp_path / "tcp.pcap", tmp_path / "serial.pcap"
    tcp_path.write_bytes(pcap(1, packets))
    serial_path.write_bytes(pcap(147, serial))
    given = ["--offset", "serial.pcap=0"]
    rows, _ = jsonl(["replay", str(tcp_path), str(serial_path), *LINE, *given], capsys)
    requests = [r for r in rows if r["mode"] == "tcp" and r["kind"] == "request"]
    assert [r["gateway"]["verdict"] for r in requests] == ["ok", "ok", "line-error", "ok"]
    assert "garbled on the serial line" in requests[2]["gateway"]["text"]
    _, lines, _ = run(["replay", str(tcp_path), str(serial_path), *LINE, *given, "--stats"], capsys)
    verdicts = {
        x.split()[0]: x.split()[1] for x in lines if x.startswith("  ") and len(x.split()) > 1
    }
    assert verdicts.get("line-error") == "1" and "gateway-fault" not in verdicts
