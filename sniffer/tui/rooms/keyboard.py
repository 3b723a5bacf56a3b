"""Provides the keys' room: where the focus is, which keys apply there, keys typed into the
filter or the prompt in order, Enter and Esc in an input, the list's moving keys."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from textual import events
from textual.widgets import DataTable, Input

from sniffer.tui.keys import Context, key_context
from sniffer.tui.rooms.base import Room, focus_now
from sniffer.tui.screens.dialogs import HelpScreen
from sniffer.tui.widgets.prompt import LineInput

if TYPE_CHECKING:
    from sniffer.tui.app import ModscopeApp


class Keyboard(Room):
    """Routes the main screen's keys by focus (see `sniffer.tui.keys`)."""

    def __init__(self, app: ModscopeApp) -> None:
        super().__init__(app)
        # keys typed into a register watch that has no row yet (`w Tab x ↓ x R` at once:
        # its scan has only begun), and every key after them, in order: they are
        # handed on once it shows rows or has read everything (`release`)
        self.held: list[events.Key] = []

    def context(self) -> Context:
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

    def allows(self, action: str) -> bool:
        """The main screen's keys apply only where the focus is (see `sniffer.tui.keys`);
        a key that does not apply goes on to the focused widget."""
        if self.app.screen is not self.main:
            return True
        context = key_context(action)
        if context is None:
            return True
        here = self.context()
        if context is Context.ANY:
            return here is not Context.INPUT
        if action == "list":  # the moving keys move the units and watch tables too
            return here in (Context.LIST, Context.UNITS, Context.WATCH)
        return here is context

    def focus_changed(self) -> None:
        if self.main.alive:
            self.main.keybar.show(self.context())

    async def take(self, event: events.Event) -> bool:
        """Keys for the filter or the prompt are typed into it here, as they arrive, so
        they keep their order with the keys before and after them (see LineInput); True
        if the event was handled (the app then does nothing more with it).

        A terminal sends Esc and a key typed right after it as one sequence, which reads
        as alt+key: no key of modscope uses alt, so it is taken as the two keys typed."""
        app = self.app
        if (
            isinstance(event, events.Key)
            and event.key.startswith("alt+")
            and "+" not in event.key[4:]
            and not event.is_forwarded
        ):
            event.stop()
            for key, char in (("escape", "\x1b"), (event.key[4:], event.character)):
                typed = events.Key(key, char)
                typed.set_sender(app)
                await app.on_event(typed)
            return True
        if isinstance(event, events.Key) and not event.is_forwarded and app.screen is self.main:
            if self.held or (self.main.focused is self.main.watch_panel and self._watch_empty()):
                event.stop()
                self.held.append(event)
                return True
            if self.main.prompt.confirming:  # a one-key question: this key answers it
                event.stop()
                self.main.prompt.settle(event.key)
                return True
            field = self.main.focused
            if isinstance(field, LineInput) and event.key == "ctrl+j":
                # a newline: Enter typed before the terminal was switched to raw mode
                # (type-ahead while modscope starts) arrives as LF, not CR
                event.stop()
                self.submit()
                return True
            if isinstance(field, LineInput) and await field.type_key(event):
                event.stop()
                return True
        return False

    def _watch_empty(self) -> bool:
        """The register watch has no row yet but its scan has more to read."""
        watching = self.app.watching
        return not self.main.watch_panel.row_count and watching.progress() is not None

    def release(self) -> None:
        """Hand on the keys held for the register watch, once it shows rows (or has read
        everything there is: then the keys find what is there, perhaps nothing)."""
        if not self.held or self._watch_empty():
            return
        keys, self.held = self.held, []
        self.app.call_later(self._replay, keys)

    async def _replay(self, keys: list[events.Key]) -> None:
        app = self.app
        for i, key in enumerate(keys):
            if self.held:  # the watch emptied again (a restart): keep the rest, in order
                self.held[:0] = keys[i:]
                return
            typed = events.Key(key.key, key.character)
            typed.set_sender(app)
            await app.on_event(typed)

    def move(self, name: str, step: int) -> None:
        """The list's moving keys, in the frame list or the focused units or watch table."""
        self.app.feeding.forget("go to")  # a move of one's own outranks a jump still waiting
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

    def submitted(self, event: Input.Submitted) -> None:
        """Enter in an input that did not come through the priority key (a click, a paste)."""
        event.stop()
        if event.input is self.main.filter_input:
            self.app.filtering.apply(event.value)
        elif event.input is self.main.prompt.input:
            self._close_prompt(submit=True)

    def submit(self) -> None:
        main = self.main
        field = main.focused
        focus_now(self.frames)  # keys typed after Enter go to the list
        if field is main.filter_input:
            self.app.filtering.apply(main.filter_input.value)
        elif field is main.prompt.input:
            main.prompt.close(True)

    def cancel(self) -> None:
        main = self.main
        field = main.focused
        focus_now(self.frames)
        if field is main.filter_input:
            self.app.filtering.revert()
        elif field is main.prompt.input:
            main.prompt.close(False)

    def ask(self, prompt: str, answer: Callable[[str | None], None], default: str = "") -> None:
        self.main.prompt.ask(prompt, answer, default=default)

    def _close_prompt(self, submit: bool) -> None:
        focus_now(self.frames)
        self.main.prompt.close(submit)

    def next_pane(self) -> None:
        self.main.focus_next()

    def to_list(self) -> None:
        self.main.remove_class("-detail-full")
        focus_now(self.frames)

    def help(self) -> None:
        self.app.push_screen(HelpScreen())
