"""Navigation without filtering: find (F, n, N), problems (] [), marks (m '), copy (c C) and
Enter on a unit, on the hostile capture (rows as listed in tests/support/tui.py)."""

from __future__ import annotations

import json
import time

import pytest
from textual.pilot import Pilot

from sniffer.meaning.query import parse_query
from sniffer.meaning.select import Options
from sniffer.tui.app import ModscopeApp
from sniffer.tui.navigate import find_row
from tests.support.tui import burst, hostile_session, synthetic_session


async def until(pilot: Pilot[int], ok: object, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    assert callable(ok)
    while not ok():
        assert time.monotonic() < deadline, "never happened"
        await pilot.pause(0.02)


async def opened(pilot: Pilot[int], app: ModscopeApp) -> None:
    await until(pilot, app.indexed.is_set)
    await pilot.pause()


@pytest.mark.asyncio
async def test_problems_forward_and_back() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await opened(pilot, app)
        seen = []
        for _ in range(6):
            await pilot.press("right_square_bracket")
            seen.append(app.frames.cursor_row)
        # the request answered by an exception 6, the exception 7, timeout 8, noise 9,
        # bad check 10 (as `!` shows them); then nothing after 10
        assert seen == [6, 7, 8, 9, 10, 10]
        assert any("no problem after #10" in s for s in app.said)
        await pilot.press("left_square_bracket")
        assert app.frames.cursor_row == 9
        assert app.frames.count == 17  # nothing was filtered


@pytest.mark.asyncio
async def test_find_typed_at_once_then_n_and_shift_n() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await opened(pilot, app)
        burst(app, ["F", *"fc:3 kind:request", "enter"])
        await until(pilot, lambda: app.frames.cursor_row == 2)
        await pilot.press("n")
        assert app.frames.cursor_row == 8
        await pilot.press("n")
        assert app.frames.cursor_row == 15
        await pilot.press("N", "N")
        assert app.frames.cursor_row == 2
        await pilot.press("N")
        assert app.frames.cursor_row == 2 and any(
            "no 'fc:3 kind:request' before" in s for s in app.said
        )


@pytest.mark.asyncio
async def test_find_of_a_word_spelled_as_the_unit_column_names_the_unit_term() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await opened(pilot, app)
        burst(app, ["F", *"fc16", "enter"])
        await until(pilot, lambda: any("for fc 16 write fc:16" in s for s in app.said))


@pytest.mark.asyncio
async def test_marks_are_shown_and_jumped_between() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await opened(pilot, app)
        await pilot.press("j", "j", "m", "j", "j", "j", "j", "m", "home")
        assert app.model.marks == {2, 6}
        number, when = app.frames.render_line(2).text.split()[:2]
        assert number == "#2" and when.startswith("●")
        await pilot.press("apostrophe")
        assert app.frames.cursor_row == 2
        await pilot.press("apostrophe")
        assert app.frames.cursor_row == 6
        await pilot.press("apostrophe")
        assert app.frames.cursor_row == 2  # round again


@pytest.mark.asyncio
async def test_copy_puts_hex_or_json_on_the_clipboard() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await opened(pilot, app)
        await pilot.press("j", "c")
        assert app.clipboard.startswith("03 04 08 00 01 00 62 01 9f 00 00")
        await pilot.press("C")
        record = json.loads(app.clipboard)
        assert record["index"] == 1 and record["unit"] == 3


@pytest.mark.asyncio
async def test_enter_on_a_unit_filters_to_it() -> None:
    app = ModscopeApp(synthetic_session(400))
    async with app.run_test(size=(80, 24)) as pilot:
        await opened(pilot, app)
        burst(app, ["u", "tab", "down", "enter"])
        await until(pilot, lambda: app.model.query.text.startswith("unit:"))
        unit = int(app.model.query.text.split(":")[1])
        await until(pilot, lambda: app.model.job is not None and app.model.job.caught_up)
        reader = app.model.reader
        assert app.frames.count > 0
        assert {reader.unit[app.model.view.row(k)] for k in range(app.frames.count)} == {unit}
        assert app.main.filter_input.value == f"unit:{unit}" and app.frames.has_focus


def test_a_search_cut_short_says_where_it_stopped() -> None:
    session = synthetic_session(3000)
    from sniffer.tui.model import ViewModel

    model = ViewModel(session)
    model.publish(len(session.store))
    found = find_row(
        model.reader,
        model.describer,
        parse_query('"no such words anywhere"'),
        Options(),
        0,
        1,
        model.published,
        lambda r: True,
        budget=0.0,
    )
    assert found.row is None and not found.complete and 0 < found.stopped < model.published
