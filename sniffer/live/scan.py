"""Provides the line-settings scan: listen passively at each common setting, score each by
what the framer makes of the bytes (`sniffer.analysis.linescore`), and name the setting
the line is using, with its confidence.

The port is only ever opened passively (`sniffer.live.port.open_passive`: RTS and DTR not
asserted, line settings set before the port opens) and read; a scan changes nothing but
the local port's settings, one open per setting. A setting the port refuses is skipped
and said; a port that has no line settings of its own (a pseudo-terminal, a raw TCP
connection, an RFC 2217 server that takes no settings) is said before anything is tried.
"""

from __future__ import annotations

import os
import re
import select
import stat
import sys
import time
from collections.abc import Callable, Sequence
from urllib.parse import urlsplit

import serial

from sniffer.analysis.linescore import (
    BAUDS,
    ENOUGH_BYTES,
    FORMATS,
    Refusal,
    Sample,
    ScanResult,
    Trial,
    candidates,
    decide,
    first_round,
    parse_format,
    score,
)
from sniffer.live.port import (
    URL,
    PortError,
    PortFactory,
    PortSpec,
    SettingsRefusedError,
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
    "NoLineSettingsError",
    "PortListener",
    "Refusal",
    "Sample",
    "ScanResult",
    "SettingRefusedError",
    "Trial",
    "driver_counters",
    "listen_trial",
    "live_command",
    "no_line_settings",
    "scan",
]

DWELL = 0.6  # seconds of listening per setting, at first
MAX_DWELL = 4.0  # seconds a quiet setting is listened to at most
PTY_MAJORS = range(136, 144)  # Linux: the majors of Unix98 pseudo-terminal slaves

Listen = Callable[[LineSettings, float], Sample]
"""Listens at one setting for about that many seconds; raises SettingRefusedError when
the port will not take the setting, NoLineSettingsError when it takes none at all."""


class SettingRefusedError(Exception):
    """The port would not take this setting; the scan skips it and says so."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class NoLineSettingsError(Exception):
    """The port has no line settings a scan could find; the message says why."""


def no_line_settings(name: str) -> str | None:
    """Why the port `name` has no line settings to find, or None where it has.

    A pseudo-terminal passes bytes at any "setting" (the real line, if any, ends
    somewhere else: socat, a tunnel, an emulator); so does a raw TCP connection
    (`socket://`: the server's UART read the line at settings set there) and pyserial's
    loopback. RFC 2217 servers take settings, and are found out when they refuse."""
    if URL.match(name):
        parts = urlsplit(name)
        scheme = parts.scheme.lower()
        if scheme == "socket":
            return (
                f"{name} is a raw TCP connection: the bytes were read off the line by the "
                "server's UART, at the settings set on the server, and arrive the same at "
                "any setting here"
            )
        if scheme == "loop":
            return f"{name} is pyserial's loopback: there is no line behind it"
        if scheme == "spy":
            return no_line_settings(parts.netloc + parts.path)
        return None
    return _pseudo_terminal(name)


def _pseudo_terminal(name: str) -> str | None:
    try:
        real = os.path.realpath(name)
        st = os.stat(real)
    except OSError:
        return None  # a missing port is said when it is opened
    if not stat.S_ISCHR(st.st_mode):
        return None
    pts = real.startswith("/dev/pts/") or (
        sys.platform == "linux" and os.major(st.st_rdev) in PTY_MAJORS
    )
    if not pts and sys.platform == "darwin":
        pts = re.fullmatch(r"/dev/ttys\d+", real) is not None
    if not pts:
        return None
    shown = name if real == name else f"{name} ({real})"
    return (
        f"{shown} is a pseudo-terminal: bytes pass through it unchanged at any baud rate "
        "and format, so there are no line settings to find here; the real line's "
        "settings are set where it ends (socat, a serial-over-network tunnel, an emulator)"
    )


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

    In two rounds. The first reads each baud rate at one format without parity and one
    with it per data width (8N1 and 8E1, and 7E1 for ASCII; see
    `linescore.first_round`): at the right speed one of them reads the data bytes of
    every format of its width, whatever the receiver. The second tries the other formats
    at the baud rates whose first round read valid frames, where the data and (if the
    driver counts) the line errors tell the formats apart. Fastest first: a fast
    receiver takes any falling edge for a start bit and hears every line, where a slow
    one can miss fast traffic altogether (its start bit check lands between the short
    frames); so two settings in a row that hear nothing in `max_dwell` end the scan: the
    line is silent. A setting the port refuses is skipped and kept for the verdict.
    """
    firsts = first_round(formats)
    trials: list[Trial] = []
    refused: list[Refusal] = []

    def run(line: LineSettings) -> Trial | None:
        try:
            trial = listen_trial(listen, line, dwell, max_dwell, enough)
        except SettingRefusedError as exc:
            refused.append(Refusal(line, exc.reason))
            return None
        trials.append(trial)
        if progress is not None:
            progress(trial)
        return trial

    silent = 0
    for baud in sorted(bauds, reverse=True):
        read: set[int] = set()  # data widths that read valid frames at this baud
        for line in candidates([baud], firsts):
            trial = run(line)
            if trial is None:
                continue
            silent = silent + 1 if trial.bytes == 0 else 0
            if silent >= 2:  # two full dwells without a byte: no traffic at any setting
                return decide(trials, refused)
            if trial.valid:
                read.add(line.bytesize)
        rest = [f for f in formats if f not in firsts and parse_format(f)[0] in read]
        for line in candidates([baud], rest):
            run(line)
    return decide(trials, refused)


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


# pyserial's words when an RFC 2217 server takes no line settings at all (it does not
# speak the protocol, or never acknowledges a setting)
NO_RFC2217_CONTROL = ("does not seem to support RFC2217", "does not accept parameter change")


class PortListener:
    """Listens on one port at a given setting: opens it passively, reads, closes.

    Nothing is ever written; RTS and DTR stay off (see sniffer.live.port.open_passive)."""

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

    def _open(self, line: LineSettings) -> serial.Serial:
        spec = PortSpec(self.name, line)
        try:
            port, warnings = open_passive(spec, self.factory)
        except SettingsRefusedError as exc:
            raise SettingRefusedError(_refusal_reason(str(exc))) from None
        except PortError as exc:
            text = str(exc)
            if spec.is_url and any(words in text for words in NO_RFC2217_CONTROL):
                raise NoLineSettingsError(
                    f"{self.name}: the server takes no line settings from a client (it "
                    "refused RFC 2217 control), so there are none to find from here; its "
                    "line is set on the server"
                ) from None
            raise
        for w in warnings:
            if w not in self.warnings:
                self.warnings.append(w)
        return port

    def __call__(self, line: LineSettings, seconds: float) -> Sample:
        port = self._open(line)
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


def _refusal_reason(text: str) -> str:
    """The port's own words from a refusal message (`explain` puts them in brackets)."""
    found = re.search(r"\(([^()]*)\); check --baud", text)
    return found.group(1) if found else text
