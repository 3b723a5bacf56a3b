"""Provides the filter's room: the filter bar (query, problems, transactions) and the
worker that matches the published rows as they arrive."""

from __future__ import annotations

import time
from functools import partial
from typing import TYPE_CHECKING

from rich.text import Text
from textual.message import Message
from textual.widgets import Input
from textual.worker import get_current_worker

from sniffer.meaning.query import QueryError, parse_query
from sniffer.meaning.select import FilterJob
from sniffer.tui.rooms.base import Room, focus_now

if TYPE_CHECKING:
    from sniffer.tui.app import ModscopeApp


class FilterUpdated(Message):
    def __init__(self, generation: int) -> None:
        super().__init__()
        self.generation = generation

    def can_replace(self, message: Message) -> bool:
        return isinstance(message, FilterUpdated) and message.generation == self.generation


class Filtering(Room):
    """What the list shows of the rows: the query applied from the bar, `!` and `t`."""

    def __init__(self, app: ModscopeApp) -> None:
        super().__init__(app)
        self.generation = 0  # of the filter worker: a message of an older one is dropped
        self.applied = ""  # the filter text that the rows show
        self.error = ""  # why the query on the bar was refused ('' if it was not)
        self.refused = ""  # the text that was refused

    def show_new_rows(self) -> None:
        model = self.model
        model.shown = model.published
        if model.job is not None:
            self._ensure_worker()
        elif model.view.count != model.shown:
            model.update_view()
            self.frames.rows_changed()

    def restart(self) -> None:
        model = self.model
        frames = self.frames
        keep = frames.cursor_row
        self.generation += 1
        self.app.workers.cancel_group(self.app, "filter")
        job = model.new_job()
        if job is not None:  # the first rows now, so keys typed after Enter find them
            job.advance(
                model.shown, budget=0.05, final=model.done and model.shown == model.published
            )
            model.update_view()
        frames.anchor_row = None if frames.following else keep
        frames.reset()
        frames.rows_changed()
        self.info()
        if job is not None:
            self._run(job, self.generation)

    def _ensure_worker(self) -> None:
        job = self.model.job
        running = any(w.group == "filter" and w.is_running for w in self.app.workers)
        if job is not None and not running:
            self._run(job, self.generation)

    def _run(self, job: FilterJob, generation: int) -> None:
        self.app.run_worker(
            partial(self._match, job, generation),
            name="filter",
            group="filter",
            exclusive=True,
            thread=True,
        )

    def _match(self, job: FilterJob, generation: int) -> None:
        """The filter worker (a thread): matches rows as they are published."""
        worker = get_current_worker()
        seen = (-1, -1.0)
        while not worker.is_cancelled:
            model = self.model
            final = model.done and model.shown == model.published
            more = job.advance(model.shown, lambda: worker.is_cancelled, final=final)
            state = (len(job.rows), job.progress)
            if state != seen:
                seen = state
                self.app.post_message(FilterUpdated(generation))
            if not more:
                if job.caught_up and job.upto >= self.model.shown and self.model.done:
                    break
                time.sleep(0.1)

    def updated(self, message: FilterUpdated) -> None:
        if message.generation != self.generation or self.model.job is None:
            return
        if not self.main.alive:
            return
        self.model.update_view()
        self.frames.rows_changed()
        self.info()
        self.app.panes.refresh_ladder()
        self.app.feeding.run_waiting()

    def info(self) -> None:
        model = self.model
        info = self.main.filter_info
        bar = self.main.filter_bar
        if self.error:  # a refused query stays said while it is on the bar
            info.update(Text(self.error))
            return
        bar.set_class(model.problems_only, "-problems")
        bar.set_class(model.transactions, "-transactions")
        parts = []
        edited = self.main.filter_input.value != self.applied
        bar.set_class(edited, "-edited")
        if edited:
            parts.append("edited: ⏎ applies, esc restores")
        if model.problems_only:
            parts.append("problems")
        if model.transactions:
            parts.append("transactions")
        job = model.job
        if job is not None:
            if not job.caught_up or job.progress < 1.0:
                parts.append(f"{len(job.rows):,} rows, {job.progress:.0%}")
            else:
                parts.append(f"{len(job.rows):,} of {model.shown:,}")
        info.update(Text(" · ".join(parts)))

    def changed(self, event: Input.Changed) -> None:
        field = self.main.filter_input
        if event.input is field:
            # the input's text now, not the event's: keys typed at once post their
            # Changed messages after Enter has refused the whole line, and the stale
            # ones (`unit:3` of `unit:3 or`) must not clear the refusal of what is there
            if self.error and field.value != self.refused:
                self._clear_error()
            self.info()

    def _clear_error(self) -> None:
        self.error = ""
        self.main.filter_bar.remove_class("-error")

    def apply(self, text: str) -> None:
        bar = self.main.filter_bar
        try:
            query = parse_query(text)
        except QueryError as exc:
            bar.add_class("-error")
            self.error = str(exc)  # shown until the text is edited or Esc
            self.refused = text
            self.info()
            self.app.say(self.error, title="filter", severity="error")  # all of it
            focus_now(self.main.filter_input)  # to correct it
            return
        self.error = ""
        bar.remove_class("-error")
        self.model.query = query
        self.applied = text
        for hint in query.hints():
            self.app.say(hint, title="filter")
        self.restart()

    def revert(self) -> None:
        self._clear_error()
        self.main.filter_input.value = self.applied  # the bar shows what is applied
        self.info()

    def edit(self) -> None:
        focus_now(self.main.filter_input)
        self.main.filter_input.select_all()

    def toggle_problems(self) -> None:
        self.model.problems_only = not self.model.problems_only
        self.restart()

    def toggle_transactions(self) -> None:
        self.model.transactions = not self.model.transactions
        self.restart()

    def unit_under_cursor(self) -> None:
        """Enter in the units pane: filter the list to that unit."""
        units = self.main.units
        k = units.cursor_row
        keys = [str(key.value) for key in units.rows]
        if not 0 <= k < len(keys):
            return
        text = f"unit:{keys[k]}"
        self.main.filter_input.value = text
        self.apply(text)
        focus_now(self.frames)
