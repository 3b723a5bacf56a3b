"""Provides the jumps' room: go to a time or a row, find (`F` `n` `N`), problems (`]` `[`),
the paired request or answer (`p`), marks (`m` `'`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from sniffer.framing.store import FrameStore
from sniffer.meaning.query import Query, QueryError, parse_query, parse_time_point
from sniffer.meaning.select import resolve_time, time_bounds
from sniffer.tui.navigate import find_row
from sniffer.tui.rooms.base import Room

if TYPE_CHECKING:
    from sniffer.tui.app import ModscopeApp

PROBLEMS = parse_query("status:problem")


class Jumps(Room):
    """Moves the list's cursor to a row asked for; the filter stays as it is."""

    def __init__(self, app: ModscopeApp) -> None:
        super().__init__(app)
        self.search: Query | None = None  # what n/N look for
        self.search_text = ""
        self.search_from: tuple[int, int] | None = None  # (step, row) a cut-short scan reached

    def to_row(self, row: int | None) -> None:
        """Show `row` in the list and its details (a row picked on another screen)."""
        if row is None:
            return
        if not self.model.view.contains(row):
            self.app.say("that frame is hidden by the filter; showing the nearest")
        self.frames.go_to_row(row)
        self.app.panes.pane("detail")

    def go_to(self) -> None:
        self.app.keyboard.ask("go to (12.5, 2m, 1:02:03.5, 14:03:07, #1234):", self._go_to)

    def _go_to(self, answer: str | None) -> None:
        if not answer:
            return
        model, say = self.model, self.app.say
        feeding = self.app.feeding
        feeding.forget("go to")
        reading = self.app.live is None and not model.done  # a capture still being read
        if answer.startswith("#"):
            try:
                row = int(answer[1:])
            except ValueError:
                say(f"{answer!r} is not a row number", severity="error")
                return
            if row >= model.published and reading:
                # typed at start-up: the cursor goes there once the row is read
                say(f"#{row} is not read yet: the cursor goes there once it is")
                feeding.when(
                    "go to", lambda: model.published > row or model.done, lambda: self._row(row)
                )
                return
            self._row(row)
            return
        try:
            point = parse_time_point(answer)
        except QueryError as exc:
            say(str(exc), severity="error")
            return
        t = resolve_time(point, model.origin)
        if reading and (model.published == 0 or t > model.latest):
            say(f"{answer} is not read yet: the cursor goes there once it is")
            feeding.when(
                "go to",
                lambda: model.done or (model.published > 0 and model.latest >= t),
                lambda: self._time(answer),
            )
            return
        self.frames.go_to(model.view.at_time(model.reader, t))

    def _row(self, row: int) -> None:
        model = self.model
        if row >= model.published:
            more = "" if model.done else " yet"
            self.app.say(f"there is no #{row}{more} ({model.published:,} rows): the last is shown")
        self.frames.go_to_row(row)

    def _time(self, answer: str) -> None:
        model = self.model
        t = resolve_time(parse_time_point(answer), model.origin)
        self.frames.go_to(model.view.at_time(model.reader, t))

    def find(self) -> None:
        ask = self.app.keyboard.ask
        ask("find (filter terms; n/N next/previous):", self._set_search, self.search_text)

    def _set_search(self, answer: str | None) -> None:
        if not answer:
            return
        try:
            self.search = parse_query(answer)
        except QueryError as exc:
            self.app.say(str(exc), severity="error")
            return
        self.search_text = answer
        self.search_from = None
        for hint in self.search.hints():
            self.app.say(hint, title="find")
        self.find_next(1)

    def find_next(self, step: int) -> None:
        if self.search is None:
            self.find()
            return
        self._find(self.search, step, f"{self.search_text!r}")

    def problem(self, step: int) -> None:
        self._find(PROBLEMS, step, "problem")

    def _find(self, query: Query, step: int, what: str) -> None:
        model, frames = self.model, self.frames
        here = frames.cursor_row
        if here is None:
            return
        start = here
        if what != "problem" and self.search_from is not None and self.search_from[0] == step:
            start = self.search_from[1]  # a scan cut short goes on where it stopped
        self.search_from = None
        lo, hi = time_bounds(model.reader, query, model.origin, model.shown)
        start = max(lo - 1, min(start, hi)) if step > 0 else min(hi, max(start, lo - 1))
        found = find_row(
            model.reader,
            model.describer,
            query,
            model.options(),
            start,
            step,
            hi,
            model.view.contains,
        )
        if found.row is not None:
            frames.go_to_row(found.row)
        elif not found.complete:
            self.search_from = (step, found.stopped)
            self.app.say(f"no {what} up to #{found.stopped} yet: press again to search on")
        else:
            where = "after" if step > 0 else "before"
            self.app.say(f"no {what} {where} #{here}")

    def partner(self) -> None:
        row = self.frames.cursor_row
        if row is None:
            return
        j = self.model.partner(row)
        across = link_peer(self.model.describer.store, row)
        if across is not None and self.model.view.contains(across):
            self.frames.go_to_row(across)  # both sides of a gateway: the other side
        elif j is None:
            self.app.say("this frame has no paired request or answer")
        elif self.model.view.contains(j):
            self.frames.go_to_row(j)
        else:
            self.app.panes.pane("detail")
            self.app.panes.show_detail(row, partner_first=True)

    def mark(self) -> None:
        row = self.frames.cursor_row
        if row is None:
            return
        marks = self.model.marks
        if row in marks:
            marks.discard(row)
            self.app.say(f"mark on #{row} removed")
        else:
            marks.add(row)
            self.app.say(f"marked #{row}: ' jumps between marks")
        self.frames.reset()

    def jump_mark(self) -> None:
        marks = sorted(r for r in self.model.marks if self.model.view.contains(r))
        row = self.frames.cursor_row
        if not marks or row is None:
            self.app.say("no marks: m marks the selected row")
            return
        later = [r for r in marks if r > row]
        self.frames.go_to_row(later[0] if later else marks[0])


def link_peer(store: FrameStore, row: int) -> int | None:
    """The row on the other side of a gateway linked to `row`, if any."""
    link = store.links.get(row)
    peer = None if link is None else link.get("peer")
    return peer if isinstance(peer, int) else None
