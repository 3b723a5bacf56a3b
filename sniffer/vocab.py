"""Provides the pipeline's vocabulary: frame kinds, flags, transaction status, and what each means.

Every stage stores what it finds as small integers (a kind, a flag word, a status per
row) so that millions of rows stay compact. This module defines those integers once,
with one table that gives each flag and status its problem kind, severity, sentence,
short tag and the stage that sets it. Views read the table; nobody writes a second one
or rebuilds a mask.

Severities are the dissector's: `error` (the frame is wrong or lost), `warning` (it
works, but a rule is broken or something is suspicious), `info` (a fact worth showing).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

ERROR = "error"
WARNING = "warning"
INFO = "info"
SEVERITIES = (ERROR, WARNING, INFO)  # most severe first


class Kind(enum.IntEnum):
    """What a stored row is."""

    NOISE = 0
    REQUEST = 1
    RESPONSE = 2
    EXCEPTION = 3
    UNKNOWN = 4  # a frame whose check is right but whose direction cannot be told
    EVENT = 5  # no bus bytes: something the source reported (reconnect, data lost)


class Flag(enum.IntFlag):
    """Problems and facts about a row, stored per row as one integer.

    The stage that sets each one is in `FLAGS`; framing sets bits 0-10, pairing and
    annotation set 11-15 on stored rows, sources 16; Modbus TCP framing and pairing
    (`sniffer.framing.tcp`) set 17-19; the ASCII framer sets 20. Bit 24 and up are facts.
    """

    NONE = 0
    CHECK_BAD = 1 << 0
    GAP_INSIDE = 1 << 1
    SHORT_SILENCE = 1 << 2
    LINE_ERROR = 1 << 3
    NON_HEX = 1 << 4
    ABORTED = 1 << 5
    UNTERMINATED = 1 << 6
    TOO_LONG = 1 << 7
    LONG_GAP = 1 << 8
    SILENCE_FRAMED = 1 << 9
    NO_CR = 1 << 10
    RETRY = 1 << 11
    LATE = 1 << 12
    ANSWERED_BROADCAST = 1 << 13
    DEVICE_SLOW = 1 << 14
    QUIET_VIOLATED = 1 << 15
    LINE_EVENT = 1 << 16
    ENVELOPE_BAD = 1 << 17  # MBAP protocol id not 0, or a length wrong or out of range
    TID_REUSED = 1 << 18  # a Modbus TCP request reusing an id still waiting for its answer
    CUT_SHORT = 1 << 19  # cut by a gap in the captured TCP stream or by its end
    VENDOR_START = 1 << 20  # an ASCII frame opened by a vendor's start character, not ':'
    ASCII = 1 << 24  # the frame was sent in ASCII mode (a fact, not a problem)
    MBAP = 1 << 25  # a Modbus TCP frame: raw = MBAP header + PDU (a fact, not a problem)


class Status(enum.IntEnum):
    """What became of a transaction (stored per row, for requests and answers alike)."""

    NONE = 0  # noise, events, frames not (yet) part of a transaction
    OK = 1
    EXCEPTION = 2
    TIMEOUT = 3  # a request that got no answer
    ORPHAN = 4  # an answer with no request
    BROADCAST = 5  # a request to address 0: no answer expected
    OPEN = 6  # a request still waiting (live), or the capture ended first
    BAD_ANSWER = 7  # the answer came with a wrong CRC or LRC (the master drops it)

    @property
    def label(self) -> str:
        """The word listings use: `ok`, `bad answer`, '' for NONE."""
        return STATUS_NAMES[self]


STATUS_NAMES = ("", "ok", "exception", "timeout", "orphan", "broadcast", "open", "bad answer")
KIND_NAMES = ("noise", "request", "response", "exception", "unknown", "event")

FRAMING = "framing"
PAIRING = "pairing"
ANNOTATION = "annotation"
SOURCE = "source"


@dataclass(frozen=True, slots=True)
class Meaning:
    """What one flag or status says about a row.

    `kind` is the stable problem code (in JSONL `problem_details`), `tag` the short word
    a one-line summary starts with ('' where the row's colour already says it), `text`
    the sentence the detail pane and listings show.
    """

    kind: str
    severity: str
    text: str
    tag: str
    stage: str


# The one table of meanings, in the order problems are listed.
FLAGS: tuple[tuple[Flag, Meaning], ...] = (
    (Flag.CHECK_BAD, Meaning("check", ERROR, "CRC or LRC does not match", "", FRAMING)),
    (
        Flag.GAP_INSIDE,
        Meaning(
            "gap-inside",
            WARNING,
            "silence longer than 1.5 characters inside the frame",
            "gap",
            FRAMING,
        ),
    ),
    (
        Flag.SHORT_SILENCE,
        Meaning(
            "short-silence",
            WARNING,
            "less than 3.5 characters of silence before the frame",
            "short-silence",
            FRAMING,
        ),
    ),
    (
        Flag.LINE_ERROR,
        Meaning("line-error", ERROR, "framing or parity error on the line", "line-error", FRAMING),
    ),
    (
        Flag.NON_HEX,
        Meaning(
            "non-hex",
            ERROR,
            "characters other than hex digits between ':' and CR LF",
            "non-hex",
            FRAMING,
        ),
    ),
    (
        Flag.ABORTED,
        Meaning("aborted", ERROR, "aborted: a new ':' came before CR LF", "aborted", FRAMING),
    ),
    (
        Flag.UNTERMINATED,
        Meaning(
            "unterminated", WARNING, "no CR LF before the capture ended", "unterminated", FRAMING
        ),
    ),
    (
        Flag.TOO_LONG,
        Meaning("too-long", ERROR, "longer than the mode's longest frame", "too-long", FRAMING),
    ),
    (
        Flag.LONG_GAP,
        Meaning(
            "long-gap",
            WARNING,
            "more than 1 s between two characters of the frame",
            "long-gap",
            FRAMING,
        ),
    ),
    (
        Flag.SILENCE_FRAMED,
        Meaning(
            "silence-framed",
            INFO,
            "framed by silence alone: no length rule knows this function code",
            "",
            FRAMING,
        ),
    ),
    (Flag.NO_CR, Meaning("no-cr", WARNING, "LF without CR", "no-cr", FRAMING)),
    (
        Flag.RETRY,
        Meaning("retry", WARNING, "retry of a request that got no answer", "retry", PAIRING),
    ),
    (
        Flag.LATE,
        Meaning("late", WARNING, "answer came after the response timeout", "late", PAIRING),
    ),
    (
        Flag.ANSWERED_BROADCAST,
        Meaning(
            "answered-broadcast",
            WARNING,
            "answer to a broadcast, which must get none",
            "answered-broadcast",
            PAIRING,
        ),
    ),
    (
        Flag.DEVICE_SLOW,
        Meaning(
            "device-slow",
            WARNING,
            "slower than the device's documented response time",
            "slow",
            ANNOTATION,
        ),
    ),
    (
        Flag.QUIET_VIOLATED,
        Meaning(
            "quiet-time",
            WARNING,
            "sent during the device's quiet time after a write",
            "quiet-time",
            ANNOTATION,
        ),
    ),
    (
        Flag.LINE_EVENT,
        Meaning("line-event", WARNING, "the source reported something here", "", SOURCE),
    ),
    (
        Flag.ENVELOPE_BAD,
        Meaning(
            "mbap-header",
            ERROR,
            "MBAP header wrong (protocol id or length)",
            "mbap",
            FRAMING,
        ),
    ),
    (
        Flag.TID_REUSED,
        Meaning(
            "tid-reused",
            WARNING,
            "transaction id reused while a request with it waits",
            "tid-reused",
            PAIRING,
        ),
    ),
    (
        Flag.CUT_SHORT,
        Meaning(
            "cut-short",
            ERROR,
            "frame cut short by a gap in the capture or its end",
            "cut-short",
            FRAMING,
        ),
    ),
    (
        Flag.VENDOR_START,
        Meaning(
            "vendor-start",
            INFO,
            "vendor variant: '>' where Modbus ASCII has ':' (ABL eMH1 answers)",
            "vendor",
            FRAMING,
        ),
    ),
)
FLAG_MEANINGS: dict[Flag, Meaning] = dict(FLAGS)

# Statuses that are problems in themselves (the others are said by the status column).
STATUS_PROBLEMS: dict[Status, Meaning] = {
    Status.TIMEOUT: Meaning("timeout", ERROR, "no answer (timeout)", "", PAIRING),
    Status.ORPHAN: Meaning("orphan", WARNING, "answer without a request", "", PAIRING),
}

NOISE_MEANING = Meaning("noise", WARNING, "bytes no frame claims", "", FRAMING)
EVENT_MEANING = Meaning("event", INFO, "the source reported an event", "", SOURCE)

# Masks, each defined here once.
# the frame's check cannot be trusted (a Modbus TCP frame's only check is its header)
BAD_CHECK = int(Flag.CHECK_BAD | Flag.NON_HEX | Flag.ENVELOPE_BAD)
PROBLEM_MASK = int(sum(int(f) for f, m in FLAGS if m.severity != INFO))  # flags worth a look
PAIRING_FLAGS = int(sum(int(f) for f, m in FLAGS if m.stage == PAIRING))
