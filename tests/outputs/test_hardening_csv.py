"""CSV exports never hold a cell a spreadsheet would run as a formula (issue 15, item 3).

Text from dictionaries (names, units, enum texts) and from the bus (decoded strings)
that starts with `=`, `+`, `-` or `@` gets a leading `'`; numbers stay numbers;
`raw=True` (the `--raw-csv` option) writes the text as it is."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.meaning.annotate import load_bindings
from sniffer.model import Chunk, LineSettings
from sniffer.outputs.export import REGISTER_COLUMNS, register_records, write_table
from sniffer.outputs.listing import CSV_COLUMNS, Lister
from sniffer.session.session import Session
from sniffer.text import FORMULA_START, csv_cell
from tests.support.hostile import HOSTILE_TOML

RTU = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")


def session_with(tmp_path: Path) -> Session:
    path = tmp_path / "hostile.toml"
    path.write_text(HOSTILE_TOML, encoding="utf-8")
    bindings = load_bindings(None, ["1=hostile:-label"], [str(path)])
    s = Session(RTU, exact_timing=True, timeout=0.1, bindings=bindings)
    request = with_crc(bytes.fromhex("010300000004"))
    # 40001 = 65535 (s16 -1 would be a number), 40002 = 0 ("-2+3"), 40003-4 = "=1+1"
    answer = with_crc(bytes.fromhex("010308ffff0000") + b"=1+1")
    t = 1_750_000_000.0
    for frame in (request, answer):
        s.feed(Chunk(frame, t + len(frame) * RTU.char_time, t_start=t))
        t += 0.03
    s.finish()
    return s


def cells(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text)))


def formula_cells(rows: list[list[str]]) -> list[str]:
    return [c for row in rows[1:] for c in row if c[:1] in FORMULA_START and not is_number(c)]


def is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def test_register_table_escapes_dictionary_and_bus_text(tmp_path: Path) -> None:
    s = session_with(tmp_path)
    out = io.StringIO()
    write_table(out, "csv", REGISTER_COLUMNS, register_records(s.describer, range(len(s.store))))
    rows = cells(out.getvalue())
    assert formula_cells(rows) == []
    flat = [c for row in rows for c in row]
    assert "'=cmd|' /C calc'!A0" in flat  # dictionary name
    assert "'@SUM(1+1)" in flat  # dictionary unit
    assert any(c.startswith("'-2+3") for c in flat)  # enum text
    assert any(c.startswith("'=1+1") for c in flat)  # string decoded from the bus
    assert "'-label" in flat  # a unit label given on the command line


def test_raw_csv_writes_text_as_it_is(tmp_path: Path) -> None:
    s = session_with(tmp_path)
    out = io.StringIO()
    records = register_records(s.describer, range(len(s.store)))
    write_table(out, "csv", REGISTER_COLUMNS, records, raw_csv=True)
    flat = [c for row in cells(out.getvalue()) for c in row]
    assert "=cmd|' /C calc'!A0" in flat
    assert "@SUM(1+1)" in flat


@pytest.mark.parametrize("raw", [False, True])
def test_frame_listing_csv_escapes_event_text_from_a_capture(raw: bool) -> None:
    # a capture's comment names the event (pcapng opt_comment, RTAC records)
    s = Session(RTU, exact_timing=True, timeout=0.1)
    s.feed(Chunk(b"", 1.0, event="=cmd|' /C calc'!A0", note="@x"))
    s.finish()
    out = io.StringIO()
    Lister(out, "csv", s.describer, raw_csv=raw).write(range(len(s.store)))
    rows = cells(out.getvalue())
    summary = rows[1][CSV_COLUMNS.index("summary")]
    assert summary == ("=cmd|' /C calc'!A0: @x" if raw else "'=cmd|' /C calc'!A0: @x")
    if not raw:
        assert formula_cells(rows) == []


def test_numbers_stay_numbers() -> None:
    assert csv_cell(-5) == -5
    assert csv_cell(-1.5) == -1.5
    assert csv_cell("-1.500") == "-1.500"  # a latency or time we formatted
    assert csv_cell("+3e5") == "+3e5"
    assert csv_cell(float("-inf")) == "'-inf"
    assert csv_cell(None) == ""
    assert csv_cell(True) == "True"


def test_control_characters_are_escaped_before_the_guard() -> None:
    assert csv_cell("\t=1+1") == "\\x09=1+1"
    assert csv_cell("\r=1+1") == "\\x0d=1+1"
    assert csv_cell("a\x1b[31mred") == "a\\x1b[31mred"
    assert csv_cell("-1-1") == "'-1-1"


@given(st.text())
def test_no_text_cell_can_start_a_formula(text: str) -> None:
    cell = csv_cell(text)
    assert isinstance(cell, str)
    assert cell[:1] not in FORMULA_START or is_number(cell)
    assert not any(ord(ch) < 0x20 for ch in cell)
