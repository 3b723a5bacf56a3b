"""Provides the register table screen (`R` in the watch): the registers picked with `x`,
side by side, one row a poll, newest at the bottom. A value that differs from the row
above stands out. Only the rows on screen are drawn."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from rich.text import Text
from textual.binding import Binding, BindingType

from sniffer.text import plain
from sniffer.tui.regtable import PollRow, RegisterTable
from sniffer.tui.render import time_text, time_width
from sniffer.tui.screens.view import RowsWidget, ViewScreen

if TYPE_CHECKING:
    from sniffer.tui.watch import Series

COL_MIN, COL_MAX = 9, 18


class TableView(RowsWidget):
    """The table's header (two lines) and the rows from `top`; `cursor` is a row index."""

    COMPONENT_CLASSES: ClassVar[set[str]] = {
        "table-view--head",
        "table-view--time",
        "table-view--changed",
        "table-view--missing",
        "table-view--cursor",
    }

    def __init__(
        self,
        table: RegisterTable,
        series: list[Series],
        origin: float,
        absolute: bool,
        *,
        id: str | None = None,
    ) -> None:
        super().__init__(id=id)
        self.table = table
        self.series = series
        self.origin = origin
        self.absolute = absolute
        self.cursor = 0
        self.top = 0
        self.following = True
        self.first_column = 0
        self.shown_columns = 0

    def rows(self) -> list[PollRow]:
        with self.table.lock:
            rows = list(self.table.rows)
        return rows

    def widths(self) -> list[int]:
        out = []
        for s in self.series:
            title = max(len(plain(s.name, 60)), len(f"u{s.key[0]} {s.unit_text}"))
            out.append(max(COL_MIN, min(COL_MAX, title)))
        return out

    def render(self) -> Text:
        style = self.get_component_rich_style
        head = style("table-view--head", partial=True)
        changed = style("table-view--changed", partial=True)
        missing = style("table-view--missing", partial=True)
        time_style = style("table-view--time", partial=True)
        cursor_style = style("table-view--cursor", partial=True)
        rows = self.rows()
        width, height = self.size.width, max(1, self.size.height - 2)
        last = rows[-1].t if rows else self.origin
        tw = time_width(last - self.origin, self.absolute)
        widths = self.widths()
        self.first_column = max(0, min(self.first_column, len(widths) - 1))
        cols: list[int] = []
        used = tw
        for n in range(self.first_column, len(widths)):
            if used + 2 + widths[n] > width and cols:
                break
            cols.append(n)
            used += 2 + widths[n]
        self.shown_columns = len(cols)
        out = Text(no_wrap=True, overflow="crop")
        names = Text(" " * tw, style=head)
        units = Text("time".rjust(tw), style=head)
        for n in cols:
            s, w = self.series[n], widths[n]
            name = plain(s.name, 60)
            name = name if len(name) <= w else name[: w - 1] + "…"
            names.append("  " + name.rjust(w), head)
            units.append("  " + f"u{s.key[0]} {plain(s.unit_text, 8)}".strip().rjust(w), head)
        out.append_text(names)
        out.append("\n")
        out.append_text(units)
        if not rows:
            out.append("\n")
            out.append("no poll yet carried these registers", missing)
            return out
        if self.following:
            self.cursor = len(rows) - 1
        self.cursor = max(0, min(self.cursor, len(rows) - 1))
        if self.cursor < self.top:
            self.top = self.cursor
        if self.cursor >= self.top + height:
            self.top = self.cursor - height + 1
        for k in range(self.top, min(len(rows), self.top + height)):
            r = rows[k]
            before = rows[k - 1] if k > 0 else None
            line = Text(no_wrap=True, overflow="crop")
            line.append(time_text(r.t, self.origin, self.absolute).rjust(tw), time_style)
            for n in cols:
                w = widths[n]
                value = r.values[n]
                if value is None:
                    line.append("  " + "·".rjust(w), missing)
                    continue
                text = value if len(value) <= w else value.split(" ")[0]
                text = text if len(text) <= w else "…"  # never a number cut in half
                moved = before is not None and before.values[n] not in (None, value)
                line.append("  " + text.rjust(w), changed if moved else None)
            if k == self.cursor:
                line.pad_right(width - line.cell_len)
                line.stylize(cursor_style)
            out.append("\n")
            out.append_text(line)
        return out

    def move(self, step: int) -> None:
        self.following = False
        self.cursor = max(0, self.cursor + step)
        rows = len(self.table.rows)
        if rows and self.cursor >= rows - 1:
            self.cursor = rows - 1
        self.refresh()

    @property
    def cursor_row(self) -> int | None:
        rows = self.rows()
        return rows[self.cursor].row if 0 <= self.cursor < len(rows) else None


class TableScreen(ViewScreen):
    """Dismissed with the frame of the selected poll (Enter), or None (Esc, q)."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape,q,R", "close", "back", priority=True),
        Binding("enter", "jump", "go to frame", priority=True),
        Binding("up,k", "move(-1)", "up", priority=True),
        Binding("down,j", "move(1)", "down", priority=True),
        Binding("pageup", "page(-1)", "page up", priority=True),
        Binding("pagedown", "page(1)", "page down", priority=True),
        Binding("home", "first", "first", priority=True),
        Binding("end,f", "end", "follow", priority=True),
        Binding("left,h", "columns(-1)", "left", priority=True),
        Binding("right,l", "columns(1)", "right", priority=True),
    ]

    HINTS: ClassVar[tuple[tuple[str, str], ...]] = (
        ("↑↓ PgUp PgDn", "move"),
        ("←→", "columns"),
        ("End/f", "follow"),
        ("⏎", "to frame"),
        ("esc", "back"),
    )

    def __init__(
        self, table: RegisterTable, series: list[Series], origin: float, absolute: bool
    ) -> None:
        self.table = table
        self.view = TableView(table, series, origin, absolute, id="table")
        self.scanned: float | None = 0.0
        super().__init__(self.view, id="table-screen")

    def progress(self, scanned: float | None) -> None:
        """How much of the capture the table has read (None: all of it)."""
        self.scanned = scanned
        self.update_title()
        self.view.refresh()

    def update_title(self) -> None:
        table, view = self.table, self.view
        title = Text("register table", "bold")
        title.append(f"  {len(table.keys)} registers, {len(table.rows):,} polls")
        if table.dropped:
            title.append(f" (the oldest {table.dropped:,} let go)")
        hidden = len(table.keys) - view.shown_columns
        if view.shown_columns and hidden > 0:
            title.append(f"  {hidden} more: ←→")
        if self.scanned is not None:
            title.append("  ")
            title.append(f"PARTIAL: {self.scanned:.0%} read", "bold reverse")
        self.title_bar.update(title)

    def action_page(self, step: int) -> None:
        self.view.move(step * max(1, self.view.size.height - 3))

    def action_first(self) -> None:
        self.view.following = False
        self.view.cursor = 0
        self.view.refresh()

    def action_end(self) -> None:
        self.view.following = True
        self.view.refresh()

    def action_columns(self, step: int) -> None:
        self.view.first_column = max(0, self.view.first_column + step)
        self.view.refresh()
        self.call_after_refresh(self.update_title)
