"""Provides the prompt line: one question at a time (go to, export, record, find) asked in a line of
the main screen, not in a separate screen, so its input has the focus at once and keys
typed right after the key that opened it land in it, in order."""

from __future__ import annotations

from collections.abc import Callable

from rich.text import Text
from textual import events
from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.widgets import Input, Static

Answer = Callable[[str | None], None]


class LineInput(Input):
    """An input that handles its editing keys (Backspace, arrows, ...) in its own queue, in
    order with the characters. Textual's Input leaves them to its bindings, which run when
    the key has bubbled up to the app: in a fast burst a later character is inserted
    first (`ab` Backspace `c` gave `ab`). Enter and Esc belong to the app (it moves the
    focus at once, then commits here after the characters before them)."""

    async def _on_key(self, event: events.Key) -> None:
        if not event.is_printable and event.key not in ("enter", "escape", "tab"):
            for binding in self._bindings.key_to_bindings.get(event.key, ()):
                event.stop()
                event.prevent_default()
                await self.run_action(binding.action)
                return
        await super()._on_key(event)


class PromptBar(Horizontal):
    """A prompt and an input; hidden until `ask`."""

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.label = Static(Text(""), id="prompt-label")
        self.input = LineInput(id="prompt-input")
        self.answer: Answer | None = None
        self.default = ""

    def compose(self) -> ComposeResult:
        yield self.label
        yield self.input

    @property
    def open(self) -> bool:
        return self.answer is not None

    def ask(self, prompt: str, answer: Answer, *, default: str = "", value: str = "") -> None:
        """Show `prompt` and focus the input now. `answer` gets the text (the `default`
        when the input is left empty) or None (Esc)."""
        if self.answer is not None:
            self.answer(None)  # a question still open is cancelled
        self.answer = answer
        self.default = default
        self.label.update(Text(prompt))
        self.input.value = value
        self.input.placeholder = default
        self.display = True
        self.screen.set_focus(self.input)  # now: the next key is already on its way

    def close(self, submit: bool) -> None:
        answer, self.answer = self.answer, None
        text = (self.input.value.strip() or self.default) if submit else None
        self.display = False
        self.input.value = ""
        if answer is not None:
            answer(text or None)
