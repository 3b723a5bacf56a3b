"""Provides the status bar: source and line settings, frames/s, bytes, errors, recording, losses."""

from __future__ import annotations

from dataclasses import dataclass

from rich.text import Text
from textual.widgets import Static

from sniffer.text import plain


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


def size_text(n: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.1f}{unit}"
    return f"{n}B"


def status_text(s: StatusInfo, width: int) -> Text:
    sep = " │ "
    parts = [plain(s.source, 40) + " " + s.line]
    if s.indexing:
        parts.append(f"indexing… {s.rows:,} frames {size_text(s.bytes)}")
    else:
        parts.append(f"{s.rows:,} frames {size_text(s.bytes)}")
    if s.rate is not None:
        parts.append(f"{s.rate:.1f} fr/s")
    parts.append(f"{s.errors} err")
    if s.losses:
        parts.append(f"lost {size_text(s.losses)}")
    if s.recording:
        size = f" {size_text(s.recorded_bytes)}" if s.recorded_bytes is not None else ""
        parts.append("rec " + plain(s.recording, 40) + size)
    if s.speed:
        parts.append(s.speed)
    if s.paused:
        parts.append("PAUSED")
    elif s.following:
        parts.append("following")
    if s.note:
        parts.append(plain(s.note, 200))
    text = Text(sep.join(parts), no_wrap=True, overflow="ellipsis")
    text.truncate(width, overflow="ellipsis")
    return text


class StatusBar(Static):
    """One line at the bottom; CSS classes show paused, indexing and problems."""

    def show(self, info: StatusInfo) -> None:
        self.set_class(info.paused, "-paused")
        self.set_class(info.indexing, "-indexing")
        self.set_class(bool(info.note), "-error")
        self.update(status_text(info, max(20, self.size.width)))
