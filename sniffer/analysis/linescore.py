"""Provides the scoring of line settings: how well the bytes read at one baud rate and
format frame as Modbus, which of several settings the line is using, and how sure that is.

A receiver set to the wrong baud rate or format still delivers bytes: the UART finds
start bits in the middle of characters and, where its driver counts them, reports
framing and parity errors. What cannot happen by chance is a run of frames whose CRC (or
LRC) checks, answered by frames that fit them. So each setting is judged first by its
data: the share of its bytes that framed as check-valid frames, and how many such frames
and answered requests it read. The driver's error counters come second, and only where
they are seen to count at all: some drivers (CP210x adapters) answer the counter ioctl
but never count, and a pseudo-terminal or a network port has none.

Several formats can read the same bytes at the right speed, and which do depends on the
receiver. Every UART checks only the first stop bit, so 8N1 and 8N2 always read alike. A
plain receiver at 8N1 reads 8E1 traffic cleanly (it takes the parity bit for a stop bit
and hunts for the next start bit); a 16550-family receiver takes a low "stop bit" for
the next start bit and garbles it, but reads 8N1 traffic at 8E1 cleanly. Where the data
and the counters leave several formats, the verdict names all of them, the one to
listen with, its confidence and what would raise it: never one format as a certainty
the evidence does not give.

The bytes come from anywhere: a live port listened to at each setting
(`sniffer.live.scan`), or a logic capture decoded at each format
(`sniffer.analysis.baud`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace

from sniffer.framing.pipeline import frame_capture
from sniffer.framing.store import NO_PARTNER
from sniffer.model import Chunk, LineSettings
from sniffer.vocab import Flag, Kind

BAUDS = (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)
FORMATS = ("8N1", "8E1", "8O1", "8N2", "7E1", "7O1")  # 7-bit: Modbus ASCII only
ENOUGH_BYTES = 200  # bytes that make one dwell enough to judge a setting
MIN_FRAMES = 2  # check-valid frames a winner needs
FEW_FRAMES = 6  # fewer valid frames than this leave the baud rate itself in some doubt
# a setting reads "as well" as the best when the share of its bytes in valid frames is
# at most this much lower (a dwell cuts a frame at either end) ...
CLEAN_SLACK = 0.15
# ... and it read at least this share of the best frame rate (a listen can fall on a
# quieter stretch of the poll cycle)
RATE_SHARE = 0.6
ERROR_SLACK = 0.01  # line errors per byte that still count as "as few as the fewest"

HIGH, MEDIUM, LOW = "high", "medium", "low"
LEVELS = (HIGH, MEDIUM, LOW)


def parse_format(text: str) -> tuple[int, str, int]:
    """`8E1` -> (8, "E", 1). ValueError for anything else."""
    t = text.strip().upper()
    if len(t) != 3 or t[0] not in "78" or t[1] not in "NEO" or t[2] not in "12":
        raise ValueError(f"line format {text!r}: write data bits, parity, stop bits, e.g. 8E1")
    return int(t[0]), t[1], int(t[2])


def format_of(line: LineSettings) -> str:
    return f"{line.bytesize}{line.parity}{line.stopbits}"


def listen_rank(text: str) -> tuple[int, int, int]:
    """The order in which formats that read alike are named and the first chosen to
    listen with: fewest stop bits, then no parity, even, odd (even is Modbus's default
    parity; without parity a receiver checks the least)."""
    bytesize, parity, stopbits = parse_format(text)
    return (stopbits, "NEO".index(parity), -bytesize)


def first_round(formats: Sequence[str]) -> list[str]:
    """The formats the first round reads each baud rate at: per data width, the first
    without parity and the first with it (in the order given). At the right speed one of
    the two reads the data bytes of every format of that width on any common receiver:
    a 16550-family receiver garbles parity traffic read without parity, a plain one
    garbles back-to-back no-parity traffic read with parity, and neither checks a second
    stop bit or which parity it is."""
    out: list[str] = []
    taken: set[tuple[int, bool]] = set()
    for text in formats:
        bytesize, parity, _stopbits = parse_format(text)
        key = (bytesize, parity != "N")
        if key not in taken:
            taken.add(key)
            out.append(text)
    return out


def candidates(
    bauds: Sequence[int] = BAUDS, formats: Sequence[str] = FORMATS
) -> list[LineSettings]:
    """Every setting to try, in the order given (7-bit ones as ASCII)."""
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
    valid_bytes: int = 0  # bytes inside check-valid frames

    @property
    def counted(self) -> bool:
        """The port reported error counts for this setting (zero or more)."""
        return self.framing_errors is not None or self.parity_errors is not None

    @property
    def errors(self) -> int:
        return (self.framing_errors or 0) + (self.parity_errors or 0)

    @property
    def error_rate(self) -> float:
        """Line errors per byte read."""
        return self.errors / max(self.bytes, 1)

    @property
    def clean(self) -> float:
        """The share of the bytes read that framed as check-valid frames."""
        return self.valid_bytes / max(self.bytes, 1)

    @property
    def rate(self) -> float:
        """Valid frames per second of listening."""
        return self.frames / max(self.seconds, 1e-9)

    @property
    def score(self) -> float:
        """What the data says, per second (so a longer dwell on a quiet setting does not
        win by itself): valid frames and answered requests for, failed checks and noise
        against. Line errors are left out: a driver may never count them."""
        good = 10 * self.frames + 10 * self.pairs
        bad = 4 * self.bad_frames + self.noise / 4
        return round((good - bad) / max(self.seconds, 1e-9), 1)

    @property
    def valid(self) -> bool:
        return self.frames >= MIN_FRAMES and self.frames > self.bad_frames

    def settings(self) -> str:
        return f"{self.line.baud} {format_of(self.line)}"


def score(line: LineSettings, sample: Sample) -> Trial:
    """Frame a sample at `line` and count what came out. An 8-bit setting is framed as
    the framer's auto mode takes it and, where that found no frame but the bytes hold a
    colon, as ASCII too (a listen that starts inside an ASCII frame can lead the auto
    mode to RTU); the better reading counts."""
    trial = _score(line, sample)
    if trial.frames or line.mode != "auto":
        return trial
    if not any(b":" in c.data for c in sample.chunks):
        return trial
    ascii_trial = _score(replace(line, mode="ascii"), sample)
    if ascii_trial.frames <= trial.frames:
        return trial
    return replace(ascii_trial, line=line)


def _score(line: LineSettings, sample: Sample) -> Trial:
    store = frame_capture(sample.chunks, line)
    frames = bad = noise = pairs = valid_bytes = 0
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
        valid_bytes += store.length[i]
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
        valid_bytes,
    )


@dataclass(frozen=True, slots=True)
class Refusal:
    """A setting the port would not take (a pseudo-terminal refusing even parity, an RFC
    2217 server rejecting a value): skipped, and said."""

    line: LineSettings
    reason: str

    def settings(self) -> str:
        return f"{self.line.baud} {format_of(self.line)}"


def counter_state(trials: Iterable[Trial]) -> str:
    """What the driver's error counters are worth in this scan: "counting" (they counted
    an error at some setting, so a zero means something), "silent" (they answered but
    never counted one, not even at settings that read garbage: a driver that does not
    count, as CP210x adapters' do not) or "none" (the port keeps none)."""
    reported = [t for t in trials if t.counted]
    if any(t.errors for t in reported):
        return "counting"
    return "silent" if reported else "none"


COUNTER_WORDS = {
    "silent": (
        "this port's driver reported no framing or parity error at any setting, not even "
        "at those that read garbage, so it does not count them (CP210x adapters do not)"
    ),
    "none": "this port keeps no framing or parity error counters",
}
MORE_COUNTING = (
    "a port whose driver counts parity and framing errors (an FTDI adapter or a "
    "built-in 16550 UART) would tell them apart"
)
STOP_BITS_SAID = (
    "a receiver checks only the first stop bit, so it reads one stop bit and two alike "
    "(a second stop bit is idle line to it)"
)
MORE_STOP_BITS = (
    "the devices' manual, or a logic analyser on the line (a master that sends two stop "
    "bits leaves at least two bit times of idle between the characters of a frame), would "
    "tell one stop bit from two; listening at {listen} reads either"
)


@dataclass(frozen=True, slots=True)
class ScanResult:
    """Every trial, best first, and what they add up to."""

    trials: tuple[Trial, ...]
    winner: Trial | None  # the setting to listen with
    verdict: str  # one sentence for the engineer
    quiet: bool = False  # too little traffic at any setting to decide
    counters: str = "none"  # see counter_state
    alike: tuple[str, ...] = ()  # formats at the winner's speed that read as well, named first
    confidence: str = ""  # high, medium or low; empty without a winner
    reason: str = ""  # why the confidence is what it is
    raise_it: tuple[str, ...] = ()  # what would raise it
    doubts: tuple[str, ...] = field(default=())
    refused: tuple[Refusal, ...] = ()

    @property
    def counted_errors(self) -> bool:
        """The driver's counters counted, so zero errors at a setting mean something."""
        return self.counters == "counting"

    def table(self, limit: int = 12) -> str:
        """The ranked table, as text ("-" where the port counts no errors)."""
        head = f"{'#':>2}  {'setting':<12} {'mode':<5} {'bytes':>6} {'valid':>5} {'clean':>5} "
        head += f"{'bad':>4} {'pairs':>5} {'errors':>6} {'noise':>5} {'score':>7}"
        rows = [head]
        for n, t in enumerate(self.trials[:limit], 1):
            errors = t.errors if t.counted and self.counters == "counting" else "-"
            rows.append(
                f"{n:>2}  {t.settings():<12} {t.mode:<5} {t.bytes:>6} {t.frames:>5} "
                f"{round(100 * t.clean):>4}% {t.bad_frames:>4} {t.pairs:>5} {errors!s:>6} "
                f"{t.noise:>5} {t.score:>7}"
            )
        if len(self.trials) > limit:
            rows.append(f"    ({len(self.trials) - limit} more settings read nothing better)")
        return "\n".join(rows)

    def refused_text(self) -> str:
        """The refused settings in one line per reason, or ""."""
        by_reason: dict[str, list[str]] = {}
        for r in self.refused:
            by_reason.setdefault(r.reason, []).append(r.settings())
        return "\n".join(
            f"skipped {len(names)} settings the port refused ({', '.join(names)}): {reason}"
            if len(names) > 1
            else f"skipped {names[0]}, which the port refused: {reason}"
            for reason, names in by_reason.items()
        )


def _rank(trials: Sequence[Trial], trusted: bool) -> tuple[list[Trial], list[Trial]]:
    """(every trial best first, the valid ones that read as well as the best).

    By the data first: the settings whose share of bytes in valid frames is near the
    best share, and whose frame rate is near the best rate among them. The counters then
    split those only when `trusted`: a driver that never counts says nothing by its
    zeros."""
    valid = [t for t in trials if t.valid]
    rest = sorted((t for t in trials if not t.valid), key=lambda t: (-t.score, t.line.baud))
    if not valid:
        return rest, []
    top = max(t.clean for t in valid)
    data = [t for t in valid if t.clean >= top - CLEAN_SLACK]
    # the rate to be near is set by the cleanest readings: a setting that garbles most
    # bytes but happened to listen over a busier stretch must not set the bar
    bar_from = data
    if trusted:
        cleanest = min(t.error_rate for t in data)
        bar_from = [t for t in data if t.error_rate <= cleanest + 0.05]
    bar = RATE_SHARE * max(t.rate for t in bar_from)
    near = [t for t in data if t.rate >= bar]
    alike = near
    if trusted:
        lowest = min(t.error_rate for t in near)
        alike = [t for t in near if t.error_rate <= lowest + ERROR_SLACK]
    lead = max(alike, key=lambda t: (round(t.clean, 2), t.rate, t.pairs))
    group = sorted(
        (
            t
            for t in alike
            if t.line.baud == lead.line.baud and t.line.bytesize == lead.line.bytesize
        ),
        key=lambda t: listen_rank(format_of(t.line)),
    )
    others = sorted(
        (t for t in valid if t not in group),
        key=lambda t: (
            -float(t in alike),
            -round(t.clean, 2),
            t.error_rate if trusted else 0.0,
            -t.score,
            t.line.baud,
        ),
    )
    return group + others + rest, alike


def either(names: Sequence[str], word: str = "or") -> str:
    """`8N1 or 8N2`, `8N1, 8E1 or 8N2`."""
    if len(names) < 2:
        return "".join(names)
    return f"{', '.join(names[:-1])} {word} {names[-1]}"


def _stop_bit_twin(text: str) -> str:
    return f"{text[:2]}{2 if text[2] == '1' else 1}"


def decide(trials: Iterable[Trial], refused: Iterable[Refusal] = ()) -> ScanResult:
    """Rank trials and name the winner with its confidence, or say why there is none."""
    tried = list(trials)
    refusals = tuple(refused)
    counters = counter_state(tried)
    trusted = counters == "counting"
    ranked_list, alike_trials = _rank(tried, trusted)
    ranked = tuple(ranked_list)
    total = sum(t.bytes for t in ranked)
    if not ranked and refusals:
        return ScanResult(
            ranked,
            None,
            f"the port refused all {len(refusals)} settings tried; none could be listened to",
            refused=refusals,
        )
    if not ranked or total == 0:
        return ScanResult(
            ranked,
            None,
            f"too quiet to decide: no byte arrived in {sum(t.seconds for t in ranked):.1f} s "
            "of listening. Is the adapter on the bus (A and B the right way round), and "
            "is the master polling?",
            quiet=True,
            counters=counters,
            refused=refusals,
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
                counters=counters,
                refused=refusals,
            )
        return ScanResult(
            ranked,
            None,
            "no setting gave valid Modbus frames: the line carries bytes, but none read "
            "as RTU or ASCII at a common setting (another protocol, an unusual baud rate, "
            "or A/B swapped).",
            counters=counters,
            refused=refusals,
        )
    return _judge(ranked, alike_trials, counters, refusals)


def _judge(
    ranked: tuple[Trial, ...],
    alike_trials: list[Trial],
    counters: str,
    refusals: tuple[Refusal, ...],
) -> ScanResult:
    """The winner's verdict, with its confidence and what would raise it."""
    best = ranked[0]
    baud, bytesize = best.line.baud, best.line.bytesize
    here = [t for t in ranked if t.line.baud == baud and t.line.bytesize == bytesize]
    tried_here = {format_of(t.line) for t in here}
    formats = {format_of(t.line) for t in alike_trials if t in here}
    # a receiver checks one stop bit: the other count reads alike unless tried and beaten
    for text in list(formats):
        twin = _stop_bit_twin(text)
        if text[1] == "N" and twin not in tried_here:
            formats.add(twin)
    alike = tuple(sorted(formats, key=listen_rank))
    refused_here = sorted(
        {format_of(r.line) for r in refusals if r.line.baud == baud and r.line.bytesize == bytesize}
        - formats,
        key=listen_rank,
    )
    level = HIGH
    reasons: list[str] = []
    raise_it: list[str] = []
    doubts: list[str] = []
    named = either(alike)
    parities = {f[1] for f in alike}
    counter_words = COUNTER_WORDS.get(counters, "")

    def lower(to: str) -> None:
        nonlocal level
        level = max(level, to, key=LEVELS.index)

    if len(alike) == 1:
        beaten = sorted(
            (t for t in here if format_of(t.line) not in formats),
            key=lambda t: listen_rank(format_of(t.line)),
        )
        garbled = [t for t in beaten if not t.valid or t.clean < best.clean - CLEAN_SLACK]
        counted = [t for t in beaten if t not in garbled]
        if garbled:
            names = [format_of(t.line) for t in garbled]
            verb = "garble" if len(names) > 1 else "garbles"
            reasons.append(f"at {baud} baud {either(names, 'and')} {verb} the frames")
        if counted:
            names = [format_of(t.line) for t in counted]
            rates = either([f"{round(100 * t.error_rate)}%" for t in counted], "and")
            reasons.append(
                f"{either(names, 'and')} read the frames with line errors on {rates} of "
                f"the bytes, {alike[0]} on {round(100 * best.error_rate)}%"
            )
        if not beaten:
            lower(MEDIUM)
            reasons.append(f"{alike[0]} was the only format of its width tried at {baud} baud")
            raise_it.append("scan again with all the formats (drop --formats)")
    elif parities == {"N"}:
        lower(MEDIUM)
        reasons.append(f"{named}: {STOP_BITS_SAID}")
        raise_it.append(MORE_STOP_BITS.format(listen=alike[0]))
    elif "N" not in parities and len({f[2] for f in alike}) == 1:
        lower(MEDIUM)
        reasons.append(f"{named}: even and odd parity read alike, as {counter_words}")
        raise_it.append(MORE_COUNTING)
    else:
        lower(LOW)
        reasons.append(
            f"{either(alike, 'and')} read the same frames at {baud} baud, and "
            f"{counter_words}: nothing here tells them apart"
        )
        raise_it.append(MORE_COUNTING)
        raise_it.append(MORE_STOP_BITS.format(listen=alike[0]))
    if refused_here and counters != "counting":
        lower(MEDIUM)
        reasons.append(
            f"{', '.join(refused_here)} could not be tried at {baud} baud (the port refused)"
        )
    elsewhere = sorted({t.settings() for t in alike_trials if t not in here})
    if elsewhere:
        lower(LOW)
        reasons.append(f"{either(elsewhere, 'and')} read valid frames as well")
        raise_it.append("scan again with a longer --dwell while the master polls")
    if best.frames < FEW_FRAMES or best.pairs == 0:
        lower(MEDIUM)
        what = f"only {best.frames} valid frames"
        if best.pairs == 0:
            what += " and no answered request"
        reasons.append(what)
        raise_it.append("listen longer while the master polls (--dwell, --max-dwell)")
    verdict = f"{baud} {named} ({best.mode.upper()}): {best.frames} valid frames"
    verdict += f", {best.pairs} answered requests" if best.pairs else ""
    if counters == "counting" and best.counted:
        verdict += f", {best.errors} line errors"
    if len(alike) > 1:
        doubts.append(f"listening at {best.settings()}, which reads {named} alike")
    return ScanResult(
        ranked,
        best,
        verdict,
        counters=counters,
        alike=alike,
        confidence=level,
        reason="; ".join(reasons),
        raise_it=tuple(dict.fromkeys(raise_it)),
        doubts=tuple(doubts),
        refused=refusals,
    )
