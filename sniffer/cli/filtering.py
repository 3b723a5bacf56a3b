"""Provides --filter QUERY and -c/--count N for the commands that list frames (replay,
live, export): the TUI's filter language and matcher, so a query means the same on the
command line as in the frame list's filter bar, with the same error messages."""

from __future__ import annotations

import argparse
from array import array
from collections.abc import Sequence
from typing import TextIO

from sniffer.errors import UsageError
from sniffer.meaning.annotate import Annotator
from sniffer.meaning.query import Query, QueryError, parse_query
from sniffer.meaning.select import FilterJob, Options  # the TUI's matcher, in the core
from sniffer.session.session import Session

FILTER_HELP = (
    "only frames matching QUERY, in the TUI's filter language: unit:3 fc:3,16 "
    'kind:exception status:timeout reg:"Under Voltage" t:10-20 and plain words; '
    "-fc:3 excludes; or, and, not and parentheses combine terms: "
    "'(unit:3 or unit:4) not status:ok' (see docs/tui.md)"
)


def add_filter_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("selecting frames")
    g.add_argument("--filter", metavar="QUERY", help=FILTER_HELP)
    g.add_argument("-c", "--count", type=int, metavar="N", help="stop after N frames")


def query_of(args: argparse.Namespace, err: TextIO | None = None) -> Query | None:
    """The parsed --filter, or None; a bad query is a UsageError with the TUI's message.
    Given `err`, what the query's words may mean instead is said there (`Query.hints`):
    once a command, so only where it first reads the filter."""
    text = getattr(args, "filter", None)
    count = getattr(args, "count", None)
    if count is not None and count < 1:
        raise UsageError(f"-c/--count must be at least 1, not {count}")
    if not text:
        return None
    try:
        query = parse_query(text)
    except QueryError as exc:
        raise UsageError(f"--filter: {exc}") from None
    if err is not None:
        for hint in query.hints():
            err.write(f"modscope: note: --filter: {hint}\n")
    return None if query.empty else query


class Selection:
    """Rows to show, in order: all of them, or those a query matches; at most `count`.

    `take(upto, final)` returns the rows below `upto` not handed out before. With a query,
    rows whose request still waits for its answer are held until it is decided (as the
    TUI does), unless `final`.

    A capture taken a segment at a time (`sniffer.session.streamed`): `next_segment` once
    the session's store holds the next segment's rows, which `take` then numbers from 0;
    `first` is the capture's first time (what a query's times count from) and
    `annotator` the one the segment's rows are described with.
    """

    def __init__(
        self,
        session: Session,
        query: Query | None,
        count: int | None,
        *,
        first: float | None = None,
        annotator: Annotator | None = None,
    ) -> None:
        self.session = session
        self.query = query
        self.left = count
        self.given = 0  # rows (or matches) handed out so far
        self.job: FilterJob | None = None
        self.first = first
        self.annotator = annotator

    def next_segment(self, annotator: Annotator | None = None) -> None:
        """The session's store now holds the next segment's rows (see above)."""
        self.given = 0
        self.job = None
        self.annotator = annotator

    @property
    def done(self) -> bool:
        return self.left is not None and self.left <= 0

    def origin(self) -> float | None:
        """The capture's first time: filtered listings count time from it, as the TUI."""
        if self.first is not None:
            return self.first
        store = self.session.store
        return store.t[0] if len(store) else None

    def take(self, upto: int, final: bool = False) -> Sequence[int]:
        # a range or a slice of the matches' array, never a list: a list of every row
        # number cost about 40 bytes a row (115 MB for 3M rows) for the whole listing
        if self.done:
            return range(0)
        store = self.session.store
        if self.query is None:
            rows: Sequence[int] = range(self.given, upto)
            self.given = max(self.given, upto)
        else:
            if self.job is None:
                origin = self.origin()
                annotator = self.annotator or self.session.annotator
                bound = Options(bound=annotator.bindings)
                self.job = FilterJob(store, self.query, bound, annotator, origin or 0.0)
            while self.job.advance(upto, budget=1.0, final=final):
                pass
            found: array[int] = self.job.rows
            rows = found[self.given :]
            self.given = len(found)
        if self.left is not None:
            rows = rows[: self.left]
            self.left -= len(rows)
        return rows
