"""Provides the register table: registers picked in the watch side by side, one row a poll.

A pass over the frames that carry the picked registers (requests that write them and
answers that read them, as the register watch reads them), a slice at a time from a
worker thread. A row is one poll: it gathers the picked registers' values in capture
order and a new row begins with a frame that carries a register the row has already
(so registers read by separate requests, or from separate units, share a row per round).
Every value is kept as read (no thinning): the newest `MAX_ROWS` rows stay, and the
table says how many older ones were let go. Nothing here imports Textual.
"""

from __future__ import annotations

import threading
import time as _time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from sniffer.framing.store import FrameStore
from sniffer.meaning.annotate import Annotator
from sniffer.meaning.describe import Describer
from sniffer.tui.watch import SeriesKey, value_text
from sniffer.vocab import BAD_CHECK, Kind

MAX_ROWS = 200_000
_ECHO_FUNCTIONS = (5, 6, 15, 16)  # answers that repeat what the request wrote


@dataclass(frozen=True, slots=True)
class PollRow:
    t: float  # the time of the first value in the row
    row: int  # the frame that carried the first value
    values: tuple[str | None, ...]  # one a picked register, None: not read in this poll


class RegisterTable:
    """The picked registers' values over time, filled by `advance(upto)` (any thread)."""

    def __init__(self, store: FrameStore, annotator: Annotator, keys: Sequence[SeriesKey]) -> None:
        self.store = store
        self.keys = tuple(keys)
        self.index = {k: n for n, k in enumerate(self.keys)}
        self.units = frozenset(k[0] for k in self.keys)
        self.describer = Describer(store, annotator, size=256)
        self.rows: deque[PollRow] = deque(maxlen=MAX_ROWS)
        self.dropped = 0  # older rows let go (more than MAX_ROWS polls)
        self.next = 0  # the first store row not read yet
        self.lock = threading.Lock()
        self.version = 0
        self._current: list[str | None] = [None] * len(self.keys)
        self._start: tuple[float, int] | None = None

    def advance(
        self, upto: int, should_stop: Callable[[], bool] | None = None, budget: float = 0.05
    ) -> bool:
        """Take in rows below `upto` for about `budget` seconds; True if work is left."""
        store = self.store
        kind, unit, fc, flags = store.kind, store.unit, store.fc, store.flags
        deadline = _time.monotonic() + budget
        units = self.units
        i = self.next
        while i < upto:
            if should_stop is not None and i % 256 == 0 and should_stop():
                break
            k = kind[i]
            if (
                unit[i] in units
                and not flags[i] & BAD_CHECK
                and (k == Kind.REQUEST or (k == Kind.RESPONSE and fc[i] not in _ECHO_FUNCTIONS))
            ):
                d = self.describer.detail(i)
                found = [
                    (n, value_text(r))
                    for r in d.registers
                    if not r.partial
                    and (n := self.index.get((d.view.unit, r.table, r.address, r.name))) is not None
                ]
                if found:
                    # a frame belongs to one poll: a register it carries again starts the next
                    if any(self._current[n] is not None for n, _ in found):
                        self._close()
                    if self._start is None:
                        self._start = (d.view.t, i)
                    for n, text in found:
                        self._current[n] = text
            i += 1
            if i % 64 == 0 and _time.monotonic() > deadline:
                break
        self.next = i
        return i < upto

    def finish(self) -> None:
        """The capture has ended: the last poll's row is complete."""
        if self._start is not None:
            self._close()

    def _close(self) -> None:
        assert self._start is not None
        t, row = self._start
        with self.lock:
            if len(self.rows) == self.rows.maxlen:
                self.dropped += 1
            self.rows.append(PollRow(t, row, tuple(self._current)))
            self.version += 1
        self._current = [None] * len(self.keys)
        self._start = None

    def current(self) -> PollRow | None:
        """The poll being gathered (values so far), shown as the newest row while live."""
        if self._start is None:
            return None
        return PollRow(self._start[0], self._start[1], tuple(self._current))
