"""Provides the shell of the full-screen views (the ladder, the register table): a title,
the view, the state line and the key line, and the keys every such view shares."""

from __future__ import annotations

from typing import ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.screen import Screen
from textual.widget import Widget
from textual.widgets import Static

from sniffer.tui.widgets.keybar import key_hints
from sniffer.tui.widgets.status import StatusBar


class RowsWidget(Widget, can_focus=True):
    """A view whose lines stand for rows of the capture, with a cursor on one of them."""

    @property
    def cursor_row(self) -> int | None:
        """The capture row under the cursor, if any."""
        raise NotImplementedError

    def move(self, step: int) -> None:
        raise NotImplementedError


class ViewScreen(Screen[int | None]):
    """A view of rows over the whole screen. Closing gives None; Enter gives the row under
    the cursor, for the list to go to. Subclasses set `HINTS` (the key line) and write
    `update_title`."""

    HINTS: ClassVar[tuple[tuple[str, str], ...]] = ()

    def __init__(self, view: RowsWidget, *, id: str) -> None:
        super().__init__(id=id)
        self.rows_view = view
        self.title_bar = Static(Text(""), classes="view-title")
        self.status = StatusBar(classes="view-status")
        self.keys = Static(Text(""), classes="view-keys")

    def compose(self) -> ComposeResult:
        yield self.title_bar
        yield self.rows_view
        yield self.status
        yield self.keys

    def on_mount(self) -> None:
        self.rows_view.focus()
        self.update_title()
        self.keys.update(key_hints(self.HINTS))

    def update_title(self) -> None:
        raise NotImplementedError

    def action_close(self) -> None:
        self.dismiss(None)

    def action_jump(self) -> None:
        self.dismiss(self.rows_view.cursor_row)

    def action_move(self, step: int) -> None:
        self.rows_view.move(step)
