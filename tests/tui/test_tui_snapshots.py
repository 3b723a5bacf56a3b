"""Snapshots of the TUI's main screens on the demo capture, at 80x24 and 120x36.

Review the SVGs in tests/__snapshots__/ when they change; regenerate them with
`pytest --snapshot-update tests/tui/test_tui_snapshots.py`.
"""

from __future__ import annotations

import time
from collections.abc import Awaitable, Callable, Iterable
from typing import Any

import pytest
from textual.pilot import Pilot

from sniffer.meaning.annotate import load_bindings
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, replay_file
from sniffer.tui.app import ModscopeApp

pytestmark = pytest.mark.skipif(not DEMO_CAPTURE.exists(), reason="the demo capture is missing")

SnapCompare = Callable[..., bool]
_SESSION: list[Session] = []


def demo_app(*, light: bool = False) -> ModscopeApp:
    if not _SESSION:
        _SESSION.append(replay_file(DEMO_CAPTURE, bindings=load_bindings(DEMO_BUS)))
    return ModscopeApp(_SESSION[0], blink=False, light=light)


def after(*keys: str, watch: bool = False) -> Callable[[Pilot[Any]], Awaitable[None]]:
    """A run_before that presses keys, then waits for every worker to finish."""

    async def run(pilot: Pilot[Any]) -> None:
        app = pilot.app
        assert isinstance(app, ModscopeApp)
        await pilot.pause()
        for key in keys:
            await pilot.press(key)
            await _idle(pilot, app)
        if watch:
            deadline = time.monotonic() + 20
            w = app.watching.watch
            while w is None or w.next < app.model.shown:
                assert time.monotonic() < deadline
                await pilot.pause(0.05)
                w = app.watching.watch
            app.watching.show()
        await _idle(pilot, app)

    return run


async def _idle(pilot: Pilot[Any], app: ModscopeApp) -> None:
    deadline = time.monotonic() + 20
    job = app.model.job
    while job is not None and not (job.caught_up and job.upto >= app.model.shown):
        assert time.monotonic() < deadline
        await pilot.pause(0.05)
    await pilot.pause()
    await pilot.pause()


SIZES: Iterable[tuple[int, int]] = ((80, 24), (120, 36), (160, 48))
NEW_SIZES: Iterable[tuple[int, int]] = ((80, 24), (160, 48))


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_main_screen(snap_compare: SnapCompare, size: tuple[int, int]) -> None:
    assert snap_compare(demo_app(), terminal_size=size, run_before=after())


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_units_panel(snap_compare: SnapCompare, size: tuple[int, int]) -> None:
    assert snap_compare(demo_app(), terminal_size=size, run_before=after("u"))


def test_transactions_with_problems_only(snap_compare: SnapCompare) -> None:
    assert snap_compare(
        demo_app(), terminal_size=(120, 36), run_before=after("t", "exclamation_mark")
    )


def test_field_tree_and_hex_highlight(snap_compare: SnapCompare) -> None:
    keys = ("down", "down", "down", "enter", "down", "down", "down", "down", "down")
    assert snap_compare(demo_app(), terminal_size=(120, 36), run_before=after(*keys))


def test_register_watch(snap_compare: SnapCompare) -> None:
    assert snap_compare(demo_app(), terminal_size=(120, 36), run_before=after("w", watch=True))


def test_register_plot(snap_compare: SnapCompare) -> None:
    keys = ("tab", "down", "enter")
    run = after("w", watch=True)

    async def open_plot(pilot: Pilot[Any]) -> None:
        await run(pilot)
        for key in keys:
            await pilot.press(key)
        await pilot.pause()

    assert snap_compare(demo_app(), terminal_size=(120, 36), run_before=open_plot)


def test_help_screen(snap_compare: SnapCompare) -> None:
    assert snap_compare(demo_app(), terminal_size=(80, 24), run_before=after("question_mark"))


def test_filter_error(snap_compare: SnapCompare) -> None:
    async def bad_filter(pilot: Pilot[Any]) -> None:
        await after("slash")(pilot)
        for key in "unti:3":
            await pilot.press(key)
        await pilot.press("enter")
        await pilot.pause()

    assert snap_compare(demo_app(), terminal_size=(80, 24), run_before=bad_filter)


@pytest.mark.parametrize("size", NEW_SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_prompt_line_and_keys(snap_compare: SnapCompare, size: tuple[int, int]) -> None:
    async def ask(pilot: Pilot[Any]) -> None:
        await after()(pilot)
        await pilot.press("e", *"rows.csv")
        await pilot.pause()

    assert snap_compare(demo_app(), terminal_size=size, run_before=ask)


@pytest.mark.parametrize("size", NEW_SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_light_theme_problems(snap_compare: SnapCompare, size: tuple[int, int]) -> None:
    run = after("exclamation_mark", "right_square_bracket", "right_square_bracket")
    assert snap_compare(demo_app(light=True), terminal_size=size, run_before=run)


@pytest.mark.parametrize("size", NEW_SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_register_watch_sizes(snap_compare: SnapCompare, size: tuple[int, int]) -> None:
    assert snap_compare(demo_app(), terminal_size=size, run_before=after("w", watch=True))


@pytest.mark.parametrize("size", NEW_SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_edited_filter_is_marked(snap_compare: SnapCompare, size: tuple[int, int]) -> None:
    async def edit(pilot: Pilot[Any]) -> None:
        await after()(pilot)
        await pilot.press("slash", *"unit:3", "enter")
        await after()(pilot)
        await pilot.press("slash", *"fc:6")
        await pilot.pause()

    assert snap_compare(demo_app(), terminal_size=size, run_before=edit)


@pytest.mark.parametrize("size", NEW_SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_ladder(snap_compare: SnapCompare, size: tuple[int, int]) -> None:
    """The demo's transactions as a ladder (host read times: one line a frame)."""
    run = after("slash", *"unit:3", "enter", "j", "j", "j", "l")
    assert snap_compare(demo_app(), terminal_size=size, run_before=run)


@pytest.mark.parametrize("size", NEW_SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_ladder_to_scale(snap_compare: SnapCompare, size: tuple[int, int]) -> None:
    """Exact stamps: gaps to scale, a timeout, noise and a bad check."""
    from tests.tui.test_tui_ladder import exact_session

    app = ModscopeApp(exact_session(), blink=False)
    assert snap_compare(app, terminal_size=size, run_before=after("j", "l"))


@pytest.mark.parametrize("size", NEW_SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_register_table(snap_compare: SnapCompare, size: tuple[int, int]) -> None:
    run = after("w", watch=True)

    async def table(pilot: Pilot[Any]) -> None:
        await run(pilot)
        await pilot.press("tab", "x", "down", "x", "down", "down", "x", "down", "x", "R")
        app = pilot.app
        screen = app.screen
        deadline = time.monotonic() + 20
        while getattr(screen, "scanned", None) is not None:
            assert time.monotonic() < deadline
            await pilot.pause(0.05)
        await pilot.press("home", "down", "down")
        await pilot.pause()

    assert snap_compare(demo_app(), terminal_size=size, run_before=table)


@pytest.mark.parametrize("size", NEW_SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_filter_refused(snap_compare: SnapCompare, size: tuple[int, int]) -> None:
    async def refused(pilot: Pilot[Any]) -> None:
        await after()(pilot)
        await pilot.press("slash", *"t:20-10", "enter")
        await pilot.pause()

    assert snap_compare(demo_app(), terminal_size=size, run_before=refused)
