"""Tests that a recording is evidence: `r` and `q` ask before they end one, a new file begins
before the old one ends (no read in neither), and leaving says where each one is.

A real `LiveCapture` reads a pseudo-terminal (`VirtualBus`) that a thread keeps writing
numbered Write Register requests to; the files are read back as `modscope replay` does.
"""

from __future__ import annotations

import asyncio
import os
import threading
import time
from pathlib import Path

import pytest
from textual.pilot import Pilot

from dissectors.checks import with_crc
from sniffer.live.engine import LiveCapture
from sniffer.live.port import LiveReader, PortSpec
from sniffer.live.recorder import Recorder
from sniffer.model import LineSettings
from sniffer.session.session import Session, replay_file
from sniffer.tui.app import ModscopeApp
from sniffer.tui.widgets.status import size_text
from tests.support.tui import burst, screen_text
from tests.support.virtual_bus import VirtualBus

pytestmark = pytest.mark.asyncio
LINE = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
SIZE = (80, 24)


def request(n: int) -> bytes:
    """Write Single Register to unit 3, register 0x000D, value n: the frames are numbered."""
    return with_crc(bytes([3, 6, 0, 0x0D]) + (n & 0xFFFF).to_bytes(2, "big"))


class Master(threading.Thread):
    """Writes numbered requests onto the bus, one every 8 ms, until stopped."""

    def __init__(self, bus: VirtualBus) -> None:
        super().__init__(daemon=True)
        self.bus = bus
        self.sent = 0
        self.halt = threading.Event()

    def run(self) -> None:
        while not self.halt.is_set():
            self.bus.inject(request(self.sent), source="master")
            self.sent += 1
            time.sleep(0.008)


def numbers(path: Path) -> list[int]:
    """The numbers of the requests a recording holds, framed again from its reads."""
    store = replay_file(path).store
    store.sync()
    found = []
    for i in range(len(store)):
        raw = store.raw(i)
        if len(raw) == 8 and raw[:4] == bytes([3, 6, 0, 0x0D]):
            found.append(int.from_bytes(raw[4:6], "big"))
    return found


async def wait_until(pilot: Pilot[int], what: object, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not callable(what) or not what():
        assert time.monotonic() < deadline, "waited in vain"
        await pilot.pause(0.05)


async def test_r_and_q_ask_first_and_a_new_file_begins_before_the_old_one_ends(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    first, second = tmp_path / "rec.pcapng", tmp_path / "next.pcapng"
    monkeypatch.chdir(tmp_path)  # a short name to type: each key redraws the live screen
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        spec = PortSpec(str(tap), LINE)
        session = Session(LINE, exact_timing=False, source=str(tap))
        live = LiveCapture(LiveReader([spec]), session, recorder=Recorder(first, [spec]))
        live.start()
        master = Master(bus)
        master.start()
        app = ModscopeApp(session, live=live)
        try:
            async with app.run_test(size=SIZE) as pilot:
                await wait_until(pilot, lambda: app.model.published > 20)
                # keys as a terminal delivers them: `Pilot.press` would also wait for the
                # animations live traffic keeps starting, about 1 s a key at 125 frames/s
                burst(app, ["r"])  # a stray r: it asks, the recording goes on
                await wait_until(pilot, lambda: app.main.prompt.confirming)
                assert "r stops it" in screen_text(app)
                burst(app, ["x"])
                await wait_until(pilot, lambda: not app.main.prompt.confirming)
                assert live.recorder is not None and live.recorder.path == first
                recording = live.recorder
                # r n, then a new name typed slowly: the old file records meanwhile
                burst(app, ["r", "n"])
                await wait_until(pilot, lambda: app.main.prompt.open)
                app.main.prompt.input.value = ""
                # typed as a person types, 10 ms apart
                for char in second.name:
                    burst(app, [char])
                    await asyncio.sleep(0.01)
                await wait_until(pilot, lambda: app.main.prompt.input.value == second.name)
                typed_at = master.sent
                burst(app, ["enter"])
                await wait_until(pilot, lambda: live.recorder is not recording)
                assert live.recorder is not None
                assert Path(live.recorder.path).resolve() == second
                assert any(f"ended: {first}" in said for said in app.said)
                await wait_until(pilot, lambda: master.sent > typed_at + 20)
                burst(app, ["q"])  # asks; any other key keeps going
                await wait_until(pilot, lambda: app.main.prompt.confirming)
                assert app.is_running
                assert "q again quits" in screen_text(app)
                burst(app, ["j"])
                await wait_until(pilot, lambda: not app.main.prompt.confirming)
                assert app.is_running and Path(live.recorder.path).resolve() == second
                burst(app, ["q", "q"])
                await wait_until(pilot, lambda: not app.is_running)
        finally:
            master.halt.set()
            master.join()
            live.stop()
    assert app.return_value == 0
    old, new = numbers(first), numbers(second)
    # every request from the first file's first to the second file's last is in one of them
    assert old and new and old[-1] >= typed_at - 5  # the old file ran while the name was typed
    assert new[0] <= old[-1] + 1, f"a gap: {old[-1]} then {new[0]}"
    assert sorted(set(old) | set(new)) == list(range(old[0], new[-1] + 1))
    report = app.recording.report()
    assert len(report) == 2
    for line, path in zip(report, (first, second), strict=True):
        assert f"recorded {path.absolute()}: {size_text(os.stat(path).st_size)}" in line
        assert " frames (" in line and " reads)" in line


async def test_quitting_without_a_recording_asks_nothing(tmp_path: Path) -> None:
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        spec = PortSpec(str(tap), LINE)
        session = Session(LINE, source=str(tap))
        live = LiveCapture(LiveReader([spec]), session)
        live.start()
        app = ModscopeApp(session, live=live)
        try:
            async with app.run_test(size=SIZE) as pilot:
                await pilot.press("q")
                await wait_until(pilot, lambda: not app.is_running)
        finally:
            live.stop()
    assert app.recording.report() == []


async def test_ctrl_q_over_the_ladder_asks_on_the_main_screen(tmp_path: Path) -> None:
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        spec = PortSpec(str(tap), LINE)
        session = Session(LINE, source=str(tap))
        live = LiveCapture(
            LiveReader([spec]), session, recorder=Recorder(tmp_path / "r.pcapng", [spec])
        )
        live.start()
        app = ModscopeApp(session, live=live)
        try:
            async with app.run_test(size=SIZE) as pilot:
                await pilot.press("l")
                assert app.screen is not app.main
                await pilot.press("ctrl+q")
                await wait_until(pilot, lambda: app.screen is app.main)
                assert app.main.prompt.confirming and app.is_running
                await pilot.press("ctrl+q")
                await wait_until(pilot, lambda: not app.is_running)
        finally:
            live.stop()
