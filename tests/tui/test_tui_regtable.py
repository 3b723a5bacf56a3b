"""The register table (x picks in the watch, R shows them side by side, one row a poll),
the units pane's `seen`, and exception summaries that name the exception once."""

from __future__ import annotations

import time

import pytest

from dissectors.checks import with_crc
from sniffer.model import Chunk
from sniffer.session.session import Session
from sniffer.tui.app import ModscopeApp
from sniffer.tui.regtable import RegisterTable
from sniffer.tui.screens.regtable import TableScreen
from sniffer.tui.watch import SeriesKey
from tests.support.tui import LINE, hostile_session, ready, screen_text

VOLTAGE: SeriesKey = (3, "input_registers", 2, "Voltage")
TRIP: SeriesKey = (3, "holding_registers", 13, "Under Voltage Trip")
OVERLOAD: SeriesKey = (3, "holding_registers", 11, "Overload Trip")


def test_one_row_a_poll_a_new_row_when_a_register_comes_again() -> None:
    session = hostile_session()
    table = RegisterTable(session.store, session.annotator, [VOLTAGE, TRIP, OVERLOAD])
    while table.advance(len(session.store)):
        pass
    table.finish()
    rows = [(r.row, r.values) for r in table.rows]
    # row 1 reads the voltage (415 V), row 3 the trip (300 V) and overload (115 %): one
    # poll; row 4 writes the trip again (320 V): a new poll; row 16 reads both again
    assert rows == [
        (1, ("415 V", "300 V", "115 %")),
        (4, (None, "320 V", None)),
        (16, (None, "320 V", "115 %")),
    ]


def test_a_table_read_in_slices_matches_one_read_at_once() -> None:
    session = hostile_session()
    whole = RegisterTable(session.store, session.annotator, [TRIP, VOLTAGE])
    whole.advance(len(session.store), budget=10)
    whole.finish()
    sliced = RegisterTable(session.store, session.annotator, [TRIP, VOLTAGE])
    for upto in range(1, len(session.store) + 1):
        sliced.advance(upto, budget=10)
    sliced.finish()
    assert list(sliced.rows) == list(whole.rows)


@pytest.mark.asyncio
async def test_x_picks_and_r_shows_the_table_enter_goes_to_the_frame() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(120, 36)) as pilot:
        await ready(pilot, app)
        await pilot.press("w")
        deadline = time.monotonic() + 10
        while app.watching.watch is None or app.watching.watch.next < app.model.shown:
            assert time.monotonic() < deadline
            await pilot.pause(0.05)
        app.watching.show()
        await pilot.press("tab")
        assert app.focused is app.main.watch_panel
        panel = app.main.watch_panel
        picks = []
        for key in panel.keys:
            if key in (TRIP, VOLTAGE):
                panel.move_cursor(row=panel.keys.index(key))
                await pilot.press("x")
                picks.append(key)
        assert list(panel.picked) == picks
        assert "✓ Under Voltage Trip" in screen_text(app)
        await pilot.press("R")
        assert isinstance(app.screen, TableScreen)
        screen = app.screen
        while screen.scanned is not None:
            assert time.monotonic() < deadline
            await pilot.pause(0.05)
        text = screen_text(app)
        assert "2 registers, 3 polls" in text and "PARTIAL" not in text
        assert "Under Voltage Trip" in text and "320 V" in text and "415 V" in text
        await pilot.press("home", "enter")
        assert not isinstance(app.screen, TableScreen)
        assert app.frames.cursor_row == 1


@pytest.mark.asyncio
async def test_seen_is_when_a_unit_was_last_heard() -> None:
    """Unit 7 is polled and never answers: SILENT, and not `seen` just because the master
    keeps asking; unit 3 answers: seen a moment ago."""
    char = LINE.char_time
    frames: list[tuple[float, bytes]] = []
    for k in range(6):
        t = k * 1.0
        frames.append((t, with_crc(bytes([3, 3, 0, 0, 0, 1]))))
        frames.append((t + 0.02, with_crc(bytes([3, 3, 2, 0, k]))))
        frames.append((t + 0.1, with_crc(bytes([7, 3, 0, 0, 0, 1]))))
    session = Session(LINE, exact_timing=True, source="x")
    session.ingest([Chunk(raw, t_start=t, t_end=t + len(raw) * char) for t, raw in frames])
    app = ModscopeApp(session)
    async with app.run_test(size=(120, 36)) as pilot:
        await ready(pilot, app)
        await pilot.press("u")
        await pilot.pause()
        lines = screen_text(app).splitlines()
        (unit7,) = [line for line in lines if "SILENT" in line]
        (unit3,) = [line for line in lines if line.lstrip().startswith("3 ")]
        assert unit7.lstrip().startswith("7") and "ago" not in unit7
        assert unit3.rstrip().endswith("ms ago") and "SILENT" not in unit3


def test_an_exception_summary_names_the_exception_once() -> None:
    session = hostile_session()
    summary = session.describer.detail(7).summary
    assert summary.count("illegal data address") == 1
    assert "the address is not allowed" in summary
