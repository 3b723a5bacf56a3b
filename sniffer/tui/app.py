"""Provides the modscope TUI app and `run_tui`: frame list, details, filter, units, register watch.

Structure: a background thread feeds the session (a capture file, or a live line) and
posts batched `Indexed` messages; the app publishes the new row count to its
`ViewModel` and the widgets redraw what is on screen. Filters and the register watch
run in their own worker threads over the published rows and post their progress.
"""

from __future__ import annotations

import io
import time
from array import array
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import replace
from pathlib import Path

from rich.text import Text
from textual import events, work
from textual.app import App
from textual.message import Message
from textual.notifications import SeverityLevel
from textual.widget import Widget
from textual.widgets import DataTable, Input
from textual.worker import get_current_worker

from sniffer.framing.store import FrameStore
from sniffer.live.recorder import RecordError
from sniffer.meaning.describe import Describer
from sniffer.meaning.query import Query, QueryError, parse_query, parse_time_point
from sniffer.meaning.select import FilterJob, resolve_time, time_bounds
from sniffer.model import Chunk
from sniffer.outputs.listing import FORMATS, Lister
from sniffer.session.paged import PagedStore
from sniffer.session.paged import wanted as paged_wanted
from sniffer.session.session import Session, open_session
from sniffer.sources import Capture, ReadOptions
from sniffer.sources.reads import Reads
from sniffer.tui.feed import (
    FeedProgress,
    LiveSource,
    LiveStatus,
    Pacing,
    Recordable,
    feed_capture,
    feed_live,
    live_status,
)
from sniffer.tui.keys import Context, key_context
from sniffer.tui.model import ViewModel
from sniffer.tui.navigate import find_row
from sniffer.tui.regtable import RegisterTable
from sniffer.tui.screens.dialogs import HelpScreen
from sniffer.tui.screens.ladder import LadderScreen
from sniffer.tui.screens.main import MainScreen
from sniffer.tui.screens.register import RegisterScreen
from sniffer.tui.screens.regtable import TableScreen
from sniffer.tui.theme import themes
from sniffer.tui.watch import Watch
from sniffer.tui.widgets.frame_list import FrameList
from sniffer.tui.widgets.prompt import LineInput
from sniffer.tui.widgets.status import StatusInfo
from sniffer.tui.widgets.units import Cache, unit_rows
from sniffer.tui.widgets.watch import WatchPanel

Reopen = Callable[[], tuple[Session, Capture]]
PROBLEMS = parse_query("status:problem")
PANES = ("detail", "units", "watch")
EXPORT_DEFAULT = "modscope-export.jsonl"
# bytes a capture file spends on each chunk besides its data (to estimate indexing progress)
RECORD_OVERHEAD = {"pcap": 16, "pcapng": 32, "raw": 0}
EXPORT_FORMATS = {"jsonl": "jsonl", "json": "jsonl", "ndjson": "jsonl", "csv": "csv"}


class Indexed(Message):
    """The feeding thread published rows (batched: a newer one replaces a queued one)."""

    def __init__(self, progress: FeedProgress, generation: int) -> None:
        super().__init__()
        self.progress = progress
        self.generation = generation

    def can_replace(self, message: Message) -> bool:
        return isinstance(message, Indexed) and message.generation == self.generation


class PortNotice(Message):
    """Something happened on a live port (lost, back, data lost)."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.text = text


class FilterUpdated(Message):
    def __init__(self, generation: int) -> None:
        super().__init__()
        self.generation = generation

    def can_replace(self, message: Message) -> bool:
        return isinstance(message, FilterUpdated) and message.generation == self.generation


class ModscopeApp(App[int]):
    """The analyser's main screen."""

    CSS_PATH = "modscope.tcss"
    TITLE = "modscope"
    ENABLE_COMMAND_PALETTE = False

    def __init__(
        self,
        session: Session,
        capture: Capture | None = None,
        live: LiveSource | None = None,
        *,
        reopen: Reopen | None = None,
        speed: float | None = None,
        blink: bool = True,
        light: bool = False,
    ) -> None:
        super().__init__()
        for theme in themes():
            self.register_theme(theme)
        self.theme = "modscope-light" if light else "modscope-dark"
        self.session = session
        self.capture = capture
        self.live = live
        self.reopen = reopen
        self.model = ViewModel(session, _paged(session, live, speed))
        self.main = MainScreen(self.model, blink=blink)
        self.pacing = Pacing(speed)
        self.generation = 0
        self.filter_generation = 0
        self.paused = False
        self.blink = blink
        self.watch_model: Watch | None = None
        self.units_cache: Cache = {}
        self.feed_note = ""
        self.said: deque[str] = deque(maxlen=50)  # what `say` told the user, newest last
        self._rate_mark: tuple[float, int] = (time.monotonic(), 0)
        self._rate: float | None = None
        self.indexed = _Flag()  # set when the feed has ended (tests and benchmarks wait on it)
        self.applied_filter = ""  # the filter text that the rows show
        self.filter_error = ""  # why the query on the bar was refused ('' if it was not)
        self.filter_refused = ""  # the text that was refused
        self.search: Query | None = None  # what n/N look for
        self.search_text = ""
        self.search_from: tuple[int, int] | None = None  # (step, row) a cut-short scan reached
        self._file_size: int | None = None  # of the capture file, for indexing progress
        self._bytes_done = 0
        self._share: float | None = None  # how far the feed said it is
        self._chunks_done = [0]

    # -- layout ----------------------------------------------------------------------------

    @property
    def frames(self) -> FrameList:
        return self.main.frames

    async def on_mount(self) -> None:
        await self.push_screen(self.main)
        frames = self.frames
        frames.following = self.live is not None or self.pacing.speed is not None
        self._focus(frames)
        self.watch(self.main, "focused", self._focus_changed)
        self.call_after_refresh(self._start_feed)  # the first screen first
        self.set_interval(0.5, self._tick)
        self.call_after_refresh(self._header)

    def on_resize(self) -> None:
        self.call_after_refresh(self._header)

    def _header(self) -> None:
        if not self.main.alive:
            return  # a resize before the main screen is up, or while leaving
        self.main.header.show(self.frames.columns())
        self._status()

    # -- feeding ---------------------------------------------------------------------------

    def _start_feed(self) -> None:
        gen = self.generation
        session, pacing = self.session, self.pacing

        def publish(p: FeedProgress) -> None:
            self.post_message(Indexed(p, gen))

        def report(text: str) -> None:
            self.post_message(PortNotice(text))

        if self.live is not None:
            live = self.live
            self.run_worker(
                lambda: feed_live(session, live, pacing, publish, report=report),
                thread=True,
                group="feed",
            )
        elif self.capture is not None:
            capture = self.capture
            try:
                self._file_size = Path(capture.info.path).stat().st_size
            except OSError:
                self._file_size = None
            counter = self._chunks_done = [0]

            def counted(chunks: Iterable[Chunk]) -> Iterator[Chunk]:
                for chunk in chunks:  # (packets: a batch of reads is one per read)
                    counter[0] += len(chunk) if isinstance(chunk, Reads) else 1
                    yield chunk

            chunks: Iterable[Chunk] = counted(capture.chunks())
            paged = self.model.paged
            self.run_worker(
                lambda: feed_capture(
                    session,
                    chunks,
                    pacing,
                    publish,
                    warnings=capture.warnings,
                    paged=paged,
                    size=self._file_size,
                ),
                thread=True,
                group="feed",
            )
        else:  # a session ingested before the app started
            session.store.sync()
            self.post_message(Indexed(FeedProgress(len(session.store), 0, True), gen))

    def on_indexed(self, message: Indexed) -> None:
        if message.generation != self.generation or not self.main.alive:
            return
        p = message.progress
        if p.reopen:  # the rows start over: as a restart, from the capture this time
            self.say(f"{p.error}: indexing the capture again", severity="warning")
            self._restart(self.pacing.speed)
            return
        self._bytes_done = p.bytes_done
        self._share = p.share
        self.model.publish(p.rows)
        if p.done:
            self.model.done = True
            self.indexed.set()
            if p.error:
                self.feed_note = p.error
                self.say(p.error, title="the feed stopped", severity="error")
            for w in self.session.warnings[:5]:
                self.say(w, title="capture", severity="warning")
        if not self.paused:
            self._show_new_rows()
            self._refresh_ladder()
        # the header follows the columns here, not only through ColumnsChanged: that is
        # posted while the list draws, and it was seen not to arrive (row numbers grew
        # a digit and the header stayed as it was)
        self.main.header.show(self.frames.columns())
        self._status()

    def _refresh_ladder(self) -> None:
        if isinstance(self.screen, LadderScreen):
            self.screen.refresh_rows()

    def on_port_notice(self, message: PortNotice) -> None:
        self.say(message.text, title="port", severity="warning")

    def _show_new_rows(self) -> None:
        model = self.model
        model.shown = model.published
        if model.job is not None:
            self._ensure_filter_worker()
        elif model.view.count != model.shown:
            model.update_view()
            self.frames.rows_changed()

    # -- filtering -------------------------------------------------------------------------

    def _restart_filter(self) -> None:
        model = self.model
        frames = self.frames
        keep = frames.cursor_row
        self.filter_generation += 1
        self.workers.cancel_group(self, "filter")
        job = model.new_job()
        if job is not None:  # the first rows now, so keys typed after Enter find them
            job.advance(
                model.shown, budget=0.05, final=model.done and model.shown == model.published
            )
            model.update_view()
        frames.anchor_row = None if frames.following else keep
        frames.reset()
        frames.rows_changed()
        self._filter_info()
        if job is not None:
            self._run_filter(job, self.filter_generation)

    def _ensure_filter_worker(self) -> None:
        job = self.model.job
        running = any(w.group == "filter" and w.is_running for w in self.workers)
        if job is not None and not running:
            self._run_filter(job, self.filter_generation)

    @work(thread=True, group="filter", exclusive=True)
    def _run_filter(self, job: FilterJob, generation: int) -> None:
        worker = get_current_worker()
        seen = (-1, -1.0)
        while not worker.is_cancelled:
            model = self.model
            final = model.done and model.shown == model.published
            more = job.advance(model.shown, lambda: worker.is_cancelled, final=final)
            state = (len(job.rows), job.progress)
            if state != seen:
                seen = state
                self.post_message(FilterUpdated(generation))
            if not more:
                if job.caught_up and job.upto >= self.model.shown and self.model.done:
                    break
                time.sleep(0.1)

    def on_filter_updated(self, message: FilterUpdated) -> None:
        if message.generation != self.filter_generation or self.model.job is None:
            return
        if not self.main.alive:
            return
        self.model.update_view()
        self.frames.rows_changed()
        self._filter_info()
        self._refresh_ladder()

    def _filter_info(self) -> None:
        model = self.model
        info = self.main.filter_info
        bar = self.main.filter_bar
        if self.filter_error:  # a refused query stays said while it is on the bar
            info.update(Text(self.filter_error))
            return
        bar.set_class(model.problems_only, "-problems")
        bar.set_class(model.transactions, "-transactions")
        parts = []
        edited = self.main.filter_input.value != self.applied_filter
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

    def on_input_submitted(self, event: Input.Submitted) -> None:
        """Enter in an input that did not come through the priority key (a click, a paste)."""
        event.stop()
        if event.input is self.main.filter_input:
            self._apply_filter(event.value)
        elif event.input is self.main.prompt.input:
            self._close_prompt(submit=True)

    def on_input_changed(self, event: Input.Changed) -> None:
        if event.input is self.main.filter_input:
            if self.filter_error and event.value != self.filter_refused:
                self._clear_filter_error()
            self._filter_info()

    def _clear_filter_error(self) -> None:
        self.filter_error = ""
        self.main.filter_bar.remove_class("-error")

    def _apply_filter(self, text: str) -> None:
        bar = self.main.filter_bar
        try:
            query = parse_query(text)
        except QueryError as exc:
            bar.add_class("-error")
            self.filter_error = str(exc)  # shown until the text is edited or Esc
            self.filter_refused = text
            self._filter_info()
            self.say(self.filter_error, title="filter", severity="error")  # all of it
            self._focus(self.main.filter_input)  # to correct it
            return
        self.filter_error = ""
        bar.remove_class("-error")
        self.model.query = query
        self.applied_filter = text
        self._restart_filter()

    # -- focus and keys --------------------------------------------------------------------

    def _focus(self, widget: Widget) -> None:
        """Focus `widget` now, not after the keys already queued (`Widget.focus` waits)."""
        widget.screen.set_focus(widget)

    def focus_context(self) -> Context:
        main, focused = self.main, self.main.focused
        if focused is None or focused is main.frames:
            return Context.LIST
        if isinstance(focused, Input):
            return Context.INPUT
        if focused is main.units:
            return Context.UNITS
        if focused is main.watch_panel:
            return Context.WATCH
        return Context.ANY

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """The main screen's keys apply only where the focus is (see `sniffer.tui.keys`);
        a key that does not apply goes on to the focused widget."""
        if self.screen is not self.main:
            return True
        context = key_context(action)
        if context is None:
            return True
        here = self.focus_context()
        if context is Context.ANY:
            return here is not Context.INPUT
        if action == "list":  # the moving keys move the units and watch tables too
            return here in (Context.LIST, Context.UNITS, Context.WATCH)
        return here is context

    def _focus_changed(self) -> None:
        if self.main.alive:
            self.main.keybar.show(self.focus_context())

    def action_list(self, name: str, step: int) -> None:
        table = self.main.focused
        if isinstance(table, DataTable):  # units or watch: moved here, in key order
            if name == "cursor":
                (table.action_cursor_up if step < 0 else table.action_cursor_down)()
            elif name == "page":
                (table.action_page_up if step < 0 else table.action_page_down)()
            elif name == "first":
                table.action_scroll_top()
            else:
                table.action_scroll_bottom()
            return
        frames = self.frames
        if name == "cursor":
            frames.action_cursor(step)
        elif name == "page":
            frames.action_page(step)
        elif name == "first":
            frames.action_first()
        else:
            frames.action_follow()

    async def on_event(self, event: events.Event) -> None:
        """Keys for the filter or the prompt are typed into it here, as they arrive, so
        they keep their order with the keys before and after them (see LineInput).

        A terminal sends Esc and a key typed right after it as one sequence, which reads
        as alt+key: no key of modscope uses alt, so it is taken as the two keys typed."""
        if (
            isinstance(event, events.Key)
            and event.key.startswith("alt+")
            and "+" not in event.key[4:]
            and not event.is_forwarded
        ):
            event.stop()
            for key, char in (("escape", "\x1b"), (event.key[4:], event.character)):
                typed = events.Key(key, char)
                typed.set_sender(self)
                await self.on_event(typed)
            return
        if isinstance(event, events.Key) and not event.is_forwarded and self.screen is self.main:
            field = self.main.focused
            if isinstance(field, LineInput) and event.key == "ctrl+j":
                # a newline: Enter typed before the terminal was switched to raw mode
                # (type-ahead while modscope starts) arrives as LF, not CR
                event.stop()
                self.action_submit()
                return
            if isinstance(field, LineInput) and await field.type_key(event):
                event.stop()
                return
        await super().on_event(event)

    def action_submit(self) -> None:
        main = self.main
        field = main.focused
        self._focus(self.frames)  # keys typed after Enter go to the list
        if field is main.filter_input:
            self._apply_filter(main.filter_input.value)
        elif field is main.prompt.input:
            main.prompt.close(True)

    def action_cancel(self) -> None:
        main = self.main
        field = main.focused
        self._focus(self.frames)
        if field is main.filter_input:
            self._revert_filter()
        elif field is main.prompt.input:
            main.prompt.close(False)

    def _revert_filter(self) -> None:
        self._clear_filter_error()
        self.main.filter_input.value = self.applied_filter  # the bar shows what is applied
        self._filter_info()

    def action_next_pane(self) -> None:
        self.main.focus_next()

    def _ask(self, prompt: str, answer: Callable[[str | None], None], default: str = "") -> None:
        self.main.prompt.ask(prompt, answer, default=default)

    def _close_prompt(self, submit: bool) -> None:
        self._focus(self.frames)
        self.main.prompt.close(submit)

    # -- cursor and details ----------------------------------------------------------------

    def on_frame_list_cursor_moved(self, message: FrameList.CursorMoved) -> None:
        self._show_detail(message.row)

    def on_frame_list_columns_changed(self, message: FrameList.ColumnsChanged) -> None:
        if self.main.alive:
            self.main.header.show(message.cols)

    def on_frame_list_follow_changed(self, message: FrameList.FollowChanged) -> None:
        self._status()

    def _show_detail(self, row: int | None, *, partner_first: bool = False) -> None:
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

    # -- actions ---------------------------------------------------------------------------

    def action_help(self) -> None:
        self.push_screen(HelpScreen())

    def action_edit_filter(self) -> None:
        self._focus(self.main.filter_input)
        self.main.filter_input.select_all()

    def action_to_list(self) -> None:
        self._focus(self.frames)

    def action_fields(self) -> None:
        if self.main.lower.current == "detail":
            self._focus(self.main.detail.query_one("#fields"))

    def action_problems(self) -> None:
        self.model.problems_only = not self.model.problems_only
        self._restart_filter()

    def action_transactions(self) -> None:
        self.model.transactions = not self.model.transactions
        self._restart_filter()

    def action_absolute(self) -> None:
        self.model.absolute = not self.model.absolute
        self.frames.reset()
        self._header()

    def action_follow(self) -> None:
        self.frames.action_follow()

    def action_theme(self) -> None:
        self.theme = "modscope-light" if self.theme == "modscope-dark" else "modscope-dark"
        self.frames.reset()

    def action_pause(self) -> None:
        self.paused = not self.paused
        self.pacing.paused = self.paused and self.live is None
        self.set_class(self.paused, "-paused")
        if not self.paused:
            self._show_new_rows()
        self._status()

    def action_partner(self) -> None:
        row = self.frames.cursor_row
        if row is None:
            return
        j = self.model.partner(row)
        across = link_peer(self.model.describer.store, row)
        if across is not None and self.model.view.contains(across):
            self.frames.go_to_row(across)  # both sides of a gateway: the other side
        elif j is None:
            self.say("this frame has no paired request or answer")
        elif self.model.view.contains(j):
            self.frames.go_to_row(j)
        else:
            self.action_pane("detail")
            self._show_detail(row, partner_first=True)

    def action_pane(self, name: str) -> None:
        if name not in PANES:
            return
        switcher = self.main.lower
        self.main.remove_class("-zoom")
        switcher.current = name
        switcher.border_title = {"detail": "details", "units": "units"}.get(name, "")
        if name == "detail":
            self._show_detail(self.frames.cursor_row)
        elif name == "units":
            self._units()
        else:
            self._start_watch()
            self._watch()

    def action_ladder(self) -> None:
        frames = self.frames
        k = frames.cursor or 0
        screen = LadderScreen(self.model, k, following=frames.following)
        self.push_screen(screen, self._from_ladder)
        self.call_after_refresh(self._status)

    def _from_ladder(self, row: int | None) -> None:
        if row is not None:
            self.frames.go_to_row(row)

    def action_zoom(self) -> None:
        self.main.toggle_class("-zoom")

    def action_go_to(self) -> None:
        self._ask("go to (12.5, 2m, 1:02:03.5, 14:03:07, #1234):", self._go_to)

    def _go_to(self, answer: str | None) -> None:
        if not answer:
            return
        model, frames = self.model, self.frames
        if answer.startswith("#"):
            try:
                row = int(answer[1:])
            except ValueError:
                self.say(f"{answer!r} is not a row number", severity="error")
                return
            if row >= model.published:
                more = "" if model.done else " yet"
                self.say(f"there is no #{row}{more} ({model.published:,} rows): the last is shown")
            frames.go_to_row(row)
            return
        try:
            point = parse_time_point(answer)
        except QueryError as exc:
            self.say(str(exc), severity="error")
            return
        t = resolve_time(point, model.origin)
        frames.go_to(model.view.at_time(model.reader, t))

    def action_speed(self) -> None:
        if self.live is not None:
            self.say("a live capture runs at the line's own speed")
            return
        if self.pacing.speed is None:
            if self.model.done:
                self._restart(speed=1.0)
            else:
                self.pacing.speed = 1.0
                self.frames.action_follow()
        else:
            self.pacing.speed = None
        self._status()

    def action_record(self) -> None:
        """Start recording the live line to a file, or stop the running recording."""
        live = self.live
        if live is None or not isinstance(live, Recordable):
            self.say(
                "recording is for a live line (modscope live PORT); this capture is a file "
                "already: e exports the rows shown"
            )
            return
        if getattr(live, "recorder", None) is not None:
            files = live.stop_recording()
            where = ", ".join(str(f) for f in files) or "nothing written"
            self.say(f"recording stopped: {where}")
            self._status()
            return
        stamp = time.strftime("%Y%m%d-%H%M%S")
        self._ask("record to (pcapng; r stops):", self._record, f"modscope-{stamp}.pcapng")

    def _record(self, answer: str | None) -> None:
        live = self.live
        if not answer or not isinstance(live, Recordable):
            return
        try:
            recorder = live.start_recording(Path(answer).expanduser())
        except RecordError as exc:
            self.say(str(exc), severity="error")
            return
        self.say(f"recording to {recorder.files[-1] if recorder.files else answer}")
        self._status()

    def action_export(self) -> None:
        count = len(self.model.view)
        self._ask(f"export {count:,} rows to (.jsonl .csv .txt):", self._export, EXPORT_DEFAULT)

    def _export(self, answer: str | None) -> None:
        if not answer:
            return
        view = self.model.view
        rows: Iterable[int] = (
            range(view.count) if view.rows is None else array("Q", view.rows[: view.count])
        )
        # the rows, store and options of now: `s` may start the capture again (a new
        # store) while the file is being written
        model = self.model
        describer = Describer(model.reader, self.session.annotator, size=256)
        self._write_export(Path(answer).expanduser(), rows, describer, model.absolute)

    @work(thread=True, group="export")
    def _write_export(
        self, path: Path, rows: Iterable[int], describer: Describer, absolute: bool
    ) -> None:
        suffix = path.suffix.lower().lstrip(".")
        fmt = EXPORT_FORMATS.get(suffix, "text")
        assert fmt in FORMATS
        try:
            with path.open("w", encoding="utf-8", newline="" if fmt == "csv" else None) as out:
                lister = Lister(out, fmt, describer, absolute=absolute)
                n = lister.write(rows, flush=False)
        except OSError as exc:
            reason = f"cannot write {path}: {exc.strerror or exc}"
            self.call_from_thread(self.say, reason, severity="error")
            return
        self.call_from_thread(self.say, f"wrote {n:,} rows to {path} ({fmt})")

    # -- search, problems, marks, copy ------------------------------------------------------

    def action_find(self) -> None:
        self._ask("find (filter terms; n/N next/previous):", self._set_search, self.search_text)

    def _set_search(self, answer: str | None) -> None:
        if not answer:
            return
        try:
            self.search = parse_query(answer)
        except QueryError as exc:
            self.say(str(exc), severity="error")
            return
        self.search_text = answer
        self.search_from = None
        self.action_find_next(1)

    def action_find_next(self, step: int) -> None:
        if self.search is None:
            self.action_find()
            return
        self._find(self.search, step, f"{self.search_text!r}")

    def action_problem(self, step: int) -> None:
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
            self.say(f"no {what} up to #{found.stopped} yet: press again to search on")
        else:
            where = "after" if step > 0 else "before"
            self.say(f"no {what} {where} #{here}")

    def action_mark(self) -> None:
        row = self.frames.cursor_row
        if row is None:
            return
        marks = self.model.marks
        if row in marks:
            marks.discard(row)
            self.say(f"mark on #{row} removed")
        else:
            marks.add(row)
            self.say(f"marked #{row}: ' jumps between marks")
        self.frames.reset()

    def action_jump_mark(self) -> None:
        marks = sorted(r for r in self.model.marks if self.model.view.contains(r))
        row = self.frames.cursor_row
        if not marks or row is None:
            self.say("no marks: m marks the selected row")
            return
        later = [r for r in marks if r > row]
        self.frames.go_to_row(later[0] if later else marks[0])

    def action_copy(self, what: str) -> None:
        row = self.frames.cursor_row
        if row is None:
            return
        if what == "hex":
            text = self.model.reader.raw(row).hex(" ")
        else:
            out = io.StringIO()
            Lister(out, "jsonl", self.model.describer, absolute=self.model.absolute).write(
                [row], flush=False
            )
            text = out.getvalue().strip()
        self.copy_to_clipboard(text)
        self.say(f"copied #{row} as {what} ({len(text):,} characters, OSC 52)")

    def action_filter_unit(self) -> None:
        units = self.main.units
        k = units.cursor_row
        keys = [str(key.value) for key in units.rows]
        if not 0 <= k < len(keys):
            return
        text = f"unit:{keys[k]}"
        self.main.filter_input.value = text
        self._apply_filter(text)
        self._focus(self.frames)

    # -- restart (replay at the original speed) --------------------------------------------

    def _restart(self, speed: float | None) -> None:
        try:
            session, capture = (self.reopen or (lambda: reopen_file(self.session)))()
        except Exception as exc:  # the file went away, or cannot be read again
            self.say(f"cannot replay the capture again: {exc}", severity="error")
            return
        self.pacing.stop.set()
        self.workers.cancel_group(self, "filter")
        self.workers.cancel_group(self, "watch")
        old = self.model
        self.generation += 1
        self.session, self.capture = session, capture
        self.model = ViewModel(session, _paged(session, None, speed))
        self.model.absolute, self.model.transactions = old.absolute, old.transactions
        self.model.problems_only, self.model.query = old.problems_only, old.query
        self.watch_model = None
        self.units_cache = {}
        self.indexed = _Flag()
        self.feed_note = ""
        self.pacing = Pacing(speed)
        self._rate_mark, self._rate = (time.monotonic(), 0), None
        frames = self.frames
        frames.model = self.main.model = self.model
        frames.following = True
        self._restart_filter()
        self._start_feed()
        if self.main.lower.current == "watch":
            self._start_watch()

    # -- periodic --------------------------------------------------------------------------

    def _tick(self) -> None:
        if not self.main.alive:
            return
        now = time.monotonic()
        mark_t, mark_rows = self._rate_mark
        rows = self.model.published
        if rows < mark_rows:  # a restart (s) began again from the first row
            self._rate_mark, self._rate = (now, rows), None
        elif now - mark_t >= 1.0:
            self._rate = (rows - mark_rows) / (now - mark_t) if not self.model.done else None
            self._rate_mark = (now, rows)
        self._status()
        current = self.main.lower.current
        if current == "units":
            self._units()
        elif current == "watch":
            self._watch()
        if self.model.job is not None:
            self._filter_info()

    def _status(self) -> None:
        model, session = self.model, self.session
        stats = session.stats
        errors = sum(u.check_errors for u in list(stats.units.values())) + stats.noise_spans
        rate = self._rate
        if model.done:  # the capture's own rate
            span = model.latest - model.origin
            rate = model.published / span if span > 0 else None
        live = self.live
        status = live_status(live) if live is not None else LiveStatus()
        line = session.line.describe()
        if session.mode != session.line.mode:
            line += f" ({session.mode})"
        info = StatusInfo(
            source=Path(session.source).name if live is None else session.source,
            line=line,
            rows=model.published,
            bytes=model.reader.bytes_total,
            errors=errors,
            rate=rate,
            indexing=not model.done and live is None and self.pacing.speed is None,
            paused=self.paused,
            following=self.frames.following,
            speed="1x" if self.pacing.speed else "",
            recording=Path(status.recording).name if status.recording else "",
            recorded_bytes=status.recorded_bytes,
            losses=status.lost_bytes,
            note=self.feed_note or status.failure,
            live=live is not None,
            reconnecting=status.reconnecting,
            progress=self._index_progress(),
        )
        self.main.status.show(info)
        if isinstance(self.screen, LadderScreen | TableScreen):
            self.screen.status.show(info)

    def _index_progress(self) -> float | None:
        """How far indexing got: as the feed says (`FeedProgress.share`), else estimated
        from the file's size (pcap formats, raw)."""
        if self._share is not None:
            return self._share
        capture = self.capture
        overhead = RECORD_OVERHEAD.get(capture.info.format) if capture is not None else None
        if overhead is None or self._file_size is None or not self._file_size:
            return None
        done = self._bytes_done + self._chunks_done[0] * overhead
        return max(0.0, min(0.99, done / self._file_size))

    def _units(self) -> None:
        model = self.model
        labels = {u: b.label for u, b in self.session.annotator.bindings.items()}
        units = list(self.session.stats.units.values())
        rows = unit_rows(units, labels, dict(model.last_answer), model.latest, self.units_cache)
        # `seen` is when the unit was last heard (its last answer), in every pane: a unit
        # the master keeps asking but that never answers is SILENT and not `seen` lately
        rows = [replace(r, last_seen=r.last_answer or 0.0) for r in rows]
        self.main.units.show(rows, model.latest)

    def _start_watch(self) -> None:
        if self.watch_model is None:
            self.watch_model = Watch(self.model.reader, self.session.annotator)
            if not self.watch_model.bound:
                self.say(
                    "no unit is bound to a device dictionary, so no register has a name: "
                    "use --bus or --unit ADDR=MODEL"
                )
            self._run_watch(self.watch_model, self.generation)

    @work(thread=True, group="watch", exclusive=True)
    def _run_watch(self, watch: Watch, generation: int) -> None:
        worker = get_current_worker()
        while not worker.is_cancelled and generation == self.generation:
            more = watch.advance(self.model.shown, should_stop=lambda: worker.is_cancelled)
            if not more:
                if self.model.done and watch.next >= self.model.shown:
                    break
                time.sleep(0.2)

    def _watch_progress(self) -> float | None:
        """How much of the capture the register watch has read; None once it has all."""
        watch, model = self.watch_model, self.model
        if watch is None:
            return 0.0
        if watch.next >= model.published and (model.done or self.live is not None):
            return None  # all of it (a live line is never done: caught up is complete)
        return watch.next / max(1, model.published)

    def _watch(self) -> None:
        watch = self.watch_model
        if watch is None:
            return
        scanned = self._watch_progress()
        self.main.lower.border_title = (
            "register watch"
            if scanned is None
            else f"register watch · PARTIAL: {scanned:.0%} read, values so far"
        )
        panel = self.main.watch_panel
        panel.show(watch.snapshot(), self.model.latest, watch.version)

    def on_watch_panel_open(self, message: WatchPanel.Open) -> None:
        watch = self.watch_model
        if watch is None or message.key not in watch.series:
            return
        with watch.lock:
            series = watch.series[message.key]
        scanned = self._watch_progress()
        screen = RegisterScreen(series, self.model.origin, self.model.absolute, scanned)
        self.push_screen(screen, self._jump_to_row)

    # -- the register table (x picks in the watch, R shows) -----------------------------------

    def action_open_register(self) -> None:
        panel = self.main.watch_panel
        key = panel.cursor_key()
        if key is not None:
            panel.post_message(WatchPanel.Open(key))

    def action_pick(self) -> None:
        panel = self.main.watch_panel
        key = panel.cursor_key()
        if key is None:
            return
        picked = panel.toggle_pick(key)
        if picked and len(panel.picked) == 1:  # the ✓ shows the others: say it once
            self.say("picked (✓): x picks more, R shows them side by side")

    def action_register_table(self) -> None:
        watch, panel = self.watch_model, self.main.watch_panel
        if watch is None:
            return
        keys = list(panel.picked) or [k for k in [panel.cursor_key()] if k is not None]
        with watch.lock:
            series = [watch.series[k] for k in keys if k in watch.series]
        if not series:
            self.say("no register to show: pick some with x in the register watch")
            return
        table = RegisterTable(self.model.reader, self.session.annotator, [s.key for s in series])
        screen = TableScreen(table, series, self.model.origin, self.model.absolute)
        self.push_screen(screen, self._jump_to_row)
        self._run_table(table, screen, self.generation)
        self.call_after_refresh(self._status)

    @work(thread=True, group="table", exclusive=True)
    def _run_table(self, table: RegisterTable, screen: TableScreen, generation: int) -> None:
        worker = get_current_worker()
        sent = (-1, False)
        while not worker.is_cancelled and generation == self.generation:
            more = table.advance(self.model.shown, should_stop=lambda: worker.is_cancelled)
            caught_up = table.next >= self.model.shown
            done = self.model.done and caught_up
            if done:
                table.finish()
            complete = done or (caught_up and self.live is not None)
            if (table.version, complete) != sent:
                sent = (table.version, complete)
                scanned = None if complete else table.next / max(1, self.model.published)
                self.call_from_thread(self._table_progress, screen, scanned)
            if done and not self.live:
                break
            if not more:
                time.sleep(0.2)

    def _table_progress(self, screen: TableScreen, scanned: float | None) -> None:
        if screen.is_attached:
            screen.progress(scanned)

    def _jump_to_row(self, row: int | None) -> None:
        if row is None:
            return
        if not self.model.view.contains(row):
            self.say("that frame is hidden by the filter; showing the nearest")
        self.frames.go_to_row(row)
        self.action_pane("detail")

    def say(self, text: str, *, title: str = "", severity: SeverityLevel = "information") -> None:
        """Tell the user something (never as markup); kept in `said` for a while."""
        self.said.append(text)
        self.notify(text, title=title, severity=severity, markup=False)

    # -- leaving ---------------------------------------------------------------------------

    async def action_quit(self) -> None:
        self._stop_feed()
        self.exit(0)

    def _stop_feed(self) -> None:
        self.pacing.stop.set()

    def on_unmount(self) -> None:
        self._stop_feed()


class _Flag:
    """A flag set once on the UI thread; `wait` polls it from async code (tests, benchmarks)."""

    def __init__(self) -> None:
        self.value = False

    def set(self) -> None:
        self.value = True

    def is_set(self) -> bool:
        return self.value


def reopen_file(session: Session) -> tuple[Session, Capture]:
    """Open the session's capture file again, with the same line settings and bindings."""
    line = session.line
    options = ReadOptions(
        baud=line.baud,
        bytesize=line.bytesize,
        parity=line.parity,
        stopbits=line.stopbits,
        mode=line.mode,
    )
    return open_session(
        session.source,
        options,
        bindings=session.annotator.bindings,
        timeout=session.pipeline.pairer.timeout,
    )


def _paged(session: Session, live: LiveSource | None, speed: float | None) -> PagedStore | None:
    """A store for the rows of a capture big enough to have a sidecar index, paged from
    it (see `sniffer.session.paged`); None: the session's store is shown as it is."""
    return PagedStore() if paged_wanted(session, live is not None, speed) else None


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


def link_peer(store: FrameStore, row: int) -> int | None:
    """The row on the other side of a gateway linked to `row`, if any."""
    link = store.links.get(row)
    peer = None if link is None else link.get("peer")
    return peer if isinstance(peer, int) else None


def run_tui(
    session: Session,
    capture: Capture | None = None,
    live: LiveSource | None = None,
    *,
    reopen: Reopen | None = None,
    speed: float | None = None,
) -> int:
    """Run the TUI on a session: a capture being opened, a live source, or an ingested one."""
    app = ModscopeApp(session, capture, live, reopen=reopen, speed=speed)
    result = app.run()
    return result if isinstance(result, int) else 0
