"""The health screen (`H`): the bus doctor's findings in the TUI, the same as `modscope
doctor` gives, on a replayed capture and as rows arrive."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest
from textual.pilot import Pilot

from sniffer.analysis.doctor import diagnose
from sniffer.model import Chunk
from sniffer.session.session import Session, open_session
from sniffer.sources import ReadOptions
from sniffer.tui.app import ModscopeApp
from sniffer.tui.widgets.health import HealthScreen
from tests.analysis.test_doctor_bus import LINE, read_ans, read_req

DOCTOR = Path(__file__).resolve().parents[2] / "tests" / "captures" / "doctor"


async def _all_shown(pilot: Pilot[Any]) -> None:
    app = pilot.app
    assert isinstance(app, ModscopeApp)
    deadline = time.monotonic() + 30
    while not app.indexed.is_set() or app.model.published < len(app.session.store):
        assert time.monotonic() < deadline
        await pilot.pause(0.05)


@pytest.mark.asyncio
async def test_h_shows_the_findings_the_command_gives() -> None:
    session, capture = open_session(
        DOCTOR / "silent-unit.csv", ReadOptions(baud=19200), index=False
    )
    app = ModscopeApp(session, capture, blink=False)
    async with app.run_test(size=(120, 36)) as pilot:
        await _all_shown(pilot)
        await pilot.press("H")
        await pilot.pause(0.2)
        screen = app.screen
        assert isinstance(screen, HealthScreen)
        assert screen.diagnosis is not None
        kinds = [(f.kind, f.units) for f in screen.diagnosis.findings]
        assert kinds == [("silent-unit", (7,))]
        # the same as the command's analysis of the whole capture
        whole = diagnose(session.store, session.line, session.pipeline.pairer.timeout)
        assert [f.record() for f in whole.findings] == [
            f.record() for f in screen.diagnosis.findings
        ]
        assert "ERROR silent-unit [unit 7]" in screen.text
        assert "1 errors" in str(screen.title_bar.render())
        await pilot.press("escape")
        await pilot.pause()
        assert app.screen is app.main


@pytest.mark.asyncio
async def test_the_screen_follows_new_rows() -> None:
    """Live: rows arrive while the screen is open; a unit that stops answering shows up."""
    session = Session(LINE)
    app = ModscopeApp(session, blink=False)
    t = 1_700_000_000.0
    char = LINE.char_time

    def feed(unit: int, answered: bool) -> None:
        nonlocal t
        req = read_req(unit, 3, 0, 2)
        session.feed(Chunk(req, t + len(req) * char, t_start=t))
        t += len(req) * char + 0.01
        if answered:
            ans = read_ans(unit, 3, [1, 2])
            session.feed(Chunk(ans, t + len(ans) * char, t_start=t))
            t += len(ans) * char
        t += 0.4

    async with app.run_test(size=(120, 36)) as pilot:
        for _ in range(5):
            feed(1, True)
        session.refresh()
        app.model.published = len(session.store)
        await pilot.press("H")
        await pilot.pause(0.2)
        screen = app.screen
        assert isinstance(screen, HealthScreen)
        assert screen.diagnosis is not None and screen.diagnosis.findings == ()
        for _ in range(5):
            feed(9, False)
            feed(1, True)
        session.refresh()
        app.model.published = len(session.store)
        await pilot.pause(1.5)  # (the screen looks again once a second)
        later = screen.diagnosis
        assert later is not None
        assert [(f.kind, f.units) for f in later.findings] == [("silent-unit", (9,))]
