"""Provides the offline line estimate: the baud rate of a logic capture from its shortest
pulses, the character format from how the characters decode, and a check that tells when
a capture's bytes were read at the wrong speed.

On a UART line every level lasts a whole number of bit times, so the shortest pulses
(a lone 0 or 1 bit) measure one bit time; the baud rate is the sample rate over it,
snapped to the nearest common rate when it is within 4 % of one. The format is then the
one under which the characters decode with the fewest framing and parity errors and the
most check-valid Modbus frames; where several read alike, parity formats (which would
have shown parity errors) come first, then one stop bit, then two (a sender that leaves
gaps between characters reads cleanly with either).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import compress

from sniffer.analysis.linescore import Sample, format_of, parse_format, score
from sniffer.framing.columns import both, but_not, flag_mask, marking
from sniffer.framing.store import FrameStore
from sniffer.model import Chunk, LineSettings
from sniffer.sources.base import LineGuess, ReadOptions
from sniffer.sources.sigrok import UartDecoder
from sniffer.vocab import BAD_CHECK, Flag, Kind

__all__ = [
    "COMMON_BAUDS",
    "FORMATS",
    "BaudGuess",
    "LineGuess",
    "SpeedCheck",
    "choose_format",
    "describe_choice",
    "estimate_baud",
    "estimate_line",
    "pulse_widths",
    "wrong_speed",
]

COMMON_BAUDS = (
    300, 600, 1200, 2400, 4800, 9600, 14400, 19200, 28800, 38400, 56000, 57600,
    76800, 115200, 128000, 230400, 250000, 256000, 460800, 500000, 921600, 1000000,
)  # fmt: skip
SNAP = 0.04  # a measured rate within 4 % of a common one is taken as that one
MIN_PULSES = 8  # pulses needed before a width is trusted
FORMATS = ("8E1", "8O1", "8N1", "8N2", "7E1", "7O1")  # also the preference order


@dataclass(frozen=True, slots=True)
class BaudGuess:
    """A baud rate measured from pulse widths."""

    baud: int
    measured: float  # the rate the pulses give, before snapping
    bit_samples: float  # samples per bit
    pulses: int  # pulses the estimate rests on
    common: bool  # snapped to a common rate


def pulse_widths(levels: bytes) -> list[int]:
    """The lengths (in samples) of every run of equal levels but the first and last
    (cut by the capture's start and end)."""
    widths: list[int] = []
    start = 0
    find = levels.find
    level = levels[0] if levels else 1
    while True:
        nxt = find(b"\x00" if level else b"\x01", start)
        if nxt < 0:
            break
        if start:
            widths.append(nxt - start)
        start = nxt
        level ^= 1
    return widths


def estimate_baud(samplerate: float, levels: Sequence[bytes]) -> BaudGuess | None:
    """The baud rate the shortest pulses of one or more probes give, or None when there
    are too few pulses (or the rate is beyond what the sample rate resolves)."""
    widths = sorted(w for probe in levels for w in pulse_widths(probe) if w >= 2)
    if len(widths) < MIN_PULSES:
        return None
    floor = widths[len(widths) // 100]  # the shortest 1 % may be glitches
    single = [w for w in widths if floor <= w < floor * 1.5]
    if len(single) < MIN_PULSES // 2:
        return None
    bit = sum(single) / len(single)
    # pulses of 2, 3 ... bits refine the estimate: each is close to a multiple of `bit`
    total = 0.0
    count = 0
    for w in widths:
        k = round(w / bit)
        if 1 <= k <= 10 and abs(w - k * bit) <= 0.25 * bit:
            total += w / k
            count += 1
    if count:
        bit = total / count
    measured = samplerate / bit
    if measured < 1:  # pulses a second long or more: no UART line (and no LineSettings)
        return None
    nearest = min(COMMON_BAUDS, key=lambda b: abs(b - measured))
    common = abs(nearest - measured) <= SNAP * nearest
    baud = nearest if common else round(measured)
    return BaudGuess(baud, measured, bit, count or len(single), common)


def choose_format(
    baud: int,
    decode: Callable[[LineSettings], tuple[list[Chunk], int, int]],
    formats: Sequence[str] = FORMATS,
    mode: str = "auto",
) -> tuple[LineSettings, int, str]:
    """The format under which `decode` gives the most valid frames and fewest errors,
    with its count of valid frames and a sentence of evidence.

    `decode(line)` returns the characters as chunks and the framing and parity errors.
    """
    results = []
    for rank, text in enumerate(formats):
        bytesize, parity, stopbits = parse_format(text)
        # 7 data bits carry Modbus ASCII only
        line = LineSettings(baud, bytesize, parity, stopbits, "ascii" if bytesize == 7 else mode)
        chunks, framing, parity_errors = decode(line)
        trial = score(line, Sample(tuple(chunks), 1.0, framing, parity_errors))
        rate = trial.error_rate
        results.append((-trial.frames, round(rate, 2), rank, trial))
    results.sort(key=lambda r: r[:3])
    best = results[0][3]
    why = f"{best.frames} valid frames, {best.errors} line errors in {best.bytes} characters"
    return best.line, best.frames, why


def wrong_speed(store: FrameStore, min_bytes: int = 64) -> str | None:
    """A warning when a capture's bytes look read at the wrong speed: many bytes, no
    check-valid frame (and line errors, where the source reported them)."""
    check = SpeedCheck()
    check.add(store)
    return check.warning(min_bytes)


class SpeedCheck:
    """`wrong_speed` over rows given in parts (`add`): a whole store, or the segments of
    a windowed session one after the other. It keeps three counts."""

    def __init__(self) -> None:
        self.valid = False  # a check-valid frame was seen: the speed is right
        self.total = 0  # bytes of every row but events
        self.noise = 0  # bytes of noise rows
        self.errors = 0  # rows (but events) with framing or parity errors

    def add(self, store: FrameStore, start: int = 0) -> None:
        """Count the rows of `store` from `start` on."""
        if self.valid:
            return
        store.sync()
        n = len(store)
        kinds = store.kind[start:n].tobytes()
        # one valid frame is enough: the speed is right (the columns are scanned in C, not
        # a row at a time: bytes read at the wrong speed have no valid frame to stop at)
        if 1 in but_not(kinds.translate(_IS_FRAME), flag_mask(store.flags, BAD_CHECK, start, n)):
            self.valid = True
            return
        lengths = store.length[start:n]
        on_bus = kinds.translate(_IS_BUS_BYTES)  # every row but events
        self.total += sum(compress(lengths, on_bus))
        self.noise += sum(compress(lengths, kinds.translate(_IS_NOISE)))
        self.errors += both(on_bus, flag_mask(store.flags, int(Flag.LINE_ERROR), start, n)).count(1)

    def warning(self, min_bytes: int = 64) -> str | None:
        """The warning, for the rows added so far (None: no reason to doubt the speed)."""
        total = self.total
        if self.valid or total < min_bytes or self.noise < total // 2:
            return None
        lead = f"{total} bytes and no valid Modbus frame"
        if self.errors:
            lead += f" ({self.errors} rows with framing or parity errors)"
        return (
            f"{lead}: were these bytes read at the wrong speed or format? "
            "On the line itself, `modscope scan PORT` finds its settings"
        )


_IS_BUS_BYTES = marking(k for k in range(256) if k != Kind.EVENT)  # kind byte -> 0/1
_IS_NOISE = marking((Kind.NOISE,))
_IS_FRAME = marking(k for k in range(256) if k not in (Kind.NOISE, Kind.EVENT))


def describe_choice(guess: BaudGuess, line: LineSettings, why: str) -> str:
    measured = f"{guess.measured:.0f} baud measured from {guess.pulses} pulses"
    if guess.common:
        head = f"no --baud given: chose {line.baud} {format_of(line)} ({measured}"
    else:
        head = f"no --baud given: chose {line.baud} {format_of(line)}, not a common rate "
        head += f"({measured}"
    return f"{head}; {why}). Give --baud and --parity to override"


def estimate_line(
    samplerate: float, levels: Sequence[bytes], options: ReadOptions
) -> LineGuess | None:
    """The line settings of logic levels (one bytes string of 0/1 per probe), keeping
    whatever the options give (data bits, parity, stop bits, mode): the
    `sniffer.sources.base.LineEstimator` a session gives the readers (a sigrok capture
    replayed without --baud)."""
    guess = estimate_baud(samplerate, levels)
    if guess is None:
        return None

    def fits(text: str) -> bool:
        bytesize, parity, stopbits = parse_format(text)
        return (
            options.bytesize in (None, bytesize)
            and options.parity in (None, parity)
            and options.stopbits in (None, stopbits)
        )

    formats = [f for f in FORMATS if fits(f)]
    if not formats:  # a combination not in the list: take it as given
        line = options.line(LineSettings(guess.baud))
        return LineGuess(line, describe_choice(guess, line, "format as given"))

    def decode(line: LineSettings) -> tuple[list[Chunk], int, int]:
        chunks: list[Chunk] = []
        framing = parity = 0
        for channel, probe in enumerate(levels):
            decoder = UartDecoder(samplerate, line, channel=channel)
            for chunk in decoder.feed(probe, final=True):
                if chunk.event == "parity error":
                    parity += 1
                elif chunk.event == "framing error":
                    framing += 1
                elif chunk.data:
                    chunks.append(chunk)
        chunks.sort(key=lambda c: c.t_end)
        return chunks, framing, parity

    line, frames, why = choose_format(guess.baud, decode, formats, options.mode or "auto")
    if not frames:
        if guess.common and guess.pulses >= 100:
            why += "; no valid frame at any format: check --probe and --invert"
            return LineGuess(line, describe_choice(guess, line, why))
        return None  # a few pulses and no frame confirm nothing: keep the defaults
    return LineGuess(line, describe_choice(guess, line, why))
