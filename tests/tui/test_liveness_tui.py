"""Liveness in the TUI: with no new frame, only the live clock moving, the units pane
ages and calls the unit SILENT and the status bar turns IDLE (an injected clock); a
capture file's bar never says IDLE."""

from __future__ import annotations

import pytest

from dissectors.checks import with_crc
from sniffer.model import Chunk
from sniffer.session.session import Session
from sniffer.tui.app import ModscopeApp
from sniffer.tui.widgets.status import StatusInfo, status_text
from sniffer.tui.widgets.units import UnitsPanel
from tests.support.live import T0
from tests.support.tui import LINE, FakeLive, screen_text, wait_rows

PERIOD = 0.5  # seconds between the master's polls
POLLS = 10


def polls() -> list[Chunk]:
    """Unit 3 read every PERIOD from T0, each answered 20 ms later; then nothing."""
    out = []
    for k in range(POLLS):
        t = T0 + k * PERIOD
        out.append(Chunk(with_crc(bytes([3, 3, 0, 0, 0, 1])), t))
        out.append(Chunk(with_crc(bytes([3, 3, 2, 0, 42])), t + 0.02))
    return out


LAST = T0 + (POLLS - 1) * PERIOD + 0.02  # the last answer starts here


class ClockedLive(FakeLive):
    """A live source with a clock the test sets, as `LiveCapture.now` gives one."""

    def __init__(self, session: Session) -> None:
        super().__init__(session)
        self.time = T0

    def now(self) -> float:
        return self.time


async def wait_for(pilot: object, app: ModscopeApp, text: str) -> str:
    for _ in range(60):  # the app's tick is every 0.5 s
        shown = screen_text(app)
        if text in shown:
            return shown
        await pilot.pause(0.1)  # type: ignore[attr-defined]
    raise AssertionError(f"{text!r} never shown:\n{screen_text(app)}")


async def unit_row(pilot: object, app: ModscopeApp, state: str) -> dict[str, str]:
    """Unit 3's row in the units pane once its state is `state`. The pane is drawn again
    on the app's tick (every 0.5 s); the status bar also on every batch the feed hands
    over, so it may turn IDLE up to a tick before the pane says SILENT (seen under load)."""
    table = app.main.query_one("#units", UnitsPanel)
    row: dict[str, str] = {}
    for _ in range(60):
        row = dict(zip(table.shown, (str(c) for c in table.get_row("3")), strict=True))
        if row["state"] == state:
            return row
        await pilot.pause(0.1)  # type: ignore[attr-defined]
    raise AssertionError(f"unit 3 never {state}: {row}")


@pytest.mark.asyncio
async def test_the_clock_alone_turns_the_line_idle_and_the_unit_silent() -> None:
    session = Session(LINE, exact_timing=True, source="/dev/ttyUSB0")
    live = ClockedLive(session)
    app = ModscopeApp(session, live=live)
    async with app.run_test(size=(80, 24)) as pilot:
        live.time = LAST + 0.3
        live.waiting.extend(polls())
        await wait_rows(pilot, app, 2 * POLLS)
        await pilot.press("u")
        shown = await wait_for(pilot, app, "LIVE ▼ │ last")
        assert "/dev/ttyUSB0" in shown and "20 fr" in shown and "lost 0B" in shown
        await unit_row(pilot, app, "ok")
        # the master stops: no frame comes, only the clock moves on, past 3 periods
        # (1.5 s) and the 2 s floor
        live.time = LAST + 4.0
        await wait_for(pilot, app, "IDLE ▼ │ last 4.0s")
        assert app.main.query_one("#status").has_class("-idle")
        row = await unit_row(pilot, app, "SILENT")
        assert row["answer"] == "4.0s ago"
        # frames again: live at once
        live.time = LAST + 4.6
        live.waiting.append(Chunk(with_crc(bytes([3, 3, 0, 0, 0, 1])), LAST + 4.5))
        await wait_for(pilot, app, "LIVE ▼ │ last")


@pytest.mark.asyncio
async def test_a_capture_file_is_never_idle_and_counts_to_its_end() -> None:
    session = Session(LINE, exact_timing=True, source="pump.pcapng")
    for chunk in polls():
        session.feed(chunk)
    session.finish()
    live = FakeLive(session)  # no clock: judged like the file it could be
    app = ModscopeApp(session, live=live)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_rows(pilot, app, 2 * POLLS)
        await pilot.press("u")
        await pilot.pause(0.6)
        shown = screen_text(app)
        assert "IDLE" not in shown and "last frame" not in shown
        table = app.main.query_one("#units", UnitsPanel)
        row = dict(zip(table.shown, (str(c) for c in table.get_row("3")), strict=True))
        assert row["state"] == "ok"


@pytest.mark.asyncio
async def test_follow_mark_only_at_the_newest_row() -> None:
    session = Session(LINE, exact_timing=True, source="/dev/ttyUSB0")
    live = ClockedLive(session)
    app = ModscopeApp(session, live=live)
    async with app.run_test(size=(80, 24)) as pilot:
        live.time = LAST + 0.3
        live.waiting.extend(polls())
        await wait_rows(pilot, app, 2 * POLLS)
        await wait_for(pilot, app, "LIVE ▼")
        await pilot.press("up")
        app.status_line.show()
        await pilot.pause()
        assert "▼" not in screen_text(app) and not app.frames.at_newest
        await pilot.press("f")
        app.status_line.show()
        await pilot.pause()
        assert "LIVE ▼" in screen_text(app)


def bar(**kw: object) -> str:
    base: dict[str, object] = {
        "source": "/dev/ttyUSB0",
        "line": "19200 8E1 rtu",
        "rows": 1_562_000,
        "bytes": 24_800_000,
        "errors": 3,
        "rate": 26.1,
        "indexing": False,
        "paused": False,
        "following": True,
        "live": True,
        "liveness": "live",
        "since_frame": 0.2,
    }
    base.update(kw)
    return status_text(StatusInfo(**base), 78).plain  # type: ignore[arg-type]


def test_at_80_columns_the_bar_keeps_state_age_port_rate_frames_and_losses() -> None:
    rec = {"recording": "modscope-20240615-021733.pcapng", "recorded_bytes": 1_234_567}
    assert (
        bar(**rec) == "LIVE ▼ │ last 200ms │ ● rec │ lost 0B │ 1.56M fr │ 26.1 fr/s │ /dev/ttyUSB0"
    )
    assert bar(liveness="idle", since_frame=42.0, following=False, rate=0.0, rows=1500) == (
        "IDLE │ last 42.0s │ lost 0B │ 3 err │ 1,500 fr │ 0.0 fr/s │ /dev/ttyUSB0"
    )
    assert bar(liveness="quiet", since_frame=None, rows=0, rate=None).startswith(
        "QUIET ▼ │ no frame yet │ lost 0B"
    )
    # without a clock to judge by (a capture file), no age and never IDLE
    assert bar(live=False, liveness="", following=False).startswith("REPLAY │ 3 err")
