"""Provides the reader interface every capture reader shares: options, captures, errors
(`CaptureError` lives with the other user errors in `sniffer.errors`)."""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Protocol

from sniffer.model import Chunk, LineSettings, SourceInfo

# Times a capture may carry: from the epoch to the year 2286 (1e10 s). Damaged files give
# others (a pcapng tick count of 2**64, a hex dump's "1e30"), which no clock shows and no
# pcapng can hold; `Capture` gives such a record the time of the one before.
MAX_TIME = 1e10
MAX_CHANNEL = 255  # the frame store keeps a channel in one byte


# Warnings a reader keeps of one kind (`warning_kind`), and the kinds it tells apart; past
# these, a warning is counted, not kept (`Warnings`)
WARNINGS_PER_KIND = 20
WARNING_KINDS = 100
# what differs between two warnings of one kind: numbers (a line, an offset, a length, a
# time: digits, their commas and points; hex `0x1f` as a whole), and a quoted excerpt of
# the file (as `!r` writes it: from the first quote to the last)
_NUMBERS = b"0123456789,."
_HEX = re.compile(r"0[xX][0-9A-Fa-f]+")
_OTHER_KIND = b"\0other"


def warning_kind(text: str) -> bytes:
    """What a warning says without its numbers and quoted excerpts: `x.log line 7: cannot
    read '0Z' as hex bytes` and `x.log line 9: cannot read '1' as hex bytes` are one
    kind. Cheap (a microsecond; a regular expression only for hex numbers): a file may
    hold millions of warnings."""
    if "0x" in text or "0X" in text:
        text = _HEX.sub("#", text)
    raw = text.encode("utf-8", "surrogatepass").translate(None, _NUMBERS)
    single, double = raw.find(b"'"), raw.find(b'"')
    if single < 0 and double < 0:
        return raw
    first = single if double < 0 or 0 <= single < double else double
    return raw[:first] + raw[max(raw.rfind(b"'"), raw.rfind(b'"')) + 1 :]


class Warnings(list[str]):
    """A reader's warnings, in memory bounded whatever the file holds: the first
    `WARNINGS_PER_KIND` of each kind (`warning_kind`; past `WARNING_KINDS` kinds, the
    others are one kind) are kept as they come, the rest counted. `close` says each
    count once, in one line after the others, with the last warning counted (so a file
    of ten million unreadable lines gives 20 warnings and one line `and 9,999,980 more
    like it ...`, not ten million). A plain list of warnings can be bounded the same way
    afterwards (`bound`)."""

    def __init__(self, items: Iterable[str] = ()) -> None:
        super().__init__()
        self._seen: dict[bytes, int] = {}  # kind: how many
        self._last: dict[bytes, str] = {}  # kind: the last warning counted, not kept
        self._told: dict[bytes, int] = {}  # kind: where its count is said (an index)
        self.extend(items)

    def append(self, text: str, /) -> None:
        kind = warning_kind(text)
        seen = self._seen.get(kind)
        if seen is None:
            if len(self._seen) >= WARNING_KINDS:
                kind = _OTHER_KIND
            seen = self._seen.get(kind, 0)
        seen += 1
        self._seen[kind] = seen
        if seen <= WARNINGS_PER_KIND:
            super().append(text)
        else:
            self._last[kind] = text

    def extend(self, items: Iterable[str], /) -> None:
        for text in items:
            self.append(text)

    def close(self) -> None:
        """Say how many warnings of each kind were counted, not kept: a line each, after
        the others (a count said before is brought up to date in place)."""
        for kind, last in self._last.items():
            more = self._seen[kind] - WARNINGS_PER_KIND
            told = (
                f"and {more:,} more warning(s) like it, not shown (the first "
                f"{WARNINGS_PER_KIND} of each kind are); the last: {last}"
            )
            if kind in self._told:
                self[self._told[kind]] = told
            else:
                self._told[kind] = len(self)
                super().append(told)

    @classmethod
    def bound(cls, items: list[str]) -> None:
        """Bound a plain list of warnings in place (as if it had been `Warnings`)."""
        if isinstance(items, Warnings):
            items.close()
            return
        bounded = cls(items)
        if len(bounded) < len(items):
            bounded.close()
            items[:] = bounded


@dataclass(frozen=True, slots=True)
class LineGuess:
    """The line settings chosen for a capture, and the sentence that says so."""

    line: LineSettings
    note: str


class LineEstimator(Protocol):
    """Measures the line settings of logic levels (one bytes string of 0/1 per probe)
    sampled at `samplerate`, keeping whatever `options` give; None: no estimate."""

    def __call__(
        self, samplerate: float, levels: Sequence[bytes], options: ReadOptions
    ) -> LineGuess | None: ...


@dataclass(frozen=True, slots=True)
class ReadOptions:
    """Settings from the command line. None means: take it from the file, or the default.

    `probes` picks logic analyser channels by name or 1-based number (names win); with
    two, the first carries the master's requests and the second the slaves' responses.
    `invert` is for logic captures of idle-low lines (the RS-232 side of a converter).
    `carrier` and `port` are for network captures (see `sniffer.sources.net`).
    `estimator` measures a logic capture's line when no baud rate is given: choosing
    the format means framing the characters, which is above the readers, so it is
    passed in (`sniffer.session.session.open_session` passes
    `sniffer.analysis.baud.estimate_line`); without one the defaults are used.
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
    estimator: LineEstimator | None = None

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
    only found at the end), so read it after iterating. Every warning names the file
    (`path: ...`, added here for readers that leave it out). Warnings of one kind past
    the first `WARNINGS_PER_KIND` are counted, in one line at the end (`Warnings`: a
    reader that keeps its warnings in one holds them in bounded memory). `data_bytes` counts the
    bytes the chunks carried; a file that gave none gets a warning saying so, and
    `empty` is then true: nothing in it was usable.
    """

    info: SourceInfo
    _chunks: Iterator[Chunk]
    warnings: list[str] = field(default_factory=list)
    data_bytes: int = 0
    finished: bool = False

    def __post_init__(self) -> None:
        self._name_warnings()

    @property
    def empty(self) -> bool:
        """True once the chunks were read to the end and carried no byte."""
        return self.finished and self.data_bytes == 0

    def chunks(self) -> Iterator[Chunk]:
        return self._read()

    def _read(self) -> Iterator[Chunk]:
        last = 0.0
        retimed = 0
        try:
            for chunk in self._chunks:
                t = chunk.t_end
                if not 0.0 <= t < MAX_TIME or not 0 <= chunk.channel <= MAX_CHANNEL:
                    chunk, retimed = self._repair(chunk, last), retimed + 1
                last = chunk.t_end
                self.data_bytes += len(chunk.data)
                yield chunk
            self.finished = True
            if retimed:
                self.warnings.append(
                    f"{retimed:,} record(s) had a time outside 1970-2286 or a channel "
                    f"over {MAX_CHANNEL}, signs of damage; their bytes are kept, with the "
                    f"time of the record before (and channel {MAX_CHANNEL})"
                )
            if not self.data_bytes:
                self.warnings.append(
                    "no serial data could be read from it; check that it is a capture of "
                    "the bus (pcapng, pcap, sigrok .sr, hex dump or raw bytes)"
                )
        finally:
            Warnings.bound(self.warnings)
            self._name_warnings()

    @staticmethod
    def _repair(chunk: Chunk, last: float) -> Chunk:
        if 0.0 <= chunk.t_end < MAX_TIME:
            t_end, t_start = chunk.t_end, chunk.t_start
            if t_start is not None and not 0.0 <= t_start <= t_end:
                t_start = None
        else:
            # a point in time just after the record before, so the order stays the file's
            t_end = t_start = last + 1e-6
        channel = min(max(chunk.channel, 0), MAX_CHANNEL)
        return replace(chunk, t_end=t_end, t_start=t_start, channel=channel)

    def _name_warnings(self) -> None:
        path = self.info.path
        for i, text in enumerate(self.warnings):
            if not text.startswith(path):  # `FILE: ...`, `FILE line 12: ...` name it already
                self.warnings[i] = f"{path}: {text}"
