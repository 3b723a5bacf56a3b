"""Liveness in the TUI on a live virtual line: a real `LiveCapture` on a pty of the
virtual RS-485 bus, a master that polls unit 1 and then stops. With no new frame, the
port's clock alone turns the status bar IDLE and the unit SILENT in the units pane."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
from textual.pilot import Pilot

from sniffer.live.engine import LiveCapture
from sniffer.live.port import LiveReader, PortSpec
from sniffer.session.session import Session
from sniffer.tui.app import ModscopeApp
from sniffer.tui.widgets.units import UnitsPanel
from tests.live.test_live import LINE, answer, req
from tests.support.tui import screen_text
from tests.support.virtual_bus import VirtualBus

PERIOD = 0.1
POLLS = 15


def unit_row(app: ModscopeApp, unit: str) -> dict[str, str]:
    table = app.main.query_one("#units", UnitsPanel)
    return dict(zip(table.shown, (str(c) for c in table.get_row(unit)), strict=True))


async def until(pilot: Pilot[int], check: object, what: str, app: ModscopeApp) -> None:
    end = time.monotonic() + 20
    while time.monotonic() < end:
        if check():  # type: ignore[operator]
            return
        await pilot.pause(0.1)
    raise AssertionError(f"{what} never came:\n{screen_text(app)}")


@pytest.mark.asyncio
async def test_a_stopped_master_turns_the_tui_idle_and_silent(tmp_path: Path) -> None:
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        session = Session(LINE, timeout=0.05, source=str(tap))
        capture = LiveCapture(LiveReader([PortSpec(str(tap), LINE)]), session)
        capture.start()
        app = ModscopeApp(session, live=capture)

        def master() -> None:
            for _ in range(POLLS):
                bus.inject(req(1, 3, 0, 2), source="master")
                time.sleep(0.01)
                bus.inject(answer(1, 3, [7, 8]), source="master")
                time.sleep(PERIOD - 0.01)

        try:
            async with app.run_test(size=(80, 24)) as pilot:
                await pilot.press("u")
                polling = threading.Thread(target=master)
                polling.start()
                await until(
                    pilot, lambda: "LIVE ▼ │ last" in screen_text(app), "LIVE while polling", app
                )
                polling.join()
                await until(
                    pilot,
                    lambda: app.model.published == 2 * POLLS,
                    "every frame",
                    app,
                )
                await until(pilot, lambda: "IDLE" in screen_text(app), "IDLE", app)
                assert app.main.status.has_class("-idle")
                await until(pilot, lambda: unit_row(app, "1")["state"] == "SILENT", "SILENT", app)
                row = unit_row(app, "1")
                assert row["answer"].endswith("s ago") and row["period"].endswith("ms")
                # no new frame came: the clock alone did it
                assert app.model.published == len(session.store) == 2 * POLLS
        finally:
            capture.stop()
