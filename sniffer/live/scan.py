"""Provides the line-settings scan: listen passively at each common setting, score each by
what the framer makes of the bytes (`sniffer.analysis.linescore`), and name the setting
the line is using.

The port is only ever opened passively (`port.open_passive`: RTS and DTR not
asserted, line settings set before the port opens) and read; a scan changes nothing but
the local port's settings, one open per setting.
"""

from __future__ import annotations

import os
import select
import time
from collections.abc import Callable, Sequence

import serial

from sniffer.analysis.linescore import (
    BAUDS,
    ENOUGH_BYTES,
    FORMATS,
    Sample,
    ScanResult,
    Trial,
    candidates,
    decide,
    parse_format,
    score,
)
from sniffer.live.port import (
    PortError,
    PortFactory,
    PortSpec,
    WallClock,
    close_port,
    open_passive,
    posix_fd,
    read_icount,
)
from sniffer.model import Chunk, LineSettings

# the scoring's names that this module's callers pass in or get back
__all__ = [
    "BAUDS",
    "DWELL",
    "ENOUGH_BYTES",
    "FORMATS",
    "MAX_DWELL",
    "CounterReader",
    "Listen",
    "PortListener",
    "Sample",
    "ScanResult",
    "Trial",
    "driver_counters",
    "listen_trial",
    "live_command",
    "scan",
]

DWELL = 0.6  # seconds of listening per setting, at first
MAX_DWELL = 4.0  # seconds a quiet setting is listened to at most

Listen = Callable[[LineSettings, float], Sample]
"""Listens at one setting for about that many seconds."""


def live_command(port: str, trial: Trial) -> str:
    """The exact `modscope live` command for a winning trial."""
    line = trial.line
    cmd = f"modscope live {port} --baud {line.baud} --parity {line.parity}"
    if line.stopbits != 1:
        cmd += f" --stopbits {line.stopbits}"
    if line.bytesize != 8:
        cmd += f" --bytesize {line.bytesize}"
    if trial.mode == "ascii":
        cmd += " --mode ascii"
    return cmd


def listen_trial(
    listen: Listen, line: LineSettings, dwell: float, max_dwell: float, enough: int
) -> Trial:
    """Listen at one setting, longer while the line is quiet, and score what came."""
    chunks: list[Chunk] = []
    seconds = 0.0
    framing: int | None = None
    parity: int | None = None
    step = dwell
    while True:
        sample = listen(line, step)
        chunks.extend(sample.chunks)
        seconds += sample.seconds
        if sample.framing_errors is not None:
            framing = (framing or 0) + sample.framing_errors
        if sample.parity_errors is not None:
            parity = (parity or 0) + sample.parity_errors
        if sum(len(c.data) for c in chunks) >= enough or seconds >= max_dwell - 1e-9:
            break
        step = min(step * 2, max_dwell - seconds)
    return score(line, Sample(tuple(chunks), seconds, framing, parity))


def scan(
    listen: Listen,
    bauds: Sequence[int] = BAUDS,
    formats: Sequence[str] = FORMATS,
    *,
    dwell: float = DWELL,
    max_dwell: float = MAX_DWELL,
    enough: int = ENOUGH_BYTES,
    progress: Callable[[Trial], None] | None = None,
) -> ScanResult:
    """Listen at each setting and decide.

    In two rounds: at the right baud rate a receiver reads the data bytes of every format
    of its width correctly (only the parity and stop bits differ), so the first round
    tries each baud rate with one format per width (8N1, and 7E1 for ASCII); the second
    tries the other formats at the baud rates whose first round read valid frames, where
    the driver's parity and framing error counts tell the formats apart. Fastest first: a
    fast receiver takes any falling edge for a start bit and hears every line, where a
    slow one can miss fast traffic altogether (its start bit check lands between the
    short frames); so two settings in a row that hear nothing in `max_dwell` end the
    scan: the line is silent.
    """
    widths: dict[int, list[str]] = {}
    for text in formats:
        widths.setdefault(parse_format(text)[0], []).append(text)
    firsts = [group[0] for group in widths.values()]
    trials: list[Trial] = []

    def run(line: LineSettings) -> Trial:
        trial = listen_trial(listen, line, dwell, max_dwell, enough)
        trials.append(trial)
        if progress is not None:
            progress(trial)
        return trial

    silent = 0
    for line in candidates(sorted(bauds, reverse=True), firsts):
        first = run(line)
        silent = silent + 1 if first.bytes == 0 else 0
        if silent >= 2:  # two full dwells without a byte: no traffic at any setting
            break
        if first.valid:
            for text in widths[line.bytesize][1:]:
                run(candidates([line.baud], [text])[0])
    return decide(trials)


# -- listening on a real port ------------------------------------------------------------

CounterReader = Callable[[serial.Serial], tuple[int, int] | None]
"""(framing errors, parity errors) the driver has counted so far, or None."""


def driver_counters(port: serial.Serial) -> tuple[int, int] | None:
    """The Linux driver's framing and parity error counters of a local port."""
    fd = posix_fd(port)
    if fd is None:
        return None
    found = read_icount(fd)
    return None if found is None else (found.frame, found.parity)


class PortListener:
    """Listens on one port at a given setting: opens it passively, reads, closes.

    Nothing is ever written; RTS and DTR stay off (see port.open_passive)."""

    def __init__(
        self,
        name: str,
        *,
        factory: PortFactory | None = None,
        counters: CounterReader | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.name = name
        self.factory = factory
        self.counters = counters if counters is not None else driver_counters
        self.clock = clock
        self.wall = WallClock()
        self.warnings: list[str] = []

    def __call__(self, line: LineSettings, seconds: float) -> Sample:
        port, warnings = open_passive(PortSpec(self.name, line), self.factory)
        for w in warnings:
            if w not in self.warnings:
                self.warnings.append(w)
        chunks: list[Chunk] = []
        start = self.clock()
        try:
            before = self.counters(port)
            fd = posix_fd(port)
            while (left := seconds - (self.clock() - start)) > 0:
                data = self._read(port, fd, min(left, 0.1))
                if data:
                    chunks.append(Chunk(data, self.wall.now()))
            after = self.counters(port)
        finally:
            close_port(port)
        framing = parity = None
        if before is not None and after is not None:
            framing, parity = after[0] - before[0], after[1] - before[1]
        return Sample(tuple(chunks), self.clock() - start, framing, parity)

    @staticmethod
    def _read(port: serial.Serial, fd: int | None, wait: float) -> bytes:
        if fd is not None:
            ready, _, _ = select.select([fd], [], [], wait)
            if not ready:
                return b""
            try:
                data = os.read(fd, 1 << 16)
            except (BlockingIOError, InterruptedError):
                return b""
            except OSError as exc:
                raise PortError(f"{port.port}: read failed during the scan ({exc})") from None
            if not data:
                raise PortError(f"{port.port}: the port went away during the scan")
            return data
        got: bytes = port.read(1)  # waits at most the timeout set before the port opened
        if got and port.in_waiting:
            got += port.read(port.in_waiting)
        return got
