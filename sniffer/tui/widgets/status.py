"""Provides the status bar: the state first (LIVE, REPLAY, PAUSED, INDEXING n%, RECONNECTING), the
recording and its size, losses, then errors, frames, rate and the source as room allows.

The parts are laid out in order of importance and the least important ones are left
out whole when the line is too narrow, so nothing that matters at 2 a.m. is ever cut
off the right edge. The bar's CSS class follows the state, and so does its colour.
"""

from __future__ import annotations

from dataclasses import dataclass

from rich.cells import cell_len
from rich.text import Text
from textual.widgets import Static

from sniffer.text import plain

SEP = " │ "
STATES = ("live", "replay", "paused", "indexing", "reconnecting", "stopped")


@dataclass(frozen=True, slots=True)
class StatusInfo:
    source: str  # file name or port
    line: str  # "19200 8E1 rtu"
    rows: int
    bytes: int
    errors: int
    rate: float | None  # frames per second (live: arriving; replay: of the capture)
    indexing: bool
    paused: bool
    following: bool
    speed: str = ""  # "1x" while replaying at the original speed
    recording: str = ""
    recorded_bytes: int | None = None
    losses: int = 0  # bytes the capture lost
    note: str = ""  # an error that ended the feed
    live: bool = False
    reconnecting: bool = False  # a live port was lost and is being waited for
    progress: float | None = None  # 0..1 while indexing, when it can be told


def size_text(n: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.1f}{unit}"
    return f"{n}B"


def state_of(s: StatusInfo) -> str:
    """The one word the bar starts with, as a CSS class name."""
    if s.note:
        return "stopped"
    if s.reconnecting:
        return "reconnecting"
    if s.paused:
        return "paused"
    if s.indexing:
        return "indexing"
    return "live" if s.live else "replay"


def state_text(s: StatusInfo) -> str:
    state = state_of(s)
    if state == "indexing":
        word = "INDEXING" + (f" {s.progress:.0%}" if s.progress is not None else "…")
    else:
        word = state.upper()
    if s.speed and state in ("replay", "paused"):
        word += " " + s.speed
    if s.following and state in ("live", "replay"):
        word += " ▼"  # the list follows the newest row
    return word


def middle_cut(text: str, width: int) -> str:
    """`modscope-2…0615.pcapng`: the start and the end of a long name are kept."""
    if len(text) <= width:
        return text
    head = (width - 1) // 2
    return text[:head] + "…" + text[len(text) - (width - 1 - head) :]


def status_text(s: StatusInfo, width: int) -> Text:
    """The bar's line: whole parts, most important first, as many as fit in `width`."""
    parts: list[str] = [state_text(s)]
    if s.recording:
        size = f" {size_text(s.recorded_bytes)}" if s.recorded_bytes is not None else ""
        parts.append("● rec " + middle_cut(plain(s.recording, 200), 36) + size)
    if s.losses or s.live:
        parts.append(f"lost {size_text(s.losses)}")
    if s.note:
        parts.append(plain(s.note, 200))
    parts.append(f"{s.errors} err")
    parts.append(f"{s.rows:,} fr {size_text(s.bytes)}")
    if s.rate is not None:
        parts.append(f"{s.rate:.1f} fr/s")
    parts.append(middle_cut(plain(s.source, 60), 32) + " " + s.line)
    shown: list[str] = []
    used = 0
    for n, part in enumerate(parts):
        cost = cell_len(part) + (len(SEP) if shown else 0)
        if used + cost > width:
            if n == 0 or (s.note and part == plain(s.note, 200)):
                shown.append(
                    part[: max(0, width - used - len(SEP))]
                )  # the state, or why it stopped
            continue
        shown.append(part)
        used += cost
    text = Text(SEP.join(shown), no_wrap=True, overflow="crop")
    text.stylize("bold", 0, len(shown[0]))
    text.truncate(width)
    return text


class StatusBar(Static):
    """One line at the bottom; its CSS class (`-live`, `-paused`, ...) is the state."""

    def show(self, info: StatusInfo) -> None:
        state = state_of(info)
        for name in STATES:
            self.set_class(name == state, f"-{name}")
        self.update(status_text(info, max(20, self.size.width - 2)))
