"""Provides the register watch panel: latest value, last change and a sparkline per register."""

from __future__ import annotations

from typing import ClassVar

from rich.style import Style
from rich.text import Text
from textual.message import Message
from textual.widgets import DataTable

from sniffer.text import plain
from sniffer.tui.render import ago_text, fit_columns, sparkline
from sniffer.tui.watch import Series, SeriesKey

# fixed widths: columns that grew with whatever was shown first would jump about
COLUMNS = (
    ("unit", 12),
    ("register", 30),
    ("value", 18),
    ("changed", 10),
    ("history", 16),
    ("values", 7),
)
# what stays when the pane is narrow, most important first; `values` counts the values
# seen (`seen` is an age everywhere: when a unit was last heard)
PRIORITY = ("register", "value", "changed", "unit", "history", "values")
SPARK_WIDTH = 16
# what a wide pane gives the columns beyond their widths above, in this order: the
# device label, the register's name and the value whole first, then a longer history
GROW = (("unit", 24), ("register", 50), ("value", 30), ("history", 80))


def grown(names: list[str], width: int, pad: int = 2) -> dict[str, int]:
    """The widths of the columns `names` in a pane `width` cells wide: each its width in
    COLUMNS, and the room left given out as GROW says (up to each one's most)."""
    widths = {n: w for n, w in COLUMNS if n in names}
    room = width - sum(w + pad for w in widths.values())
    for name, most in GROW:
        if name in widths and room > 0:
            more = min(room, most - widths[name])
            widths[name] += more
            room -= more
    return widths


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
        self.widths: dict[str, int] = dict(COLUMNS)
        self.version = -1
        self.picked: dict[SeriesKey, None] = {}  # picked with x, in the order picked

    def cursor_key(self) -> SeriesKey | None:
        k = self.cursor_row
        return self.keys[k] if 0 <= k < len(self.keys) else None

    def toggle_pick(self, key: SeriesKey) -> bool:
        """Pick `key` for the register table, or unpick it; True if now picked."""
        if key in self.picked:
            del self.picked[key]
        else:
            self.picked[key] = None
        self.version = -1
        self.show(*self.last, version=0)
        return key in self.picked

    def on_mount(self) -> None:
        self.shown: list[str] = []
        self.last: tuple[list[Series], float] = ([], 0.0)
        self._columns(fit_columns(COLUMNS, PRIORITY, 200))

    def _columns(self, names: list[str], width: int = 0) -> None:
        self.clear(columns=True)
        self.keys = []
        self.shown = names
        widths = self.widths = {**dict(COLUMNS), **grown(names, width)}
        for name in names:
            right = name in ("changed", "values")
            self.add_column(
                Text(name, justify="right" if right else "left"), key=name, width=widths[name]
            )

    def on_resize(self) -> None:
        width = self.size.width - 1
        names = fit_columns(COLUMNS, PRIORITY, width)
        if names != self.shown or grown(names, width) != {n: self.widths[n] for n in names}:
            self._columns(names, width)
            self.version = -1
            self.show(*self.last, version=0)

    def show(self, series: list[Series], now: float, version: int) -> None:
        if version == self.version:
            return
        self.version = version
        self.last = (series, now)
        keys = [s.key for s in series]
        spark = self.get_component_rich_style("watch-panel--spark", partial=True)
        recent = self.get_component_rich_style("watch-panel--recent", partial=True)
        names = [name for name, _ in COLUMNS]
        rows = [dict(zip(names, self._cells(s, now, spark, recent), strict=True)) for s in series]
        if keys != self.keys:
            cursor = self.cursor_row
            self.clear()
            self.keys = keys
            for s, cells in zip(series, rows, strict=True):
                self.add_row(*(cells[n] for n in self.shown), key=_key_text(s.key))
            if rows:
                self.move_cursor(row=min(cursor, len(rows) - 1))
            return
        for s, cells in zip(series, rows, strict=True):
            for name in self.shown:
                self.update_cell(_key_text(s.key), name, cells[name])

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
        w = self.widths
        return [
            Text(label_fit(f"{s.key[0]} " + plain(s.label), w["unit"]), no_wrap=True),
            Text(("✓ " if s.key in self.picked else "") + plain(s.name, 60), no_wrap=True),
            Text(value_fit(value, w["value"]), style=recent if fresh else "", no_wrap=True),
            Text(changed, justify="right"),
            Text(sparkline(numbers, w["history"]), style=spark),
            Text(str(s.seen), justify="right"),
        ]

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        k = event.cursor_row
        if 0 <= k < len(self.keys):
            event.stop()
            self.post_message(self.Open(self.keys[k]))


def value_fit(value: str, width: int) -> str:
    """A value in `width` cells, never cut inside its number: a long value loses its
    engineering unit first (`10.0 %` stays whole), then shows `…` alone."""
    text = plain(value, 200)
    if len(text) <= width:
        return text
    number = text.split(" ")[0]
    return number if len(number) <= width else "…"


def label_fit(text: str, width: int) -> str:
    """A unit and its device label in `width` cells, the label shortened with `…`."""
    return text if len(text) <= width else text[: max(1, width - 1)] + "…"


def _key_text(key: SeriesKey) -> str:
    return f"{key[0]}/{key[1]}/{key[2]}/{key[3]}"
