"""Provides the health screen (`H`): the bus doctor's findings (`sniffer.analysis.doctor`) on
the rows shown so far, ranked, with evidence and advice, kept up to date while a capture
is read or a line is listened to.

The findings are worked out again from the published rows at most every REFRESH seconds,
only when rows were added since, in a worker thread, and never sooner after a look than
ten times what it took (a capture of millions of rows). The text is the one `modscope
doctor` prints, shown as plain text (never markup: summaries quote bytes and labels).
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import VerticalScroll
from textual.screen import Screen
from textual.widgets import Static

from sniffer.analysis.doctor import Diagnosis, diagnose, report, response_bounds
from sniffer.tui.widgets.keybar import key_hints

if TYPE_CHECKING:
    from sniffer.tui.app import ModscopeApp

REFRESH = 1.0  # seconds between looks at new rows
LOOK_SPACING = 10.0  # a look that took t seconds is not followed by another for 10 t


class HealthScreen(Screen[None]):
    """The findings over the whole screen; Escape, `q` or `H` go back to the list."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape,q,H", "close", "back", show=False),
        Binding("up,k", "scroll(-1)", "up", show=False),
        Binding("down,j", "scroll(1)", "down", show=False),
        Binding("pageup", "scroll(-10)", "page up", show=False),
        Binding("pagedown", "scroll(10)", "page down", show=False),
    ]
    HINTS: ClassVar[tuple[tuple[str, str], ...]] = (("↑↓", "scroll"), ("esc", "back"))

    def __init__(self, owner: ModscopeApp) -> None:
        super().__init__(id="health")
        self.owner = owner
        self.title_bar = Static(Text(""), classes="view-title")
        self.body = Static(Text(""), id="health-text")
        self.scroller = VerticalScroll(self.body, id="health-scroll")
        self.keys = Static(Text(""), classes="view-keys")
        self.looked = -1  # published rows the findings were worked out from
        self.diagnosis: Diagnosis | None = None
        self.text = ""
        self.busy = False  # a look is being worked out
        self.next_look = 0.0  # (monotonic) no look before this

    def compose(self) -> ComposeResult:
        yield self.title_bar
        yield self.scroller
        yield self.keys

    def on_mount(self) -> None:
        self.keys.update(key_hints(self.HINTS))
        self.scroller.focus()
        self.look()
        self.set_interval(REFRESH, self.look)

    def look(self) -> None:
        """Work the findings out again, in a worker thread, if rows were published since
        the last look and the last look is not too recent for what it cost."""
        app = self.owner
        published = app.model.published
        if published == self.looked or self.busy or time.monotonic() < self.next_look:
            return
        self.looked = published
        self.busy = True
        self.run_worker(lambda: self._work(published), thread=True, exclusive=True)

    def _work(self, published: int) -> None:
        app = self.owner
        session = app.session
        # a big capture's rows are paged from its sidecar (the session's store then holds
        # only the newest segment): the doctor reads them where the list does
        store = app.model.paged if app.model.paged is not None else session.store
        bindings = session.annotator.bindings
        bounds = response_bounds({u: b.dictionary.timing for u, b in bindings.items()})
        started = time.monotonic()
        diagnosis = diagnose(
            store, session.line, session.pipeline.pairer.timeout, bounds, rows=published
        )
        labels = {u: b.label for u, b in bindings.items()}
        title = f"{published:,} rows, {session.line.describe()}"
        text = report(diagnosis, title, labels)
        took = time.monotonic() - started
        app.call_from_thread(self._show, diagnosis, text, took)

    def _show(self, diagnosis: Diagnosis, text: str, took: float) -> None:
        self.busy = False
        # a look that took long is not repeated at once: the screen stays responsive on
        # a capture of millions of rows
        self.next_look = time.monotonic() + LOOK_SPACING * took
        self.diagnosis = diagnosis
        self.text = text
        self.body.update(Text(text))  # plain text: nothing in it is markup
        counts = diagnosis.counts()
        self.title_bar.update(
            Text(
                f"bus health: {counts['error']} errors, {counts['warning']} warnings, "
                f"{counts['info']} info"
            )
        )

    def action_close(self) -> None:
        self.dismiss(None)

    def action_scroll(self, lines: int) -> None:
        self.scroller.scroll_relative(y=lines, animate=False)
