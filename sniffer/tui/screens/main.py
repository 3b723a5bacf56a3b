"""Provides the main screen: filter bar, frame list, lower pane (details, units, watch), status."""

from __future__ import annotations

from typing import ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal
from textual.screen import Screen
from textual.widgets import ContentSwitcher, Static

from sniffer.tui.keys import KEYS
from sniffer.tui.model import ViewModel
from sniffer.tui.widgets.detail import DetailPane
from sniffer.tui.widgets.frame_list import FrameList, ListHeader
from sniffer.tui.widgets.keybar import KeyBar
from sniffer.tui.widgets.prompt import LineInput, PromptBar
from sniffer.tui.widgets.status import StatusBar
from sniffer.tui.widgets.units import UnitsPanel
from sniffer.tui.widgets.watch import WatchPanel

DETAIL_TITLE = "details (D: whole screen)"
FILTER_HINT = "none: / to filter, e.g. unit:3 fc:3 status:timeout"


class MainScreen(Screen[None]):
    """The analyser's screen; its keys call the app's actions (shown in the footer)."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding(k.keys, "app." + k.action, k.text, show=False, priority=True) for k in KEYS
    ]

    def __init__(self, model: ViewModel, *, blink: bool = True) -> None:
        super().__init__(id="main")
        self.model = model
        self.blink = blink
        # the widgets, made once: the app reaches them directly (no queries), which also
        # keeps late messages harmless while the app is being torn down
        self.filter_bar = Horizontal(id="filter-bar")
        self.filter_input = LineInput(placeholder=FILTER_HINT, id="filter")
        self.filter_info = Static(Text(""), id="filter-info")
        self.header = ListHeader(id="list-header")
        self.frames = FrameList(model, id="frames")
        self.lower = ContentSwitcher(initial="detail", id="lower")
        self.detail = DetailPane(id="detail")
        self.units = UnitsPanel(id="units")
        self.watch_panel = WatchPanel(id="watch")
        self.prompt = PromptBar(id="prompt")
        self.status = StatusBar(id="status")
        self.keybar = KeyBar(id="keys")

    def compose(self) -> ComposeResult:
        with self.filter_bar:
            yield Static(Text("filter"), id="filter-label")
            yield self.filter_input
            yield self.filter_info
        yield self.header
        yield self.frames
        with self.lower:
            yield self.detail
            yield self.units
            yield self.watch_panel
        yield self.prompt
        yield self.status
        yield self.keybar

    @property
    def alive(self) -> bool:
        """Whether the widgets are on screen (not yet, or no longer, while tearing down)."""
        return self.is_attached and self.frames.is_attached and self.status.is_attached

    def on_mount(self) -> None:
        self.filter_input.cursor_blink = self.blink
        self.prompt.input.cursor_blink = self.blink
        self.prompt.display = False
        self.lower.border_title = DETAIL_TITLE
