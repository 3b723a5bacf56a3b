"""Provides the main screen: filter bar, frame list, lower pane (details, units, watch), status."""

from __future__ import annotations

from typing import ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal
from textual.screen import Screen
from textual.widgets import ContentSwitcher, Footer, Input, Static

from sniffer.tui.model import ViewModel
from sniffer.tui.widgets.detail import DetailPane
from sniffer.tui.widgets.frame_list import FrameList, ListHeader
from sniffer.tui.widgets.status import StatusBar
from sniffer.tui.widgets.units import UnitsPanel
from sniffer.tui.widgets.watch import WatchPanel

FILTER_HINT = 'unit:3 fc:3 status:timeout reg:"Under Voltage" t:10-20 text'


class MainScreen(Screen[None]):
    """The analyser's screen; its keys call the app's actions (shown in the footer)."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("question_mark", "app.help", "help"),
        Binding("q", "app.quit", "quit"),
        Binding("slash", "app.edit_filter", "filter"),
        Binding("exclamation_mark", "app.problems", "problems"),
        Binding("t", "app.transactions", "txn"),
        Binding("p", "app.partner", "pair"),
        Binding("g", "app.go_to", "go to"),
        Binding("e", "app.export", "export"),
        Binding("r", "app.record", "record"),
        Binding("u", "app.pane('units')", "units"),
        Binding("w", "app.pane('watch')", "watch"),
        Binding("d", "app.pane('detail')", "detail"),
        Binding("space", "app.pause", "pause"),
        Binding("s", "app.speed", "speed"),
        Binding("f", "app.follow", "follow", show=False),
        Binding("a", "app.absolute", "time", show=False),
        Binding("z", "app.zoom", "zoom", show=False),
        Binding("enter", "app.fields", "fields", show=False),
        Binding("escape", "app.to_list", "back", show=False),
    ]

    def __init__(self, model: ViewModel, *, blink: bool = True) -> None:
        super().__init__(id="main")
        self.model = model
        self.blink = blink
        # the widgets, made once: the app reaches them directly (no queries), which also
        # keeps late messages harmless while the app is being torn down
        self.filter_bar = Horizontal(id="filter-bar")
        self.filter_input = Input(placeholder=FILTER_HINT, id="filter")
        self.filter_info = Static(Text(""), id="filter-info")
        self.header = ListHeader(id="list-header")
        self.frames = FrameList(model, id="frames")
        self.lower = ContentSwitcher(initial="detail", id="lower")
        self.detail = DetailPane(id="detail")
        self.units = UnitsPanel(id="units")
        self.watch_panel = WatchPanel(id="watch")
        self.status = StatusBar(id="status")

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
        yield self.status
        yield Footer()

    @property
    def alive(self) -> bool:
        """Whether the widgets are on screen (not yet, or no longer, while tearing down)."""
        return self.is_attached and self.frames.is_attached and self.status.is_attached

    def on_mount(self) -> None:
        self.filter_input.cursor_blink = self.blink
