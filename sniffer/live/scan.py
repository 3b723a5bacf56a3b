"""Provides the line-settings scan: listen passively at each common setting, score each by
what the framer makes of the bytes, and name the setting the line is using.

A receiver set to the wrong baud rate or format still delivers bytes: the UART finds
start bits in the middle of characters and reports framing and parity errors. What
cannot happen by chance is a run of frames whose CRC (or LRC) checks, answered by frames
that fit them. So each setting is scored by its check-valid frames and request/answer
pairs, less its framing and parity errors and the bytes that framed as noise.

Several settings can read the same bytes: a receiver at 8N1 reads 8E1 traffic cleanly
(it takes the parity bit for idle line), and only the driver's parity error counter
tells them apart. Where the port has no counters the scan says the format is a guess.

The port is only ever opened passively (`serial_source.open_passive`: RTS and DTR not
asserted, line settings set before the port opens) and read; a scan changes nothing but
the local port's settings, one open per setting.
"""

from __future__ import annotations

import os
import select
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import serial

from sniffer.framing.pipeline import frame_capture
from sniffer.framing.store import NO_PARTNER
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
from sniffer.vocab import Flag, Kind

BAUDS = (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)
FORMATS = ("8N1", "8E1", "8O1", "8N2", "7E1", "7O1")  # 7-bit: Modbus ASCII only
DWELL = 0.6  # seconds of listening per setting, at first
MAX_DWELL = 4.0  # seconds a quiet setting is listened to at most
ENOUGH_BYTES = 200  # bytes that make one dwell enough to judge a setting
MIN_FRAMES = 2  # check-valid frames a winner needs
# which of several equally good readings to name: parity-checking formats first (with
# no parity errors counted they are confirmed), then 8N1, which a receiver cannot tell
# from 8N2 (it checks one stop bit) and which is the more common of the two
PREFERENCE = ("8E1", "8O1", "7E1", "7O1", "8N1", "8N2")


def parse_format(text: str) -> tuple[int, str, int]:
    """`8E1` -> (8, "E", 1). ValueError for anything else."""
    t = text.strip().upper()
    if len(t) != 3 or t[0] not in "78" or t[1] not in "NEO" or t[2] not in "12":
        raise ValueError(f"line format {text!r}: write data bits, parity, stop bits, e.g. 8E1")
    return int(t[0]), t[1], int(t[2])


def format_of(line: LineSettings) -> str:
    return f"{line.bytesize}{line.parity}{line.stopbits}"


def candidates(
    bauds: Sequence[int] = BAUDS, formats: Sequence[str] = FORMATS
) -> list[LineSettings]:
    """Every setting to try, fastest first within a format order (7-bit ones as ASCII)."""
    out: list[LineSettings] = []
    for baud in bauds:
        for text in formats:
            bytesize, parity, stopbits = parse_format(text)
            mode = "ascii" if bytesize == 7 else "auto"
            out.append(LineSettings(baud, bytesize, parity, stopbits, mode))
    return out


@dataclass(frozen=True, slots=True)
class Sample:
    """What one setting gave: chunks read, seconds listened, and the driver's error
    counts (None where the port keeps none, e.g. a pseudo-terminal or a network port)."""

    chunks: tuple[Chunk, ...]
    seconds: float
    framing_errors: int | None = None
    parity_errors: int | None = None

    @property
    def size(self) -> int:
        return sum(len(c.data) for c in self.chunks)


Listen = Callable[[LineSettings, float], Sample]
"""Listens at one setting for about that many seconds."""


@dataclass(frozen=True, slots=True)
class Trial:
    """One setting, listened to and scored."""

    line: LineSettings
    seconds: float
    bytes: int
    frames: int  # check-valid frames
    bad_frames: int  # frames whose CRC/LRC failed
    noise: int  # bytes that framed as no frame at all
    pairs: int  # requests answered by a response or exception
    framing_errors: int | None
    parity_errors: int | None
    mode: str  # what the framer took the traffic for: rtu or ascii

    @property
    def errors(self) -> int:
        return (self.framing_errors or 0) + (self.parity_errors or 0)

    @property
    def error_rate(self) -> float:
        """Line errors per byte read."""
        return self.errors / max(self.bytes, 1)

    @property
    def score(self) -> float:
        """Valid frames and pairs count for, errors and noise against (per second, so a
        longer dwell on a quiet setting does not win by itself)."""
        good = 10 * self.frames + 10 * self.pairs
        bad = 4 * self.bad_frames + self.errors + self.noise / 4
        return round((good - bad) / max(self.seconds, 1e-9), 1)

    @property
    def valid(self) -> bool:
        return self.frames >= MIN_FRAMES and self.frames > self.bad_frames

    def settings(self) -> str:
        return f"{self.line.baud} {format_of(self.line)}"


def score(line: LineSettings, sample: Sample) -> Trial:
    """Frame a sample at `line` and count what came out."""
    store = frame_capture(sample.chunks, line)
    frames = bad = noise = pairs = 0
    ascii_frames = 0
    for i in range(len(store)):
        kind = store.kind[i]
        if kind == Kind.EVENT:
            continue
        if kind == Kind.NOISE:
            noise += store.length[i]
            continue
        if store.flags[i] & (Flag.CHECK_BAD | Flag.NON_HEX):
            bad += 1
            continue
        frames += 1
        ascii_frames += bool(store.flags[i] & Flag.ASCII)
        if kind == Kind.REQUEST and store.partner[i] != NO_PARTNER:
            pairs += 1
    if frames:
        mode = "ascii" if ascii_frames * 2 > frames else "rtu"
    else:
        mode = "ascii" if line.mode == "ascii" else "rtu"
    return Trial(
        line,
        sample.seconds,
        sample.size,
        frames,
        bad,
        noise,
        pairs,
        sample.framing_errors,
        sample.parity_errors,
        mode,
    )


def _rank(trials: Sequence[Trial]) -> list[Trial]:
    """Best first. Among settings that read valid frames, those reading nearly as many
    frames as the best (a dwell can cut a frame at either end) are compared by their
    line-error rate; what remains equal is decided by PREFERENCE, then lower baud."""
    valid = [t for t in trials if t.valid]
    rest = sorted((t for t in trials if not t.valid), key=lambda t: (-t.score, t.line.baud))
    if not valid:
        return rest
    # the frame rate to be near is set by the cleanest readings: a setting that garbles
    # most bytes but happened to listen over a busier stretch must not set the bar
    cleanest = min(t.error_rate for t in valid)
    trusted = [t for t in valid if t.error_rate <= cleanest + 0.05]
    rate = max(t.frames / max(t.seconds, 1e-9) for t in trusted)
    near = [t for t in valid if t.frames / max(t.seconds, 1e-9) >= 0.6 * rate]
    lowest = min(t.error_rate for t in near)

    def key(t: Trial) -> tuple[float, ...]:
        in_near = t in near
        clean = in_near and t.error_rate <= lowest + 0.01
        return (
            -float(clean),
            -float(in_near),
            float(PREFERENCE.index(format_of(t.line))) if clean else t.error_rate,
            -t.score,
            float(t.line.baud),
        )

    return sorted(valid, key=key) + rest


@dataclass(frozen=True, slots=True)
class ScanResult:
    """Every trial, best first, and what they add up to."""

    trials: tuple[Trial, ...]
    winner: Trial | None
    verdict: str  # one or two sentences for the engineer
    quiet: bool = False  # too little traffic at any setting to decide
    counted_errors: bool = False  # the port reported framing/parity errors at all
    doubts: tuple[str, ...] = field(default=())

    def table(self, limit: int = 12) -> str:
        """The ranked table, as text."""
        head = f"{'#':>2}  {'setting':<12} {'mode':<5} {'bytes':>6} {'valid':>5} {'bad':>4} "
        head += f"{'pairs':>5} {'errors':>6} {'noise':>5} {'score':>7}"
        rows = [head]
        for n, t in enumerate(self.trials[:limit], 1):
            errors = "-" if t.framing_errors is None and t.parity_errors is None else t.errors
            rows.append(
                f"{n:>2}  {t.settings():<12} {t.mode:<5} {t.bytes:>6} {t.frames:>5} "
                f"{t.bad_frames:>4} {t.pairs:>5} {errors!s:>6} {t.noise:>5} {t.score:>7}"
            )
        if len(self.trials) > limit:
            rows.append(f"    ({len(self.trials) - limit} more settings read nothing better)")
        return "\n".join(rows)


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


def decide(trials: Iterable[Trial]) -> ScanResult:
    """Rank trials and name the winner, or say why there is none."""
    ranked = tuple(_rank(list(trials)))
    counted = any(t.framing_errors is not None or t.parity_errors is not None for t in ranked)
    total = sum(t.bytes for t in ranked)
    if not ranked or total == 0:
        return ScanResult(
            ranked,
            None,
            f"too quiet to decide: no byte arrived in {sum(t.seconds for t in ranked):.1f} s "
            "of listening. Is the adapter on the bus (A and B the right way round), and "
            "is the master polling?",
            quiet=True,
            counted_errors=counted,
        )
    best = ranked[0]
    if not best.valid:
        busiest = max(t.bytes for t in ranked)
        if busiest < ENOUGH_BYTES:
            return ScanResult(
                ranked,
                None,
                f"too quiet to decide: at most {busiest} bytes per setting and no run of "
                "valid frames. Scan again while the master polls, or with a longer --dwell.",
                quiet=True,
                counted_errors=counted,
            )
        return ScanResult(
            ranked,
            None,
            "no setting gave valid Modbus frames: the line carries bytes, but none read "
            "as RTU or ASCII at a common setting (another protocol, an unusual baud rate, "
            "or A/B swapped).",
            counted_errors=counted,
        )
    doubts: list[str] = []
    same = [
        t
        for t in ranked[1:]
        if t.valid and t.line.baud == best.line.baud and t.line.bytesize == best.line.bytesize
    ]
    if same and not counted:
        others = ", ".join(format_of(t.line) for t in same)
        doubts.append(
            f"{others} read the same frames; this port reports no parity or framing errors, "
            f"so {format_of(best.line)} is the likelier format, not a certain one"
        )
    if format_of(best.line) in ("8N1", "8N2"):
        doubts.append(
            "one stop bit or two read alike (a receiver checks only the first); "
            "8N1 is named, set 8N2 if the devices' manual says so"
        )
    verdict = f"{best.settings()} ({best.mode.upper()}): {best.frames} valid frames"
    verdict += f", {best.pairs} answered requests" if best.pairs else ""
    if best.framing_errors is not None or best.parity_errors is not None:
        verdict += f", {best.errors} line errors"
    return ScanResult(ranked, best, verdict, counted_errors=counted, doubts=tuple(doubts))


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

    Nothing is ever written; RTS and DTR stay off (see serial_source.open_passive)."""

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
