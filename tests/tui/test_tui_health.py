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


async def _looked(pilot: Pilot[Any], screen: HealthScreen, rows: int) -> None:
    """Wait for the screen's worker to have looked at `rows` rows."""
    deadline = time.monotonic() + 30
    while screen.busy or screen.looked != rows or screen.diagnosis is None:
        assert time.monotonic() < deadline
        await pilot.pause(0.05)


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
        await pilot.pause()
        screen = app.screen
        assert isinstance(screen, HealthScreen)
        await _looked(pilot, screen, app.model.published)
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
        await pilot.pause()
        screen = app.screen
        assert isinstance(screen, HealthScreen)
        await _looked(pilot, screen, app.model.published)
        assert screen.diagnosis is not None and screen.diagnosis.findings == ()
        for _ in range(5):
            feed(9, False)
            feed(1, True)
        session.refresh()
        app.model.published = len(session.store)
        await _looked(pilot, screen, app.model.published)  # (it looks again each second)
        later = screen.diagnosis
        assert later is not None
        assert [(f.kind, f.units) for f in later.findings] == [("silent-unit", (9,))]


@pytest.mark.asyncio
async def test_a_paged_capture_is_diagnosed_whole(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A capture big enough for a sidecar is paged (the session's store then holds only
    its newest segment): the screen reads every row where the list does."""
    from sniffer.session import index
    from tests.analysis.test_doctor_bus import CYCLES, silent_unit

    monkeypatch.setattr(index, "BLOCK", 1024)  # segments of 960 rows, not 61,440
    monkeypatch.setattr(index, "MIN_SIZE", 256 << 10)  # a sidecar from 256 KiB, not 4 MiB

    text = silent_unit().csv()
    header, rows = text.split("\n", 1)
    copies = index.MIN_SIZE // len(rows) + 1
    span = 0.1 + CYCLES * 0.5  # each copy goes on where the one before ended
    lines = [header]
    for k in range(copies):
        for row in rows.splitlines():
            t, rest = row.split(",", 1)
            lines.append(f"{float(t) + k * span:.9f},{rest}")
    big = tmp_path / "big.csv"
    big.write_text("\n".join(lines) + "\n")
    session, capture = open_session(big, ReadOptions(baud=19200))
    app = ModscopeApp(session, capture, blink=False)
    async with app.run_test(size=(120, 36)) as pilot:
        await _all_shown(pilot)
        assert app.model.paged is not None
        assert len(session.store) < app.model.published  # the rest is in the sidecar
        await pilot.press("H")
        await pilot.pause()
        screen = app.screen
        assert isinstance(screen, HealthScreen)
        await _looked(pilot, screen, app.model.published)
        assert screen.diagnosis is not None
        (silent,) = screen.diagnosis.findings
        assert (silent.kind, silent.units) == ("silent-unit", (7,))
        assert silent.evidence["requests"] == copies * CYCLES
