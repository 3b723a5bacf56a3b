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

    def compose(self) -> ComposeResult:
        with Horizontal(id="filter-bar"):
            yield Static(Text("filter"), id="filter-label")
            yield Input(placeholder=FILTER_HINT, id="filter")
            yield Static(Text(""), id="filter-info")
        yield ListHeader(id="list-header")
        yield FrameList(self.model, id="frames")
        with ContentSwitcher(initial="detail", id="lower"):
            yield DetailPane(id="detail")
            yield UnitsPanel(id="units")
            yield WatchPanel(id="watch")
        yield StatusBar(id="status")
        yield Footer()

    def on_mount(self) -> None:
        self.query_one("#filter", Input).cursor_blink = self.blink
