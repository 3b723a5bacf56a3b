"""Provides the rows the frame list shows: all of them, one per transaction, or a filter's matches.

The matcher itself (`FilterJob`, the column masks, `Options`) lives in `sniffer.meaning.select`,
shared with the command line's `--filter`. This module adds what only the list needs: a
read-only view of a store another thread fills, the mapping from
list positions to rows, and each unit's last answer. Nothing here imports Textual; the
app runs `FilterJob.advance` in a worker thread while the UI reads `FilterJob.rows`.
"""

from __future__ import annotations

from array import array
from bisect import bisect_left

from sniffer.framing.store import FrameStore
from sniffer.meaning.select import _and, _bytes_mask, _table  # the masks last_answers scans
from sniffer.vocab import Kind


class StoreReader(FrameStore):
    """A read-only view of a store that another thread is filling.

    It shares the store's columns and streams but never grows them (`sync` does nothing),
    so the UI thread can describe rows while the ingest thread appends. Read only rows
    below the count the ingest thread last published: all their columns are complete.
    """

    def __init__(self, store: FrameStore) -> None:  # shares the columns: no super().__init__
        self.streams = store.streams
        self.offset = store.offset
        self.length = store.length
        self.t = store.t
        self.t_end = store.t_end
        self.kind = store.kind
        self.unit = store.unit
        self.fc = store.fc
        self.flags = store.flags
        self.channel = store.channel
        self.partner = store.partner
        self.status = store.status
        self.notes = store.notes
        self.peers = store.peers  # network captures and gateway links (filled as read)
        self.servers = store.servers
        self.links = store.links
        self._source = store
        self.stamps = store.stamps
        self.resolution = store.resolution

    def sync(self) -> None:
        # read through what the ingest thread may refine (the read resolution)
        self.stamps = self._source.stamps
        self.resolution = self._source.resolution
        return None


class RowView:
    """The rows the list shows: positions 0..count-1 mapped to store rows."""

    def __init__(self, rows: array[int] | None = None, count: int = 0) -> None:
        self.rows = rows  # None: every row (position == row)
        self.count = count if rows is None else min(count, len(rows))

    def __len__(self) -> int:
        return self.count

    def row(self, k: int) -> int:
        return k if self.rows is None else self.rows[k]

    def position(self, row: int) -> int:
        """The position of `row`, or of the first shown row after it (clamped)."""
        if self.count == 0:
            return 0
        if self.rows is None:
            return min(max(row, 0), self.count - 1)
        k = bisect_left(self.rows, row, 0, self.count)
        return min(k, self.count - 1)

    def contains(self, row: int) -> bool:
        if self.rows is None:
            return 0 <= row < self.count
        k = bisect_left(self.rows, row, 0, self.count)
        return k < self.count and self.rows[k] == row

    def at_time(self, store: FrameStore, t: float) -> int:
        """The position of the first shown row at or after time `t` (clamped)."""
        if self.count == 0:
            return 0
        if self.rows is None:
            return min(bisect_left(store.t, t, 0, self.count), self.count - 1)
        rows = self.rows
        k = bisect_left(range(self.count), t, key=lambda p: store.t[rows[p]])
        return min(k, self.count - 1)


def last_answers(store: FrameStore, lo: int, hi: int) -> dict[int, int]:
    """The last answer (normal or exception) of each unit among rows [lo, hi)."""
    if hi <= lo:
        return {}
    answers = _bytes_mask(store.kind, lo, hi, (Kind.RESPONSE, Kind.EXCEPTION))
    units = store.unit[lo:hi].tobytes()
    out: dict[int, int] = {}
    for u in set(units):
        k = _and(answers, units.translate(_table((u,)))).rfind(1)
        if k >= 0:
            out[u] = lo + k
    return out
