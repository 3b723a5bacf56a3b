"""Provides the ladder screen (`l`): master and slaves as columns, transactions as arrows
down the time axis, the picture drawn on a whiteboard when a bus misbehaves.

It shows the rows of the frame list (its filter applies) from the selected one; only
the lines on screen are built. `Enter` goes back to the list at the selected row.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from rich.text import Text
from textual.binding import Binding, BindingType

from sniffer.tui.ladder import (
    Ladder,
    LadderLine,
    Lanes,
    exact,
    lane_header,
    lanes_for,
    pick_scale,
    scale_text,
)
from sniffer.tui.render import Styles, time_width
from sniffer.tui.screens.view import RowsWidget, ViewScreen

if TYPE_CHECKING:
    from sniffer.tui.model import ViewModel

STYLE_NAMES = (
    "time",
    "rail",
    "head",
    "request",
    "answer",
    "latency",
    "unit",
    "dim",
    "noise",
    "event",
    "check",
    "timeout",
    "exception",
    "orphan",
    "problem",
    "cursor",
)
SCALE_STEPS = (0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)


class LadderView(RowsWidget):
    """The ladder's lines from `top` (a view position); `cursor` is a view position."""

    COMPONENT_CLASSES: ClassVar[set[str]] = {f"ladder--{n}" for n in STYLE_NAMES}

    def __init__(self, model: ViewModel, cursor: int, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.model = model
        self.cursor = cursor
        self.top = cursor
        self.following = False
        reader = model.reader
        lo = max(0, cursor - 100)
        sample = [model.view.row(k) for k in range(lo, min(model.view.count, lo + 200))]
        self.scale: float | None = pick_scale(reader, sample) if exact(reader) else None
        self.lanes: Lanes | None = None

    def styles_map(self) -> Styles:
        return {n: self.get_component_rich_style(f"ladder--{n}", partial=True) for n in STYLE_NAMES}

    def units(self) -> list[int]:
        """The slaves, in address order: those the session has seen (not broadcast)."""
        stats = self.model.session.stats
        return sorted(u for u in list(stats.units) if u != 0)

    def ladder(self) -> Ladder:
        model = self.model
        describer = model.describer

        def summary(row: int) -> str:
            return describer.detail(row).summary

        return Ladder(
            model.reader,
            model.view,
            origin=model.origin,
            absolute=model.absolute,
            scale=self.scale,
            summary=summary,
        )

    def render(self) -> Text:
        model = self.model
        width, height = self.size.width, max(1, self.size.height - 1)
        span = model.latest - model.origin
        tw = time_width(span, model.absolute)
        units = self.units()
        lanes = self.lanes = lanes_for(width, tw, units)
        styles = self.styles_map()
        count = model.view.count
        if count == 0:
            out = lane_header(lanes, styles)
            out.append("\n")
            out.append("no rows: the filter shows none, or nothing was read yet", styles["dim"])
            return out
        if self.following:
            self.cursor = count - 1
        self.cursor = max(0, min(self.cursor, count - 1))
        ladder = self.ladder()
        lines = self._fit(ladder, height, lanes, styles)
        if len(lanes.slaves) < len(units):  # too many for the width: those on screen
            store = model.reader
            here = {store.unit[r] for r in (x.row for x in lines) if r is not None}
            lanes = self.lanes = lanes_for(width, tw, sorted(u for u in here if u in units))
            lines = self._fit(ladder, height, lanes, styles)
        out = lane_header(lanes, styles)
        for line in lines:
            out.append("\n")
            out.append_text(line.text)
        return out

    def _fit(self, ladder: Ladder, height: int, lanes: Lanes, styles: Styles) -> list[LadderLine]:
        view = self.model.view
        cursor_row = view.row(self.cursor)
        if self.top > self.cursor:
            self.top = self.cursor
        if self.following:
            self.top = max(0, self.cursor - height + 1)
        self.top = max(0, min(self.top, view.count - 1))
        for _ in range(4 * height + 4):
            prev = view.row(self.top - 1) if self.top > 0 else None
            lines = ladder.lines(self.top, height, lanes, styles, cursor_row, prev)
            rows = [line.row for line in lines if line.row is not None]
            if cursor_row in rows or self.top >= self.cursor:
                return lines
            self.top += 1
        return lines

    def move(self, step: int) -> None:
        self.following = False
        self.cursor = max(0, min(self.cursor + step, self.model.view.count - 1))
        self.refresh()

    def page(self, step: int) -> None:
        self.move(step * max(1, self.size.height - 2))

    def to_end(self) -> None:
        self.following = True
        self.refresh()

    def zoom(self, step: int) -> None:
        if self.scale is None:
            return
        k = min(range(len(SCALE_STEPS)), key=lambda i: abs(SCALE_STEPS[i] - (self.scale or 0)))
        self.scale = SCALE_STEPS[max(0, min(len(SCALE_STEPS) - 1, k + step))]
        self.refresh()

    @property
    def cursor_row(self) -> int | None:
        view = self.model.view
        return view.row(self.cursor) if 0 <= self.cursor < view.count else None


class LadderScreen(ViewScreen):
    """Dismissed with the row to select in the list (Enter), or None (Esc, l, q)."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape,l,q", "close", "back", priority=True),
        Binding("enter", "jump", "go to frame", priority=True),
        Binding("up,k", "move(-1)", "up", priority=True),
        Binding("down,j", "move(1)", "down", priority=True),
        Binding("pageup", "page(-1)", "page up", priority=True),
        Binding("pagedown,space", "page(1)", "page down", priority=True),
        Binding("home", "first", "first", priority=True),
        Binding("end,f", "end", "follow", priority=True),
        Binding("plus,equals_sign", "zoom(-1)", "zoom in", priority=True),
        Binding("minus", "zoom(1)", "zoom out", priority=True),
    ]

    HINTS: ClassVar[tuple[tuple[str, str], ...]] = (
        ("↑↓ PgUp PgDn", "move"),
        ("End/f", "follow"),
        ("+/-", "scale"),
        ("⏎", "to list"),
        ("esc/l", "back"),
    )

    def __init__(self, model: ViewModel, cursor: int, following: bool = False) -> None:
        self.model = model
        self.view = LadderView(model, cursor, id="ladder")
        self.view.following = following
        super().__init__(self.view, id="ladder-screen")

    def update_title(self) -> None:
        view = self.view
        reader = self.model.reader
        title = Text("ladder", "bold")
        if view.scale is not None:
            title.append(f"  a line = {scale_text(view.scale)} (exact times)")
        elif reader.stamps.name == "READ_END" and reader.resolution > 0:
            title.append("  gaps not to scale (host read times)")
        else:
            title.append("  gaps not to scale")
        lanes = view.lanes
        units = view.units()
        if lanes is not None and len(lanes.slaves) < len(units):
            title.append(f"  {len(lanes.slaves)} of {len(units)} units (those on screen)")
        self.title_bar.update(title)

    def refresh_rows(self) -> None:
        """New rows were published (live, indexing) or the filter changed."""
        self.view.refresh()
        self.update_title()

    def action_page(self, step: int) -> None:
        self.view.page(step)

    def action_first(self) -> None:
        self.view.following = False
        self.view.cursor = 0
        self.view.top = 0
        self.view.refresh()

    def action_end(self) -> None:
        self.view.to_end()

    def action_zoom(self, step: int) -> None:
        self.view.zoom(step)
        self.update_title()
