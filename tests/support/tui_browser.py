"""A headless chromium that loads a page and prints what the page's websockets received.

Run as a script (by tests/tui/test_tui_serve.py, inside a network namespace, so the browser is
on "another machine"): `python tests/support/tui_browser.py URL SECONDS WORD...`. It starts
chromium with a fresh profile and a DevTools port, turns on network events, loads URL,
and collects the text of every websocket frame the page receives until each WORD was
seen or SECONDS passed. It prints one JSON object: the URL of each websocket the page
opened, whether every word was seen, and the text received (ANSI sequences removed).
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import aiohttp

CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--window-size=1280,800",
)
ANSI = re.compile(r"\x1b\[[0-9;?]*[ -/]*[@-~]|\x1b\][^\x07\x1b]*(?:\x07|\x1b\\)|\x1b[()][A-Z0-9]")


async def watch(port: int, url: str, seconds: float, words: list[str]) -> dict[str, Any]:
    async with aiohttp.ClientSession() as http:
        deadline = time.monotonic() + 20
        while True:
            try:
                async with http.get(f"http://127.0.0.1:{port}/json/list") as r:
                    targets = await r.json()
                pages = [t for t in targets if t.get("type") == "page"]
                if pages:
                    break
            except aiohttp.ClientError:
                pass
            if time.monotonic() > deadline:
                raise SystemExit("chromium's DevTools port never answered")
            await asyncio.sleep(0.2)
        sockets: list[str] = []
        received: list[bytes] = []
        async with http.ws_connect(pages[0]["webSocketDebuggerUrl"], max_msg_size=0) as ws:
            await ws.send_json({"id": 1, "method": "Network.enable"})
            await ws.send_json({"id": 2, "method": "Page.navigate", "params": {"url": url}})
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                text = _text(received)
                if all(w in text for w in words):
                    break
                try:
                    msg = await ws.receive(timeout=max(0.1, end - time.monotonic()))
                except TimeoutError:
                    break
                if msg.type != aiohttp.WSMsgType.TEXT:
                    break
                event = json.loads(msg.data)
                method = event.get("method")
                if method == "Network.webSocketCreated":
                    sockets.append(event["params"]["url"])
                elif method == "Network.webSocketFrameReceived":
                    frame = event["params"]["response"]
                    if frame.get("opcode") == 2:  # binary: the terminal's bytes, base64
                        received.append(base64.b64decode(frame["payloadData"]))
    text = _text(received)
    return {"sockets": sockets, "all_seen": all(w in text for w in words), "text": text}


def _text(frames: list[bytes]) -> str:
    return ANSI.sub("", b"".join(frames).decode("utf-8", "replace"))


def stop_group(browser: subprocess.Popen[bytes]) -> None:
    """End chromium and every helper process it started, and wait until all are gone:
    helpers outliving the browser go on writing its profile while it is being removed."""
    group = browser.pid  # start_new_session: the group id is the browser's pid
    for sig, grace in ((signal.SIGTERM, 10.0), (signal.SIGKILL, 5.0)):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(group, sig)
        deadline = time.monotonic() + grace
        while time.monotonic() < deadline:
            browser.poll()  # reap the browser itself, or the group never empties
            try:
                os.killpg(group, 0)
            except ProcessLookupError:
                return
            time.sleep(0.05)


def main() -> int:
    url, seconds, words = sys.argv[1], float(sys.argv[2]), sys.argv[3:]
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise SystemExit("chromium is not installed")
    port = 9333
    with tempfile.TemporaryDirectory(prefix="modscope-chromium-") as profile:
        browser = subprocess.Popen(
            [
                chromium,
                *CHROMIUM_FLAGS,
                f"--user-data-dir={Path(profile)}",
                f"--remote-debugging-port={port}",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,  # its helpers (zygote, renderers) share its group
        )
        try:
            result = asyncio.run(watch(port, url, seconds, words))
        finally:
            stop_group(browser)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
