"""`modscope serve` safe by default (issue #30, item 1): a visitor with no token, a
WebSocket opened by a page of another origin, and one session past --max-sessions are
refused by a real server (textual-serve, aiohttp) in a subprocess; a served visitor's
export names no path outside the export folder."""

from __future__ import annotations

import asyncio
import json
import os
import re
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from sniffer.cli import serve
from sniffer.tui.rooms import exporting

ROOT = Path(__file__).resolve().parent.parent.parent

aiohttp = pytest.importorskip("aiohttp", reason="the [serve] extra is not installed")
pytest.importorskip("textual_serve", reason="the [serve] extra is not installed")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[str, str]]:
    """A running `modscope serve --max-sessions 1 --export-dir TMP`: (its base URL, the
    token it printed)."""
    port = _free_port()
    env = {k: v for k, v in os.environ.items() if k != serve.TOKEN_ENV}
    env["PYTHONPATH"] = str(ROOT)
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sniffer.cli",
            "serve",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--max-sessions",
            "1",
            "--export-dir",
            str(tmp_path),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
        cwd=tmp_path,
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        found = re.search(r"browsers open (http://\S+)/\?token=(\S+)", line)
        assert found, line
        deadline = time.monotonic() + 20
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert proc.poll() is None, "serve stopped before it listened"
                assert time.monotonic() < deadline, "serve never listened"
                time.sleep(0.2)
        yield found.group(1), found.group(2)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


async def _status(url: str, **kw: object) -> int:
    async with aiohttp.ClientSession() as http, http.get(url, **kw) as r:
        return int(r.status)


async def _ws_status(base: str, origin: str, token: str | None) -> int:
    """The status of a WebSocket handshake to /ws (101 when it opens)."""
    cookies = {serve.COOKIE: token} if token else {}
    async with aiohttp.ClientSession(cookies=cookies) as http:
        try:
            async with http.ws_connect(f"{base}/ws", headers={"Origin": origin}) as ws:
                got = await ws.receive(timeout=30)  # the app's first screen bytes
                assert got.type in (aiohttp.WSMsgType.BINARY, aiohttp.WSMsgType.TEXT)
                return 101
        except aiohttp.WSServerHandshakeError as exc:
            return int(exc.status)


@pytest.mark.slow
def test_serve_checks_token_origin_and_cap(served: tuple[str, str]) -> None:
    base, token = served
    assert len(token) >= 16  # random, printed: not guessable
    assert asyncio.run(_status(f"{base}/")) == 403  # a visitor with no token
    assert asyncio.run(_status(f"{base}/?token=wrong")) == 403
    assert asyncio.run(_status(f"{base}/?token={token}")) == 200
    # a WebSocket with no token, and one from a page of another origin (cross-site)
    assert asyncio.run(_ws_status(base, base, None)) == 403
    assert asyncio.run(_ws_status(base, "http://evil.example", token)) == 403
    assert asyncio.run(_ws_status(base, "http://127.0.0.1:1", token)) == 403

    async def two_sessions() -> tuple[int, int]:
        cookies = {serve.COOKIE: token}
        async with (
            aiohttp.ClientSession(cookies=cookies) as http,
            http.ws_connect(f"{base}/ws", headers={"Origin": base}) as first,
        ):
            await first.receive(timeout=30)
            second = await _ws_status(base, base, token)  # past --max-sessions 1
            return 101, second

    assert asyncio.run(two_sessions()) == (101, 503)


def test_a_served_export_stays_in_the_export_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert (exporting.SERVED_ENV, exporting.EXPORT_DIR_ENV) == (
        serve.SERVED_ENV,
        serve.EXPORT_DIR_ENV,
    )
    monkeypatch.setenv(exporting.SERVED_ENV, "1")
    monkeypatch.delenv(exporting.EXPORT_DIR_ENV, raising=False)
    assert exporting.served_path("rows.csv") == (None, "")  # a download only
    monkeypatch.setenv(exporting.EXPORT_DIR_ENV, str(tmp_path))
    assert exporting.served_path("rows.csv") == (tmp_path / "rows.csv", "")
    (tmp_path / "kept.jsonl").write_text("{}\n")
    for answer in ("/etc/passwd", "../rows.csv", "sub/rows.csv", "~/.bashrc", ".hidden", ""):
        path, why = exporting.served_path(answer)
        assert path is None and why, answer
    path, why = exporting.served_path("kept.jsonl")
    assert path is None and "exists" in why


@pytest.mark.asyncio
async def test_a_served_visitors_export_goes_to_the_folder_and_downloads(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The app as `serve` starts it: a path outside the export folder is refused; a plain
    name is written inside it, never over a file (the download: the served test below)."""
    from sniffer.tui.app import ModscopeApp
    from tests.support.tui import hostile_session, ready
    from tests.tui.test_tui_app import SIZE, wait_said

    folder = tmp_path / "exports"
    folder.mkdir()
    monkeypatch.setenv("HOME", str(tmp_path / "home"))  # (Textual's headless delivery)
    monkeypatch.setenv(exporting.SERVED_ENV, "1")
    monkeypatch.setenv(exporting.EXPORT_DIR_ENV, str(folder))
    outside = tmp_path / "outside.jsonl"
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("e", "ctrl+u", *str(outside), "enter")
        await wait_said(pilot, app, "give a plain file name")
        await pilot.press("e", "ctrl+u", *"rows.jsonl", "enter")
        await wait_said(pilot, app, "wrote")
        await pilot.press("e", "ctrl+u", *"rows.jsonl", "enter")
        await wait_said(pilot, app, "exists in the export folder")
    assert not outside.exists()
    written = (folder / "rows.jsonl").read_text(encoding="utf-8").splitlines()
    assert written and all(json.loads(x)["index"] >= 0 for x in written)


async def _read_until_closed(ws: Any) -> None:
    """Read (and drop) what the app draws; reading answers the server's pings."""
    while not ws.closed:
        got = await ws.receive()
        if got.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED):
            return


async def _export_through_the_browser(base: str, token: str) -> tuple[bytes, int]:
    """As a browser does: open the app, press `e` and Enter (the default name), take the
    download the app offers; (its bytes, the status a visitor without the cookie gets)."""
    cookies = {serve.COOKIE: token}
    async with (
        aiohttp.ClientSession(cookies=cookies) as http,
        http.ws_connect(f"{base}/ws?width=120&height=36", headers={"Origin": base}) as ws,
    ):
        screen = b""
        while b"demo.pcapng" not in screen:  # the status bar names the capture: ready
            got = await ws.receive(timeout=30)
            if got.type == aiohttp.WSMsgType.BINARY:
                screen += got.data
        await ws.send_json(["stdin", "e"])
        await asyncio.sleep(0.5)  # (the prompt opens; its default name is offered)
        await ws.send_json(["stdin", "\r"])
        while True:
            got = await ws.receive(timeout=30)
            if got.type == aiohttp.WSMsgType.TEXT and got.data.startswith('["deliver_file_start"'):
                key = json.loads(got.data)[1]
                break
        # the page goes on reading its WebSocket meanwhile, as a browser does: the server
        # pings it every 15 s and closes an unanswered one, ending the app and cutting
        # the download short (seen on a loaded machine, the download taking over 20 s)
        reading = asyncio.create_task(_read_until_closed(ws))
        try:
            async with http.get(f"{base}/download/{key}") as r:
                assert r.status == 200
                body = await r.read()
        finally:
            reading.cancel()
    async with aiohttp.ClientSession() as stranger, stranger.get(f"{base}/download/{key}") as r:
        return body, int(r.status)


@pytest.mark.slow
def test_an_export_in_the_browser_is_a_download_and_stays_in_the_folder(
    served: tuple[str, str], tmp_path: Path
) -> None:
    base, token = served
    body, stranger = asyncio.run(_export_through_the_browser(base, token))
    kept = (tmp_path / exporting.EXPORT_DEFAULT).read_bytes()
    assert body == kept and kept.count(b"\n") > 10  # the rows, as written in the folder
    assert stranger == 403
