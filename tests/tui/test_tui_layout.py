"""The 80x24 layout: the list keeps at least half the rows, panes leave out whole columns by
priority, values are never cut inside a number, notices stay off the status bar."""

from __future__ import annotations

import time

import pytest
from hypothesis import given
from hypothesis import strategies as st
from textual.pilot import Pilot

from dissectors.dictionary import RegisterValue
from sniffer.tui.app import ModscopeApp
from sniffer.tui.render import fit_columns, register_label
from sniffer.tui.widgets import units, watch
from sniffer.tui.widgets.watch import value_fit
from tests.support.tui import hostile_session, screen_text


async def opened(pilot: Pilot[int], app: ModscopeApp) -> None:
    deadline = time.monotonic() + 10
    while not app.indexed.is_set():
        assert time.monotonic() < deadline
        await pilot.pause(0.02)
    await pilot.pause()


@pytest.mark.asyncio
@pytest.mark.parametrize("pane", ["d", "u", "w"])
async def test_the_list_keeps_half_the_rows_at_80x24(pane: str) -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await opened(pilot, app)
        await pilot.press(pane)
        await pilot.pause()
        assert app.frames.page_height >= 12
        status = app.main.status.region
        keys = app.main.keybar.region
        assert status.bottom <= keys.y and keys.bottom <= 24 and keys.height == 2


@pytest.mark.asyncio
async def test_units_at_80_columns_keep_state_answer_and_latency() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await opened(pilot, app)
        await pilot.press("u")
        await pilot.pause()
        shown = app.main.units.shown
        assert {"unit", "state", "answer", "exc", "t/o", "median", "p95"} <= set(shown)
        assert "device" not in shown  # the least important goes first
        text = screen_text(app)
        assert "p95" in text and "answer" in text


@pytest.mark.asyncio
async def test_a_notice_leaves_the_status_bar_alone() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24), notifications=True) as pilot:
        await opened(pilot, app)
        await pilot.press("r")  # a capture file: a notice explains
        await pilot.pause(0.3)
        rack = app.screen.query_one("#textual-toastrack")
        assert rack.children
        status = app.main.status.region
        for toast in rack.children:
            assert not toast.region.overlaps(status)
            assert toast.region.bottom <= app.frames.region.bottom


def test_columns_are_left_out_whole_least_important_first() -> None:
    assert fit_columns(units.COLUMNS, units.PRIORITY, 10_000) == [n for n, _ in units.COLUMNS]
    narrow = fit_columns(units.COLUMNS, units.PRIORITY, 40)
    assert narrow == ["unit", "state", "exc", "t/o", "answer"]  # in their own order
    assert fit_columns(watch.COLUMNS, watch.PRIORITY, 79)[:2] == ["unit", "register"]


@given(st.floats(-1e6, 1e6, allow_nan=False), st.integers(1, 40))
def test_a_watched_value_is_whole_or_not_there(value: float, width: int) -> None:
    text = f"{value:.1f} %"
    shown = value_fit(text, width)
    assert shown in (text, text.split(" ")[0], "…")
    assert len(shown) <= max(width, 1)


@given(st.text(min_size=1, max_size=60), st.floats(-1e6, 1e6, allow_nan=False), st.integers(0, 80))
def test_a_register_label_never_cuts_its_value(name: str, value: float, width: int) -> None:
    shown = f"{value:.1f} %"
    r = RegisterValue(
        table="holding",
        address=10,
        name=name,
        value=value,
        unit="%",
        text=f"{name} = {shown}",
        raw=(100,),
    )
    label = register_label(r, width)
    assert label.endswith(shown) or label.endswith(shown + "  [0x0064]")


@pytest.mark.asyncio
async def test_a_plot_from_a_partial_scan_says_so() -> None:
    from sniffer.tui.screens.register import RegisterScreen
    from sniffer.tui.watch import Sample, Series

    series = Series((3, "holding", 13, "Under Voltage Trip"), "Under Voltage Trip", "V", "Pump")
    for k, v in enumerate((300.0, 300.0, 320.0)):
        series.add(Sample(float(k), v, f"{v:.0f} V", k))
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await opened(pilot, app)
        await app.push_screen(RegisterScreen(series, 0.0, False, scanned=0.45))
        await pilot.pause()
        text = screen_text(app)
        assert "PARTIAL: 45% of the capture read" in text and "latest so far: 320 V" in text
        app.pop_screen()
        await pilot.press("w")
        deadline = time.monotonic() + 10
        while app.watching.progress() is not None:
            assert time.monotonic() < deadline
            await pilot.pause(0.05)
        app.watching.show()
        assert app.main.lower.border_title == "register watch"
