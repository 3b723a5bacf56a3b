"""Provides batches of reads: consecutive reads of one channel carried as one chunk.

A day's recording is millions of 16 ms reads. Handing each to the pipeline as its own
`Chunk` costs more than framing its bytes, so a reader may pass a run of consecutive
reads of one channel as one `Reads`: their bytes joined, with each read's end offset and
times. It is a `Chunk` (the joined bytes, the first read's start, the last read's end),
so code that does not know batches still sees valid data; the pipeline frames it read
by read, exactly as if each had come alone.

Readers make batches only inside `batching()`, which `Session.ingest` opens: every other
consumer of a capture's chunks (tests, the MQTT publisher, a paced TUI replay) sees one
chunk per read as before.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field

from sniffer.model import Chunk

_BATCHING: ContextVar[bool] = ContextVar("modscope_batching", default=False)

MAX_BATCH_SPAN = 0.25  # seconds of reads in one batch (a paced replay stays smooth)
MAX_BATCH_BYTES = 1 << 16


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
    `t_starts[k]` its first byte's time or None (estimated from the line speed, as for a
    lone chunk). The chunk's own `t_end` is the last read's, `t_start` the first's.
    """

    ends: list[int] = field(default_factory=list)
    t_starts: list[float | None] = field(default_factory=list)
    t_ends: list[float] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.ends)

    def split(self) -> Iterator[Chunk]:
        """The reads one chunk each, as a reader outside `batching()` gives them."""
        start = 0
        for end, t0, t1 in zip(self.ends, self.t_starts, self.t_ends, strict=True):
            yield Chunk(self.data[start:end], t1, t0, self.channel, self.direction, note=self.note)
            start = end
