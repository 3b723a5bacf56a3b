"""Provides the Modbus TCP envelope: the MBAP header read and checked, problems as values.

An MBAP frame is a 7-byte header (transaction id, protocol id, length, unit id; big
endian) and the PDU. `length` counts the unit byte and the PDU, so a whole frame is
`6 + length` bytes. The unit byte and the PDU together are the same body an RTU frame
carries without its CRC: `body()` hands exactly that to `dissectors.dissect.dissect`.

Problem spans are byte offsets within the frame (header included); `dissect()` spans are
within the body, which starts at offset `BODY_OFFSET` of the frame.
"""

from __future__ import annotations

from dataclasses import dataclass

from dissectors.values import Problem, make_problem

HEADER_SIZE = 7  # transaction id 2, protocol id 2, length 2, unit 1
BODY_OFFSET = 6  # where the unit byte (the body dissect() takes) starts
MIN_LENGTH = 2  # unit + function code
MAX_LENGTH = 254  # unit + the longest PDU (253 bytes)
MAX_FRAME = BODY_OFFSET + MAX_LENGTH

ERROR = "error"
WARNING = "warning"


@dataclass(frozen=True, slots=True)
class Mbap:
    """One MBAP header as read, with what is wrong with it (fields the frame is too short
    to hold read as 0 and are named in `problems`)."""

    transaction: int
    protocol: int
    length: int
    unit: int
    problems: tuple[Problem, ...]

    @property
    def frame_length(self) -> int:
        """Bytes the header announces for the whole frame."""
        return BODY_OFFSET + self.length


def parse(frame: bytes) -> Mbap:
    """Read the MBAP header of one whole frame (header and PDU) and check it against the
    frame's size. Never raises."""
    n = len(frame)
    problems: list[Problem] = []
    transaction = int.from_bytes(frame[0:2], "big") if n >= 2 else 0
    protocol = int.from_bytes(frame[2:4], "big") if n >= 4 else 0
    length = int.from_bytes(frame[4:6], "big") if n >= 6 else 0
    unit = frame[6] if n >= 7 else 0
    if n < HEADER_SIZE:
        problems.append(
            make_problem(
                "mbap-short",
                ERROR,
                f"MBAP header cut short: {n} of {HEADER_SIZE} bytes",
                (0, n),
            )
        )
    if n >= 4 and protocol != 0:
        problems.append(
            make_problem(
                "mbap-protocol",
                ERROR,
                f"protocol id {protocol} (0x{protocol:04X}) is not 0 (Modbus)",
                (2, 4),
            )
        )
    if n >= 6:
        if not MIN_LENGTH <= length <= MAX_LENGTH:
            problems.append(
                make_problem(
                    "mbap-length-range",
                    ERROR,
                    f"MBAP length {length} outside {MIN_LENGTH}..{MAX_LENGTH}",
                    (4, 6),
                )
            )
        if n != BODY_OFFSET + length:
            problems.append(
                make_problem(
                    "mbap-length",
                    ERROR,
                    f"MBAP length {length} announces {BODY_OFFSET + length} bytes, "
                    f"the frame has {n}",
                    (4, 6),
                )
            )
    return Mbap(transaction, protocol, length, unit, tuple(problems))


def body(frame: bytes) -> bytes:
    """The unit byte and the PDU of a frame: what `dissect()` takes."""
    return frame[BODY_OFFSET:]


def plausible(buf: bytes | bytearray, pos: int = 0) -> bool:
    """Whether a frame could start at `pos`: protocol 0, a length in range, a function
    code byte that is not 0. Needs the 8 bytes up to the function code."""
    if len(buf) < pos + HEADER_SIZE + 1:
        return False
    if buf[pos + 2] or buf[pos + 3]:
        return False
    length = buf[pos + 4] << 8 | buf[pos + 5]
    return MIN_LENGTH <= length <= MAX_LENGTH and buf[pos + 7] not in (0, 0x80)


def announced(buf: bytes | bytearray, pos: int = 0) -> int | None:
    """Bytes of the frame starting at `pos` per its length field, None with < 6 bytes."""
    if len(buf) < pos + BODY_OFFSET:
        return None
    return BODY_OFFSET + (buf[pos + 4] << 8 | buf[pos + 5])


def consistent(payload: bytes | bytearray) -> bool:
    """Whether `payload` reads as whole MBAP frames back to back. The first must be
    whole; after it, the last may run past the end (a segment split inside a frame)."""
    pos = 0
    while pos < len(payload):
        if not plausible(payload, pos):
            return pos > 0 and len(payload) - pos < HEADER_SIZE + 1
        size = announced(payload, pos)
        assert size is not None
        if pos == 0 and size > len(payload):
            return False
        pos += size
    return pos > 0
