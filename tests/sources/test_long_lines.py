"""Text readers and a line past `MAX_LINE` (issue #30.8): each reader family (the log
readers, forwards and, for CAS without its spill, backwards; lines cut at CR; Saleae
CSV; socat; text2pcap dumps) reads such a line on to its end in pieces without holding
it, skips it as it skips a line it cannot read, and says so once: the file, the line,
its length and its first characters. Everything else in the file reads as if the line
were a short unreadable one.

`python -m tests.sources.test_long_lines FAMILY SIZE_MB OUT` writes a file of that family
with one line of SIZE_MB megabytes in it, for measuring by hand (docs/untrusted-input.md).
"""

from __future__ import annotations

import sys
import tracemalloc
from pathlib import Path

import pytest

from sniffer.model import Chunk
from sniffer.sources import ReadOptions, open_capture
from sniffer.sources.logs import base as logs_base
from sniffer.sources.logs.base import MAX_LINE

CAPTURES = Path(__file__).resolve().parents[1] / "captures"

# family: (seed file, the long line's start, what it repeats, whether its lines end at CR)
FAMILIES: dict[str, tuple[Path, bytes, bytes, bool]] = {
    "esphome": (
        CAPTURES / "logs" / "esphome_hex_ms.log",
        b"[12:00:00.000][D][uart_debug:158]: >>> ",
        b"0A",
        False,
    ),
    "pymodbus": (CAPTURES / "logs" / "pymodbus_3x.log", b"DEBUG send: ", b"0x1 ", False),
    "cas": (CAPTURES / "logs" / "cas_newest_first.log", b"[10:15:00] => Poll: ", b"01 ", False),
    "monitor-cr": (CAPTURES / "logs" / "generic_txrx.log", b"12:00:00.400 TX: ", b"01 ", True),
    "saleae": (CAPTURES / "logs" / "saleae_logic2_table.csv", b'"Master","data",0.5,', b"0", False),
    "socat": (CAPTURES / "hexdump" / "socat_modbus.log", b" 01 03 ", b"0a ", False),
    "text2pcap": (CAPTURES / "hexdump" / "text2pcap_modbus.txt", b"000010 ", b"01 ", False),
}


def with_line(family: str, line: bytes) -> bytes:
    """The family's seed with `line` put in the middle."""
    seed, _, _, cr = FAMILIES[family]
    lines = seed.read_bytes().split(b"\n")
    middle = len(lines) // 2
    lines.insert(middle, line)
    text = b"\n".join(lines)
    return text.replace(b"\n", b"\r") if cr else text


def long_line(family: str, size: int) -> bytes:
    _, start, filler, _ = FAMILIES[family]
    return start + filler * ((size - len(start)) // len(filler) + 1)


def line_number(family: str) -> int:
    return len(FAMILIES[family][0].read_bytes().split(b"\n")) // 2 + 1


def read(path: Path) -> tuple[list[Chunk], list[str]]:
    capture = open_capture(path, ReadOptions())
    chunks = list(capture.chunks())
    return chunks, capture.warnings


def _long_warnings(warnings: list[str]) -> list[str]:
    return [w for w in warnings if "a line may hold" in w]


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_a_line_past_the_cap_is_skipped_and_told_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, family: str
) -> None:
    """A line of 4 MiB with the cap lowered to 64 KiB: one warning naming the file, the
    line, the length and the first characters; the rest of the file read as with a short
    unreadable line in its place (same chunks, same other warnings)."""
    monkeypatch.setattr(logs_base, "MAX_LINE", 1 << 16)
    line = long_line(family, 4 << 20)
    path = tmp_path / f"long-{family}.txt"
    path.write_bytes(with_line(family, line))
    short = tmp_path / f"short-{family}.txt"
    short.write_bytes(with_line(family, b"x"))
    chunks, warnings = read(path)
    expected_chunks, expected_warnings = read(short)
    told = _long_warnings(warnings)
    assert told == [
        f"{path} line {line_number(family)}: a line of {len(line):,} bytes, more than the "
        f"65,536 a line may hold; the line is skipped (it starts "
        f"{line[: logs_base.LONG_HEAD].decode()!r})"
    ]
    assert chunks == expected_chunks
    number = f" line {line_number(family)}"
    assert [w for w in warnings if w not in told] == [
        w.replace(str(short), str(path)) for w in expected_warnings if number not in w
    ]


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_a_line_at_the_cap_is_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, family: str
) -> None:
    """A line of exactly `MAX_LINE` bytes is a line like any other: no warning about it."""
    monkeypatch.setattr(logs_base, "MAX_LINE", 1 << 12)
    line = long_line(family, 1 << 12)[: 1 << 12]
    path = tmp_path / f"at-{family}.txt"
    path.write_bytes(with_line(family, line))
    _, warnings = read(path)
    assert not _long_warnings(warnings)


@pytest.mark.parametrize("family", ["esphome", "cas", "monitor-cr", "saleae", "socat", "text2pcap"])
def test_a_16_mib_line_is_read_without_holding_it(tmp_path: Path, family: str) -> None:
    """With the default cap (1 MiB), reading a file with a line of 16 MiB allocates a
    few blocks at most, not the line: before, the line was held whole (as bytes and
    then as text, 32 MiB and more)."""
    line = long_line(family, 16 << 20)
    path = tmp_path / f"big-{family}.txt"
    path.write_bytes(with_line(family, line))
    tracemalloc.start()
    try:
        chunks, warnings = read(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 8 * MAX_LINE, f"{peak:,} bytes allocated at the peak"
    assert len(_long_warnings(warnings)) == 1
    assert f"{len(line):,} bytes" in _long_warnings(warnings)[0]
    assert any(chunk.data for chunk in chunks)


def test_cas_read_backwards_without_its_spill_skips_the_line_too(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A CAS log (newest line first) whose spill is dropped is read a second time from
    its end (`TextFile.lines_reversed`): the long line is skipped there too, told once."""
    monkeypatch.setattr(logs_base, "MAX_LINE", 1 << 16)
    path = tmp_path / "cas.log"
    path.write_bytes(with_line("cas", long_line("cas", 4 << 20)))
    spilled_chunks, spilled_warnings = read(path)
    monkeypatch.setattr(logs_base, "SPILL_LIMIT", 0)
    chunks, warnings = read(path)
    assert chunks == spilled_chunks
    assert warnings == spilled_warnings
    assert len(_long_warnings(warnings)) == 1


def test_lines_of_the_text_file_cut_long_lines_out(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`TextFile` lines, forwards and backwards, with LF and CR line ends, blocks smaller
    than the cap: a line longer than the cap is "", every other line as it is."""
    monkeypatch.setattr(logs_base, "MAX_LINE", 5)
    monkeypatch.setattr(logs_base, "BLOCK", 3)
    for cut in (b"\n", b"\r"):
        last = b"x\r" if cut == b"\n" else b"x"
        lines = [b"abc", b"abcdef", b"", b"12345", b"1234567890123", last]
        path = tmp_path / "f.log"
        path.write_bytes(cut.join(lines) + cut)
        text = logs_base.TextFile.survey(path)
        forwards = list(text.lines())
        expected = ["abc", "", "", "12345", "", "x"] + ([] if cut == b"\n" else [""])
        assert forwards == list(enumerate(expected, start=1))
        assert list(text.lines_reversed(text.count())) == forwards[::-1]
        assert [w.split(": ", 1)[1].split(",")[0] for w in text.warnings] == [
            "a line of 6 bytes",
            "a line of 13 bytes",
        ]


if __name__ == "__main__":
    family, size_mb, out = sys.argv[1], int(sys.argv[2]), Path(sys.argv[3])
    out.write_bytes(with_line(family, long_line(family, size_mb * 1_000_000)))
