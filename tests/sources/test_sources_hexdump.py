"""Tests the hex text dump readers against real socat logs and text2pcap's own reading."""

from __future__ import annotations

import os
import select
import shutil
import subprocess
import time
import tty
from pathlib import Path

import pytest

from dissectors.checks import with_crc
from sniffer.model import Direction, Labels, Stamp
from sniffer.sources import Capture, ReadOptions, open_capture
from sniffer.sources.hexdump import parse_time

CAPTURES = Path(__file__).parent.parent / "captures" / "hexdump"
SOCAT_FIXTURE = CAPTURES / "socat_modbus.log"
TEXT2PCAP_FIXTURE = CAPTURES / "text2pcap_modbus.txt"
PLAIN_FIXTURE = CAPTURES / "od_modbus.txt"

# request/response pairs sent through the socat relay (CR and LF bytes included on purpose)
EXCHANGES = [
    (with_crc(bytes.fromhex("010300000002")), with_crc(bytes.fromhex("010304000a000d"))),
    (with_crc(bytes.fromhex("11060d0a0a0d")), with_crc(bytes.fromhex("11060d0a0a0d"))),
    (
        with_crc(bytes.fromhex("0110000100020400010002")),
        with_crc(bytes.fromhex("011000010002")),
    ),
]


def _read_exactly(fd: int, count: int, timeout: float = 5.0) -> bytes:
    out = b""
    deadline = time.monotonic() + timeout
    while len(out) < count:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise TimeoutError(f"read {len(out)} of {count} bytes")
        ready, _, _ = select.select([fd], [], [], remaining)
        if ready:
            out += os.read(fd, count - len(out))
    return out


def run_socat_relay(folder: Path, exchanges: list[tuple[bytes, bytes]]) -> str:
    """Relay request/response pairs between two ptys through `socat -x -v`; its log."""
    left, right, log = folder / "left", folder / "right", folder / "socat.log"
    with log.open("wb") as log_file:
        proc = subprocess.Popen(
            [
                "socat",
                "-x",
                "-v",
                f"PTY,link={left},raw,echo=0",
                f"PTY,link={right},raw,echo=0",
            ],
            stdout=subprocess.DEVNULL,
            stderr=log_file,
        )
        try:
            deadline = time.monotonic() + 5
            while not (left.exists() and right.exists()):
                if time.monotonic() > deadline:
                    raise TimeoutError("socat did not create its ptys")
                time.sleep(0.02)
            master = os.open(left, os.O_RDWR | os.O_NOCTTY)
            slave = os.open(right, os.O_RDWR | os.O_NOCTTY)
            try:
                tty.setraw(master)
                tty.setraw(slave)
                for request, response in exchanges:
                    os.write(master, request)
                    assert _read_exactly(slave, len(request)) == request
                    time.sleep(0.02)
                    os.write(slave, response)
                    assert _read_exactly(master, len(response)) == response
                    time.sleep(0.02)
            finally:
                os.close(master)
                os.close(slave)
        finally:
            proc.terminate()
            proc.wait(timeout=5)
    return log.read_text(encoding="latin-1")


def _by_direction(capture: Capture) -> dict[Direction, bytes]:
    out: dict[Direction, bytes] = {}
    for chunk in capture.chunks():
        out[chunk.direction] = out.get(chunk.direction, b"") + chunk.data
    return out


def test_socat_fixture_made_by_real_socat() -> None:
    capture = open_capture(SOCAT_FIXTURE)
    assert capture.info.format == "socat"
    chunks = list(capture.chunks())
    assert capture.warnings == []
    requests = b"".join(c.data for c in chunks if c.direction == Direction.MASTER)
    responses = b"".join(c.data for c in chunks if c.direction == Direction.SLAVE)
    assert requests == b"".join(r for r, _ in EXCHANGES)
    assert responses == b"".join(r for _, r in EXCHANGES)
    # one stream in the order socat relayed it; `>`/`<` are labels on it
    assert {c.channel for c in chunks} == {0}
    assert capture.info.labels == Labels.HINT and capture.info.stamps == Stamp.PRINT
    times = [c.t_end for c in chunks]
    assert times == sorted(times)
    assert 0.1 < times[-1] - times[0] < 5  # socat 1.7.4's nine-digit microseconds
    assert times[0] > 1.6e9  # wall clock


@pytest.mark.peer
@pytest.mark.skipif(shutil.which("socat") is None, reason="socat not installed")
def test_socat_live_log(tmp_path: Path) -> None:
    text = run_socat_relay(tmp_path, EXCHANGES)
    path = tmp_path / "dump.txt"
    path.write_text(text, encoding="latin-1")
    capture = open_capture(path)
    assert capture.info.format == "socat"
    found = _by_direction(capture)
    assert capture.warnings == []
    assert found[Direction.MASTER] == b"".join(r for r, _ in EXCHANGES)
    assert found[Direction.SLAVE] == b"".join(r for _, r in EXCHANGES)


def test_socat_short_record_is_skipped_with_warning(tmp_path: Path) -> None:
    text = SOCAT_FIXTURE.read_text(encoding="latin-1")
    cut = text[: text.rindex("length=")]  # keep the last header's start only
    cut = cut[: cut.rindex("\n") + 1] + "> 2024/05/01 12:00:00.500000  length=8 from=0 to=7\n"
    cut += " 01 03 00 00                                      ....\n"
    path = tmp_path / "cut.log"
    path.write_text(cut, encoding="latin-1")
    capture = open_capture(path)
    chunks = list(capture.chunks())
    assert len(chunks) == len(EXCHANGES) * 2 - 1
    assert len(capture.warnings) == 1
    assert "announces 8 bytes but has 4" in capture.warnings[0]
    assert "byte offset" in capture.warnings[0]


def test_socat_six_digit_fractions(tmp_path: Path) -> None:
    path = tmp_path / "six.log"
    path.write_text(
        "> 2024/05/01 12:00:00.250000  length=2 from=0 to=1\n"
        " 01 02                                            ..\n"
        "--\n"
        "< 2024/05/01 12:00:00.750000  length=1 from=0 to=0\n"
        " 03                                               .\n"
        "--\n",
        encoding="ascii",
    )
    chunks = list(open_capture(path).chunks())
    assert [c.data for c in chunks] == [b"\x01\x02", b"\x03"]
    assert chunks[1].t_end - chunks[0].t_end == pytest.approx(0.5)
    assert [c.direction for c in chunks] == [Direction.MASTER, Direction.SLAVE]


def test_socat_ascii_column_that_looks_like_hex(tmp_path: Path) -> None:
    path = tmp_path / "hexish.log"
    path.write_text(
        "> 2024/05/01 12:00:00.250000  length=3 from=0 to=2\n"
        " 61 62 20                                         ab \n"
        "--\n",
        encoding="ascii",
    )
    assert [c.data for c in open_capture(path).chunks()] == [b"ab "]


def _text2pcap(source: Path, target: Path, *args: str) -> Capture:
    subprocess.run(
        ["text2pcap", "-q", "-l", "147", *args, str(source), str(target)],
        check=True,
        capture_output=True,
    )
    return open_capture(target)


@pytest.mark.peer
@pytest.mark.skipif(shutil.which("text2pcap") is None, reason="text2pcap not installed")
@pytest.mark.parametrize("pcap_format", ["pcapng", "pcap", "nsecpcap"])
def test_text2pcap_reads_the_same_bytes_and_times(tmp_path: Path, pcap_format: str) -> None:
    ours = open_capture(TEXT2PCAP_FIXTURE)
    assert ours.info.format == "hexdump"
    mine = list(ours.chunks())
    assert ours.warnings == []
    theirs_capture = _text2pcap(
        TEXT2PCAP_FIXTURE, tmp_path / f"out.{pcap_format}", "-D", "-t", "ISO", "-F", pcap_format
    )
    theirs = list(theirs_capture.chunks())
    assert theirs_capture.info.format == ("pcapng" if pcap_format == "pcapng" else "pcap")
    assert [c.data for c in mine] == [c.data for c in theirs]
    assert [c.t_end for c in mine] == pytest.approx([c.t_end for c in theirs], abs=1e-6)
    assert len(mine) == 5
    assert mine[0].t_end == pytest.approx(1714564800.123456, abs=1e-6)
    assert [c.direction for c in mine] == [
        Direction.MASTER,
        Direction.SLAVE,
        Direction.MASTER,
        Direction.SLAVE,
        Direction.MASTER,
    ]
    if pcap_format == "pcapng":  # text2pcap writes O as outbound: the capturing master sent it
        assert [c.direction for c in theirs][0::2] == [Direction.MASTER] * 3


@pytest.mark.peer
@pytest.mark.skipif(shutil.which("text2pcap") is None, reason="text2pcap not installed")
def test_text2pcap_plain_dump_same_bytes(tmp_path: Path) -> None:
    ours = open_capture(PLAIN_FIXTURE)
    mine = list(ours.chunks())
    theirs = list(_text2pcap(PLAIN_FIXTURE, tmp_path / "plain.pcapng").chunks())
    assert [c.data for c in mine] == [c.data for c in theirs]
    assert len(mine) == 3
    assert all(c.direction == Direction.UNKNOWN for c in mine)
    # no times in the dump: bytes follow each other one character time apart
    line = ReadOptions().line()
    assert mine[0].t_start == 0.0
    assert mine[0].t_end == pytest.approx(len(mine[0].data) * line.char_time)
    assert mine[1].t_start == mine[0].t_end


def test_hexdump_unexpected_offset_warns(tmp_path: Path) -> None:
    path = tmp_path / "bad.txt"
    path.write_text(
        "000000 01 02 03 04\n000010 05 06\n000000 07 08\n",
        encoding="ascii",
    )
    capture = open_capture(path)
    assert [c.data for c in capture.chunks()] == [b"\x01\x02\x03\x04", b"\x07\x08"]
    assert len(capture.warnings) == 1
    assert "line 2" in capture.warnings[0]
    assert "byte offset 19" in capture.warnings[0]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("2024-05-01T12:00:00Z", 1714564800.0),
        ("2024-05-01T12:00:00.25Z", 1714564800.25),
        ("2024-05-01 14:00:00.5+02:00", 1714564800.5),
        ("12:00:01.5", 43201.5),
        ("1714564800.125", 1714564800.125),
        ("hello", None),
        ("2024-13-01T12:00:00Z", None),
    ],
)
def test_parse_time(text: str, expected: float | None) -> None:
    assert parse_time(text) == (pytest.approx(expected) if expected is not None else None)
