"""Fuzz: each text log reader on its own (evcc, ModbusTools, CAS, ESPHome, libmodbus,
pymodbus, monitor, mbpoll, tio, sscom, the generic TX/RX and arrow logs, the serial port
monitor and text2pcap dumps) and the Saleae CSV exports, with damage a text file meets
line by line: a stray CR, a field past 131,072 characters (the csv module's limit),
broken timestamps, bytes that are not UTF-8, NUL, lines repeated, dropped, swapped or
cut, CRLF line ends.

Same invariants as test_fuzz_sources: only CaptureError escapes and names the file, no
hang, every byte read lands in one row, every warning names the file.
"""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sniffer.sources import ReadOptions
from tests.fuzz.harness import CAPTURES, budget
from tests.fuzz.test_fuzz_sources import read_and_frame

pytestmark = [pytest.mark.fuzz, pytest.mark.slow]

LOGS = CAPTURES / "logs"


def _family(name: str) -> str:
    return name.split("_", 1)[0].split(".", 1)[0]


FAMILIES: dict[str, list[bytes]] = {}
for _path in sorted(LOGS.iterdir()):
    FAMILIES.setdefault(_family(_path.name), []).append(_path.read_bytes())

HUGE = 131_073  # one past the csv module's default field size limit


@st.composite
def damaged_lines(draw: st.DrawFn, seeds: list[bytes]) -> bytes:
    """A seed log with lines damaged (module doc)."""
    lines = draw(st.sampled_from(seeds)).split(b"\n")
    for _ in range(draw(st.integers(1, 4))):
        at = draw(st.integers(0, len(lines) - 1))
        line = lines[at]
        op = draw(
            st.sampled_from(
                ["cr", "huge", "stamp", "utf8", "nul", "repeat", "drop", "swap", "cut", "crlf"]
            )
        )
        if op == "cr":  # a stray CR inside the line, or alone on one
            pos = draw(st.integers(0, len(line)))
            lines[at] = line[:pos] + b"\r" + line[pos:]
        elif op == "huge":  # one field grown past the csv limit (or a long line)
            pos = draw(st.integers(0, len(line)))
            filler = draw(st.sampled_from([b"A", b"0", b"01 ", b'"', b","]))
            lines[at] = line[:pos] + filler * (HUGE // len(filler) + 1) + line[pos:]
        elif op == "stamp":  # a timestamp's digits replaced
            digits = [i for i, b in enumerate(line) if 0x30 <= b <= 0x39]
            if digits:
                i = draw(st.sampled_from(digits))
                junk = draw(st.sampled_from([b"9", b"x", b"99999999999999999999", b"-", b":", b""]))
                lines[at] = line[:i] + junk + line[i + 1 :]
        elif op == "utf8":
            pos = draw(st.integers(0, len(line)))
            bad = draw(st.sampled_from([b"\xff", b"\xc3", b"\xed\xa0\x80", b"\xb5\xc4"]))
            lines[at] = line[:pos] + bad + line[pos:]
        elif op == "nul":
            pos = draw(st.integers(0, len(line)))
            lines[at] = line[:pos] + b"\0" * draw(st.integers(1, 3)) + line[pos:]
        elif op == "repeat":
            lines.insert(at, line)
        elif op == "drop" and len(lines) > 1:
            del lines[at]
        elif op == "swap" and at + 1 < len(lines):
            lines[at], lines[at + 1] = lines[at + 1], line
        elif op == "cut":
            lines[at] = line[: draw(st.integers(0, len(line)))]
        elif op == "crlf":
            lines = [x + b"\r" for x in lines]
    return b"\n".join(lines)


OPTIONS = st.sampled_from([ReadOptions(), ReadOptions(baud=9600, parity="N", mode="rtu")])


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_each_log_reader_survives_damaged_lines(
    tmp_path_factory: pytest.TempPathFactory, family: str
) -> None:
    folder = tmp_path_factory.mktemp(family)
    suffix = ".csv" if family == "saleae" else ".log"

    @budget(30 if family != "saleae" else 80)
    @given(damaged_lines(FAMILIES[family]), OPTIONS)
    def run(data: bytes, options: ReadOptions) -> None:
        path = folder / f"capture{suffix}"
        path.write_bytes(data)
        read_and_frame(path, options)

    run()
