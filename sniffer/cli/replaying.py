"""Provides what `modscope replay` of one capture and of several together
(`sniffer.cli.together`) share: standard input kept in a file, the listing written."""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

from sniffer.cli.filtering import Selection
from sniffer.framing.store import FrameStore
from sniffer.meaning.describe import Describer
from sniffer.meaning.query import Query
from sniffer.outputs.listing import Lister
from sniffer.outputs.parallel import workers_for, write_text
from sniffer.session.index import DamagedError
from sniffer.session.session import Progress, Session
from sniffer.session.streamed import Learnt, learn, segments
from sniffer.sources import Capture


@contextmanager
def stdin_copy() -> Iterator[Path]:
    """Standard input kept in a temporary file (readers look at a file's content)."""
    with tempfile.TemporaryDirectory(prefix="modscope-") as folder:
        path = Path(folder) / "stdin"
        with path.open("wb") as f:
            shutil.copyfileobj(sys.stdin.buffer, f, 1 << 20)
        yield path


def write_listing(
    out: TextIO, args: argparse.Namespace, session: Session, query: Query | None
) -> None:
    """The rows a filter and -c let through, in the format asked for (text by default),
    by `--jobs` processes over ranges of rows when that pays (see `sniffer.outputs.parallel`).

    Every row in the store (several files replayed together, a network capture); one
    serial capture is listed a segment at a time (`write_streamed`)."""
    fmt = args.format or "text"
    selection = Selection(session, query, args.count)
    origin = selection.origin()  # what relative times count from, in every range
    rows = selection.take(len(session.store), final=True)

    lister = lister_of(args, fmt, origin)

    def write(stream: TextIO, part: Sequence[int], first: bool) -> int:
        return lister(stream, part, first, session.describer, 0)

    jobs = workers_for(getattr(args, "jobs", 1), len(rows), out)
    write_text(out, rows, jobs, write)
    out.flush()


def first_pass(
    session: Session,
    capture: Capture,
    progress: Progress,
    reopen: Callable[[bool], tuple[Session, Capture]],
    index: bool,
    also: Callable[[Session], None] | None = None,
) -> tuple[Session, Capture, Learnt]:
    """The first pass of a listing a segment at a time (`sniffer.session.streamed.learn`),
    the session and capture it ends with: `reopen(index)` a new session on the capture,
    taken where a sidecar read back was found damaged (indexed again, the sidecar
    written anew, as for `replay --stats`). `also`: see `learn`."""
    try:
        learnt = learn(session, capture, progress, also=also)
    except DamagedError:
        session, capture = reopen(index)
        learnt = learn(session, capture, progress, also=also)
    return session, capture, learnt


# writes rows `part` of a segment's store to `stream` (with the header, if any, when
# `header`), as described by `describer`, rows numbered `base` on; returns the count
PartWriter = Callable[[TextIO, Iterable[int], bool, Describer, int], int]


def lister_of(args: argparse.Namespace, fmt: str, origin: float | None) -> PartWriter:
    """The listing's part writer: `Lister` lines, relative times counting from `origin`
    (the capture's first row)."""

    def write(
        stream: TextIO, part: Iterable[int], header: bool, describer: Describer, base: int
    ) -> int:
        lister = Lister(
            stream,
            fmt,
            describer,
            absolute=args.time == "abs",
            raw_csv=args.raw_csv,
            header=header,
        )
        lister.origin = origin
        lister.base = base
        return lister.write(part, flush=False)

    return write


def each_segment(
    args: argparse.Namespace,
    learnt: Learnt,
    second: tuple[Session, Capture],
    query: Query | None,
    take: Callable[[Sequence[int], Describer, int], None],
    shown: Callable[[int, int], None] | None = None,
) -> None:
    """The rows a filter and -c let through, a segment at a time: `learnt` from a first
    pass over the capture (`sniffer.session.streamed.learn`), `second` a new session on
    it, which hands on each segment as it drops it (`segments`); `take(rows, describer,
    base)` is given each segment's chosen rows (none is not given), read as one store of
    every row would read them: a filter's relative times count from the capture's first
    row, rows are described as after every row and numbered `base` on. `shown(done,
    total)`: told the rows of the capture done after each segment (`Progress.share`)."""
    session, capture = second
    if learnt.kept is not None:  # the first pass kept every row: listed from its store
        session = learnt.kept
    selection = Selection(session, query, args.count, first=learnt.origin)

    def each(s: Session, describer: Describer) -> bool:
        if selection.done:
            return False
        selection.next_segment(describer.annotator)
        rows = selection.take(len(s.store), final=True)
        if rows:
            take(rows, describer, s.base)
        if shown is not None:
            shown(s.base + len(s.store), learnt.rows)
        return not selection.done

    segments(session, capture, learnt, each)


def write_streamed(
    out: TextIO,
    args: argparse.Namespace,
    learnt: Learnt,
    second: tuple[Session, Capture],
    query: Query | None,
    writer: PartWriter | None = None,
    shown: Callable[[int, int], None] | None = None,
) -> int:
    """`write_listing` of a capture a segment at a time, in memory flat in its size
    (`each_segment`). The bytes are those `write_listing` writes of one store of every
    row; `--jobs` processes share each segment's rows. `writer`: what writes the rows
    (default: the listing in `args.format`, text by default; `export` gives its tables);
    with no row, it is given none, so that a CSV header still goes out. `shown`: see
    `each_segment`. Returns how many rows (records) were written."""
    write_part = writer or lister_of(args, args.format or "text", learnt.origin)
    listed = [False]  # whether the header went out (the first segment's range)
    count = [0]

    def take(rows: Sequence[int], describer: Describer, base: int) -> None:
        def write(stream: TextIO, part: Sequence[int], first: bool) -> int:
            return write_part(stream, part, first and not listed[0], describer, base)

        jobs = workers_for(getattr(args, "jobs", 1), len(rows), out)
        count[0] += write_text(out, rows, jobs, write)
        listed[0] = True

    each_segment(args, learnt, second, query, take, shown)
    if not listed[0]:  # no row: the header alone, as of an empty store
        write_part(out, (), True, Describer(FrameStore()), 0)
    out.flush()
    return count[0]
