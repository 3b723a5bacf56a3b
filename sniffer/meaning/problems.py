"""Provides the problems of a stored row as structured values: checks, timing, pairing, events.

Each problem is a `dissectors.values.Problem` (kind, severity, text, span), the same type
the dissector gives, so a view can colour by severity and highlight the bytes. Spans are
offsets in the frame's body (unit byte and PDU, decoded for ASCII), as field spans are;
the check's span runs past the body over the CRC or LRC. Meanings come from
`sniffer.vocab`; this module only fills in the numbers.
"""

from __future__ import annotations

from dissectors.envelope import open_ascii, open_mbap, open_rtu
from dissectors.values import Problem
from sniffer.framing.store import FrameView
from sniffer.vocab import (
    EVENT_MEANING,
    FLAGS,
    NOISE_MEANING,
    PROBLEM_MASK,
    STATUS_PROBLEMS,
    Flag,
    Kind,
)

# flags whose sentence has numbers in it: the check's here, the device's timing in the
# describer (which knows the dictionary); an event row says its own note
_SAID_ELSEWHERE = Flag.CHECK_BAD | Flag.DEVICE_SLOW | Flag.LINE_EVENT | Flag.ENVELOPE_BAD
# facts (info) listed with the problems, so every view and export says them
_SAID_TOO = Flag.VENDOR_START
_LISTED = tuple(
    (int(flag), m)
    for flag, m in FLAGS
    if flag & (PROBLEM_MASK | _SAID_TOO) and not flag & _SAID_ELSEWHERE
)
_CHECK = dict(FLAGS)[Flag.CHECK_BAD]
# plain ints for the per-row tests (`int & IntFlag` makes an enum member each time)
_CHECK_BAD, _ENVELOPE_BAD = int(Flag.CHECK_BAD), int(Flag.ENVELOPE_BAD)
_STATUS = {int(status): m for status, m in STATUS_PROBLEMS.items()}
_ENVELOPE = dict(FLAGS)[Flag.ENVELOPE_BAD]
_NOISE_EVENT = (int(Kind.NOISE), int(Kind.EVENT))


def check_text(frame: FrameView) -> str:
    """`CRC 0x1234 wrong, expected 0x5678` for a bad check; empty when it is right."""
    if frame.kind in (Kind.NOISE, Kind.EVENT) or not frame.flags & _CHECK_BAD:
        return ""
    envelope = open_ascii(frame.raw) if frame.ascii else open_rtu(frame.raw)
    return envelope.check_text


def _check_span(frame: FrameView) -> tuple[int, int] | None:
    """Body offsets of the CRC (two bytes) or LRC (one decoded byte) after the body."""
    n = len(frame.body())
    if frame.ascii:
        return (n, n + 1) if n else None
    return (n, n + 2) if len(frame.raw) >= 3 else None


def frame_problems(frame: FrameView, note: str = "") -> list[Problem]:
    """Every problem framing, pairing and the source found on this row."""
    if not frame.flags and frame.status not in _STATUS and frame.kind not in _NOISE_EVENT:
        return []  # most rows: no flag, no check to say, no status worth a word
    out: list[Problem] = []
    if frame.kind == Kind.NOISE:
        m = NOISE_MEANING
        text = f"noise: {len(frame.raw)} {m.text}"
        out.append(Problem(m.kind, m.severity, text, None))
    if frame.kind == Kind.EVENT:
        m = EVENT_MEANING
        out.append(Problem(m.kind, m.severity, note or "event", None))
        return out
    text = check_text(frame)
    if text:
        out.append(Problem(_CHECK.kind, _CHECK.severity, text, _check_span(frame)))
    if frame.flags & _ENVELOPE_BAD:
        # the header's own sentences; its spans lie before the body, so none is given
        m = _ENVELOPE
        for p in open_mbap(frame.raw).problems:
            out.append(Problem(m.kind, m.severity, f"MBAP: {p.text}", None))
    flags = frame.flags
    if flags:
        out.extend(Problem(m.kind, m.severity, m.text, None) for f, m in _LISTED if flags & f)
    meaning = _STATUS.get(frame.status)
    if meaning is not None:
        out.append(Problem(meaning.kind, meaning.severity, meaning.text, None))
    return out
