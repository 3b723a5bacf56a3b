"""Every burst of keys docs/tui.md promises works typed in one burst: at start-up (while the
demo capture is still being read) and right after a jump (`g`, then the burst at once).

`burst` hands the app the whole line at once, as a terminal does for a paste or a slow
SSH link; nothing waits between the keys.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from textual.pilot import Pilot

from sniffer.meaning.annotate import load_bindings
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, open_session
from sniffer.tui.app import ModscopeApp
from sniffer.tui.screens.regtable import TableScreen
from tests.support.tui import burst

pytestmark = [
    pytest.mark.asyncio,
    pytest.mark.skipif(not DEMO_CAPTURE.exists(), reason="the demo capture is missing"),
]
WHEN = ["start-up", "after a jump"]


def demo_app() -> ModscopeApp:
    """The demo capture as `modscope tui` opens it: read by the app's own feed."""
    session, capture = open_session(DEMO_CAPTURE, bindings=load_bindings(DEMO_BUS))
    return ModscopeApp(session, capture, blink=False)


async def until(pilot: Pilot[int], ok: object, timeout: float = 15.0) -> None:
    deadline = time.monotonic() + timeout
    assert callable(ok)
    while not ok():
        assert time.monotonic() < deadline, "never happened"
        await pilot.pause(0.02)


async def begin(pilot: Pilot[int], app: ModscopeApp, when: str) -> None:
    """At start-up: nothing (the burst comes at once). After a jump: `g#50` Enter, then
    the burst comes right behind it."""
    if when == "after a jump":
        await until(pilot, app.indexed.is_set)
        burst(app, ["g", *"#50", "enter"])


@pytest.mark.parametrize("when", WHEN)
async def test_a_filter(when: str) -> None:
    app = demo_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await begin(pilot, app, when)
        burst(app, [*"/unit:3 fc:6", "enter"])
        await until(pilot, lambda: app.model.query.text == "unit:3 fc:6")
        await until(pilot, app.indexed.is_set)
        assert not app.model.transactions and app.frames.has_focus


@pytest.mark.parametrize("when", WHEN)
async def test_a_refused_filter_turns_the_bar_red(when: str) -> None:
    app = demo_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await begin(pilot, app, when)
        burst(app, [*"/unti:3", "enter"])
        await until(pilot, lambda: app.main.filter_bar.has_class("-error"))
        for _ in range(10):  # the late messages of the keys do not clear it
            await pilot.pause(0.02)
        assert app.main.filter_bar.has_class("-error")
        assert app.main.filter_input.value == "unti:3"


@pytest.mark.parametrize("when", WHEN)
async def test_a_go_to(when: str) -> None:
    app = demo_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await begin(pilot, app, when)
        burst(app, ["g", *"#1234", "enter"])
        await until(pilot, lambda: app.frames.cursor_row == 1234)
        await until(pilot, app.indexed.is_set)
        await pilot.pause(0.1)
        assert app.frames.cursor_row == 1234  # and stays there


@pytest.mark.parametrize("when", WHEN)
async def test_an_export(when: str, tmp_path: Path) -> None:
    target = tmp_path / "rows.csv"
    app = demo_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await begin(pilot, app, when)
        burst(app, ["e", *str(target), "enter"])
        await until(pilot, target.exists)
        # "wrote ...": at start-up the app first says the export waits for the rows, which
        # names the file too; the file exists (empty) from the moment the writer opens it
        await until(pilot, lambda: any(s.startswith("wrote") and "rows.csv" in s for s in app.said))
    assert target.read_text().count("\n") > 1


@pytest.mark.parametrize("when", WHEN)
async def test_two_registers_picked_and_their_table(when: str) -> None:
    app = demo_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await begin(pilot, app, when)
        burst(app, ["w", "tab", "x", "down", "x", "R"])
        await until(pilot, lambda: isinstance(app.screen, TableScreen))
        screen = app.screen
        assert isinstance(screen, TableScreen)
        assert len(screen.table.keys) == 2


@pytest.mark.parametrize("when", WHEN)
async def test_keys_after_enter_in_a_plot_go_to_the_main_screen_not_the_filter(when: str) -> None:
    from sniffer.tui.screens.register import RegisterScreen

    app = demo_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await begin(pilot, app, when)
        burst(app, ["w", "tab", "enter"])  # the plot of the first register
        await until(pilot, lambda: isinstance(app.screen, RegisterScreen))
        burst(app, ["enter", "tab", "x"])  # to its newest frame, then Tab x at once
        await until(pilot, lambda: app.screen is app.main)
        await pilot.pause(0.2)
        assert app.main.filter_input.value == ""
        assert app.main.focused is not app.main.filter_input
