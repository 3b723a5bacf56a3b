"""Provides the key bar: every key that applies where the focus is, on as many lines as it needs
(two at 80 columns), instead of Textual's one-line footer that cuts the last keys off."""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

from rich.style import Style
from rich.text import Text
from textual.widgets import Static

from sniffer.tui.keys import KEYS, Context, Key

MAX_LINES = 2


def key_hints(pairs: Sequence[tuple[str, str]]) -> Text:
    """One line of `key what` hints, keys in bold (the full screens' key lines)."""
    text = Text()
    for key, what in pairs:
        text.append(key, "bold")
        text.append(f" {what}  ")
    return text


def key_lines(keys: Sequence[Key], width: int, key_style: Style, text_style: Style) -> Text:
    """The keys as `key text` pairs, wrapped at `width` cells, at most MAX_LINES lines:
    two spaces between pairs, or one when two do not fit. When even that does not fit,
    the last line ends with `? more` (the help lists every key)."""
    items = [(k.label, k.text) for k in keys if k.bar]
    for sep in (2, 1):
        lines = _wrap(items, width, sep)
        if len(lines) <= MAX_LINES:
            break
    else:
        lines = lines[:MAX_LINES]
        last = lines[-1]
        while last and sum(len(a) + len(b) + 1 + sep for a, b in last) + 7 > width:
            last.pop()
        last.append(("?", "more"))
    out = Text(no_wrap=True, overflow="crop")
    for n, line in enumerate(lines):
        if n:
            out.append("\n")
        for m, (label, text) in enumerate(line):
            if m:
                out.append(" " * sep)
            out.append(label, key_style)
            out.append(" " + text, text_style)
    return out


def _wrap(items: list[tuple[str, str]], width: int, sep: int) -> list[list[tuple[str, str]]]:
    lines: list[list[tuple[str, str]]] = [[]]
    used = 0
    for label, text in items:
        cells = len(label) + 1 + len(text)
        if lines[-1] and used + sep + cells > width:
            lines.append([])
            used = 0
        used += cells + (sep if lines[-1] else 0)
        lines[-1].append((label, text))
    return lines


class KeyBar(Static):
    """The keys at the bottom of the main screen."""

    COMPONENT_CLASSES: ClassVar[set[str]] = {"key-bar--key", "key-bar--text"}

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.context = Context.LIST

    def show(self, context: Context) -> None:
        self.context = context
        self._draw()

    def on_resize(self) -> None:
        self._draw()

    def _draw(self) -> None:
        if self.context is Context.INPUT:
            keys = [k for k in KEYS if k.context is Context.INPUT]
        else:  # the keys of the focused pane first
            keys = [k for k in KEYS if k.context is self.context and k.context is not Context.ANY]
            keys += [k for k in KEYS if k.context is Context.ANY]
        key_style = self.get_component_rich_style("key-bar--key", partial=True)
        text_style = self.get_component_rich_style("key-bar--text", partial=True)
        width = self.size.width or 80
        self.update(key_lines(keys, width, key_style, text_style))
