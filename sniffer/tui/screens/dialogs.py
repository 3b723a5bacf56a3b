"""Provides the help screen (questions are asked in the main screen's prompt line)."""

from __future__ import annotations

from typing import ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Static

HELP = """\
modscope: keys

  ↑ ↓ PgUp PgDn Home   move in the frame list (moving up stops following)
  End  f               follow the newest frame again
  Enter                show the frame's fields (Tab moves between panes);
                       on a unit in the units pane: filter to it
  p                    jump to the paired request or answer
  /                    edit the filter (Enter applies, Esc puts back the applied one)
  !                    only problems (exceptions, timeouts, bad checks, noise)
  ] [                  next / previous problem, without filtering
  F  n N               find (filter terms), next / previous match, without filtering
  m  '                 mark the row / jump to the next mark
  c  C                 copy the frame as hex / as JSON (OSC 52)
  t                    one row per frame / one row per transaction
  a                    relative / absolute (wall clock) time
  g                    go to a time (12.5, 2m, 1:02:03, 14:03:07) or a row (#1234)
  space                pause / resume (a live capture keeps recording)
  s                    replay as fast as possible / at the original speed
  d u w                lower pane: details / units / register watch
  l                    ladder: master and slaves as columns, arrows with latencies
  x  R                 register watch: pick registers / their table, a row a poll
  z                    hide the lower pane (more frames on screen)
  D                    the details on the whole screen (again or Esc: back)
  e                    export the rows shown (.jsonl, .csv, else text)
  r                    live: record the line to a file; while one runs, ask:
                       r stops it, n goes on in a new file, other keys keep it
  T                    dark / light theme
  ?                    this help
  q                    quit (while recording: q again, other keys keep going)

filter language (terms separated by spaces, all must hold)

  unit:3  unit:1,2  unit:1-5     slave address
  fc:3  fc:3,16                  function code (exceptions included)
  kind:request|response|exception|noise|event|unknown
  status:ok|exception|timeout|orphan|broadcast|open|check|noise|problem
  reg:"Under Voltage"            a named register (bound units; dissects rows)
  t:10-20  t:10-  t:-20          seconds from the start (500ms, 2m also work)
  t:14:03-14:05                  clock time of the capture
  -fc:3  -unit:0                 leave out (unit, fc, kind and status)
  words  "two words"             text in the row: name, summary, device, problems

  e.g.  unit:3 fc:3 status:timeout    reg:"Under Voltage" t:10-20    exception -unit:4
"""


class HelpScreen(ModalScreen[None]):
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape,q,question_mark", "close", "close", priority=True),
    ]

    def compose(self) -> ComposeResult:
        with VerticalScroll(id="help-box"):
            yield Static(Text(HELP), id="help-text")

    def action_close(self) -> None:
        self.dismiss(None)
