"""`--filter` with `or`, `not`, parentheses and `==`, as a user runs it on the demo capture:
each spelling lists the rows a reader means (it used to list none, with exit status 0),
and a query it cannot read fails with exit status 2 and one line naming the part."""

from __future__ import annotations

from pathlib import Path

import pytest

from sniffer.cli import main

ROOT = Path(__file__).resolve().parent.parent.parent
DEMO = ROOT / "sniffer" / "demo" / "demo.pcapng"
BUS = ROOT / "sniffer" / "demo" / "demo-bus.toml"


def listing(query: str, capsys: pytest.CaptureFixture[str]) -> list[str]:
    code = main(["replay", str(DEMO), "--bus", str(BUS), "--format", "text", "--filter", query])
    out, err = capsys.readouterr()
    assert code == 0, err
    # the rows, without the note on what the demo's times are worth (`# timing: ...`)
    return [line for line in out.splitlines() if not line.startswith("#")]


def test_or_lists_the_rows_of_either_side_in_capture_order(
    capsys: pytest.CaptureFixture[str],
) -> None:
    three, four = listing("unit:3", capsys), listing("unit:4", capsys)
    assert three and four
    either = listing("unit:3 or unit:4", capsys)
    assert sorted(either) == sorted(three + four)
    times = [float(line.split()[0]) for line in either]
    assert times == sorted(times)
    assert listing("unit:3 OR unit:4", capsys) == either
    assert listing("(unit:4 or unit:3)", capsys) == either


@pytest.mark.parametrize(("text", "same_as"), [("(unit:3)", "unit:3"), ("unit==3", "unit:3")])
def test_other_spellings_list_the_same_rows(
    text: str, same_as: str, capsys: pytest.CaptureFixture[str]
) -> None:
    want = listing(same_as, capsys)
    assert want and listing(text, capsys) == want


def test_not_lists_the_other_rows(capsys: pytest.CaptureFixture[str]) -> None:
    every = listing("t:0-", capsys)
    three = listing("unit:3", capsys)
    others = listing("not unit:3", capsys)
    assert others and sorted(others + three) == sorted(every)
    assert listing("unit!=3", capsys) == others


def test_a_group_with_words_and_columns(capsys: pytest.CaptureFixture[str]) -> None:
    exceptions = listing("kind:exception", capsys)
    mixed = listing('unit:3 (kind:exception or reg:"Under Voltage")', capsys)
    assert mixed
    assert set(listing("kind:exception unit:3", capsys)) <= set(mixed)
    assert all(" u3 " in line for line in mixed)
    assert len(mixed) > len([line for line in exceptions if " u3 " in line])


@pytest.mark.parametrize(
    ("text", "part", "fix"),
    [
        ("unit:3 or", "unit:3 or", "e.g. unit:3 or unit:4"),
        ("(unit:3", "(unit:3", "add a ) where the group ends"),
        ("unit == 3", "unit == 3", "together: unit==3"),
        ("unit:3 || unit:4", "||", "write or"),
        ("unit>3", "unit>3", "write a range: unit:4-255"),
    ],
)
def test_a_query_it_cannot_read_fails_in_one_line(
    text: str, part: str, fix: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["replay", str(DEMO), "--filter", text])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    (line,) = err.splitlines()
    assert line.startswith(f"modscope: error: --filter: {part}: ") and fix in line


def test_a_word_spelled_as_the_unit_column_says_which_term_selects_the_unit(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The list shows `u3`; `--filter u3` looks for that text, which no row's text holds
    (the unit column is not text): the listing is empty, and a note says what selects
    unit 3, which then lists its rows."""
    assert listing("u3", capsys) == []
    main(["replay", str(DEMO), "--bus", str(BUS), "--format", "text", "--filter", "u3 fc03"])
    notes = [x for x in capsys.readouterr().err.splitlines() if "--filter" in x]
    assert notes == [
        "modscope: note: --filter: 'u3' is looked for as text, which the unit column is "
        "not; for unit 3 write unit:3",
        "modscope: note: --filter: 'fc03' is looked for as text, which the fc column is "
        "not; for fc 3 write fc:3",
    ]
    rows = listing("unit:3", capsys)
    assert rows and all(" u3 " in line for line in rows)
    main(["replay", str(DEMO), "--filter", "unit:3 voltage"])
    assert "--filter" not in capsys.readouterr().err  # words that look like no column
