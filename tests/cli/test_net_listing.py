"""Tests what `modscope replay` says about network captures: listings in time order with
connection events at their times, a `--stats` header that describes the capture (not
serial settings), exception codes in hex, latencies never shown as 0, RTU over TCP
measured from packet to packet whatever `--baud` says, and the per-unit and per-server
tables agreeing."""

from __future__ import annotations

from pathlib import Path

import pytest

from dissectors.checks import with_crc
from sniffer.cli import main
from tests.support.gateway import mbap_frame
from tests.support.netbuild import TCP_ACK, TCP_FIN, TCP_RST, TCP_SYN, Conversation, pcap

T0 = 1_750_000_000.0
MB_REQ = bytes.fromhex("0103000a0002")
MB_ANS = bytes.fromhex("01030400010002")
RTU_REQ = with_crc(bytes.fromhex("1103 006B 0003"))
RTU_ANS = with_crc(bytes.fromhex("1103 06 022B 0000 0064"))


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str], str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out.splitlines(), err


def write(tmp_path: Path, packets: list[tuple[float, bytes]], name: str = "c.pcap") -> str:
    path = tmp_path / name
    path.write_bytes(pcap(1, sorted(packets, key=lambda p: p[0])))
    return str(path)


def modbus_tcp(tmp_path: Path) -> str:
    """A polls unit 1; B opens at 0 and stays silent until 5 s, then polls unit 7 and gets
    exception 0B; a port probe (SYN, RST) at 1.1 s; A closes (FIN), B resets (RST)."""
    a = Conversation()
    b = Conversation(client_port=50300, server_ip="192.168.1.30", server_port=503)
    probe = Conversation(client_port=50400, server_ip="192.168.1.40")
    packets = [(T0, b.client(b"", TCP_SYN)), (T0 + 0.001, b.server(b"", TCP_SYN | TCP_ACK))]
    packets += [
        (T0 + 1.1, probe.client(b"", TCP_SYN)),
        (T0 + 1.101, probe.server(b"", TCP_RST | TCP_ACK)),
    ]
    for k in range(12):
        t = T0 + 0.5 + k * 0.5
        packets += [
            (t, a.client(mbap_frame(k + 1, MB_REQ))),
            (t + 0.002, a.server(mbap_frame(k + 1, MB_ANS))),
        ]
        if k >= 9:
            packets += [
                (t + 0.1, b.client(mbap_frame(k, bytes.fromhex("070400000001")))),
                (t + 0.103, b.server(mbap_frame(k, bytes.fromhex("07840B")))),
            ]
    end = T0 + 7
    packets += [
        (end, a.client(b"", TCP_FIN | TCP_ACK)),
        (end + 0.001, a.server(b"", TCP_FIN | TCP_ACK)),
        (end + 0.002, b.client(b"", TCP_RST)),
    ]
    return write(tmp_path, packets)


def rtu_over_tcp(tmp_path: Path, delay: float = 0.0005, bad: bool = False) -> str:
    """A native RTU-over-TCP device on port 4001 answering `delay` after each poll; with
    `bad`, the first answer has its CRC bytes swapped."""
    conv = Conversation(server_port=4001)
    packets = [(T0 + k * 0.001, p) for k, p in enumerate(conv.handshake())]
    for k in range(5):
        t = T0 + 0.1 + k * 0.2
        answer = RTU_ANS[:-2] + RTU_ANS[:-3:-1] if bad and k == 0 else RTU_ANS
        packets += [(t, conv.client(RTU_REQ)), (t + delay, conv.server(answer))]
    return write(tmp_path, packets, "nport.pcap")


def times(lines: list[str]) -> list[float]:
    return [float(line.split()[0]) for line in lines]


def test_the_listing_is_in_time_order_with_events_at_their_times(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, lines, _ = run(["replay", modbus_tcp(tmp_path), "--format", "text"], capsys)
    # every time in it is a whole millisecond: a note says the clock may tick no finer
    note = lines.pop(0)
    assert note.startswith("# timing:") and "1 ms" in note
    shown = times(lines)
    assert shown == sorted(shown) and shown[0] == 0.0
    assert "opened (SYN)" in lines[0] and "192.168.1.10:50300" in lines[0]
    probe = [line for line in lines if "192.168.1.40:502" in line or ":50400" in line]
    assert times(probe) == [1.1, 1.101]
    assert [line.split("connection: ")[1] for line in lines[-3:]] == [
        "closed by the sender (FIN)",
        "closed by the sender (FIN)",
        "reset (RST)",
    ]
    assert times(lines[-3:]) == [7.0, 7.001, 7.002]


def test_stats_header_describes_the_network_capture(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, lines, _ = run(["replay", modbus_tcp(tmp_path), "--stats"], capsys)
    assert lines[0].endswith(
        "(network: 3 TCP connections, modbus-tcp, servers 192.168.1.30:503, "
        "192.168.1.20:502, 192.168.1.40:502)"
    )
    assert "8E1" not in lines[0] and "mode rtu" not in lines[0]
    _, lines, _ = run(["replay", rtu_over_tcp(tmp_path), "--stats"], capsys)
    assert lines[0].endswith("(network: 1 TCP connection, rtu-over-tcp, server 192.168.1.20:4001)")


def test_exception_codes_are_hex_in_stats_as_in_the_listing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = modbus_tcp(tmp_path)
    _, lines, _ = run(["replay", path, "--stats"], capsys)
    assert any(line.strip() == "exceptions by code: 0B x3" for line in lines)
    _, listing, _ = run(["replay", path, "--format", "text"], capsys)
    assert any("exception 0B" in line for line in listing)


@pytest.mark.parametrize("baud", ["1200", "9600", "115200"])
def test_rtu_over_tcp_latency_is_packet_to_packet_at_any_baud(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], baud: str
) -> None:
    path = rtu_over_tcp(tmp_path, delay=0.0005)
    _, lines, err = run(["replay", path, "--format", "text", "--baud", baud], capsys)
    frames = [line for line in lines if " u17 " in line]
    assert times(frames) == sorted(times(frames))
    assert [("M>S" in line, "ok" in line.split()) for line in frames] == [
        (True, True),
        (False, True),
    ] * 5
    assert all("0.5ms" in line for line in frames if "S>M" in line)
    assert "orphan" not in "\n".join(lines) and "timeout" not in "\n".join(lines)
    assert "--baud not used for TCP or UDP payloads" in err
    _, stats, _ = run(["replay", path, "--stats", "--baud", baud], capsys)
    unit = next(line for line in stats if line.split()[:1] == ["17"]).split()
    # unit, req, resp, exc, t/o, chk, lat min, median, p95, max, period
    assert unit[1:10] == ["5", "5", "0", "0", "0", "0.5", "0.5", "0.5", "0.5"]
    server = next(line for line in stats if line.startswith("192.168.1.20:4001")).split()
    # server, unit, req, resp, exc, t/o, chk, median, p95, max: as the per-unit table
    assert server[1:10] == ["17", "5", "5", "0", "0", "0", "0.5", "0.5", "0.5"]


def test_a_swapped_crc_in_a_payload_is_diagnosed_not_noise(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, lines, _ = run(["replay", rtu_over_tcp(tmp_path, bad=True), "--format", "text"], capsys)
    text = "\n".join(lines)
    assert "noise" not in text
    bad = next(line for line in lines if "BAD" in line)
    assert "S>M" in bad and "bad answer" in bad and "expected" in bad
    assert float(bad.split()[0]) == pytest.approx(0.1005, abs=1e-6)
    _, stats, _ = run(["replay", rtu_over_tcp(tmp_path, bad=True), "--stats"], capsys)
    unit = next(line for line in stats if line.split()[:1] == ["17"]).split()
    server = next(line for line in stats if line.startswith("192.168.1.20:4001")).split()
    assert unit[1:6] == ["5", "4", "0", "0", "1"] and server[2:7] == unit[1:6]


def test_a_latency_below_the_printed_precision_is_a_bound_not_zero(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A server on the capturing host answers in 30 us: shown to the microsecond the
    capture's stamps hold (0.030 ms), never as 0.0."""
    _, stats, _ = run(["replay", rtu_over_tcp(tmp_path, delay=0.00003), "--stats"], capsys)
    unit = next(line for line in stats if line.split()[:1] == ["17"]).split()
    server = next(line for line in stats if line.startswith("192.168.1.20:4001")).split()
    assert unit[6:10] == ["0.030"] * 4
    assert server[7:10] == ["0.030"] * 3
    assert all(float(x) > 0 for x in unit[6:10] + server[7:10])


def test_a_gap_in_polling_is_placed_as_the_listing_places_rows(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Seconds from the first row, as the listing shows times, not epoch seconds."""
    conv = Conversation()
    packets = []
    t = T0
    for k in range(40):
        packets += [
            (t, conv.client(mbap_frame(k + 1, MB_REQ))),
            (t + 0.002, conv.server(mbap_frame(k + 1, MB_ANS))),
        ]
        t += 10.0 if k == 30 else 0.5
    path = write(tmp_path, packets)
    _, stats, _ = run(["replay", path, "--stats"], capsys)
    assert "      gap at 15.000s: 10.0s without polls" in stats
    _, listing, _ = run(["replay", path, "--format", "text"], capsys)
    assert any(line.split()[0] == "15.000000" for line in listing)
    _, listing, _ = run(
        ["replay", rtu_over_tcp(tmp_path, delay=0.00003), "--format", "text"], capsys
    )
    answers = [line for line in listing if "S>M" in line]
    assert len(answers) == 5 and all(" 0.030ms " in line for line in answers)
