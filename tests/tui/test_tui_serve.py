"""`modscope serve` from another machine: the page's scripts connect back to --public-url,
checked with a headless chromium in a network namespace of its own (another "machine")
loading the app from a non-loopback address of this one."""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

from sniffer.cli.serve import public_url
from sniffer.errors import UsageError

ROOT = Path(__file__).resolve().parent.parent.parent
HERE, THERE = "10.213.0.1", "10.213.0.2"  # this machine's address on the link, the browser's


def test_the_public_url_is_the_host_and_port_unless_given() -> None:
    assert public_url("localhost", 8000, None) == "http://localhost:8000"
    assert public_url("10.0.0.5", 80, None) == "http://10.0.0.5"
    assert public_url("fd00::5", 8000, None) == "http://[fd00::5]:8000"
    assert public_url("0.0.0.0", 8000, None) == f"http://{socket.gethostname()}:8000"
    assert public_url("0.0.0.0", 8000, "http://10.0.0.5:9000/") == "http://10.0.0.5:9000"
    assert public_url("::", 8000, "https://scope.example:443") == "https://scope.example:443"


@pytest.mark.parametrize(
    ("url", "what"),
    [
        ("10.0.0.5:8000", "write the address browsers use"),
        ("ftp://10.0.0.5", "write the address browsers use"),
        ("http://", "write the address browsers use"),
        ("http://10.0.0.5:8000/modscope", "give only scheme, host and port"),
    ],
)
def test_a_public_url_that_cannot_work_is_refused(url: str, what: str) -> None:
    with pytest.raises(UsageError, match=what):
        public_url("0.0.0.0", 8000, url)


def _run(*argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(argv, capture_output=True, text=True, timeout=30)


@pytest.fixture
def link() -> Iterator[str]:
    """A veth pair: HERE on this machine, THERE in a new network namespace; yields the
    namespace's name and removes both afterwards."""
    for program in ("ip", "chromium"):
        if shutil.which(program) is None:
            pytest.skip(f"`{program}` is not installed (apt-get install -y {program})")
    tag = f"{os.getpid() % 100000}"
    ns, here, there = f"modscope-{tag}", f"msa{tag}", f"msb{tag}"
    steps = [
        ("ip", "netns", "add", ns),
        ("ip", "link", "add", here, "type", "veth", "peer", "name", there),
        ("ip", "link", "set", there, "netns", ns),
        ("ip", "addr", "add", f"{HERE}/24", "dev", here),
        ("ip", "link", "set", here, "up"),
        ("ip", "netns", "exec", ns, "ip", "addr", "add", f"{THERE}/24", "dev", there),
        ("ip", "netns", "exec", ns, "ip", "link", "set", there, "up"),
        ("ip", "netns", "exec", ns, "ip", "link", "set", "lo", "up"),
    ]
    try:
        for step in steps:
            done = _run(*step)
            if done.returncode != 0:
                pytest.skip(f"cannot make a test network ({' '.join(step)}): {done.stderr.strip()}")
        yield ns
    finally:
        _run("ip", "link", "del", here)
        _run("ip", "netns", "del", ns)


def _free_port(address: str) -> int:
    with socket.socket() as s:
        s.bind((address, 0))
        return int(s.getsockname()[1])


@pytest.mark.peer
@pytest.mark.slow
def test_a_browser_on_another_machine_sees_the_app(link: str) -> None:
    pytest.importorskip("textual_serve", reason="the [serve] extra is not installed")
    port = _free_port(HERE)
    url = f"http://{HERE}:{port}"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MODSCOPE_SERVE_TOKEN": "test-token"}
    # listening on every address, as on a site PC; the page points at the public URL
    server = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sniffer.cli",
            "serve",
            "--host",
            "0.0.0.0",
            "--port",
            str(port),
            "--public-url",
            url,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
        cwd=ROOT,
    )
    try:
        deadline = time.monotonic() + 20
        while True:
            try:
                socket.create_connection((HERE, port), timeout=1).close()
                break
            except OSError:
                assert server.poll() is None, "serve stopped before it listened"
                assert time.monotonic() < deadline, "serve never listened"
                time.sleep(0.2)
        browser = subprocess.run(
            [
                "ip",
                "netns",
                "exec",
                link,
                sys.executable,
                str(ROOT / "tests" / "support" / "tui_browser.py"),
                url + "/?token=test-token",
                "60",
                "REPLAY",
                "demo.pcapng",
                "Pump 1 starter",
            ],
            capture_output=True,
            text=True,
            timeout=120,
            env=env,
        )
        assert browser.returncode == 0, browser.stderr
        seen = json.loads(browser.stdout)
        # the page's websocket went to the public address, not 0.0.0.0 ...
        assert [s.split("?")[0] for s in seen["sockets"]] == [f"ws://{HERE}:{port}/ws"]
        # ... and the browser received the app's screen: its status bar and frames
        assert seen["all_seen"], seen["text"][-2000:]
        assert "#0" in seen["text"] and "Read Holding Registers" in seen["text"]
    finally:
        server.terminate()
        try:
            out, _ = server.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            server.kill()
            out, _ = server.communicate()
    assert f"browsers open {url}" in out
    assert "GET /ws" in out and THERE in out  # the visitor came from the other namespace


@pytest.mark.slow
def test_the_served_page_loads_nothing_from_the_internet() -> None:
    """The page textual-serve gives links a web font on fonts.googleapis.com; served by
    modscope it refers to nothing outside the server (a plant network has no internet)."""
    pytest.importorskip("textual_serve", reason="the [serve] extra is not installed")
    port = _free_port("127.0.0.1")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MODSCOPE_SERVE_TOKEN": "page-test"}
    # a visitor with the token (its cookie kept, as a browser keeps it)
    opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor())
    server = subprocess.Popen(
        [sys.executable, "-m", "sniffer.cli", "serve", "--port", str(port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
        cwd=ROOT,
    )
    try:
        deadline = time.monotonic() + 20
        while True:
            try:
                url = f"http://127.0.0.1:{port}/?token=page-test"
                with opener.open(url, timeout=5) as reply:
                    page = reply.read().decode()
                break
            except OSError:
                assert server.poll() is None, "serve stopped before it listened"
                assert time.monotonic() < deadline, "serve never listened"
                time.sleep(0.2)
    finally:
        server.terminate()
        try:
            server.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            server.kill()
            server.communicate()
    assert "xterm.css" in page and "textual.js" in page  # the page itself, whole
    assert "fonts.googleapis.com" not in page
    here = (f"http://127.0.0.1:{port}/", f"http://localhost:{port}/")
    found = re.findall(r"(?:href|src)=\"(https?://[^\"]+)", page)
    outside = [u for u in found if not u.startswith(here)]
    assert outside == []
