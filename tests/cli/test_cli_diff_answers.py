"""`modscope diff A B` as a user runs it, on two pcapng captures written here from byte
literals: a unit that answered every request in A and none in B is the first thing
said, with its counts, and the exit status says the captures differ."""

from __future__ import annotations

from pathlib import Path

import pytest

from dissectors.checks import with_crc
from sniffer.cli import main
from sniffer.sources.pcapng_writer import PcapngWriter


def write(path: Path, unit_9_answers: bool, value: int) -> Path:
    """Raw serial reads (link type 147) at the default 19200 8E1: 24 rounds of unit 3
    and unit 9 read, unit 9 answering or not, then a last read of unit 3."""
    rows: list[tuple[float, bytes]] = []
    for k in range(24):
        t = 0.5 * k
        rows.append((t, with_crc(bytes([3, 3, 0, 0, 0, 2]))))
        rows.append((t + 0.02, with_crc(bytes([3, 3, 4, 0, 100, 0, value]))))
        rows.append((t + 0.1, with_crc(bytes([9, 3, 0, 5, 0, 1]))))
        if unit_9_answers:
            rows.append((t + 0.12, with_crc(bytes([9, 3, 2, 0, 1]))))
    rows.append((12.0, with_crc(bytes([3, 3, 0, 0, 0, 2]))))
    rows.append((12.02, with_crc(bytes([3, 3, 4, 0, 100, 0, value]))))
    with path.open("wb") as f:
        writer = PcapngWriter(f)
        port = writer.add_interface(147, name="test")
        for t, data in rows:
            writer.write_packet(port, 1_700_000_000 + t + 0.005, data)
    return path


def test_a_unit_that_stopped_answering_comes_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a = write(tmp_path / "a.pcapng", True, 50)
    b = write(tmp_path / "b.pcapng", False, 80)
    code = main(["diff", str(a), str(b)])
    out = capsys.readouterr().out.splitlines()
    assert code == 1
    assert out[2] == (
        "unit 9: silent in B: none of 24 requests answered (24 timeouts); "
        "24 of 24 requests answered (100 %) in A"
    )
    assert out[3].startswith("unit 3: holding 1 left its range: 50..50 in A, 80..80 in B")
    code = main(["diff", str(b), str(a)])
    out = capsys.readouterr().out.splitlines()
    assert code == 1
    assert out[2].startswith("unit 9: answers again in B: 24 of 24 requests answered (100 %)")


def test_the_same_answers_are_no_difference(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a = write(tmp_path / "a.pcapng", False, 50)
    b = write(tmp_path / "b.pcapng", False, 50)
    assert main(["diff", str(a), str(b)]) == 0
    assert "no difference in units, answers," in capsys.readouterr().out
