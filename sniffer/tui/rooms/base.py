"""Provides `Room`, what every room of the TUI app starts from (see `sniffer.tui.rooms`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from textual.widget import Widget

from sniffer.tui.model import ViewModel
from sniffer.tui.screens.main import MainScreen
from sniffer.tui.widgets.frame_list import FrameList

if TYPE_CHECKING:  # the app imports the rooms: only the type checker reads this one
    from sniffer.tui.app import ModscopeApp


class Room:
    """A part of the app's behaviour with its own state; the shared state stays on the App
    (read through it every time: a restart replaces the session and the model)."""

    def __init__(self, app: ModscopeApp) -> None:
        self.app = app

    @property
    def main(self) -> MainScreen:
        return self.app.main

    @property
    def model(self) -> ViewModel:
        return self.app.model

    @property
    def frames(self) -> FrameList:
        return self.app.main.frames


def focus_now(widget: Widget) -> None:
    """Focus `widget` now, not after the keys already queued (`Widget.focus` waits)."""
    widget.screen.set_focus(widget)
