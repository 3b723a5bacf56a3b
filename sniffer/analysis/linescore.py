"""Provides the scoring of line settings: how well the bytes read at one baud rate and
format frame as Modbus, and which of several settings the line is using.

A receiver set to the wrong baud rate or format still delivers bytes: the UART finds
start bits in the middle of characters and reports framing and parity errors. What
cannot happen by chance is a run of frames whose CRC (or LRC) checks, answered by frames
that fit them. So each setting is scored by its check-valid frames and request/answer
pairs, less its framing and parity errors and the bytes that framed as noise.

Several settings can read the same bytes: a receiver at 8N1 reads 8E1 traffic cleanly
(it takes the parity bit for idle line), and only the driver's parity error counter
tells them apart. Where the port has no counters the verdict says the format is a guess.

The bytes come from anywhere: a live port listened to at each setting
(`sniffer.live.scan`), or a logic capture decoded at each format
(`sniffer.analysis.baud`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from sniffer.framing.pipeline import frame_capture
from sniffer.framing.store import NO_PARTNER
from sniffer.model import Chunk, LineSettings
from sniffer.vocab import Flag, Kind

BAUDS = (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)
FORMATS = ("8N1", "8E1", "8O1", "8N2", "7E1", "7O1")  # 7-bit: Modbus ASCII only
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
