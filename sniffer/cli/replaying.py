"""Provides what `modscope replay` of one capture and of several together
(`sniffer.cli.together`) share: standard input kept in a file, the listing written."""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterator, Sequence
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

    def write(stream: TextIO, part: Sequence[int], first: bool) -> int:
        lister = Lister(
            stream,
            fmt,
            session.describer,
            absolute=args.time == "abs",
            raw_csv=args.raw_csv,
            header=first,
        )
        lister.origin = origin
        return lister.write(part, flush=False)

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
    written anew, as for `replay --stats`) or cut a read it should have learnt from
    (`Learnt.unsure`: learnt again from the capture itself). `also`: see `learn`."""
    try:
        learnt: Learnt | None = learn(session, capture, progress, also=also)
    except DamagedError:
        learnt = None
    if learnt is None or learnt.unsure:
        session, capture = reopen(index and learnt is None)
        learnt = learn(session, capture, progress, also=also)
    return session, capture, learnt


def write_streamed(
    out: TextIO,
    args: argparse.Namespace,
    learnt: Learnt,
    second: tuple[Session, Capture],
    query: Query | None,
    fmt: str | None = None,
) -> int:
    """`write_listing` of a capture a segment at a time, in memory flat in its size:
    `learnt` from a first pass over it (`sniffer.session.streamed.learn`), `second` a
    new session on it, which lists each segment as it drops it (`segments`). The bytes
    are those `write_listing` writes of one store of every row: relative times count
    from the capture's first row, a filter's times too, rows are numbered in the whole
    capture (`Lister.base`) and described as after every row; `--jobs` processes share
    each segment's rows. `fmt`: the format, if not `args.format` (text by default).
    Returns how many rows were listed."""
    fmt = fmt or args.format or "text"
    session, capture = second
    selection = Selection(session, query, args.count, first=learnt.origin)
    listed = [False]  # whether the header went out (the first segment's range)
    count = [0]

    def each(s: Session, describer: Describer) -> bool:
        if selection.done:
            return False
        selection.next_segment(describer.annotator)
        rows = selection.take(len(s.store), final=True)
        if not rows:
            return not selection.done

        def write(stream: TextIO, part: Sequence[int], first: bool) -> int:
            lister = Lister(
                stream,
                fmt,
                describer,
                absolute=args.time == "abs",
                raw_csv=args.raw_csv,
                header=first and not listed[0],
            )
            lister.origin = learnt.origin
            lister.base = s.base
            return lister.write(part, flush=False)

        jobs = workers_for(getattr(args, "jobs", 1), len(rows), out)
        count[0] += write_text(out, rows, jobs, write)
        listed[0] = True
        return not selection.done

    segments(session, capture, learnt, each)
    if not listed[0] and fmt == "csv":  # no row: the header alone, as of an empty store
        Lister(out, fmt, Describer(FrameStore()), raw_csv=args.raw_csv)
    out.flush()
    return count[0]
