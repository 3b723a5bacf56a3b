"""Provides the sessions and helpers the TUI tests share (this module has no tests of its own).

`hostile_session()` is a small capture built from byte literals: a unit bound to the
RVS-DN dictionary under a label full of markup and escape sequences, register reads and
a write, an exception, a timeout, noise, a bad CRC, and device identification and
Report Server ID answers whose strings are markup. `synthetic_session(n)` is the
polling mix of `sniffer.sources.synth`.
"""

from __future__ import annotations

import html
import re
import time
from collections import deque
from collections.abc import Iterable
from typing import Any

from textual import events
from textual.keys import _character_to_key
from textual.pilot import Pilot

from dissectors.checks import with_crc
from dissectors.dictionary import load_model
from sniffer.meaning.annotate import Binding
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import Session
from sniffer.sources.synth import clean_chunks, polling_frames
from sniffer.tui.app import ModscopeApp

HOSTILE = "[bold red]Pump[/] [@click=app.quit]\x1b[31m"
HOSTILE_SHOWN = "[bold red]Pump[/] [@click=app.quit]\\x1b[31m"  # how it must appear
DEVICE_STRING = b"[/][@click=app.quit][bold red]Acme\x1b]0;owned\x07"
LINE = LineSettings(baud=19200, parity="E", stopbits=1, mode="rtu")


def _frames() -> list[tuple[float, bytes]]:
    def regs(*values: int) -> bytes:
        return b"".join(v.to_bytes(2, "big") for v in values)

    out: list[tuple[float, bytes]] = []
    t = 0.0

    def add(data: bytes, gap: float = 0.02, crc: bool = True) -> None:
        nonlocal t
        out.append((t, with_crc(data) if crc else data))
        t += gap

    add(bytes([3, 4, 0, 0, 0, 4]))  # 0: read 4 input registers
    add(bytes([3, 4, 8]) + regs(1, 98, 415, 0), 0.1)  # 1: Logic Status ... Voltage
    add(bytes([3, 3, 0, 0x0B, 0, 3]))  # 2: read 3 holding registers
    add(bytes([3, 3, 6]) + regs(115, 4, 300), 0.1)  # 3: ... Under Voltage Trip = 300
    add(bytes([3, 6, 0, 0x0D]) + regs(320))  # 4: write Under Voltage Trip = 320
    add(bytes([3, 6, 0, 0x0D]) + regs(320), 0.1)  # 5: echo
    add(bytes([3, 4, 0, 8, 0, 2]))  # 6: read a reserved address
    add(bytes([3, 0x84, 2]), 0.1)  # 7: exception 02
    add(bytes([5, 3, 0, 0, 0, 1]), 0.6)  # 8: no answer: timeout
    add(b"\xde\xad\xbe", 0.1, crc=False)  # 9: noise
    bad = bytearray(with_crc(bytes([3, 4, 0, 0, 0, 4])))
    bad[-1] ^= 0xFF
    add(bytes(bad), 0.1, crc=False)  # 10: bad CRC
    add(bytes([5, 43, 14, 1, 0]))  # 11: read device identification
    ident = bytes([5, 43, 14, 1, 1, 0, 0, 1, 0, len(DEVICE_STRING)]) + DEVICE_STRING
    add(ident, 0.1)  # 12: VendorName = markup
    add(bytes([5, 17]))  # 13: report server id
    add(bytes([5, 17, len(DEVICE_STRING) + 2, 0x42, 0xFF]) + DEVICE_STRING, 0.1)  # 14
    add(bytes([3, 3, 0, 0x0B, 0, 3]))  # 15: read again
    add(bytes([3, 3, 6]) + regs(115, 4, 320), 0.1)  # 16: Under Voltage Trip = 320
    return out


def hostile_chunks() -> list[Chunk]:
    char = LINE.char_time
    return [
        Chunk(raw, t_start=1_700_000_000.0 + t, t_end=1_700_000_000.0 + t + len(raw) * char)
        for t, raw in _frames()
    ]


def hostile_session(label: str = HOSTILE) -> Session:
    bindings = {3: Binding(3, label, load_model("rvs-dn"))}
    session = Session(LINE, bindings=bindings, exact_timing=True, source="hostile.pcapng")
    session.ingest(hostile_chunks())
    return session


def synthetic_session(n: int = 2000, *, seed: int = 1) -> Session:
    line = LineSettings(baud=115200, parity="N", stopbits=1, mode="rtu")
    session = Session(line, exact_timing=True, source="synthetic")
    session.ingest(clean_chunks(polling_frames(n, seed=seed, line=line), line))
    return session


def screen_text(app: Any) -> str:
    """Everything on the app's screen as plain text (from its SVG screenshot)."""
    svg = app.export_screenshot()
    parts = re.findall(r"<text[^>]*>(.*?)</text>", svg, flags=re.S)
    return html.unescape("".join(parts)).replace("\xa0", " ")


def burst(app: Any, keys: Iterable[str]) -> None:
    """Send keys as a terminal delivers a fast typist's line or a paste: all at once, none
    waiting for the one before to be handled (`Pilot.press` waits after every key)."""
    for key in keys:
        name = _character_to_key(key) if len(key) == 1 and not key.isalnum() else key
        char = key if len(key) == 1 else {"enter": "\r", "escape": "\x1b", "space": " "}.get(key)
        if key == "space":
            name = "space"
        event = events.Key(name, char)
        event.set_sender(app)
        app._driver.send_message(event)


async def ready(pilot: Pilot[int], app: ModscopeApp, timeout: float = 20.0) -> None:
    """Wait until the feed has ended and the app has caught up with it."""
    deadline = time.monotonic() + timeout
    while not app.indexed.is_set():
        assert time.monotonic() < deadline, "the feed did not end"
        await pilot.pause(0.02)
    await settle(pilot, app)


async def settle(pilot: Pilot[int], app: ModscopeApp, timeout: float = 20.0) -> None:
    """Wait for filter workers to finish and the screen to update."""
    deadline = time.monotonic() + timeout
    job = app.model.job
    while job is not None and not (job.caught_up and job.upto >= app.model.shown):
        assert time.monotonic() < deadline, "the filter did not finish"
        await pilot.pause(0.02)
        job = app.model.job
    await pilot.pause()
    await pilot.pause()


class FakeLive:
    """Feeds chunks handed to it by the test, as `sniffer.live.engine.LiveCapture.pump` does."""

    def __init__(self, session: Session) -> None:
        self.session = session
        self.waiting: deque[Chunk] = deque()
        self.messages: deque[str] = deque()

    def pump(self, timeout: float = 0.05) -> range:
        start = len(self.session.store)
        if not self.waiting:
            time.sleep(timeout)
        while self.waiting:
            self.session.feed(self.waiting.popleft())
        self.session.idle(time.time() + 2e9)
        return range(start, len(self.session.store))


async def wait_rows(pilot: Pilot[int], app: ModscopeApp, rows: int) -> None:
    deadline = time.monotonic() + 10
    while app.model.published < rows:
        assert time.monotonic() < deadline, f"only {app.model.published} rows"
        await pilot.pause(0.05)
    await pilot.pause()
