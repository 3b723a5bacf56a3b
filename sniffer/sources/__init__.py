"""Provides capture readers: each turns a file into chunks of timestamped bytes.

`open_capture(path, options)` recognises the format from the content, not the name, and
returns a `Capture`: what the file says about itself (`info`) and its chunks in time
order. Readers never raise on bad content once the format is recognised: a truncated or
damaged file gives every complete record and a warning naming the offset.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from sniffer.model import Chunk, LineSettings, SourceInfo


class CaptureError(Exception):
    """A capture file cannot be read at all. The message names the file and what to do."""


@dataclass(frozen=True, slots=True)
class ReadOptions:
    """Settings from the command line. None means: take it from the file, or the default."""

    baud: int | None = None
    bytesize: int | None = None
    parity: str | None = None
    stopbits: int | None = None
    mode: str | None = None
    probes: tuple[str, ...] = ()
    invert: bool = False

    def line(self, from_file: LineSettings | None = None) -> LineSettings:
        """Line settings: command line first, then what the file recorded, then defaults."""
        base = from_file or LineSettings()
        return LineSettings(
            baud=self.baud if self.baud is not None else base.baud,
            bytesize=self.bytesize if self.bytesize is not None else base.bytesize,
            parity=self.parity if self.parity is not None else base.parity,
            stopbits=self.stopbits if self.stopbits is not None else base.stopbits,
            mode=self.mode if self.mode is not None else base.mode,
        )


@dataclass
class Capture:
    """An opened capture: its description, its chunks, and warnings found on the way.

    `warnings` grows while `chunks()` is consumed (a truncated record is only found at the
    end), so read it after iterating.
    """

    info: SourceInfo
    _chunks: Iterator[Chunk]
    warnings: list[str] = field(default_factory=list)

    def chunks(self) -> Iterator[Chunk]:
        return self._chunks


def _raw_chunks(path: Path, line: LineSettings, block: int = 1 << 16) -> Iterator[Chunk]:
    """A raw binary file has no time: every byte is placed one character time after the
    last, so nothing looks like a gap and framing relies on lengths and checks alone."""
    char = line.char_time
    t = 0.0
    with path.open("rb") as handle:
        while data := handle.read(block):
            t_start = t
            t += char * len(data)
            yield Chunk(data=data, t_start=t_start, t_end=t)


def open_capture(path: str | Path, options: ReadOptions | None = None) -> Capture:
    """Open a capture file of any supported format, recognised from its content."""
    options = options or ReadOptions()
    path = Path(path)
    if not path.exists():
        raise CaptureError(f"{path}: no such file; give the path of a capture to replay")
    if path.is_dir():
        raise CaptureError(f"{path}: is a folder; give the path of a capture file")
    line = options.line(None)
    info = SourceInfo(path=str(path), format="raw", line=line)
    return Capture(info=info, _chunks=_raw_chunks(path, line))
