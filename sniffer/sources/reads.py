"""Provides batches of reads: consecutive reads of one channel carried as one chunk.

A day's recording is millions of 16 ms reads. Handing each to the pipeline as its own
`Chunk` costs more than framing its bytes, so a reader may pass a run of consecutive
reads of one channel as one `Reads`: their bytes joined, with each read's end offset and
times. It is a `Chunk` (the joined bytes, the first read's start, the last read's end),
so code that does not know batches still sees valid data; the pipeline frames it read
by read, exactly as if each had come alone.

Readers make batches only inside `batching()`, which `Session.ingest` opens: every other
consumer of a capture's chunks (tests, the MQTT publisher, a paced TUI replay) sees one
chunk per read.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field

from sniffer.model import Chunk

_BATCHING: ContextVar[bool] = ContextVar("modscope_batching", default=False)

# a batch ends after this many seconds of reads or bytes (the compiled walks in
# sniffer/_core.c cut at the same, tested): the pipeline frames a batch read by read, so
# the rows do not depend on them, only the cost per batch does (making the batch, the
# generator levels, the pipeline's call); batches this large make that cost small beside
# the framing, and still bound the memory a batch holds
MAX_BATCH_SPAN = 4.0
MAX_BATCH_BYTES = 1 << 19


def batching_enabled() -> bool:
    """Whether the consumer of the chunks being read takes `Reads` batches."""
    return _BATCHING.get()


@contextmanager
def batching(on: bool = True) -> Iterator[None]:
    """Let readers pass batches of reads while the block runs (in this thread)."""
    token = _BATCHING.set(on)
    try:
        yield
    finally:
        _BATCHING.reset(token)


@dataclass(frozen=True, slots=True)
class Reads(Chunk):
    """Consecutive reads of one channel and direction, none empty, none an event.

    `ends[k]` is the offset in `data` just past read k; `t_ends[k]` its time;
    `t_starts[k]` its first byte's time or NaN when the source does not know it (then it
    is estimated from the line speed, as for a lone chunk whose `t_start` is None). The
    chunk's own `t_end` is the last read's, `t_start` the first's. Arrays, so that a
    compiled reader can fill them (sniffer.core).
    """

    ends: array[int] = field(default_factory=lambda: array("q"))
    t_starts: array[float] = field(default_factory=lambda: array("d"))
    t_ends: array[float] = field(default_factory=lambda: array("d"))

    def __len__(self) -> int:
        return len(self.ends)

    def split(self) -> Iterator[Chunk]:
        """The reads one chunk each, as a reader outside `batching()` gives them."""
        start = 0
        for end, t0, t1 in zip(self.ends, self.t_starts, self.t_ends, strict=True):
            first = None if math.isnan(t0) else t0
            yield Chunk(
                self.data[start:end], t1, first, self.channel, self.direction, note=self.note
            )
            start = end
