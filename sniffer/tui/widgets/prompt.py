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
from textual.widgets.input import Selection

Answer = Callable[[str | None], None]
Decide = Callable[[str], None]  # gets the key that answered a one-key question


class LineInput(Input):
    """An input the app types into itself (`type_key`), in the app's own loop.

    Textual hands a key to the focused input by queueing it there; a key that ends the
    input (Enter) is handled by the app before the input has taken the characters
    queued ahead of it, and editing keys (Backspace, arrows) run from the input's
    bindings only after bubbling back up to the app, behind later characters. Typing
    each key into the input when the app receives it keeps every key in order with
    the keys around it, however fast they come."""

    def __init__(self, value: str = "", *, placeholder: str = "", id: str | None = None) -> None:
        super().__init__(value, placeholder=placeholder, id=id, select_on_focus=False)

    async def type_key(self, event: events.Key) -> bool:
        """Apply a key now; False if it is not one for the input (Enter, Esc, Tab)."""
        if event.is_printable and event.character is not None:
            selection = self.selection
            if selection.is_empty:
                self.insert_text_at_cursor(event.character)
            else:
                self.replace(event.character, *selection)
            return True
        for binding in self._bindings.key_to_bindings.get(event.key, ()):
            if binding.action in ("submit",):
                return False
            await self.run_action(binding.action)
            return True
        return False

    def select_all(self) -> None:
        """Select the text now (typing replaces it; an arrow key keeps it)."""
        self.selection = Selection(0, len(self.value))


class PromptBar(Horizontal):
    """A prompt and an input; hidden until `ask`."""

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.label = Static(Text(""), id="prompt-label")
        self.input = LineInput(id="prompt-input")
        self.answer: Answer | None = None
        self.decide: Decide | None = None  # a one-key question is open (see `confirm`)
        self.default = ""

    def compose(self) -> ComposeResult:
        yield self.label
        yield self.input

    @property
    def open(self) -> bool:
        return self.answer is not None

    @property
    def confirming(self) -> bool:
        return self.decide is not None

    def confirm(self, prompt: str, decide: Decide) -> None:
        """Show `prompt` with no input: the next key answers it (the app hands it to
        `settle`), whatever it is, so a stray key never does anything else meanwhile."""
        if self.answer is not None:
            self.close(False)
        self.decide = decide
        self.label.update(Text(prompt))
        self.input.display = False
        self.set_class(True, "-confirm")  # the question wraps: it names a file in full
        self.display = True

    def settle(self, key: str) -> None:
        """The key typed after a one-key question: the question closes, `decide` gets it."""
        decide, self.decide = self.decide, None
        self.display = False
        self.set_class(False, "-confirm")
        self.input.display = True
        if decide is not None:
            decide(key)

    def ask(self, prompt: str, answer: Answer, *, default: str = "", value: str = "") -> None:
        """Show `prompt` and focus the input now. `answer` gets the text (the `default`
        when the input is left empty) or None (Esc)."""
        if self.answer is not None:
            self.answer(None)  # a question still open is cancelled
        self.decide = None
        self.set_class(False, "-confirm")
        self.input.display = True
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
