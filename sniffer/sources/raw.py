"""Provides the raw binary reader: bytes with no time, spaced one character time apart."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from sniffer.model import Chunk, LineSettings


def raw_chunks(path: Path, line: LineSettings, block: int = 1 << 16) -> Iterator[Chunk]:
    """A raw binary file has no time: every byte is placed one character time after the
    last, so nothing looks like a gap and framing relies on lengths and checks alone."""
    char = line.char_time
    t = 0.0
    with path.open("rb") as handle:
        while data := handle.read(block):
            t_start = t
            t += char * len(data)
            yield Chunk(data=data, t_start=t_start, t_end=t)
