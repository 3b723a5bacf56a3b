"""A number of thousands of digits where a reader expects a time, a baud rate, a port or a
byte never stops the reading: Python's int() refuses a decimal of more than 4,300 digits
(a ValueError), so each reader bounds what it converts. Found by the log fuzz (a tio line
whose fraction of a second had 131,077 digits); each case below is a real capture with one
number made huge, and is read as the fuzz reads any damaged file."""

from __future__ import annotations

from pathlib import Path

import pytest

from sniffer.sources import ReadOptions, open_capture
from sniffer.sources.logs.base import FRACTION_DIGITS, fraction_digits, parse_stamp
from tests.fuzz.test_fuzz_sources import read_and_frame

LOGS = Path(__file__).parent.parent / "captures" / "logs"
HEXDUMP = Path(__file__).parent.parent / "captures" / "hexdump"
HUGE = "9" * 5000

CASES = {
    # file, the text replaced, what replaces it
    "tio fraction": (LOGS / "tio_hex.log", "[12:00:00.002]", f"[12:00:00.{HUGE}]"),
    "socat fraction": (HEXDUMP / "socat_modbus.log", "01:36:06.000130905", f"01:36:06.{HUGE}"),
    "libmodbus baud": (LOGS / "libmodbus_client.log", "at 9600 bauds", f"at {HUGE} bauds"),
    "mbpoll port": (LOGS / "mbpoll_tcp.log", "[192.168.1.20]:502", f"[192.168.1.20]:{HUGE}"),
    "pymodbus port": (LOGS / "pymodbus_tcp.log", "192.168.1.20:502.", f"192.168.1.20:{HUGE}."),
    "saleae byte": (LOGS / "saleae_logic1_ascii.csv", "'3'", f"'{HUGE}'"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_huge_number_is_read_without_an_error(case: str, tmp_path: Path) -> None:
    source, old, new = CASES[case]
    text = source.read_text(encoding="utf-8")
    assert old in text, f"{source.name} no longer holds {old!r}"
    damaged = tmp_path / source.name
    damaged.write_text(text.replace(old, new, 1), encoding="utf-8")
    read_and_frame(damaged, ReadOptions())  # no exception but a CaptureError naming the file
    # and the rest of the file is still read: the same reader, frames from the other lines
    capture = open_capture(damaged, ReadOptions())
    assert sum(len(chunk.data) for chunk in capture.chunks()) > 0


def test_a_long_fraction_of_a_second_keeps_what_a_float_can_hold() -> None:
    assert fraction_digits("123") == (0.123, 0.001)
    value, resolution = fraction_digits("5" + "0" * 100_000)
    assert value == 0.5 and resolution == 10.0**-FRACTION_DIGITS
    stamp = parse_stamp(f"[2024-05-01T12:00:00.25{'0' * 10_000}] 01 03")
    assert stamp is not None and stamp.seconds % 1 == 0.25
    assert stamp.resolution == 10.0**-FRACTION_DIGITS


def test_a_hex_dump_time_of_thousands_of_digits_is_read(tmp_path: Path) -> None:
    request = "01 03 00 00 00 02 c4 0b"
    path = tmp_path / "dump.txt"
    path.write_text(f"O {HUGE}.5\n0000  {request}\nO 1.{HUGE}\n0000  {request}\n")
    read_and_frame(path, ReadOptions())
    capture = open_capture(path, ReadOptions())
    assert b"".join(chunk.data for chunk in capture.chunks()) == bytes.fromhex(request) * 2
