"""Tests that a copy under tmux says whether it can arrive: a real tmux server (its own
socket, no config file: tmux's defaults) is asked for `set-clipboard`, as the TUI asks
the tmux it runs in."""

from __future__ import annotations

import os
import subprocess
import uuid
from collections.abc import Iterator

import pytest

from sniffer.tui.clipboard import TMUX_FIX, clipboard_note, tmux_clipboard


@pytest.fixture
def tmux_env() -> Iterator[tuple[dict[str, str], list[str]]]:
    """The environment of a program inside a fresh tmux server, and the server's command."""
    tmux = ["tmux", "-L", f"modscope-test-{uuid.uuid4().hex[:8]}", "-f", "/dev/null"]
    subprocess.run([*tmux, "new-session", "-d", "-s", "t", "-x", "80", "-y", "24"], check=True)
    try:
        socket = subprocess.run(
            [*tmux, "display-message", "-p", "#{socket_path},#{pid},0"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        env = {k: v for k, v in os.environ.items() if k != "TMUX"}
        env["TMUX"] = socket
        yield env, tmux
    finally:
        subprocess.run([*tmux, "kill-server"], check=False)


@pytest.mark.needs("tmux")
def test_tmux_by_default_drops_the_copy_and_the_note_says_how_to_enable_it(
    tmux_env: tuple[dict[str, str], list[str]],
) -> None:
    env, tmux = tmux_env
    assert tmux_clipboard(env) == "external"  # tmux's default
    note = clipboard_note(env)
    assert note is not None and "set-clipboard is external" in note and TMUX_FIX in note
    subprocess.run([*tmux, "set-option", "-g", "set-clipboard", "on"], check=True)
    assert tmux_clipboard(env) == "on"
    assert clipboard_note(env) is None


def test_outside_tmux_nothing_is_in_the_way() -> None:
    env = {k: v for k, v in os.environ.items() if k != "TMUX"}
    assert tmux_clipboard(env) is None and clipboard_note(env) is None
