"""Tests that the details pane shows the whole summary and every explanation, wrapped, never
cut mid-token, and that `D` gives it the whole screen at 80x24 (the demo capture: its
row #600 is an exception that the request's out-of-range value explains)."""

from __future__ import annotations

import pytest

from sniffer.meaning.annotate import load_bindings
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, replay_file
from sniffer.tui.app import ModscopeApp
from sniffer.tui.render import fit_words
from tests.support.tui import ready, screen_text

needs_demo = pytest.mark.skipif(not DEMO_CAPTURE.exists(), reason="the demo capture is missing")
EXPLANATION = "explained by the request: written value 700 V above the documented maximum 600 V"


def demo() -> Session:
    return replay_file(DEMO_CAPTURE, bindings=load_bindings(DEMO_BUS))


def words(text: str) -> str:
    """The screen's text with its line breaks and padding as single spaces (wrapping)."""
    lines = [line.split("│")[0] for line in text.splitlines()]  # the tree's side only
    return " ".join(" ".join(lines).split())


@needs_demo
@pytest.mark.asyncio
@pytest.mark.parametrize("light", [False, True])
async def test_the_explanation_of_an_exception_is_shown_whole_at_80_columns(light: bool) -> None:
    app = ModscopeApp(demo(), blink=False, light=light)
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        await pilot.press("g", "#", "6", "0", "0", "enter", "D")
        await pilot.pause()
        text = screen_text(app)
        assert EXPLANATION in words(text)
        assert "exception, exception" not in words(text)
        assert "#600 S>M u3" in text  # the title says which frame
        # the tree's line of the request ends with a whole word and an ellipsis
        assert "request #599: write 0x02BC to register …" in text
        assert "0x000│" not in text
        assert not app.frames.is_on_screen
        await pilot.press("D")  # back to the list, the pane as it was
        await pilot.pause()
        assert app.frames.is_on_screen and app.main.focused is app.frames


@needs_demo
@pytest.mark.asyncio
async def test_the_head_scrolls_when_the_pane_is_small() -> None:
    app = ModscopeApp(demo(), blink=False)
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        await pilot.press("g", "#", "6", "0", "0", "enter")
        await pilot.pause()
        head = app.main.detail.query_one("#detail-head")
        assert head.max_scroll_y > 0  # the summary and title need more than their share
        assert "maximum 600 V" not in words(screen_text(app))
        head.scroll_to(y=1, animate=False)
        await pilot.pause()
        assert "maximum 600 V" in words(screen_text(app))


def test_fit_words_never_cuts_a_token() -> None:
    assert fit_words("write 0x02BC to register 0x000D", 31) == "write 0x02BC to register 0x000D"
    assert fit_words("write 0x02BC to register 0x000D", 30) == "write 0x02BC to register …"
    assert fit_words("values: 0x26E8 0x42BF", 18) == "values: 0x26E8 …"
    assert fit_words("0x26E80x42BF", 8) == "0x26E80…"
    text = "write 0x02BC to register 0x000D: Under Voltage Trip = 700 V"
    for width in range(1, len(text) + 2):
        fitted = fit_words(text, width)
        assert len(fitted) <= width
        assert fitted == text or fitted.endswith("…")


@pytest.mark.asyncio
async def test_the_help_shows_every_key_on_one_line_in_two_columns_at_80() -> None:
    from sniffer.tui.screens.dialogs import FILTER_HELP, KEY_HELP, HelpScreen
    from tests.support.tui import hostile_session

    app = ModscopeApp(hostile_session(), blink=False)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("question_mark")
        await pilot.pause()
        assert isinstance(app.screen, HelpScreen)
        lines = [line.strip() for line in screen_text(app).splitlines()]
        half = (len(KEY_HELP) + 1) // 2
        for k, (_, text) in enumerate(KEY_HELP[:half]):  # two entries side by side
            other = KEY_HELP[half + k][1] if half + k < len(KEY_HELP) else ""
            assert any(text in line and other in line for line in lines), (text, other)
        assert all(len(line) <= 76 for line in FILTER_HELP.splitlines())


@needs_demo
@pytest.mark.asyncio
@pytest.mark.parametrize("size", [(80, 24), (200, 50)])
async def test_the_register_watch_uses_the_width(size: tuple[int, int]) -> None:
    from sniffer.tui.widgets.watch import WatchPanel

    app = ModscopeApp(demo(), blink=False)
    async with app.run_test(size=size) as pilot:
        await ready(pilot, app)
        await pilot.press("w")
        await pilot.pause(0.6)
        panel = app.main.query_one(WatchPanel)
        used = sum(column.get_render_width(panel) for column in panel.columns.values())
        assert panel.size.width - 2 - 8 <= used <= panel.size.width  # no wasted half
        text = screen_text(app)
        assert "1 Exciter G1" in text  # the device label whole, at 80 columns too
        if size[0] >= 200:
            assert "Weekly average power factor" in text and "history" in text
