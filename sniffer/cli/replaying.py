"""Provides what `modscope replay` of one capture and of several together
(`sniffer.cli.together`) share: standard input kept in a file, the listing written."""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

from sniffer.cli.filtering import Selection
from sniffer.meaning.query import Query
from sniffer.outputs.listing import Lister
from sniffer.outputs.parallel import workers_for, write_text
from sniffer.session.session import Session


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

    Not windowed (every row stays in the store, unlike `--stats`): the workers take
    ranges of one store, the filter and relative times count from its rows, a row is
    described with what the annotator learnt from the whole capture (SunSpec models,
    parameter windows found later), and the warnings come before the rows; listing
    each segment as it goes, as live does, would change some of that."""
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
