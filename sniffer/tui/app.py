"""Provides the modscope TUI app and `run_tui`: frame list, details, filter, units, register watch.

Structure: a background thread feeds the session (a capture file, or a live line) and
posts batched `Indexed` messages; the app publishes the new row count to its
`ViewModel` and the widgets redraw what is on screen. Filters and the register watch
run in their own worker threads over the published rows and post their progress.

The App holds what is shared (session, model, main screen, pacing) and composes the
rooms of `sniffer.tui.rooms`, one per pane or mode: Textual delivers every key's action
and every message to the App, which hands it to the room that owns it.
"""

from __future__ import annotations

import sys
from collections import deque
from collections.abc import Callable

from textual import events
from textual.app import App
from textual.driver import Driver
from textual.drivers.web_driver import WebDriver
from textual.notifications import SeverityLevel
from textual.widgets import Input

from sniffer.session.session import Session
from sniffer.sources import Capture
from sniffer.tui.feed import LiveSource, Pacing
from sniffer.tui.model import ViewModel
from sniffer.tui.rooms.base import focus_now
from sniffer.tui.rooms.exporting import Exporting
from sniffer.tui.rooms.feeding import Feeding, Flag, Indexed, PortNotice
from sniffer.tui.rooms.filtering import Filtering, FilterUpdated
from sniffer.tui.rooms.jumps import Jumps
from sniffer.tui.rooms.keyboard import Keyboard
from sniffer.tui.rooms.panes import Panes
from sniffer.tui.rooms.playback import Playback, paged_store
from sniffer.tui.rooms.recording import Recording
from sniffer.tui.rooms.status import StatusLine
from sniffer.tui.rooms.watching import Watching
from sniffer.tui.screens.main import MainScreen
from sniffer.tui.theme import themes
from sniffer.tui.webdriver import WholeWrites
from sniffer.tui.widgets.frame_list import FrameList
from sniffer.tui.widgets.health import HealthScreen
from sniffer.tui.widgets.watch import WatchPanel

Reopen = Callable[[], tuple[Session, Capture]]


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
        self.model = ViewModel(session, paged_store(session, live, speed))
        self.main = MainScreen(self.model, blink=blink)
        self.pacing = Pacing(speed)
        self.generation = 0  # of the rows: a restart begins a new one
        self.paused = False
        self.blink = blink
        self.said: deque[str] = deque(maxlen=50)  # what `say` told the user, newest last
        self.indexed = Flag()  # set when the feed has ended (tests and benchmarks wait on it)
        # the rooms (see `sniffer.tui.rooms`)
        self.feeding = Feeding(self)
        self.filtering = Filtering(self)
        self.keyboard = Keyboard(self)
        self.panes = Panes(self)
        self.watching = Watching(self)
        self.jumps = Jumps(self)
        self.playback = Playback(self)
        self.recording = Recording(self)
        self.exporting = Exporting(self)
        self.status_line = StatusLine(self)

    def get_driver_class(self) -> type[Driver]:
        """Textual's choice, except under textual-serve (`modscope serve`): its web driver
        with packets kept whole (see sniffer.tui.webdriver)."""
        chosen = super().get_driver_class()
        return WholeWrites if chosen is WebDriver else chosen

    @property
    def frames(self) -> FrameList:
        return self.main.frames

    async def on_mount(self) -> None:
        await self.push_screen(self.main)
        frames = self.frames
        frames.following = self.live is not None or self.pacing.speed is not None
        focus_now(frames)
        self.watch(self.main, "focused", self.keyboard.focus_changed)
        self.call_after_refresh(self.feeding.start)  # the first screen first
        self.set_interval(0.5, self._tick)
        self.call_after_refresh(self.panes.header)

    def on_resize(self) -> None:
        self.call_after_refresh(self.panes.header)

    def _tick(self) -> None:
        if not self.main.alive:
            return
        self.status_line.measure_rate()
        self.status_line.show()
        self.feeding.run_waiting()
        current = self.main.lower.current
        if current == "units":
            self.panes.units()
        elif current == "watch":
            self.watching.show()
        if self.model.job is not None:
            self.filtering.info()

    def say(
        self,
        text: str,
        *,
        title: str = "",
        severity: SeverityLevel = "information",
        timeout: float | None = None,
    ) -> None:
        """Tell the user something (never as markup); kept in `said` for a while."""
        self.said.append(text)
        self.notify(text, title=title, severity=severity, markup=False, timeout=timeout)

    # -- messages, each to its room --------------------------------------------------------

    def on_indexed(self, message: Indexed) -> None:
        self.feeding.indexed(message)

    def on_port_notice(self, message: PortNotice) -> None:
        self.say(message.text, title="port", severity="warning")

    def on_filter_updated(self, message: FilterUpdated) -> None:
        self.filtering.updated(message)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self.keyboard.submitted(event)

    def on_input_changed(self, event: Input.Changed) -> None:
        self.filtering.changed(event)

    def on_frame_list_cursor_moved(self, message: FrameList.CursorMoved) -> None:
        self.panes.show_detail(message.row)

    def on_frame_list_columns_changed(self, message: FrameList.ColumnsChanged) -> None:
        if self.main.alive:
            self.main.header.show(message.cols)

    def on_frame_list_follow_changed(self, message: FrameList.FollowChanged) -> None:
        self.status_line.show()

    def on_watch_panel_open(self, message: WatchPanel.Open) -> None:
        self.watching.open(message.key)

    async def on_event(self, event: events.Event) -> None:
        if not await self.keyboard.take(event):
            await super().on_event(event)

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        return self.keyboard.allows(action)

    # -- the keys' actions (`sniffer.tui.keys`), each to its room ----------------------------

    def action_help(self) -> None:
        self.keyboard.help()

    def action_list(self, name: str, step: int) -> None:
        self.keyboard.move(name, step)

    def action_submit(self) -> None:
        self.keyboard.submit()

    def action_cancel(self) -> None:
        self.keyboard.cancel()

    def action_next_pane(self) -> None:
        self.keyboard.next_pane()

    def action_to_list(self) -> None:
        self.keyboard.to_list()

    def action_edit_filter(self) -> None:
        self.filtering.edit()

    def action_problems(self) -> None:
        self.filtering.toggle_problems()

    def action_transactions(self) -> None:
        self.filtering.toggle_transactions()

    def action_filter_unit(self) -> None:
        self.filtering.unit_under_cursor()

    def action_pane(self, name: str) -> None:
        self.panes.pane(name)

    def action_fields(self) -> None:
        self.panes.fields()

    def action_zoom(self) -> None:
        self.panes.zoom()

    def action_detail_full(self) -> None:
        self.panes.detail_full()

    def action_ladder(self) -> None:
        self.panes.ladder()

    def action_health(self) -> None:
        self.push_screen(HealthScreen(self))

    def action_absolute(self) -> None:
        self.panes.toggle_absolute()

    def action_theme(self) -> None:
        self.panes.toggle_theme()

    def action_open_register(self) -> None:
        self.watching.open_under_cursor()

    def action_pick(self) -> None:
        self.watching.pick()

    def action_register_table(self) -> None:
        self.watching.table()

    def action_go_to(self) -> None:
        self.jumps.go_to()

    def action_find(self) -> None:
        self.jumps.find()

    def action_find_next(self, step: int) -> None:
        self.jumps.find_next(step)

    def action_problem(self, step: int) -> None:
        self.jumps.problem(step)

    def action_partner(self) -> None:
        self.jumps.partner()

    def action_mark(self) -> None:
        self.jumps.mark()

    def action_jump_mark(self) -> None:
        self.jumps.jump_mark()

    def action_follow(self) -> None:
        self.frames.action_follow()

    def action_pause(self) -> None:
        self.playback.pause()

    def action_speed(self) -> None:
        self.playback.speed()

    def action_record(self) -> None:
        self.recording.toggle()

    def action_export(self) -> None:
        self.exporting.export()

    def action_copy(self, what: str) -> None:
        self.exporting.copy(what)

    # -- leaving ---------------------------------------------------------------------------

    async def action_quit(self) -> None:
        self.recording.quit()  # asks first while a recording runs

    def leave(self) -> None:
        self.feeding.stop()
        self.exit(0)

    def on_unmount(self) -> None:
        self.feeding.stop()


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
    if app.recording.made:
        # the recordings are complete once the capture has stopped (the caller's stop()
        # after this one does nothing more); then say where each one is
        stop = getattr(live, "stop", None)
        if callable(stop):
            stop()
        for line in app.recording.report():
            print(line, file=sys.stderr)
    return result if isinstance(result, int) else 0
