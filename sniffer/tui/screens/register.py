"""Provides the register screen: one register's values over time and the frames that carried it."""

from __future__ import annotations

from typing import ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.screen import Screen
from textual.widget import Widget
from textual.widgets import DataTable, Footer, Static

from sniffer.text import plain
from sniffer.tui.render import plot, time_text
from sniffer.tui.watch import Series


class Plot(Widget):
    """A block-character plot of a series' numeric values."""

    COMPONENT_CLASSES: ClassVar[set[str]] = {"plot--line", "plot--dim"}

    def __init__(self, points: list[tuple[float, float]], *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.points = points

    def render(self) -> Text:
        styles = {
            "plot": self.get_component_rich_style("plot--line", partial=True),
            "dim": self.get_component_rich_style("plot--dim", partial=True),
        }
        return plot(self.points, self.size.width, self.size.height, styles)


class RegisterScreen(Screen[int | None]):
    """Dismissed with the row to jump to (Enter on a frame), or None (Esc)."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape,q", "close", "back", priority=True),
        Binding("enter", "jump", "go to frame"),
    ]

    def __init__(
        self, series: Series, origin: float, absolute: bool, scanned: float | None = None
    ) -> None:
        """`scanned`: how much of the capture the watch had read (None: all of it)."""
        super().__init__()
        self.scanned = scanned
        self.series = series
        self.origin = origin
        self.absolute = absolute

    def compose(self) -> ComposeResult:
        s = self.series
        title = Text(f"u{s.key[0]} ", "bold")
        title.append(plain(s.label, 40) + "  ")
        title.append(plain(s.name, 80))
        if s.unit_text:
            title.append(f" [{plain(s.unit_text, 16)}]")
        latest = s.latest
        title.append("\n")
        if self.scanned is not None:
            title.append(f"PARTIAL: {self.scanned:.0%} of the capture read", "bold reverse")
        if latest is not None:
            title.append("  latest so far: " if self.scanned is not None else "  latest: ")
            title.append(latest.text)
        title.append(f"  ({s.seen} values, {len(s.samples)} kept; plot: min-max, ━ mean)")
        yield Static(title, id="register-title")
        yield Plot(s.numbers(), id="register-plot")
        table: DataTable[Text] = DataTable(id="register-frames", cursor_type="row")
        yield table
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one("#register-frames", DataTable)
        table.add_column(Text("time"), key="time")
        table.add_column(Text("value"), key="value")
        table.add_column(Text("frame"), key="frame")
        for sample in reversed(self.series.samples):
            table.add_row(
                Text(time_text(sample.t, self.origin, self.absolute)),
                Text(sample.text),
                Text(f"#{sample.row}", justify="right"),
                key=str(sample.row),
            )
        table.focus()

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        event.stop()
        self._jump(event.cursor_row)

    def action_jump(self) -> None:
        self._jump(self.query_one("#register-frames", DataTable).cursor_row)

    def _jump(self, k: int) -> None:
        samples = self.series.samples
        if 0 <= k < len(samples):
            self.dismiss(samples[len(samples) - 1 - k].row)

    def action_close(self) -> None:
        self.dismiss(None)
