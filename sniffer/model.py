"""Provides the plain values that flow from sources to the framer: line settings and chunks."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

PARITIES = ("N", "E", "O", "M", "S")
MODES = ("rtu", "ascii", "auto")


class Direction(enum.IntEnum):
    """Who sent a chunk, when the source knows it (a probe per direction, socat `>`/`<`)."""

    UNKNOWN = 0
    MASTER = 1  # requests: master to slaves
    SLAVE = 2  # responses: slaves to master


@dataclass(frozen=True, slots=True)
class LineSettings:
    """Serial line format. The character time and RTU silences follow from it."""

    baud: int = 19200
    bytesize: int = 8
    parity: str = "E"
    stopbits: int = 1
    mode: str = "auto"

    def __post_init__(self) -> None:
        if self.baud <= 0:
            raise ValueError(f"baud rate must be positive, not {self.baud}")
        if self.bytesize not in (7, 8):
            raise ValueError(f"bytesize must be 7 or 8, not {self.bytesize}")
        if self.parity not in PARITIES:
            raise ValueError(f"parity must be one of {', '.join(PARITIES)}, not {self.parity!r}")
        if self.stopbits not in (1, 2):
            raise ValueError(f"stopbits must be 1 or 2, not {self.stopbits}")
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, not {self.mode!r}")

    @property
    def char_bits(self) -> int:
        """Bits on the wire per character: start, data, parity if any, stop bits."""
        return 1 + self.bytesize + (0 if self.parity == "N" else 1) + self.stopbits

    @property
    def char_time(self) -> float:
        """Seconds one character takes on the wire."""
        return self.char_bits / self.baud

    @property
    def t15(self) -> float:
        """Longest legal silence inside an RTU frame (fixed at 750 us above 19200 baud)."""
        return 750e-6 if self.baud > 19200 else 1.5 * self.char_time

    @property
    def t35(self) -> float:
        """Shortest legal silence between RTU frames (fixed at 1750 us above 19200 baud)."""
        return 1750e-6 if self.baud > 19200 else 3.5 * self.char_time

    def describe(self) -> str:
        """`19200 8E1 rtu` style summary."""
        return f"{self.baud} {self.bytesize}{self.parity}{self.stopbits} {self.mode}"


@dataclass(frozen=True, slots=True)
class Chunk:
    """What one read gave: bytes and the time they arrived.

    `t_end` is when the last byte was complete (for a host read: when the read returned).
    `t_start` is when the first byte started, if the source knows it exactly (logic
    analyser captures, RTAC records); otherwise None and the framer estimates it from the
    character time. Times are seconds; absolute (Unix epoch) when the source knows the
    wall clock, else relative to the start of the capture.

    `channel` separates independent byte streams (a probe or port per direction); each
    channel is framed on its own. `event` marks a chunk that carries no bus data but
    something that happened: "framing error", "parity error", "data lost", "reconnect",
    "gap" (with a text in `note`).
    """

    data: bytes
    t_end: float
    t_start: float | None = None
    channel: int = 0
    direction: Direction = Direction.UNKNOWN
    event: str = ""
    note: str = ""


class Stamp(enum.Enum):
    """What a source's timestamps mean. Pairing and latency use it to decide what the
    timing can measure: only EXACT and READ_END stamps follow the wire closely enough to
    compute gaps; the others can order frames but bound latencies only loosely."""

    EXACT = "exact"  # per character, start and end (logic analyser, RTAC records)
    READ_END = "read-end"  # when a host read returned (serial port; bursts of up to ~16 ms)
    FRAME_START = "frame-start"  # when the frame's first byte was seen
    FRAME_END = "frame-end"  # when the frame's last byte was seen
    PRINT = "print"  # when a logger printed the line: before or after the frame's end
    NONE = "none"  # no timestamps at all: any time shown is synthetic


class Labels(enum.Enum):
    """How far a source's direction labels can be trusted."""

    NONE = "none"  # no labels
    CERTAIN = "certain"  # one probe or port per direction: the wire says who sent it
    HINT = "hint"  # a logger's own sends vs receives, EPB flags, dump markers: usually right


@dataclass(frozen=True, slots=True)
class SourceInfo:
    """What a capture reader learned about its file: format, settings, warnings.

    `stamps` says what the timestamps mean and `resolution` how fine they are (seconds;
    0 when exact, 1e-3 for a logger printing milliseconds); `labels` how far the
    direction carried by the chunks can be trusted. `line` is what the capture is read
    with (the command line over the file's own); `recorded_line` what the file itself
    recorded, if it did. `network` is true for an Ethernet-family capture: its channels
    are TCP or UDP connection directions, labelled as `sniffer.sources.net` says, and it
    is framed by `sniffer.framing.tcp.NetPipeline`.
    """

    path: str
    format: str
    line: LineSettings | None = None
    exact_timing: bool = False
    channels: dict[int, str] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    stamps: Stamp = Stamp.READ_END
    resolution: float = 0.0
    labels: Labels = Labels.NONE
    notes: tuple[str, ...] = ()  # what the reader decided for the user (not warnings)
    recorded_line: LineSettings | None = None
    network: bool = False
