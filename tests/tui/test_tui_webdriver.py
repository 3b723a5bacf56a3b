"""Under `modscope serve` the app's packets reach textual-serve whole.

Textual's WebDriver writes a download's 64 KiB chunks from its input thread and the screen
from the app's thread onto one pipe; a slow reader lets one land inside the other, and the
server then loses its place in the stream (a download cut short). These tests hold the
driver the app chooses to whole packets with the pipe read slowly, as a loaded server
reads it (the plain WebDriver fails the second one: about every chunk is broken)."""

from __future__ import annotations

import asyncio
import os
import sys
import threading
import time
from typing import Any

import pytest
from textual import constants
from textual._binary_encode import load
from textual.drivers import web_driver
from textual.drivers.web_driver import WebDriver

from sniffer.tui.app import ModscopeApp
from sniffer.tui.webdriver import WholeWrites
from tests.support.tui import hostile_session

CHUNK = 70_000  # more than a pipe holds (64 KiB on Linux), as textual-serve's chunks are
CHUNKS = 12
SCREENS = 400


def test_under_textual_serve_the_app_runs_on_the_whole_packet_driver(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(constants, "DRIVER", "textual.drivers.web_driver:WebDriver")
    assert ModscopeApp(hostile_session()).get_driver_class() is WholeWrites
    assert issubclass(WholeWrites, WebDriver)
    monkeypatch.setattr(constants, "DRIVER", None)  # a terminal: Textual's own choice
    assert ModscopeApp(hostile_session()).get_driver_class() is not WholeWrites


def _packets(stream: bytes) -> list[tuple[bytes, bytes]]:
    """The (type, payload) packets of a WebDriver stream, in order, as the server reads."""
    found = []
    at = 0
    while at < len(stream):
        kind, size = stream[at : at + 1], int.from_bytes(stream[at + 1 : at + 5], "big")
        assert kind in (b"D", b"M", b"P"), f"a packet type {kind!r} at byte {at}: out of step"
        found.append((kind, stream[at + 5 : at + 5 + size]))
        at += 5 + size
    assert at == len(stream)
    return found


async def _write_from_two_threads(driver: WebDriver, read: int) -> bytes:
    chunk = bytes(range(256)) * (CHUNK // 256)

    def deliver() -> None:  # as the input thread answers textual-serve's chunk requests
        for _ in range(CHUNKS):
            driver.write_binary_encoded(("deliver_chunk", "key", chunk))

    def draw() -> None:  # as the app's thread updates the screen meanwhile
        for n in range(SCREENS):
            driver.write(f"\x1b[H screen {n} " * 20)
            time.sleep(0.0002)

    writers = [threading.Thread(target=deliver), threading.Thread(target=draw)]
    for w in writers:
        w.start()
    return b"".join(await asyncio.to_thread(_slow_read, read, writers))


def _slow_read(fd: int, writers: list[threading.Thread]) -> list[bytes]:
    got = []
    os.set_blocking(fd, False)
    while True:
        time.sleep(0.0005)
        try:
            got.append(os.read(fd, 8192))
        except BlockingIOError:
            if not any(w.is_alive() for w in writers):
                return got


def test_a_download_and_the_screen_written_at_once_arrive_as_whole_packets(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # (the driver's stdin reader is not started here; under pytest stdin cannot be polled)
    monkeypatch.setattr(web_driver, "InputReader", lambda: None)
    read, write = os.pipe()
    # the driver writes to the process's stdout, as textual-serve's app's is: here a pipe
    monkeypatch.setattr(sys, "__stdout__", open(write, "w", closefd=False))  # noqa: SIM115
    try:

        async def run() -> bytes:
            app: Any = None  # (the driver keeps it; nothing here reaches it)
            return await _write_from_two_threads(WholeWrites(app, size=(80, 24)), read)

        packets = _packets(asyncio.run(run()))
    finally:
        os.close(read)
        os.close(write)
    chunks = [load(p) for k, p in packets if k == b"P"]
    screens = [p for k, p in packets if k == b"D"]
    assert len(chunks) == CHUNKS and len(screens) == SCREENS
    whole = bytes(range(256)) * (CHUNK // 256)
    assert all(c == ("deliver_chunk", "key", whole) for c in chunks)
    assert [s.decode() for s in screens] == [f"\x1b[H screen {n} " * 20 for n in range(SCREENS)]
