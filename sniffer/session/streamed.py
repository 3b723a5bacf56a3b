"""Provides a capture's rows a segment at a time, each row described as one store of
every row would describe it: how listings keep their memory flat in the number of frames.

Two passes over the capture. The first (`learn`) ingests it keeping a window of rows
(`Session.ingest` with a window), as `replay --stats` does, and writes the sidecar index
if none fits yet: it gives what is said before the first row (the warnings and notes,
the line-speed check), the first row's time (what relative times count from), and what
the annotator learnt from every row (the SunSpec devices, their models and names, found
maybe after rows that show them). The second (`segments`) frames the capture again the
same way and hands on each segment's rows (row `i` of the store is row `session.base +
i` of the capture) before they are dropped, with a describer whose annotator knows what
the first pass learnt (`Annotator.knowing`). Used by `replay`'s listings and by every
`export` of one serial capture (frames, transactions and registers; text, JSONL, CSV,
pcapng, Parquet): `each_segment` in the command line's `replaying` module.

Why the rows are those of one store: segments end only at settled moments
(`Session.settled`): every row of a segment is final when it is handed on (paired,
flagged, annotated), and no request is in one segment and its answer in the next. What a
row's description reads of the rows before it (the parameter a window had selected, a
scale factor's value) the second pass has seen by then; what it reads of the whole
capture the first pass gives. The contents the describer shares among rows hold no row
number, so one describer serves every segment (its store and annotator set anew for
each), as one describer serves a whole store.

Why the second pass frames the capture rather than reading the sidecar back: a sidecar
read back a block at a time may cut a request from its answer at a block's start
(`sniffer.session.index.load`), and the answer would be listed unpaired. The first pass
reads a sidecar that fits (as `replay --stats`, rebuilding one found damaged), but a
SunSpec read so cut would not be learnt: where a block begins with the answer to a read
of registers of a unit with no dictionary, the first pass is done again by framing the
capture (`Learnt.unsure`). Framing costs about what reading a sidecar back does
(docs/performance.md)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from sniffer.analysis.baud import SpeedCheck
from sniffer.framing.store import NO_PARTNER
from sniffer.meaning.annotate import Annotator
from sniffer.meaning.describe import Describer
from sniffer.meaning.sunspec import READS
from sniffer.session.session import Progress, Session
from sniffer.sources import Capture
from sniffer.vocab import Kind

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
    # read back from a sidecar whose blocks cut a read of registers of a unit with no
    # dictionary from its request: learn again from the capture itself (see above)
    unsure: bool = False


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
    index and none fits; one that fits is read back (`Learnt.unsure` says when to learn
    again with a new session that may not: see the module's doc). `also(session)` is
    called with each segment, in order, as `segment` in `Session.ingest`: what else the
    caller needs of every row (the pcapng export's largest move of a packet's time,
    `sniffer.outputs.export.Moves`); a pass learnt again starts again at row 0."""
    speed = SpeedCheck()
    first: list[float] = []
    cut: list[bool] = []

    def segment(s: Session) -> None:
        if not first and len(s.store):
            first.append(s.store.t[0])
        speed.add(s.store)
        if s.base and not cut and _cut_read(s):
            cut.append(True)
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
        unsure=bool(cut) and session.indexed_from is not None,
    )


def _cut_read(session: Session) -> bool:
    """Whether the store's rows begin (before their first request) with an answer to a
    read of registers (`READS`) of a unit with no dictionary, given with no request: as
    a block read back from a sidecar begins when its request ended the block before."""
    store = session.store
    bound = session.annotator.bindings
    kinds, partners, fcs, units = store.kind, store.partner, store.fc, store.unit
    for i in range(len(store)):
        kind = kinds[i]
        if kind == Kind.REQUEST:
            return False
        if (
            kind == Kind.RESPONSE
            and partners[i] == NO_PARTNER
            and fcs[i] in READS
            and units[i] not in bound
        ):
            return True
    return False


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
    `learn`). Stops reading once `each` returns False."""
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
    session.ingest(
        capture.chunks(),
        window=window or LIST_WINDOW,
        segment=segment,
        index=False,
        should_stop=lambda: done,
    )
