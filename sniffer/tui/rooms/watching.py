"""Provides the register watch's room: the watch pane and its worker, a register's plot
(Enter), and the register table of the registers picked with `x` (`R`) and its worker."""

from __future__ import annotations

import time
from functools import partial
from typing import TYPE_CHECKING

from textual.worker import get_current_worker

from sniffer.tui.regtable import RegisterTable
from sniffer.tui.rooms.base import Room
from sniffer.tui.screens.register import RegisterScreen
from sniffer.tui.screens.regtable import TableScreen
from sniffer.tui.watch import SeriesKey, Watch
from sniffer.tui.widgets.watch import WatchPanel

if TYPE_CHECKING:
    from sniffer.tui.app import ModscopeApp


class Watching(Room):
    """The register values the capture shows, read by a worker from the published rows."""

    def __init__(self, app: ModscopeApp) -> None:
        super().__init__(app)
        self.watch: Watch | None = None  # made when the watch pane is first shown

    def reset(self) -> None:
        """The rows start over (a restart): the watch is made again when next shown."""
        self.app.workers.cancel_group(self.app, "watch")
        self.watch = None

    def start(self) -> None:
        app = self.app
        if self.watch is None:
            self.watch = Watch(self.model.reader, app.session.annotator)
            if not self.watch.bound:
                app.say(
                    "no unit is bound to a device dictionary, so no register has a name: "
                    "use --bus or --unit ADDR=MODEL"
                )
            app.run_worker(
                partial(self._scan, self.watch, app.generation),
                name="watch",
                group="watch",
                exclusive=True,
                thread=True,
            )

    def _scan(self, watch: Watch, generation: int) -> None:
        """The watch's worker (a thread): reads the rows as they are published."""
        worker = get_current_worker()
        app = self.app
        while not worker.is_cancelled and generation == app.generation:
            more = watch.advance(app.model.shown, should_stop=lambda: worker.is_cancelled)
            if not more:
                if app.model.done and watch.next >= app.model.shown:
                    break
                time.sleep(0.2)

    def progress(self) -> float | None:
        """How much of the capture the register watch has read; None once it has all."""
        watch, model = self.watch, self.model
        if watch is None:
            return 0.0
        if watch.next >= model.published and (model.done or self.app.live is not None):
            return None  # all of it (a live line is never done: caught up is complete)
        return watch.next / max(1, model.published)

    def show(self) -> None:
        watch = self.watch
        if watch is None:
            return
        scanned = self.progress()
        self.main.lower.border_title = (
            "register watch"
            if scanned is None
            else f"register watch · PARTIAL: {scanned:.0%} read, values so far"
        )
        panel = self.main.watch_panel
        panel.show(watch.snapshot(), self.model.latest, watch.version)
        self.app.keyboard.release()

    def open(self, key: SeriesKey) -> None:
        """A register's plot over time (Enter on it in the watch)."""
        watch = self.watch
        if watch is None or key not in watch.series:
            return
        with watch.lock:
            series = watch.series[key]
        scanned = self.progress()
        screen = RegisterScreen(series, self.model.origin, self.model.absolute, scanned)
        self.app.push_screen(screen, self.app.jumps.to_row)

    def open_under_cursor(self) -> None:
        panel = self.main.watch_panel
        key = panel.cursor_key()
        if key is not None:
            panel.post_message(WatchPanel.Open(key))

    def pick(self) -> None:
        panel = self.main.watch_panel
        key = panel.cursor_key()
        if key is None:
            return
        picked = panel.toggle_pick(key)
        if picked and len(panel.picked) == 1:  # the ✓ shows the others: say it once
            self.app.say("picked (✓): x picks more, R shows them side by side")

    def table(self) -> None:
        app = self.app
        watch, panel = self.watch, self.main.watch_panel
        if watch is None:
            return
        keys = list(panel.picked) or [k for k in [panel.cursor_key()] if k is not None]
        with watch.lock:
            series = [watch.series[k] for k in keys if k in watch.series]
        if not series:
            app.say("no register to show: pick some with x in the register watch")
            return
        table = RegisterTable(self.model.reader, app.session.annotator, [s.key for s in series])
        screen = TableScreen(table, series, self.model.origin, self.model.absolute)
        app.push_screen(screen, app.jumps.to_row)
        app.run_worker(
            partial(self._fill_table, table, screen, app.generation),
            name="table",
            group="table",
            exclusive=True,
            thread=True,
        )
        app.call_after_refresh(app.status_line.show)

    def _fill_table(self, table: RegisterTable, screen: TableScreen, generation: int) -> None:
        """The register table's worker (a thread): reads the rows as they are published."""
        worker = get_current_worker()
        app = self.app
        sent = (-1, False)
        while not worker.is_cancelled and generation == app.generation:
            model = app.model
            more = table.advance(model.shown, should_stop=lambda: worker.is_cancelled)
            caught_up = table.next >= model.shown
            done = model.done and caught_up
            if done:
                table.finish()
            complete = done or (caught_up and app.live is not None)
            if (table.version, complete) != sent:
                sent = (table.version, complete)
                scanned = None if complete else table.next / max(1, model.published)
                app.call_from_thread(self._table_progress, screen, scanned)
            if done and not app.live:
                break
            if not more:
                time.sleep(0.2)

    def _table_progress(self, screen: TableScreen, scanned: float | None) -> None:
        if screen.is_attached:
            screen.progress(scanned)
