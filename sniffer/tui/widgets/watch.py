"""Provides the register watch panel: latest value, last change and a sparkline per register."""

from __future__ import annotations

from typing import ClassVar

from rich.style import Style
from rich.text import Text
from textual.message import Message
from textual.widgets import DataTable

from sniffer.text import plain
from sniffer.tui.render import ago_text, sparkline
from sniffer.tui.watch import Series, SeriesKey

# fixed widths: columns that grew with whatever was shown first would jump about
COLUMNS = (
    ("unit", 15),
    ("register", 30),
    ("value", 18),
    ("changed", 10),
    ("history", 16),
    ("seen", 7),
)
SPARK_WIDTH = 16


class WatchPanel(DataTable[Text]):
    """One row per named register; Enter opens its plot and frames."""

    COMPONENT_CLASSES: ClassVar[set[str]] = {"watch-panel--spark", "watch-panel--recent"}

    class Open(Message):
        def __init__(self, key: SeriesKey) -> None:
            super().__init__()
            self.key = key

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id, cursor_type="row", zebra_stripes=True)
        self.keys: list[SeriesKey] = []
        self.version = -1

    def on_mount(self) -> None:
        for name, width in COLUMNS:
            self.add_column(Text(name), key=name, width=width)

    def show(self, series: list[Series], now: float, version: int) -> None:
        if version == self.version:
            return
        self.version = version
        keys = [s.key for s in series]
        spark = self.get_component_rich_style("watch-panel--spark", partial=True)
        recent = self.get_component_rich_style("watch-panel--recent", partial=True)
        rows = [self._cells(s, now, spark, recent) for s in series]
        if keys != self.keys:
            cursor = self.cursor_row
            self.clear()
            self.keys = keys
            for s, cells in zip(series, rows, strict=True):
                self.add_row(*cells, key=_key_text(s.key))
            if rows:
                self.move_cursor(row=min(cursor, len(rows) - 1))
            return
        for s, cells in zip(series, rows, strict=True):
            for (name, _), cell in zip(COLUMNS, cells, strict=True):
                self.update_cell(_key_text(s.key), name, cell)

    def _cells(self, s: Series, now: float, spark: Style, recent: Style) -> list[Text]:
        latest = s.latest
        value = latest.text if latest is not None else ""
        changed = "never"
        fresh = False
        if s.changed is not None:
            ago = now - s.changed
            changed = ago_text(ago) + " ago"
            fresh = ago < 5.0
        numbers = [v for _, v in s.numbers()]
        return [
            Text(f"{s.key[0]} " + plain(s.label, 12), no_wrap=True),
            Text(plain(s.name, 30), no_wrap=True),
            Text(plain(value, 18), style=recent if fresh else "", no_wrap=True),
            Text(changed, justify="right"),
            Text(sparkline(numbers, SPARK_WIDTH), style=spark),
            Text(str(s.seen), justify="right"),
        ]

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        k = event.cursor_row
        if 0 <= k < len(self.keys):
            event.stop()
            self.post_message(self.Open(self.keys[k]))


def _key_text(key: SeriesKey) -> str:
    return f"{key[0]}/{key[1]}/{key[2]}/{key[3]}"
