"""Keys typed at full speed land where they were meant to go, in order.

`burst` hands the app a whole line of keys at once, as a terminal does for a fast typist,
a paste or a slow SSH link; `Pilot.press` is tried too. Before keys were priority
bindings, `/unit:3 fc:6` Enter left the filter empty and its `t` switched on the
transaction view.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from rich.style import Style
from textual.pilot import Pilot

from sniffer.tui.app import ModscopeApp
from sniffer.tui.keys import KEYS, Context
from sniffer.tui.widgets.keybar import key_lines
from tests.support.tui import burst, hostile_session, screen_text, synthetic_session


async def until(pilot: Pilot[int], ok: object, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    assert callable(ok)
    while not ok():
        assert time.monotonic() < deadline, "never happened"
        await pilot.pause(0.02)


async def ready(pilot: Pilot[int], app: ModscopeApp) -> None:
    await until(pilot, app.indexed.is_set)
    await pilot.pause()


def rows(app: ModscopeApp) -> list[int]:
    return [app.model.view.row(k) for k in range(app.frames.count)]


@pytest.mark.parametrize("how", ["burst", "pilot"])
@pytest.mark.asyncio
async def test_a_filter_typed_at_once_is_applied_and_nothing_leaks(how: str) -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        keys = [*"/unit:3 fc:6", "enter"]
        if how == "burst":
            burst(app, keys)
        else:
            await pilot.press(*keys)
        await until(pilot, lambda: app.model.query.text == "unit:3 fc:6")
        await until(pilot, lambda: app.model.job is not None and app.model.job.caught_up)
        await pilot.pause()
        assert not app.model.transactions  # the `t` in `unit:3` was a character
        assert rows(app) == [4, 5]
        assert app.frames.has_focus


@pytest.mark.asyncio
async def test_keys_after_enter_go_to_the_list() -> None:
    app = ModscopeApp(synthetic_session(300))
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        burst(app, [*"/unit:1", "enter", "j", "j", "j"])
        await until(pilot, lambda: app.model.query.text == "unit:1")
        await until(pilot, lambda: app.frames.cursor == 3)
        assert app.main.filter_input.value == "unit:1"


@pytest.mark.asyncio
async def test_editing_keys_keep_their_place_among_characters() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        keys = [*"/unit:4", "backspace", "3", "left", "left", "backspace", "t", "enter"]
        burst(app, keys)
        await until(pilot, lambda: app.model.query.text == "unit:3")
        assert not app.main.filter_bar.has_class("-error")


@pytest.mark.asyncio
async def test_go_to_typed_at_once_moves_the_cursor() -> None:
    app = ModscopeApp(synthetic_session(2000))
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        burst(app, ["g", *"#1234", "enter"])
        await until(pilot, lambda: app.frames.cursor_row == 1234)
        assert not app.main.prompt.open and app.frames.has_focus


@pytest.mark.asyncio
async def test_an_export_typed_at_once_writes_the_named_file_only(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        burst(app, ["e", *"rows.csv", "enter"])
        await until(pilot, lambda: any("wrote 17 rows" in s for s in app.said))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rows.csv"]


@pytest.mark.asyncio
async def test_escape_puts_back_the_applied_filter() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        burst(app, [*"/unit:5", "enter"])
        await until(pilot, lambda: app.model.query.text == "unit:5")
        burst(app, ["slash", *"fc:3"])
        await until(pilot, lambda: app.main.filter_input.value == "fc:3")  # typing replaces
        await until(pilot, lambda: app.main.filter_bar.has_class("-edited"))
        assert "edited" in screen_text(app)
        burst(app, ["escape"])
        await until(pilot, lambda: app.main.filter_input.value == "unit:5")
        assert not app.main.filter_bar.has_class("-edited")
        assert app.model.query.text == "unit:5"


def test_the_key_bar_shows_every_key_in_two_lines_at_80_columns() -> None:
    plain = Style()
    keys = [k for k in KEYS if k.context in (Context.ANY, Context.LIST)]
    text = key_lines(keys, 80, plain, plain).plain
    lines = text.split("\n")
    assert len(lines) == 2 and all(len(line) <= 80 for line in lines)
    for k in keys:
        if k.bar:
            assert f"{k.label} {k.text}" in text
    assert "? more" not in text
    wide = key_lines(keys, 200, plain, plain).plain
    assert "\n" not in wide and "  q quit  " in wide  # room for two spaces between keys


def test_a_key_bar_that_cannot_hold_every_key_says_where_they_are() -> None:
    plain = Style()
    keys = [k for k in KEYS if k.context is Context.UNITS]
    keys += [k for k in KEYS if k.context is Context.ANY]
    text = key_lines(keys, 80, plain, plain).plain
    assert text.startswith("⏎ unit") and text.endswith("? more")
    assert len(text.split("\n")) == 2


@pytest.mark.asyncio
async def test_a_newline_typed_ahead_ends_the_prompt_like_enter() -> None:
    """Keys typed while modscope starts reach it through a terminal still in line mode,
    where Enter arrives as a newline (ctrl+j): `g#1234` and a newline still go to #1234."""
    app = ModscopeApp(synthetic_session(2000))
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        burst(app, ["g", *"#1234", "ctrl+j", "j"])
        await until(pilot, lambda: app.frames.cursor_row == 1235)
        assert not app.main.prompt.open and app.frames.has_focus


@pytest.mark.asyncio
async def test_moves_in_the_watch_keep_their_order_with_the_keys_after_them() -> None:
    """Tab, x, Down, x, Down, Down, x typed at once pick three different registers."""
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(120, 36)) as pilot:
        await ready(pilot, app)
        await pilot.press("w")
        await until(pilot, lambda: app.watching.watch is not None and app.watching.watch.next >= 17)
        app.watching.show()
        await pilot.pause()
        keys = app.main.watch_panel.keys
        burst(app, ["tab", "x", "down", "x", "j", "j", "x"])
        await until(pilot, lambda: len(app.main.watch_panel.picked) == 3)
        assert list(app.main.watch_panel.picked) == [keys[0], keys[1], keys[3]]


@pytest.mark.asyncio
async def test_a_row_not_read_yet_is_said() -> None:
    app = ModscopeApp(synthetic_session(200))
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        burst(app, ["g", *"#5000", "enter"])
        await until(pilot, lambda: any("there is no #5000" in s for s in app.said))
        assert app.frames.cursor_row == len(app.model.view) - 1


@pytest.mark.asyncio
async def test_escape_and_a_key_in_one_sequence_are_two_keys() -> None:
    """Esc typed right before `w` reaches the app as alt+w (one terminal sequence): it
    closes the ladder, then shows the register watch."""
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        await pilot.press("l")
        assert app.screen is not app.main
        burst(app, ["alt+w"])
        await until(pilot, lambda: app.screen is app.main and app.main.lower.current == "watch")


@pytest.mark.asyncio
@pytest.mark.parametrize("opener", ["l", "question_mark"])
@pytest.mark.parametrize("keys", [("escape", "w"), ("alt+w",), ("escape", "u"), ("alt+u",)])
async def test_a_key_right_after_the_esc_that_closes_a_screen_is_not_lost(
    opener: str, keys: tuple[str, ...]
) -> None:
    # A terminal sends Esc and a key typed right after it as one sequence (alt+key); the
    # screen Esc closes is gone before the key is handled, so the key reaches the list.
    from sniffer.tui.screens.dialogs import HelpScreen
    from sniffer.tui.screens.ladder import LadderScreen
    from tests.tui.test_tui_ladder import exact_session

    app = ModscopeApp(exact_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        await pilot.press(opener)
        assert isinstance(app.screen, LadderScreen | HelpScreen)
        await pilot.press(*keys)
        await pilot.pause(0.1)
        assert not isinstance(app.screen, LadderScreen | HelpScreen)
        assert app.main.lower.current == {"w": "watch", "u": "units"}[keys[-1][-1]]
