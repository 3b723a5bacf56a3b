"""Provides the main screen's keys, once: the bindings, the key bar and the help read this table.

Every key of the main screen is a *priority* binding: Textual handles it in the app's
own message loop, in the order the keys arrived, before it forwards the next key to
the focused widget. A key that moves the focus (`/`, `g`, `e`, Enter in an input)
therefore moves it before the keys typed after it are delivered, however fast they
come (a paste, a slow SSH link that delivers a whole line at once). Whether a key
applies depends on where the focus is (`Context`); when it does not, the key goes on
to the focused widget (a `/` typed in the filter is a character).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class Context(Enum):
    """Where the focus must be for a key to apply."""

    ANY = "any"  # anywhere but in a text input
    LIST = "list"  # the frame list
    INPUT = "input"  # the filter or the prompt input
    UNITS = "units"  # the units pane
    WATCH = "watch"  # the register watch


@dataclass(frozen=True, slots=True)
class Key:
    keys: str  # Textual key names, comma separated
    action: str  # an action of the app (without the `app.` prefix)
    label: str  # how the key bar shows the key
    text: str  # what it does, in the key bar (short)
    context: Context = Context.ANY
    bar: bool = True  # shown in the key bar


KEYS: tuple[Key, ...] = (
    # the key bar shows these, in this order, as room allows (`?` comes first)
    Key("question_mark", "help", "?", "help"),
    Key("q", "quit", "q", "quit"),
    Key("slash", "edit_filter", "/", "filter"),
    Key("exclamation_mark", "problems", "!", "probs"),
    Key("t", "transactions", "t", "txn"),
    Key("g", "go_to", "g", "goto"),
    Key("F", "find", "F", "find", bar=False),
    Key("n", "find_next(1)", "n/N", "find"),
    Key("N", "find_next(-1)", "N", "previous", bar=False),
    Key("right_square_bracket", "problem(1)", "]/[", "prob"),
    Key("left_square_bracket", "problem(-1)", "[", "problem", bar=False),
    Key("p", "partner", "p", "pair"),
    Key("m", "mark", "m/'", "mark"),
    Key("apostrophe", "jump_mark", "'", "jump", bar=False),
    Key("e", "export", "e", "export"),
    Key("c", "copy('hex')", "c/C", "copy"),
    Key("C", "copy('json')", "C", "copy JSON", bar=False),
    Key("r", "record", "r", "rec"),
    Key("d", "pane('detail')", "d/u/w/l", "pane"),
    Key("u", "pane('units')", "u", "units", bar=False),
    Key("w", "pane('watch')", "w", "watch", bar=False),
    Key("l", "ladder", "l", "ladder", bar=False),
    Key("H", "health", "H", "bus health", bar=False),
    Key("z", "zoom", "z", "zoom"),
    Key("space", "pause", "␣", "pause"),
    Key("s", "speed", "s", "speed"),
    Key("f", "follow", "f", "follow"),
    Key("a", "absolute", "a", "time"),
    Key("tab", "next_pane", "tab", "pane", bar=False),
    Key("T", "theme", "T", "light/dark", bar=False),
    # the frame list
    Key("up,k", "list('cursor', -1)", "↑", "up", Context.LIST, bar=False),
    Key("down,j", "list('cursor', 1)", "↓", "down", Context.LIST, bar=False),
    Key("pageup", "list('page', -1)", "PgUp", "page up", Context.LIST, bar=False),
    Key("pagedown", "list('page', 1)", "PgDn", "page down", Context.LIST, bar=False),
    Key("home", "list('first', 0)", "Home", "first", Context.LIST, bar=False),
    Key("end", "list('follow', 0)", "End", "last", Context.LIST, bar=False),
    Key("enter", "fields", "⏎", "fields", Context.LIST, bar=False),
    Key("enter", "filter_unit", "⏎", "unit", Context.UNITS),
    Key("enter", "open_register", "⏎", "plot", Context.WATCH),
    Key("x", "pick", "x", "pick", Context.WATCH),
    Key("R", "register_table", "R", "table", Context.WATCH),
    Key("escape", "to_list", "esc", "back", bar=False),
    # an input (the filter bar or a prompt)
    Key("enter", "submit", "⏎", "apply", Context.INPUT),
    Key("escape", "cancel", "esc", "cancel", Context.INPUT),
)


def key_context(action: str) -> Context | None:
    """The context of an action of the table (None: not one of the main screen's keys)."""
    for key in KEYS:
        if key.action == action or key.action.split("(")[0] == action:
            return key.context
    return None
