"""Provides the plain-text problems of a stored frame: checks, timing, pairing, source events."""

from __future__ import annotations

from dissectors.checks import crc16, lrc
from sniffer.framing import Flag, Kind, ascii_body
from sniffer.store import FrameView, Status

_FLAG_TEXT: tuple[tuple[int, str], ...] = tuple(
    (int(flag), text)
    for flag, text in (
        (Flag.GAP_INSIDE, "silence longer than 1.5 characters inside the frame"),
        (Flag.SHORT_SILENCE, "less than 3.5 characters of silence before the frame"),
        (Flag.LINE_ERROR, "framing or parity error on the line"),
        (Flag.NON_HEX, "characters other than hex digits between ':' and CR LF"),
        (Flag.ABORTED, "aborted: a new ':' came before CR LF"),
        (Flag.UNTERMINATED, "no CR LF before the capture ended"),
        (Flag.TOO_LONG, "longer than the mode's longest frame"),
        (Flag.LONG_GAP, "more than 1 s between two characters of the frame"),
        (Flag.NO_CR, "LF without CR"),
        (Flag.RETRY, "retry of a request that got no answer"),
        (Flag.LATE, "answer came after the response timeout"),
        (Flag.ANSWERED_BROADCAST, "answer to a broadcast, which must get none"),
        (Flag.QUIET_VIOLATED, "sent during the device's quiet time after a write"),
    )
)


def check_text(frame: FrameView) -> str:
    """`CRC 0x1234 wrong, expected 0x5678` for a bad check; empty when it is right."""
    if frame.kind in (Kind.NOISE, Kind.EVENT) or not frame.flags & Flag.CHECK_BAD:
        return ""
    if frame.ascii:
        body = ascii_body(frame.raw)
        if not body or len(body) < 2:
            return "too short for an LRC"
        return f"LRC 0x{body[-1]:02X} wrong, expected 0x{lrc(body[:-1]):02X}"
    raw = frame.raw
    if len(raw) < 3:
        return "too short for a CRC"
    sent = raw[-2] | raw[-1] << 8
    want = crc16(raw[:-2])
    return (
        f"CRC {raw[-2]:02X} {raw[-1]:02X} wrong, expected {want & 0xFF:02X} {want >> 8:02X}"
        f" (0x{sent:04X} vs 0x{want:04X})"
    )


def frame_problems(frame: FrameView, note: str = "") -> list[str]:
    """Every problem framing, pairing and device rules found on this row, as text."""
    out: list[str] = []
    if frame.kind == Kind.NOISE:
        out.append(f"noise: {len(frame.raw)} bytes no frame claims")
    if frame.kind == Kind.EVENT:
        out.append(note or "event")
        return out
    text = check_text(frame)
    if text:
        out.append(text)
    flags = frame.flags
    if flags:
        out.extend(words for flag, words in _FLAG_TEXT if flags & flag)
    if frame.status == Status.TIMEOUT:
        out.append("no answer (timeout)")
    elif frame.status == Status.ORPHAN:
        out.append("answer without a request")
    return out
