"""Provides the status bar: the state first (LIVE, IDLE, QUIET, REPLAY, PAUSED, INDEXING n%,
RECONNECTING), how long since the last frame (live), the recording and its size, losses,
then errors, frames, rate and the source as room allows.

The parts are laid out in order of importance. When the line is too narrow they are
first shortened, in a fixed order (the recording's name first, then the byte count, the
line settings, the error count, the source's name), so that at 80 columns the state,
the age of the last frame, the port or file, the rate, the frames and the losses stay;
only then are the least important left out whole, so nothing that matters at 2 a.m. is
ever cut off the right edge. The bar's CSS class follows the state, and so does its
colour. `▼` (the list follows the newest row) is shown only while the cursor is on it.
"""

from __future__ import annotations

from dataclasses import dataclass

from rich.cells import cell_len
from rich.text import Text
from textual.widgets import Static

from sniffer.analysis.liveness import age_text
from sniffer.text import plain

SEP = " │ "
STATES = ("live", "idle", "quiet", "replay", "paused", "indexing", "reconnecting", "stopped")


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
    # a live line judged from its clock (`sniffer.analysis.liveness.LineState`): "live",
    # "idle" or "quiet"; "" when there is no clock to judge it by (a capture file)
    liveness: str = ""
    since_frame: float | None = None  # seconds since the last frame, by that clock
    resolution: float = 0.0  # the stamps': an age under it is a bound (`<180ms`)


def size_text(n: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.1f}{unit}"
    return f"{n}B"


def count_text(n: int) -> str:
    """A frame count in at most 6 cells from 100,000 on: `152.3k`, `1.56M`, `2.10G`."""
    if n < 100_000:
        return f"{n:,}"
    for unit, scale in (("G", 1e9), ("M", 1e6)):
        if n >= scale:
            return f"{n / scale:.2f}{unit}"
    return f"{n / 1e3:.1f}k"


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
    if s.live:
        return s.liveness if s.liveness in ("idle", "quiet") else "live"
    return "replay"


def state_text(s: StatusInfo) -> str:
    state = state_of(s)
    if state == "indexing":
        word = "INDEXING" + (f" {s.progress:.0%}" if s.progress is not None else "…")
    else:
        word = state.upper()
    if s.speed and state in ("replay", "paused"):
        word += " " + s.speed
    if s.following and state in ("live", "idle", "quiet", "replay"):
        word += " ▼"  # the list follows the newest row
    return word


def middle_cut(text: str, width: int) -> str:
    """`modscope-2…0615.pcapng`: the start and the end of a long name are kept."""
    if len(text) <= width:
        return text
    head = (width - 1) // 2
    return text[:head] + "…" + text[len(text) - (width - 1 - head) :]


def age_words(s: StatusInfo, short: bool = False) -> str:
    """How long since the live line's last frame, by its clock ("" when not judged)."""
    if not s.live or not s.liveness:
        return ""
    if s.since_frame is None:
        return "no frame yet"
    age = age_text(s.since_frame, s.resolution)
    return f"last {age}" if short else f"last frame {age} ago"


# how far the parts are shortened, in this order, before any is left out
SHORTER = (
    "record-name",  # the recording's name, cut in the middle to 16 cells
    "no-record-name",  # ... then only its size
    "no-bytes",  # the frames without their bytes
    "no-settings",  # the source without the line's settings
    "short-age",  # `last 0.3s` for `last frame 0.3s ago`
    "no-errors",  # the error count left out
    "short-source",  # the port or file cut in the middle to 24 cells
    "shorter-source",  # ... to 16
    "no-record-size",  # `● rec` alone: a recording runs
    "shortest-source",  # the port or file cut to 12 cells (`/dev/ttyUSB0` whole)
    "short-frames",  # `1.56M fr` for `1,562,000 fr` (from 100,000 frames on)
)


def status_parts(s: StatusInfo, level: int = 0) -> list[str]:
    """The bar's parts, most important first, shortened by the first `level` steps of
    SHORTER."""
    cut = set(SHORTER[:level])
    parts: list[str] = [state_text(s)]
    age = age_words(s, "short-age" in cut)
    if age:
        parts.append(age)
    if s.recording:
        size = f" {size_text(s.recorded_bytes)}" if s.recorded_bytes is not None else ""
        if "no-record-size" in cut:
            parts.append("● rec")
        elif "no-record-name" in cut:
            parts.append("● rec" + size)
        else:
            room = 16 if "record-name" in cut else 36
            parts.append("● rec " + middle_cut(plain(s.recording, 200), room) + size)
    if s.losses or s.live:
        parts.append(f"lost {size_text(s.losses)}")
    if s.note:
        parts.append(plain(s.note, 200))
    if "no-errors" not in cut:
        parts.append(f"{s.errors} err")
    frames = f"{count_text(s.rows) if 'short-frames' in cut else f'{s.rows:,}'} fr"
    parts.append(frames if "no-bytes" in cut else f"{frames} {size_text(s.bytes)}")
    if s.rate is not None:
        parts.append(f"{s.rate:.1f} fr/s")
    room = (
        12
        if "shortest-source" in cut
        else 16
        if "shorter-source" in cut
        else 24
        if "short-source" in cut
        else 32
    )
    source = middle_cut(plain(s.source, 200), room)
    parts.append(source if "no-settings" in cut else source + " " + s.line)
    return parts


def _width(parts: list[str]) -> int:
    return sum(cell_len(p) for p in parts) + len(SEP) * (len(parts) - 1)


def status_text(s: StatusInfo, width: int) -> Text:
    """The bar's line: whole parts, most important first, shortened as SHORTER says and
    then as many as fit in `width`."""
    level = 0
    parts = status_parts(s)
    while _width(parts) > width and level < len(SHORTER):
        level += 1
        parts = status_parts(s, level)
    note = plain(s.note, 200) if s.note else None
    shown: list[str] = []
    used = 0
    for n, part in enumerate(parts):
        cost = cell_len(part) + (len(SEP) if shown else 0)
        if used + cost > width:
            if n == 0 or (note is not None and part == note):
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
