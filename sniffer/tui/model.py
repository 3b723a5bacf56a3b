"""Provides the TUI's view of a session: published rows, view options, filter, row lines.

The app owns one `ViewModel`; the widgets read it. It touches the store only through a
`StoreReader` and only below `published`, the row count the feeding thread last
reported, so the UI thread never races the ingest thread. Nothing here imports Textual.
"""

from __future__ import annotations

from rich.text import Text

from sniffer.framing.store import NO_PARTNER
from sniffer.meaning.describe import Describer, FrameDetail
from sniffer.meaning.query import Query
from sniffer.meaning.select import FilterJob, Options
from sniffer.session.paged import PagedStore
from sniffer.session.session import Session
from sniffer.tui.render import Columns, Styles, delta_text, row_text, time_text
from sniffer.tui.rows import RowView, StoreReader, last_answers
from sniffer.vocab import Kind


class ViewModel:
    """What the frame list shows and how, over one session."""

    def __init__(self, session: Session, paged: PagedStore | None = None) -> None:
        self.session = session
        # a big capture's rows come paged from its sidecar (see `sniffer.session.paged`): the
        # feeding thread fills `paged` a segment at a time; else the store is read as
        # it is filled
        self.paged = paged
        self.reader: StoreReader | PagedStore = (
            paged if paged is not None else StoreReader(session.store)
        )
        self.describer = Describer(self.reader, session.annotator, size=4096)
        self.published = 0  # rows below this are complete and may be read
        self.shown = 0  # rows the list shows (lags `published` while paused)
        self.done = False  # the feed has ended
        self.absolute = False
        self.transactions = False
        self.problems_only = False
        self.query = Query()
        self.job: FilterJob | None = None
        self.view = RowView(None, 0)
        self.marks: set[int] = set()  # store rows marked with `m`
        self.last_answer: dict[int, float] = {}  # unit -> time of its last answer
        self._answers_seen = 0

    # -- rows ------------------------------------------------------------------------------

    @property
    def origin(self) -> float:
        return self.reader.t[0] if self.published else 0.0

    @property
    def latest(self) -> float:
        """Time of the newest complete row (the capture's 'now')."""
        return self.reader.t_end[self.published - 1] if self.published else 0.0

    @property
    def filtered(self) -> bool:
        return not self.query.empty or self.transactions or self.problems_only

    def options(self) -> Options:
        return Options(
            transactions=self.transactions,
            problems_only=self.problems_only,
            bound=self.session.annotator.bindings,
        )

    def new_job(self) -> FilterJob | None:
        """Start over with the current query and options (None: every row is shown)."""
        if not self.filtered:
            self.job = None
        else:
            self.job = FilterJob(
                self.reader, self.query, self.options(), self.session.annotator, self.origin
            )
        self.update_view()
        return self.job

    def publish(self, rows: int) -> None:
        """The feeding thread completed rows below `rows`."""
        if rows <= self.published:
            return
        for unit, row in last_answers(self.reader, self._answers_seen, rows).items():
            self.last_answer[unit] = self.reader.t[row]
        self._answers_seen = rows
        self.published = rows

    def update_view(self) -> RowView:
        if self.job is None:
            self.view = RowView(None, self.shown)
        else:
            self.view = RowView(self.job.rows, len(self.job.rows))
        return self.view

    # -- details ---------------------------------------------------------------------------

    def detail(self, row: int) -> FrameDetail:
        return self.describer.detail(row)

    def partner(self, row: int) -> int | None:
        """The paired request or answer of `row`, if it is complete."""
        j = self.reader.partner[row]
        return j if j != NO_PARTNER and j < self.published else None

    def answer(self, row: int) -> FrameDetail | None:
        """For a transaction row (a request), its paired answer's details."""
        if not self.transactions or self.reader.kind[row] != Kind.REQUEST:
            return None
        j = self.partner(row)
        return self.describer.detail(j) if j is not None else None

    def line(self, k: int, cols: Columns, styles: Styles) -> Text:
        """The frame list's line for view position `k`."""
        view = self.view
        row = view.row(k)
        prev = view.row(k - 1) if k > 0 else None
        t = self.reader.t[row]
        delta = delta_text(t - self.reader.t[prev]) if prev is not None else ""
        return row_text(
            self.describer.detail(row),
            answer=self.answer(row),
            when=("●" if row in self.marks else "") + time_text(t, self.origin, self.absolute),
            delta=delta,
            cols=cols,
            styles=styles,
            number=f"#{row}",
        )
