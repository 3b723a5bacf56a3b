"""Text readers stream: memory bounded whatever the file's size, output unchanged.

Big inputs are made here by repeating the fixture logs' lines with increasing stamps
(`esphome_log`, `saleae_csv`, `cas_log`, ...); `python -m tests.sources.test_stream_readers
KIND SIZE_MB OUT` writes one for measuring by hand (docs/untrusted-input.md).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from unittest import mock

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.cli import main
from sniffer.sources import hexdump, open_capture
from sniffer.sources.logs import base as logs_base
from sniffer.sources.logs.base import split_lines

CAPTURES = Path(__file__).resolve().parents[1] / "captures"

_ESPHOME_BLOCK = (
    "[{t}][D][uart_debug:158]: >>> 01:03:00:00:00:02:C4:0B\n"
    "[{t}][D][uart_debug:158]: <<< 01:03:04:00:0A:00:0D:1B:F4\n"
    "[{t}][D][modbus_controller:040]: Modbus command to device=1 register=0x00 "
    "no response received - removed from send queue\n"
    "[{t}][D][uart_debug:158]: >>> 11:10:00:01:00:02:04:00:0A:01:02:C6:F0\n"
    "[{t}][D][uart_debug:158]: <<< 11:10:00:01:00:02:12:98\n"
    "[{t}][D][sensor:094]: 'Voltage': Sending state 230.10000 V with 1 decimals of accuracy\n"
)


def _clock(seconds: float) -> str:
    whole = int(seconds) % 86_400
    millis = round((seconds - int(seconds)) * 1000) % 1000
    return f"{whole // 3600:02d}:{whole // 60 % 60:02d}:{whole % 60:02d}.{millis:03d}"


def esphome_log(path: Path, size: int) -> Path:
    """An ESPHome uart_debug log of about `size` bytes, a block of lines every 250 ms."""
    with path.open("w", encoding="utf-8", newline="\n") as out:
        written, k = 0, 0
        while written < size:
            block = _ESPHOME_BLOCK.format(t=_clock(45_296.0 + 0.25 * k))
            written += out.write(block)
            k += 1
    return path


def saleae_csv(path: Path, size: int) -> Path:
    """A Saleae Logic 2 data table export of about `size` bytes: two analysers, a request
    and its answer every 50 ms."""
    request = bytes.fromhex("010300000002c40b")
    answer = bytes.fromhex("010304000a000d1bf4")
    char = 11 / 19_200
    with path.open("w", encoding="utf-8", newline="\n") as out:
        written = out.write("name,type,start_time,duration,data,error\n")
        k = 0
        while written < size:
            t = 0.1 + 0.05 * k
            rows = []
            for name, frame, start in (("Master", request, t), ("Slave", answer, t + 0.02)):
                for i, byte in enumerate(frame):
                    rows.append(
                        f'"{name}","data",{start + i * char:.9f},{char:.9f},0x{byte:02X},\n'
                    )
            written += out.write("".join(rows))
            k += 1
    return path


def cas_log(path: Path, size: int) -> Path:
    """A CAS Modbus Scanner log of about `size` bytes, newest line first (one poll and its
    response every second)."""
    lines = []
    total, k = 0, 0
    while total < size:
        stamp = f"[{_clock(36_000.0 + k)[:8]}]"
        pair = (
            f"{stamp} => Poll: 01 03 00 00 00 02 C4 0B\n"
            f"{stamp} <= Response: 01 03 04 00 0A 00 0D 1B F4\n"
        )
        lines.append(pair)
        total += len(pair)
        k += 1
    with path.open("w", encoding="utf-8", newline="\n") as out:
        for pair in reversed(lines):
            first, second = pair.splitlines(keepends=True)
            out.write(second + first)
    return path


def socat_log(path: Path, size: int) -> Path:
    """A `socat -x -v` log of about `size` bytes: a request and its answer every 50 ms."""
    with path.open("w", encoding="latin-1", newline="\n") as out:
        written, k = 0, 0
        while written < size:
            t = 1_714_564_800.0 + 0.05 * k
            for mark, frame in (
                (">", "01 03 00 00 00 02 c4 0b"),
                ("<", "01 03 04 00 0a 00 0d 1b f4"),
            ):
                stamp = time.strftime("%Y/%m/%d %H:%M:%S", time.gmtime(t))
                length = len(frame.split())
                written += out.write(
                    f"{mark} {stamp}.{int(t * 1e6) % 1_000_000:06d}  length={length} "
                    f"from=0 to={length - 1}\n {frame}\n--\n"
                )
                t += 0.02
            k += 1
    return path


def hexdump_text(path: Path, size: int) -> Path:
    """A text2pcap dump of about `size` bytes: direction and time before each packet."""
    with path.open("w", encoding="latin-1", newline="\n") as out:
        written, k = 0, 0
        while written < size:
            t = 1_714_564_800.0 + 0.05 * k
            for mark, frame in (
                ("O", "01 03 00 00 00 02 c4 0b"),
                ("I", "01 03 04 00 0a 00 0d 1b f4"),
            ):
                written += out.write(f"{mark} {t:.6f}\n000000 {frame}\n\n")
                t += 0.02
            k += 1
    return path


MAKERS = {
    "esphome": esphome_log,
    "saleae": saleae_csv,
    "cas": cas_log,
    "socat": socat_log,
    "hexdump": hexdump_text,
}

# ---------------------------------------------------------------- memory

# Each reader reads a generated file in a child process whose address space is capped.
# Calibrated on the 2-core EPYC (2026-12-05): Python with sniffer.sources imported peaks
# at 25 MB of address space; a streaming reader stays under 40 MB whatever the file's
# size. The readers that held the file (its bytes, its text, its lines, a record per
# line) needed about 8 times the file: 180 MB for a 20 MB ESPHome log, so 8 MB files
# under a 56 MB cap tell the two apart (a holding reader would need about 90 MB).
SIZE = 8_000_000
CAP = 56 << 20

_CHILD = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, ({cap}, {cap}))
from sniffer.sources import open_capture
capture = open_capture(sys.argv[1])
chunks = data = 0
for chunk in capture.chunks():
    chunks += 1
    data += len(chunk.data)
print(capture.info.format, chunks, data, len(capture.warnings))
"""


def _read_capped(path: Path) -> list[str]:
    done = subprocess.run(
        [sys.executable, "-c", _CHILD.format(cap=CAP), str(path)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.split()


@pytest.mark.parametrize("kind", sorted(MAKERS))
def test_a_big_text_capture_is_read_in_bounded_memory(kind: str, tmp_path: Path) -> None:
    path = MAKERS[kind](tmp_path / f"big.{kind}", SIZE)
    fmt, chunks, data, warnings = _read_capped(path)
    assert fmt == kind
    assert int(chunks) > 50_000 and int(data) > 50_000
    assert warnings == "0"


# ---------------------------------------------------------------- the same output

# `replay --format jsonl` of every capture in tests/captures/logs and hexdump (status,
# stdout, stderr; the folder's path as CAPTURES, times in UTC), as the readers that held
# the whole file gave it (main at dd8d6e6): the streaming readers give the same bytes.
# A digest that changes on purpose: print the new ones with `python -m
# tests.sources.test_stream_readers digests` and say why in the commit.
DIGESTS = {
    "hexdump/od_modbus.txt": "23d16f99293e5dff",
    "hexdump/socat_modbus.log": "9a81af31edf16f1a",
    "hexdump/text2pcap_modbus.txt": "e4d39cfb30b05deb",
    "logs/arrows_notime.log": "7e9ed3eadd00da0d",
    "logs/cas_newest_first.log": "1b670971796ebaf7",
    "logs/cas_one_second.log": "c76074a8b7ba654d",
    "logs/esphome_decimal.log": "1da7ab021624c0ef",
    "logs/esphome_hex_ms.log": "f48fde614cf6de61",
    "logs/esphome_hex_seconds.log": "6acbf9ba9bf7234d",
    "logs/esphome_rx_only.log": "7e9ed3eadd00da0d",
    "logs/esphome_string.log": "1f750225ea2c62f6",
    "logs/evcc_ascii.log": "da69531d02c69767",
    "logs/evcc_rtu.log": "0c99c416d778b741",
    "logs/evcc_tcp.log": "7f558db224b4c080",
    "logs/generic_txrx.log": "1f16f58a01553843",
    "logs/libmodbus_client.log": "9dd54b4dfbbb6526",
    "logs/libmodbus_server.log": "7e9ed3eadd00da0d",
    "logs/libmodbus_tcp_server.log": "d3b4fefd042c70f6",
    "logs/mbpoll_tcp.log": "38188dba95b7fa25",
    "logs/modbustools_ascii_notime.log": "430bd7e97b32b718",
    "logs/modbustools_client.log": "051c55dffd068dfe",
    "logs/modbustools_server_tcp.log": "8163b1e92cad4785",
    "logs/monitor_seconds.log": "5f984e198ae94aa2",
    "logs/pymodbus_2x_ha.log": "858a42a7e934cfb8",
    "logs/pymodbus_3x.log": "20b2f74bef3a0a1f",
    "logs/pymodbus_notime.log": "7e9ed3eadd00da0d",
    "logs/pymodbus_sync_37.log": "bb29446436c50361",
    "logs/pymodbus_sync_38.log": "dae31bc1304e4c36",
    "logs/pymodbus_tcp.log": "52c17fec1d9ab0af",
    "logs/rvs_dn_example2_text2pcap.txt": "aca7cf7258c4d828",
    "logs/saleae_logic1.csv": "8e2af837cbadda8c",
    "logs/saleae_logic1_ascii.csv": "f8c9795b6fd46335",
    "logs/saleae_logic1_ascii_hex.csv": "3cdf574eee21efb2",
    "logs/saleae_logic2_table.csv": "8f5da230f44990bd",
    "logs/serial_port_monitor.txt": "a12027873825e877",
    "logs/sscom_gbk.log": "be3e8d15ac48245b",
    "logs/tio_hex.log": "4c9433ca73506a60",
    "logs/tio_iso.log": "7505e25d92572d75",
}


def _listing(path: Path) -> str:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(["replay", str(path), "--format", "jsonl", "--jobs", "1", "--no-index"])
    text = f"{status}\n{out.getvalue()}\n{err.getvalue()}"
    return text.replace(str(CAPTURES / path.parent.name), f"CAPTURES/{path.parent.name}")


def _digest(path: Path) -> str:
    return hashlib.sha256(_listing(path).encode()).hexdigest()[:16]


def _captures() -> list[Path]:
    return sorted([*CAPTURES.glob("logs/*"), *CAPTURES.glob("hexdump/*")])


@pytest.fixture
def utc(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    monkeypatch.setenv("TZ", "UTC")
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()


@pytest.mark.usefixtures("utc")
def test_every_text_capture_lists_the_same_bytes_as_before() -> None:
    found = {f"{path.parent.name}/{path.name}": _digest(path) for path in _captures()}
    assert found == DIGESTS


# ---------------------------------------------------------------- lines as before

_TEXT_BYTES = st.lists(
    st.sampled_from(
        [
            b"a",
            b"01 03",
            b"\n",
            b"\r",
            b"\r\n",
            b"\x0b",
            b"\x85",
            b"\xe9",
            b"\xc3\xa9",
            b"\0",
            b"\x81\x40",
            b" ",
        ]
    ),
    max_size=30,
).map(b"".join)


@settings(max_examples=300, deadline=None)
@given(raw=_TEXT_BYTES, block=st.integers(1, 7))
def test_text_lines_are_the_whole_texts_lines(raw: bytes, block: int) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "f.log"
        path.write_bytes(raw)
        with mock.patch.object(logs_base, "BLOCK", block):
            text = logs_base.TextFile.survey(path)
            whole = logs_base.decode_text(raw)
            expected = split_lines(whole if whole is not None else raw.decode("latin-1"))
            assert [line for _, line in text.lines()] == expected
            assert [n for n, _ in text.lines()] == list(range(1, len(expected) + 1))
            assert text.count() == len(expected)
            backwards = list(text.lines_reversed(len(expected)))
            assert backwards == list(reversed(list(text.lines())))


@settings(max_examples=300, deadline=None)
@given(raw=_TEXT_BYTES, block=st.integers(1, 7))
def test_hexdump_lines_are_the_whole_texts_lines(raw: bytes, block: int) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "f.txt"
        path.write_bytes(raw)
        with mock.patch.object(hexdump, "_BLOCK", block):
            lines = raw.decode("latin-1").splitlines(keepends=True)
            assert list(hexdump._lines(path)) == [(len(line), line) for line in lines]
            pieces = list(hexdump._pieces(path))
            assert "".join(pieces) == raw.decode("latin-1")
            assert all(piece.endswith("\n") for piece in pieces[:-1])


if __name__ == "__main__":
    if sys.argv[1:] == ["digests"]:
        os.environ["TZ"] = "UTC"
        time.tzset()
        for capture in _captures():
            print(f'    "{capture.parent.name}/{capture.name}": "{_digest(capture)}",')
    else:
        MAKERS[sys.argv[1]](Path(sys.argv[3]), int(float(sys.argv[2]) * 1e6))


# ---------------------------------------------------------------- damaged lines

_FIELD = "x" * 200_000  # over the csv module's field limit (131,072 characters)


@pytest.mark.parametrize(
    ("text", "line"),
    [
        # Logic 2 table: a field over the limit, a stray CR inside a row
        (f'name,type,start_time,duration,data,error\n"M","data",0.1,0.0005,"{_FIELD}",\n', 2),
        ('name,type,start_time,duration,data,error\n"M","data",0.1,0.0005,0x0\r1,\n', 2),
        # early Logic 2, the same
        (f'Time [s],Analyzer Name,Decoded Protocol Result\n0.1,Async Serial,"{_FIELD}"\n', 2),
        ("Time [s],Analyzer Name,Decoded Protocol Result\n0.1,Async\rSerial,0x01\n", 2),
        # Logic 1: the value column takes whatever it holds
        (f"Time [s],Value,Parity Error,Framing Error\n0.1,{_FIELD},,\n", 2),
    ],
)
def test_a_damaged_saleae_row_is_a_warning_naming_its_line(
    text: str, line: int, tmp_path: Path
) -> None:
    path = tmp_path / "export.csv"
    path.write_text(text)
    with path.open("a") as out:  # a good row after the bad one: read, not lost
        out.write('"M","data",0.3,0.0005,0x03,\n' if text.startswith("name") else "0.3,x,0x03\n")
    capture = open_capture(path)
    chunks = list(capture.chunks())
    assert capture.info.format == "saleae"
    assert any(w.startswith(f"{path} line {line}: ") for w in capture.warnings), capture.warnings
    assert all(len(w) < 300 for w in capture.warnings)
    assert chunks  # the rows around it are read


def test_a_log_line_of_100_000_bytes_and_a_stray_cr_are_read(tmp_path: Path) -> None:
    path = tmp_path / "esp.log"
    big = ":".join(["0A"] * 100_000)
    path.write_text(
        "[12:00:00.000][D][uart_debug:158]: >>> 01:03:00:00:00:02:C4:0B\n"
        f"[12:00:00.100][D][uart_debug:158]: <<< {big}\n"
        "[12:00:00.200][D][uart_debug:158]: >>> 01:03\r:00:00:00:02:C4:0B\n"
        "[12:00:00.300][D][uart_debug:158]: >>> 01:03:00:00:00:02:C4:0B\n"
    )
    capture = open_capture(path)
    data = [c.data for c in capture.chunks() if c.data]
    # the CR stays inside its line (no line cut in two, no number shifted)
    assert data[1] == b"\x0a" * 100_000 and len(data) == 4
    assert data[2] == data[3] == data[0] and capture.warnings == []


def _read_all(path: Path) -> tuple[object, list[object], list[str]]:
    capture = open_capture(path)
    return capture.info, list(capture.chunks()), capture.warnings


@pytest.mark.parametrize("name", [p.name for p in sorted(CAPTURES.glob("logs/*"))])
def test_without_room_for_the_spill_the_file_is_parsed_again_alike(
    name: str, tmp_path: Path
) -> None:
    path = CAPTURES / "logs" / name
    kept = _read_all(path)

    def no_room(*args: object, **kwargs: object) -> object:
        raise OSError(28, "No space left on device")

    with mock.patch("tempfile.TemporaryFile", no_room):
        again = _read_all(path)
    assert again == kept
    # a spill past its size limit is dropped too
    with (
        mock.patch.object(logs_base, "SPILL_LIMIT", 10),
        mock.patch.object(logs_base, "SPILL_BATCH", 1),
    ):
        assert _read_all(path) == kept
