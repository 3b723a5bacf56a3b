"""Provides the reader interface every capture reader shares: options, captures, errors."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

from sniffer.model import Chunk, LineSettings, SourceInfo


class CaptureError(Exception):
    """A capture file cannot be read at all. The message names the file and what to do."""


@dataclass(frozen=True, slots=True)
class ReadOptions:
    """Settings from the command line. None means: take it from the file, or the default.

    `probes` picks logic analyser channels by name or 1-based number (names win); with
    two, the first carries the master's requests and the second the slaves' responses.
    `invert` is for logic captures of idle-low lines (the RS-232 side of a converter).
    `carrier` and `port` are for network captures (see `sniffer.sources.net`).
    """

    baud: int | None = None
    bytesize: int | None = None
    parity: str | None = None
    stopbits: int | None = None
    mode: str | None = None
    probes: tuple[str, ...] = ()
    invert: bool = False
    carrier: str | None = None  # network captures: "tcp", "rtu-over-tcp" or "rtu-over-udp"
    port: int | None = None  # network captures: the server's port; other traffic is left out

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

    `warnings` holds every warning: those known when the file was opened (also in
    `info.warnings`) and those found while `chunks()` is consumed (a truncated record is
    only found at the end), so read it after iterating.
    """

    info: SourceInfo
    _chunks: Iterator[Chunk]
    warnings: list[str] = field(default_factory=list)

    def chunks(self) -> Iterator[Chunk]:
        return self._chunks
