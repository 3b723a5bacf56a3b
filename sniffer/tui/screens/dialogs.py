"""Provides the help screen (questions are asked in the main screen's prompt line)."""

from __future__ import annotations

from typing import ClassVar

from rich.table import Table
from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Static

# the keys, as (key, what it does); shown in two columns side by side
KEY_HELP: tuple[tuple[str, str], ...] = (
    ("↑↓ PgUp/Dn", "move (up stops following)"),
    ("Home", "the first row"),
    ("End f", "follow the newest row"),
    ("Enter", "the fields; units: filter"),
    ("Tab", "next pane"),
    ("p", "the paired request/answer"),
    ("/", "filter (Esc: the applied)"),
    ("!", "only problems"),
    ("] [", "next / previous problem"),
    ("F n N", "find; next / previous"),
    ("m '", "mark / jump to next mark"),
    ("c C", "copy hex / JSON (OSC 52)"),
    ("t", "frames / transactions"),
    ("a", "relative / wall clock time"),
    ("g", "go to 12.5, 2m, 14:03, #12"),
    ("space", "pause (recording goes on)"),
    ("s", "original speed / fastest"),
    ("d u w", "details / units / watch"),
    ("D", "details on the whole screen"),
    ("l", "ladder, with latencies"),
    ("x R", "watch: pick / their table"),
    ("z", "hide the lower pane"),
    ("e", "export (.jsonl .csv text)"),
    ("r", "record; running: r stop,"),
    ("", "n new file, else keep on"),
    ("T", "dark / light theme"),
    ("?", "this help"),
    ("q", "quit (recording: q again)"),
)

FILTER_HELP = """\
filter language (side by side: all hold; or, and, not, parentheses)

  unit:3  unit:1,2  unit:1-5     slave address
  fc:3  fc:3,16                  function code (exceptions included)
  kind:request|response|exception|noise|event|unknown
  status:ok|exception|timeout|orphan|broadcast|open|check|noise|problem
  reg:"Under Voltage"            a named register (units with a dictionary)
  t:10-20  t:10-  t:-20          seconds from the start (500ms, 2m work)
  t:14:03-14:05                  clock time of the capture
  -fc:3  -unit:0                 leave out (unit, fc, kind and status)
  words  "two words"             text in the row (name, summary, device...)

  e.g.  unit:3 fc:3 status:timeout     reg:"Under Voltage" t:10-20
        exception -unit:4              (unit:3 or unit:5) status:timeout
"""


def help_table() -> Table:
    """The keys in two columns of (key, text), the text wrapped in its column."""
    table = Table.grid(padding=(0, 1), expand=True)
    for _ in range(2):
        table.add_column(no_wrap=True, style="bold")
        table.add_column(ratio=1, no_wrap=True, overflow="ellipsis")
    half = (len(KEY_HELP) + 1) // 2
    left, right = KEY_HELP[:half], KEY_HELP[half:]
    for k, (key, text) in enumerate(left):
        other = right[k] if k < len(right) else ("", "")
        table.add_row(key, text, *other)
    return table


class HelpScreen(ModalScreen[None]):
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape,q,question_mark", "close", "close", priority=True),
    ]

    def compose(self) -> ComposeResult:
        with VerticalScroll(id="help-box"):
            yield Static(Text("modscope: keys", style="bold"), id="help-title")
            yield Static(help_table(), id="help-keys")
            yield Static(Text(FILTER_HELP), id="help-text")

    def action_close(self) -> None:
        self.dismiss(None)
