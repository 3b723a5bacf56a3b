"""Provides `SessionState`: what a session has made of its capture so far.

A `Session` (`sniffer.session.session`) frames, pairs, annotates and counts a capture;
what that work leaves behind is kept here: the rows (`store`), the pipeline that framed
them, the annotator's and the statistics' state, the warnings and notes, and where the
rows stand in the whole capture once earlier segments were dropped (`base`,
`stream_base`, `frames_before`). The sidecar index (`sniffer.session.index`) writes this
object and fills it back, so it needs it alone, never the session that owns it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sniffer.analysis.stats import Stats
from sniffer.framing.pairing import StampClock
from sniffer.framing.pipeline import Pipeline
from sniffer.framing.store import FrameStore
from sniffer.meaning.annotate import Annotator


@dataclass(eq=False)
class SessionState:
    """A session's rows and everything counted and learnt from them."""

    store: FrameStore
    pipeline: Pipeline
    annotator: Annotator
    stats: Stats
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # what the user should know, not faults
    chunks: int = 0  # chunks fed (a batch of reads counts each read)
    # rows of earlier segments (a windowed capture, see `Session.new_segment`): row i of
    # `store` is row `base + i` of the capture
    base: int = 0
    # what the dropped rows leave behind: each channel's bytes before its stream's start
    # (`stream_base`), and how many of them were frames (not noise or events)
    stream_base: dict[int, int] = field(default_factory=dict)
    frames_before: int = 0

    @property
    def timing(self) -> StampClock:
        """What the source's stamps are worth: their resolution as declared and as
        measured from the stamps seen (the store keeps the resolution the rows are
        shown with, `store.resolution`)."""
        return self.pipeline.clock

    def forget_annotation(self) -> None:
        """The annotator's state carried into an emptied store (a new segment): what it
        learnt stays, the rows it learnt it from are gone. With `annotator.keep_rows` the
        rows it recorded stay too, numbered in the whole capture (the rows before the new
        store's first are `self.base + len(self.store)` here: `Session.new_segment` calls
        this before it moves `base` on, `sniffer.session.index` after it emptied the
        store)."""
        annotator = self.annotator
        annotator.next = 0
        if annotator.keep_rows:
            annotator.base = annotator.sunspec.base = self.base + len(self.store)
            return
        for track in annotator.tracks.values():  # the parameter selected last
            if track.rows:
                track.rows, track.numbers = [-1], track.numbers[-1:]
        for unit in annotator.sunspec.units.values():  # scale factors as they are
            for history in unit.scale.values():
                if history.rows:
                    history.rows, history.values = [-1], history.values[-1:]

    def framed_already(self, mode: str | None) -> None:
        """The store's rows were put there whole (a sidecar read back): the pipeline takes
        them as framed in `mode`, paired and checked against their labels."""
        pipeline = self.pipeline
        n = len(self.store)
        pipeline.mode = mode
        pipeline.pairer.next = n
        pipeline._hint_checked = n
