"""The real TUI in a real terminal (tmux at 80x24), typed into at full speed: `send-keys` hands
the whole line to the terminal at once, as a paste or a slow SSH link does."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from sniffer.session.session import DEMO_CAPTURE

ROOT = Path(__file__).resolve().parent.parent.parent
pytestmark = [
    pytest.mark.peer,
    pytest.mark.slow,
    pytest.mark.skipif(
        shutil.which("tmux") is None, reason="tmux is not installed (apt install tmux)"
    ),
    pytest.mark.skipif(not DEMO_CAPTURE.exists(), reason="the demo capture is missing"),
]

Screen = Callable[..., str]


@pytest.fixture
def tui(tmp_path: Path) -> Iterator[tuple[Callable[..., None], Screen]]:
    socket = f"modscope-test-{uuid.uuid4().hex[:8]}"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TERM": "xterm-256color"}
    command = f"cd {tmp_path} && {sys.executable} -m sniffer.cli tui"
    base = ["tmux", "-L", socket]
    subprocess.run(
        [*base, "new-session", "-d", "-s", "t", "-x", "80", "-y", "24", command],
        check=True,
        env=env,
    )

    def keys(*args: str, literal: bool = False) -> None:
        subprocess.run(
            [*base, "send-keys", "-t", "t", *(["-l"] if literal else []), *args], check=True
        )

    def screen(until: str = "", timeout: float = 20.0) -> str:
        deadline = time.monotonic() + timeout
        while True:
            shown = subprocess.run(
                [*base, "capture-pane", "-p", "-t", "t"], capture_output=True, text=True, check=True
            ).stdout
            if until in shown or time.monotonic() > deadline:
                return shown
            time.sleep(0.2)

    try:
        yield keys, screen
    finally:
        subprocess.run([*base, "kill-server"], check=False, capture_output=True)


def test_a_filter_typed_in_one_burst_is_applied(
    tui: tuple[Callable[..., None], Screen], tmp_path: Path
) -> None:
    keys, screen = tui
    assert "REPLAY" in screen(until="REPLAY")
    keys("/unit:3 fc:6", literal=True)
    keys("Enter")
    shown = screen(until="4 of 1,562")
    lines = shown.splitlines()
    assert "unit:3 fc:6" in lines[0] and "4 of 1,562" in lines[0], shown
    assert "transactions" not in lines[0] and "M<>S" not in shown  # the `t` was typed, not a key
    assert "Write Register" in lines[2]
    assert lines[-3].startswith(" REPLAY")  # the state leads the status bar


def test_an_export_typed_in_one_burst_writes_only_the_named_file(
    tui: tuple[Callable[..., None], Screen], tmp_path: Path
) -> None:
    keys, screen = tui
    screen(until="REPLAY")
    keys("erows.csv", literal=True)
    keys("Enter")
    screen(until="wrote 1,562 rows")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rows.csv"]
    keys("g#1200", literal=True)
    keys("Enter", "j", "j")
    shown = screen(until="#1202 ")
    assert "#1202 " in shown, shown
