"""Wrong input fails loudly in `replay` and `export` (issue 10): a capture of another link
type with no Modbus serial data, random bytes that form no frame, and a cut file each get
their exit status and one line that names the file."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from dissectors.checks import with_crc
from sniffer.cli import main
from sniffer.sources.pcapng_writer import PcapngWriter
from tests.support.netbuild import ethernet, ipv4, pcap, udp

REQUEST = with_crc(bytes.fromhex("010300000002"))
ANSWER = with_crc(bytes.fromhex("01030400640065"))


def dns_capture(path: Path) -> Path:
    """Ethernet (link type 1) carrying only DNS queries: no Modbus in any form."""
    packets = [
        (1_750_000_000.0 + k, ethernet(ipv4("10.0.0.1", "10.0.0.9", 17, udp(5353, 53, b"q" * 30))))
        for k in range(4)
    ]
    path.write_bytes(pcap(1, packets))
    return path


def whole_pcapng(path: Path) -> Path:
    with path.open("wb") as handle:
        writer = PcapngWriter(handle, application="test")
        iface = writer.add_interface(147, name="ttyUSB0")
        writer.write_packet(iface, 1_750_000_000.0, REQUEST)
        writer.write_packet(iface, 1_750_000_000.02, ANSWER)
    return path


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def commands(path: Path, tmp_path: Path) -> list[list[str]]:
    return [
        ["replay", str(path), "--format", "jsonl"],
        ["export", str(path), "-o", str(tmp_path / "out.pcapng")],
        ["export", str(path), "-o", str(tmp_path / "out.csv")],
    ]


def test_ethernet_capture_without_modbus_exits_2_naming_file_and_format(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = dns_capture(tmp_path / "office.pcap")
    for args in commands(path, tmp_path):
        code, out, err = run(args, capsys)
        assert code == 2, args
        errors = [line for line in err.splitlines() if line.startswith("modscope: error:")]
        assert len(errors) == 1, err
        assert errors[0].startswith(f"modscope: error: {path}: no Modbus serial data in it")
        assert "(read as pcap)" in errors[0]
        assert "link types 147, 250 and 252" in errors[0]
        assert out == ""


def test_random_bytes_with_no_frame_exit_2_and_say_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "noise.bin"
    path.write_bytes(random.Random(11).randbytes(2500))
    for args in commands(path, tmp_path):
        code, _, err = run(args, capsys)
        assert code == 2, args
        assert f"modscope: error: {path}: 2,500 bytes read and not one Modbus frame" in err


def test_truncated_capture_exits_1_with_its_rows(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    whole = whole_pcapng(tmp_path / "whole.pcapng")
    cut = tmp_path / "cut.pcapng"
    cut.write_bytes(whole.read_bytes()[:-5])
    code, out, err = run(["replay", str(cut), "--format", "jsonl"], capsys)
    assert code == 1
    assert "modscope: error" not in err
    assert f"modscope: warning: {cut}: truncated pcapng block" in err
    assert len(out.splitlines()) == 1  # the request before the cut
    code, _, err = run(["export", str(cut), "-o", str(tmp_path / "cut.csv")], capsys)
    assert code == 1
    assert (tmp_path / "cut.csv").read_text().count("\n") == 2  # header and the request


def test_whole_capture_exits_0(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    whole = whole_pcapng(tmp_path / "whole.pcapng")
    for args in commands(whole, tmp_path):
        code, _, err = run(args, capsys)
        assert code == 0, (args, err)
        assert "modscope: error" not in err
