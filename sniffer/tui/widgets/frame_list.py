"""Provides the frame list: a virtual list over the frame store, one row per frame or transaction.

A `ScrollView` with `render_line`: only the lines on screen are described (the
Describer caches what was dissected) and rendered strips are kept in an LRU cache, so
a capture of millions of frames scrolls as fast as a small one. While following, new
rows keep the cursor on the last one; moving up stops following.
"""

from __future__ import annotations

import time
from typing import ClassVar

from rich.style import Style
from rich.text import Text
from textual import events
from textual.binding import Binding, BindingType
from textual.cache import LRUCache
from textual.geometry import Size
from textual.message import Message
from textual.scroll_view import ScrollView
from textual.strip import Strip
from textual.widgets import Static

from sniffer.tui.model import ViewModel
from sniffer.tui.render import (
    ROW_STATES,
    Columns,
    columns_for,
    header_text,
)

_PARTS = ("time", "dim", "unit", "label", "name", *ROW_STATES)


class ListHeader(Static):
    """The column titles above the frame list."""

    def show(self, cols: Columns) -> None:
        self.update(header_text(cols))


class FrameList(ScrollView, can_focus=True):
    """Rows of the view model, with a cursor."""

    COMPONENT_CLASSES: ClassVar[set[str]] = {
        "frame-list--cursor",
        *(f"frame-list--{p}" for p in _PARTS),
    }

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("up,k", "cursor(-1)", "up", show=False),
        Binding("down,j", "cursor(1)", "down", show=False),
        Binding("pageup", "page(-1)", "page up", show=False),
        Binding("pagedown", "page(1)", "page down", show=False),
        Binding("home", "first", "first", show=False),
        Binding("end", "follow", "last", show=False),
    ]

    class CursorMoved(Message):
        """The cursor is on another row (`row` is a store row, None when empty)."""

        def __init__(self, row: int | None) -> None:
            super().__init__()
            self.row = row

        def can_replace(self, message: Message) -> bool:
            return isinstance(message, FrameList.CursorMoved)

    class ColumnsChanged(Message):
        """The columns changed (a resize, a longer capture): the header follows."""

        def __init__(self, cols: Columns) -> None:
            super().__init__()
            self.cols = cols

    class FollowChanged(Message):
        def __init__(self, following: bool) -> None:
            super().__init__()
            self.following = following

    def __init__(self, model: ViewModel, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.model = model
        self.cursor = 0
        self.following = True
        self.anchor_row: int | None = None  # a row to keep the cursor on while rows arrive
        self._strips: LRUCache[tuple[int, int, int], Strip] = LRUCache(1024)
        self._styles: dict[str, Style] | None = None
        self._cols: Columns | None = None
        self._last_row: int | None = None
        self.first_drawn: float | None = None  # perf_counter() when rows were first drawn
        self.drawn_at = 0.0  # perf_counter() when a line was last drawn

    # -- state -----------------------------------------------------------------------------

    @property
    def count(self) -> int:
        return len(self.model.view)

    @property
    def at_newest(self) -> bool:
        """Following with the cursor on the newest row shown: what the status bar's ▼
        says (an empty list, or a cursor left above the end, is not at the newest)."""
        count = self.count
        return self.following and count > 0 and self.cursor >= count - 1

    @property
    def cursor_row(self) -> int | None:
        """The store row under the cursor."""
        if not self.count:
            return None
        return self.model.view.row(min(self.cursor, self.count - 1))

    @property
    def page_height(self) -> int:
        return max(1, self.scrollable_content_region.height)

    def columns(self) -> Columns:
        width = max(20, self.scrollable_content_region.width)
        model = self.model
        span = model.latest - model.origin
        cols = columns_for(width, model.absolute, span, model.published)
        if cols != self._cols:
            self._cols = cols
            self._strips.clear()
            self.post_message(self.ColumnsChanged(cols))
        return cols

    def reset(self) -> None:
        """Forget rendered lines (options, filter or styles changed)."""
        self._strips.clear()
        self._cols = None
        self.refresh()

    def rows_changed(self, keep: int | None = None) -> None:
        """The view has new or other rows: keep the cursor on row `keep` (or the anchor)
        if shown, follow the end while following."""
        count = self.count
        keep = keep if keep is not None else self.anchor_row
        self.virtual_size = Size(self.scrollable_content_region.width, count)
        if self.following and count:
            self._move(count - 1, scroll_end=True)
        elif keep is not None and count:
            self._move(self.model.view.position(keep), center=True)
        elif count:
            self._move(min(self.cursor, count - 1))
        else:
            self.cursor = 0
            self._announce()
        self.refresh()

    def set_following(self, following: bool) -> None:
        self.anchor_row = None
        if following != self.following:
            self.following = following
            self.post_message(self.FollowChanged(following))

    def go_to(self, k: int, *, center: bool = True) -> None:
        """Put the cursor on view position `k` (stops following unless it is the last)."""
        if not self.count:
            return
        k = max(0, min(k, self.count - 1))
        self.set_following(False)
        self._move(k, center=center)

    def go_to_row(self, row: int) -> bool:
        """Put the cursor on store row `row` (or the next shown one); False if none."""
        if not self.count:
            return False
        self.go_to(self.model.view.position(row))
        return True

    def _move(self, k: int, *, center: bool = False, scroll_end: bool = False) -> None:
        old = self.cursor
        self.cursor = k
        height = self.page_height
        top = round(self.scroll_y)
        if scroll_end:
            self.scroll_to(y=max(0, self.count - height), animate=False)
        elif center and not top <= k < top + height:
            self.scroll_to(y=max(0, k - height // 2), animate=False)
        elif k < top:
            self.scroll_to(y=k, animate=False)
        elif k >= top + height:
            self.scroll_to(y=k - height + 1, animate=False)
        self.refresh_lines(old, 1)
        self.refresh_lines(k, 1)
        self._announce()

    def _announce(self) -> None:
        row = self.cursor_row
        if row != self._last_row:
            self._last_row = row
            self.post_message(self.CursorMoved(row))

    # -- actions ---------------------------------------------------------------------------

    def action_cursor(self, step: int) -> None:
        if not self.count:
            return
        k = max(0, min(self.count - 1, self.cursor + step))
        self.set_following(k == self.count - 1 and self.following)
        self._move(k)

    def action_page(self, step: int) -> None:
        if not self.count:
            return
        height = self.page_height
        k = max(0, min(self.count - 1, self.cursor + step * height))
        if step < 0 or k < self.count - 1:
            self.set_following(False)
        top = max(0, min(round(self.scroll_y) + step * height, self.count - height))
        self.scroll_to(y=top, animate=False)
        self._move(k)

    def action_first(self) -> None:
        self.go_to(0)

    def action_follow(self) -> None:
        self.set_following(True)
        if self.count:
            self._move(self.count - 1, scroll_end=True)

    # -- events ----------------------------------------------------------------------------

    def on_resize(self, event: events.Resize) -> None:
        self._cols = None
        self._strips.clear()
        self.virtual_size = Size(self.scrollable_content_region.width, self.count)

    def notify_style_update(self) -> None:
        super().notify_style_update()
        self._styles = None
        self._strips.clear()

    def on_click(self, event: events.Click) -> None:
        offset = event.get_content_offset(self)
        if offset is None:
            return
        k = round(self.scroll_y) + offset.y
        if 0 <= k < self.count:
            self.set_following(False)
            self._move(k)

    def _on_mouse_scroll_up(self, event: events.MouseScrollUp) -> None:
        self.set_following(False)

    # -- rendering -------------------------------------------------------------------------

    def styles_for_rows(self) -> dict[str, Style]:
        if self._styles is None:
            self._styles = {
                p: self.get_component_rich_style(f"frame-list--{p}", partial=True) for p in _PARTS
            }
        return self._styles

    def render_line(self, y: int) -> Strip:
        scroll_y = self.scroll_offset.y
        k = scroll_y + y
        width = self.scrollable_content_region.width
        base = self.rich_style
        if k >= self.count:
            return Strip.blank(width, base)
        self.drawn_at = time.perf_counter()  # any line: a cursor step redraws two
        if y == 0 and self.first_drawn is None:
            self.first_drawn = self.drawn_at
        row = self.model.view.row(k)
        key = (k, row, self.model.reader.status[row])
        strip = self._strips.get(key)
        if strip is None:
            text = self.model.line(k, self.columns(), self.styles_for_rows())
            strip = self._strip(text)
            self._strips[key] = strip
        if k == self.cursor:
            cursor = self.get_component_rich_style("frame-list--cursor", partial=True)
            strip = strip.apply_style(cursor)
            base = base + cursor
        return strip.apply_style(self.rich_style).crop_extend(0, width, base)

    def _strip(self, text: Text) -> Strip:
        segments = list(text.render(self.app.console, end=""))
        return Strip(segments, text.cell_len)
