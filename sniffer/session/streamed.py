"""Provides a capture's rows a segment at a time, each row described as one store of
every row would describe it: how listings keep their memory flat in the number of frames.

Two passes over the capture. The first (`learn`) ingests it keeping a window of rows
(`Session.ingest` with a window), as `replay --stats` does, and writes the sidecar index
if none fits yet: it gives what is said before the first row (the warnings and notes,
the line-speed check), the first row's time (what relative times count from), and what
the annotator learnt from every row (the SunSpec devices, their models and names, found
maybe after rows that show them). The second (`segments`) reads the capture again the
same way (below: its sidecar, where there is one) and hands on each segment's rows (row
`i` of the store is row `session.base + i` of the capture) before they are dropped,
with a describer whose annotator knows what the first pass learnt
(`Annotator.knowing`). Used by `replay`'s listings and by every `export` of one capture
(frames, transactions and registers; text, JSONL, CSV, pcapng, Parquet): `each_segment`
in the command line's `replaying` module.

Why the rows are those of one store: segments end only at settled moments
(`Session.settled`): every row of a segment is final when it is handed on (paired,
flagged, annotated), and no request is in one segment and its answer in the next. What a
row's description reads of the rows before it (the parameter a window had selected, a
scale factor's value) the second pass has seen by then; what it reads of the whole
capture the first pass gives. The contents the describer shares among rows hold no row
number, so one describer serves every segment (its store and annotator set anew for
each), as one describer serves a whole store.

Where the first pass read a sidecar back or wrote one (`Learnt.indexed`), the second
reads it back too, a block at a time; else it frames the capture again. Blocks are
handed on without cutting a request from its answer (`sniffer.session.index.load`), so
the rows are those framing gives. Reading back is what makes two passes cheap on a
network capture, whose framing runs in Python: a Modbus TCP pcap of 1M frames takes
about 110 s to frame, and `replay --stats` reads its sidecar back in 11 s. It also
keeps the two passes on the same rows: a capture changed under its sidecar (its size,
time and head kept) lists the rows the sidecar was written from, both passes, never a
mix."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from sniffer.analysis.baud import SpeedCheck
from sniffer.errors import CaptureError
from sniffer.meaning.annotate import Annotator
from sniffer.meaning.describe import Describer
from sniffer.session.index import DamagedError
from sniffer.session.session import Progress, Session
from sniffer.sources import Capture

# rows the first pass keeps (as `replay --stats`: about 4 MB of store)
LEARN_WINDOW = 1 << 16
# rows the second pass keeps: a segment is listed at once, by `--jobs` processes each
# forked anew, so fewer, larger segments; about 8.5 MB of store
LIST_WINDOW = 1 << 17


@dataclass
class Learnt:
    """What the first pass over a capture (`learn`) found, for the second."""

    annotator: Annotator  # after every row
    origin: float | None  # the first row's time (None: no row)
    speed: SpeedCheck  # the line-speed check of every row
    rows: int  # rows of the capture
    # whether the capture has a sidecar that fits, read back or written by the pass: the
    # second pass reads it too (see the module's doc)
    indexed: bool = False
    # the pass's session when it kept every row (the capture fits in its window): the
    # second pass lists them from it instead of reading the capture again
    kept: Session | None = None


def learn(
    session: Session,
    capture: Capture,
    progress: Progress | None = None,
    window: int | None = None,
    also: Callable[[Session], None] | None = None,
) -> Learnt:
    """The first pass: `session` ingests `capture` keeping `window` rows (default
    LEARN_WINDOW); its warnings, notes and statistics are then those of the whole
    capture, its store the last segment's. A sidecar index is written if `session` may
    index and none fits; one that fits is read back. `also(session)` is called with each
    segment, in order, as `segment` in `Session.ingest`: what else the caller needs of
    every row (the pcapng export's largest move of a packet's time,
    `sniffer.outputs.export.Moves`); a pass done again (a sidecar found damaged) starts
    again at row 0."""
    speed = SpeedCheck()
    first: list[float] = []

    def segment(s: Session) -> None:
        if not first and len(s.store):
            first.append(s.store.t[0])
        speed.add(s.store)
        if also is not None:
            also(s)

    window = window or LEARN_WINDOW  # (read now: tests set it)
    # the statistics bounded, a sidecar being written given their values on disk
    session.ingest(capture.chunks(), progress, window=window, segment=segment, bounded=True)
    return Learnt(
        session.annotator,
        first[0] if first else None,
        speed,
        session.base + len(session.store),
        indexed=session.indexed_from is not None or session.indexed_to is not None,
        kept=session if not session.base else None,
    )


def segments(
    session: Session,
    capture: Capture,
    learnt: Learnt,
    each: Callable[[Session, Describer], bool],
    window: int | None = None,
) -> None:
    """The second pass: `session`, new on the same capture, ingests `capture` keeping
    `window` rows (default LIST_WINDOW), and `each(session, describer)` is called with
    each segment's rows in `session.store` (row `i` is row `session.base + i` of the
    capture), `describer` describing them as after the whole capture (`learnt`, from
    `learn`). Stops reading once `each` returns False. Where the first pass kept every
    row (`Learnt.kept`: a capture that fits in a window), there is no second pass: its
    session's store is handed on as the one segment, so the capture is read once (a
    network capture of 65,536 rows frames in about 7 s); `session` is not read."""
    if learnt.kept is not None:
        kept = learnt.kept
        each(kept, Describer(kept.store, kept.annotator, size=0))
        return
    describer = Describer(session.store, session.annotator, size=0)  # (no row is read twice)
    done = False

    def segment(s: Session) -> None:
        nonlocal done
        if done:
            return
        describer.store = s.store
        describer.annotator = s.annotator.knowing(learnt.annotator)
        done = not each(s, describer)

    session.stats.bound()  # (nothing reads them)
    try:
        session.ingest(
            capture.chunks(),
            window=window or LIST_WINDOW,
            segment=segment,
            index=learnt.indexed,
            should_stop=lambda: done,
        )
    except DamagedError as exc:  # (the first pass read every block of it whole)
        raise CaptureError(
            f"{session.source}: changed while it was being listed ({exc}); list it again"
        ) from None
