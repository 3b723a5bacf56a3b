"""A CSV cell that starts with spaces before `=`, `+`, `-` or `@` is guarded like one
that starts with it (issue #30, item 9): a spreadsheet that trims spaces on import runs
" =1+1" as a formula; a number with spaces stays as it is."""

from __future__ import annotations

import pytest

from sniffer.text import csv_cell


@pytest.mark.parametrize("text", [" =1+1", "   @SUM(A1)", " +cmd", "  -2+3"])
def test_spaces_before_a_formula_do_not_hide_it(text: str) -> None:
    assert csv_cell(text) == "'" + text
    assert csv_cell(text, raw=True) == text


@pytest.mark.parametrize("text", [" -1.5", " 12", "plain", " name =x"])
def test_numbers_and_other_text_stay_as_they_are(text: str) -> None:
    assert csv_cell(text) == text
