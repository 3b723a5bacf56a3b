"""Provides search without filtering: the next or previous row that matches (`n` `N`, `]` `[`).

The scan goes block by block from the cursor in one direction over the store's columns
(cheap) and decodes only the candidates when the query needs details. It stops after a
time budget and says where it got to, so a search in a huge capture never freezes the
screen: the next `n` goes on from there. Nothing here imports Textual.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from itertools import compress

from sniffer.framing.store import FrameStore
from sniffer.meaning.describe import Describer, FrameDetail
from sniffer.meaning.query import Query
from sniffer.meaning.select import Options, column_mask, row_matches

BLOCK = 65536


@dataclass(frozen=True, slots=True)
class Found:
    row: int | None  # the matching row, None when none was found
    stopped: int  # the row the scan would go on from (the end reached, or the budget)
    complete: bool  # the scan reached the end in its direction


def find_row(
    store: FrameStore,
    describer: Describer,
    query: Query,
    options: Options,
    start: int,
    step: int,
    count: int,
    shown: Callable[[int], bool],
    budget: float = 0.5,
) -> Found:
    """The first row after (`step` 1) or before (`step` -1) `start`, below `count`, that
    matches `query` and that `shown` accepts (the rows the filter lets through)."""
    deadline = time.monotonic() + budget

    def one(i: int) -> list[FrameDetail]:
        return [describer.detail(i)]

    pos = start + step
    while 0 <= pos < count:
        lo, hi = (pos, min(count, pos + BLOCK)) if step > 0 else (max(0, pos - BLOCK + 1), pos + 1)
        mask = column_mask(store, lo, hi, query, options)
        rows = list(compress(range(lo, hi), mask))
        if step < 0:
            rows.reverse()
        for i in rows:
            if not shown(i):
                continue
            if query.needs_detail and not row_matches(
                store, i, query, options, one, candidate=True
            ):
                if time.monotonic() > deadline:
                    return Found(None, i, False)
                continue
            return Found(i, i, True)
        pos = hi if step > 0 else lo - 1
        if time.monotonic() > deadline and 0 <= pos < count:
            return Found(None, pos - step, False)
    return Found(None, pos - step, True)
