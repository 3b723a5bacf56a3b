"""Provides `clipboard_note`: whether a copy sent as OSC 52 can reach the clipboard here.

The TUI copies by writing an OSC 52 sequence to the terminal; nothing comes back to say
whether it arrived. Inside tmux the sequence goes to tmux, whose `set-clipboard` option
decides: `on` keeps it and passes it to the outer terminal, `external` (the default
since tmux 2.6) and `off` drop what programs inside send. tmux is asked for the option
(a read-only `show-options`), so the TUI says "copied" only where it can be, and says
how to enable it where it cannot. The outer terminal must allow OSC 52 too, which no
program inside can ask; the notice says so.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Mapping

TMUX_FIX = "add 'set -g set-clipboard on' to ~/.tmux.conf, then run 'tmux source ~/.tmux.conf'"


def tmux_clipboard(env: Mapping[str, str]) -> str | None:
    """tmux's `set-clipboard` for the tmux this process runs in; None outside tmux, ''
    when tmux cannot be asked."""
    if not env.get("TMUX"):
        return None
    tmux = shutil.which("tmux")
    if tmux is None:
        return ""
    try:
        done = subprocess.run(
            [tmux, "show-options", "-gv", "set-clipboard"],
            capture_output=True,
            text=True,
            timeout=2,
            env=dict(env),
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return ""
    return done.stdout.strip() if done.returncode == 0 else ""


def clipboard_note(env: Mapping[str, str] | None = None) -> str | None:
    """Why a copy sent now would not reach the clipboard, with the fix; None if nothing
    here stops it (the outer terminal may still refuse OSC 52)."""
    env = os.environ if env is None else env
    setting = tmux_clipboard(env)
    if setting is None or setting == "on":
        return None
    said = f"set-clipboard is {setting}" if setting else "its set-clipboard could not be read"
    return f"inside tmux ({said}) the copy does not reach the clipboard: {TMUX_FIX}"
