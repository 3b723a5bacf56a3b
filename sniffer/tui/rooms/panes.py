"""Provides the panes' room: the list's header, the lower pane (details, units, watch),
zoom, the ladder screen, the time column's format and the theme."""

from __future__ import annotations

from typing import TYPE_CHECKING

from sniffer.framing.store import FrameStore
from sniffer.tui.rooms.base import Room, focus_now
from sniffer.tui.screens.ladder import LadderScreen
from sniffer.tui.widgets.units import Cache, unit_rows

if TYPE_CHECKING:
    from sniffer.tui.app import ModscopeApp

PANES = ("detail", "units", "watch")


class Panes(Room):
    """What the main screen shows around the list, and the screens drawn from the list."""

    def __init__(self, app: ModscopeApp) -> None:
        super().__init__(app)
        self.units_cache: Cache = {}

    def header(self) -> None:
        if not self.main.alive:
            return  # a resize before the main screen is up, or while leaving
        self.main.header.show(self.frames.columns())
        self.app.status_line.show()

    def pane(self, name: str) -> None:
        if name not in PANES:
            return
        switcher = self.main.lower
        self.main.remove_class("-zoom")
        switcher.current = name
        switcher.border_title = {"detail": "details", "units": "units"}.get(name, "")
        if name == "detail":
            self.show_detail(self.frames.cursor_row)
        elif name == "units":
            self.units()
        else:
            self.app.watching.start()
            self.app.watching.show()

    def show_detail(self, row: int | None, *, partner_first: bool = False) -> None:
        if not self.main.alive or self.main.lower.current != "detail":
            return
        pane = self.main.detail
        model = self.model
        if row is None or row >= model.published:
            # nothing under the cursor, or a cursor message sent before the rows started
            # over (a restart) and handled after: its row is not one of these yet
            pane.show(None)
            return
        j = model.partner(row)
        d = model.detail(row)
        other = model.detail(j) if j is not None else None
        pane.where = where_text(model.describer.store, row)
        if partner_first and other is not None:
            pane.show(other, d)
        else:
            pane.show(d, other)

    def units(self) -> None:
        model, session = self.model, self.app.session
        labels = {u: b.label for u, b in session.annotator.bindings.items()}
        units = list(session.stats.units.values())
        # ages from the live port's clock (they grow while no frame comes), or from the
        # end of a capture
        now = self.app.status_line.now()
        resolution = model.reader.resolution
        last = dict(model.last_answer)
        rows = unit_rows(units, labels, last, now, self.units_cache, resolution)
        self.main.units.show(rows, now)

    def fields(self) -> None:
        if self.main.lower.current == "detail":
            focus_now(self.main.detail.query_one("#fields"))

    def zoom(self) -> None:
        self.main.toggle_class("-zoom")

    def ladder(self) -> None:
        frames = self.frames
        k = frames.cursor or 0
        screen = LadderScreen(self.model, k, following=frames.following)
        self.app.push_screen(screen, self._from_ladder)
        self.app.call_after_refresh(self.app.status_line.show)

    def _from_ladder(self, row: int | None) -> None:
        if row is not None:
            self.frames.go_to_row(row)

    def refresh_ladder(self) -> None:
        screen = self.app.screen
        if isinstance(screen, LadderScreen):
            screen.refresh_rows()

    def toggle_absolute(self) -> None:
        self.model.absolute = not self.model.absolute
        self.frames.reset()
        self.header()

    def toggle_theme(self) -> None:
        app = self.app
        app.theme = "modscope-light" if app.theme == "modscope-dark" else "modscope-dark"
        self.frames.reset()


def where_text(store: FrameStore, row: int) -> str:
    """A network row's sender (`ip:port`) and a gateway link's verdict, for the detail
    title; `p` then jumps across the link."""
    parts = []
    peer = store.peers.get(store.channel[row])
    if peer:
        parts.append(f"from {peer}")
    link = store.links.get(row)
    if link is not None:
        text = f"gateway: {link['verdict']}"
        if link.get("delay_ms") is not None:
            text += f", +{link['delay_ms']} ms"
        if link.get("peer") is not None:
            text += f" (p: other side #{link['peer']})"
        parts.append(text)
    return "  ".join(parts)
