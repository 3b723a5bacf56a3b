"""CSV register lists are untrusted input (issue #30, items 7 and 9): a header of 100,000
unknown columns is refused with a bounded list of problems at linear cost (the header
was once checked column against every column before it: 71 s); a cell over the csv
module's field limit (131,072 characters) is an error naming the line, not a traceback;
bidirectional controls in a register name never reach a terminal as such."""

from __future__ import annotations

from pathlib import Path

import pytest

import dissectors.dictionary.imports_csv as imports_csv
from dissectors.dictionary import DictionaryError, import_csv
from sniffer.text import plain


def test_a_header_of_100k_unknown_columns_is_refused_with_a_count(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "wide.csv"
    columns = ["table", "address", "name", *(f"c{k}" for k in range(100_000))]
    path.write_text(",".join(columns) + "\nholding,1,speed\n")
    looked_up = 0
    real = imports_csv.nearest  # type: ignore[attr-defined]

    def counted(word: str, known: object) -> str | None:
        nonlocal looked_up
        looked_up += 1
        return real(word, known)  # type: ignore[arg-type]

    monkeypatch.setattr(imports_csv, "nearest", counted)
    with pytest.raises(DictionaryError) as caught:
        import_csv(path)
    problems = caught.value.all
    assert len(problems) == imports_csv.MAX_COLUMN_PROBLEMS + 1
    assert problems[0].message == "unknown CSV column 'c0'" and problems[0].line == 1
    assert (
        problems[-1].message
        == f"{100_000 - imports_csv.MAX_COLUMN_PROBLEMS:,} more unknown or repeated columns"
    )
    assert looked_up == imports_csv.MAX_COLUMN_PROBLEMS  # not one look-up per column


def test_a_repeated_column_is_still_named(tmp_path: Path) -> None:
    path = tmp_path / "twice.csv"
    path.write_text("table,address,name,name\nholding,1,speed,x\n")
    with pytest.raises(DictionaryError, match="the header has 'name' twice"):
        import_csv(path)


def test_a_cell_over_the_csv_field_limit_names_its_line(tmp_path: Path) -> None:
    path = tmp_path / "long.csv"
    path.write_text('table,address,name\nholding,1,speed\nholding,2,"' + "y" * 140_000 + '"\n')
    with pytest.raises(DictionaryError) as caught:
        import_csv(path)
    assert caught.value.line == 3 and "field larger than field limit" in caught.value.message


@pytest.mark.parametrize("control", ["\u202e", "\u2066", "\u2067", "\u2069", "\u200f", "\u061c"])
def test_bidirectional_controls_are_escaped(control: str) -> None:
    shown = plain(f"Pump{control}1 txt.exe")
    assert control not in shown and f"\\u{ord(control):04x}" in shown
