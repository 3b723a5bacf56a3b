"""Provides the Modbus TCP envelope: the MBAP header (transaction id, protocol id,
length, unit id) and the PDU, checked by `dissectors.mbap`."""

from __future__ import annotations

from dataclasses import dataclass

from dissectors import mbap
from dissectors.values import Problem

__all__ = ["MbapFrame", "open_mbap"]


@dataclass(frozen=True, slots=True)
class MbapFrame:
    """One Modbus TCP frame's raw bytes (header and PDU), opened. Modbus TCP carries no
    CRC: the header is the frame's only check (protocol id 0, a length that fits)."""

    raw: bytes
    header: mbap.Mbap

    transport = "mbap"

    @property
    def transaction(self) -> int:
        return self.header.transaction

    @property
    def unit(self) -> int | None:
        return self.raw[mbap.BODY_OFFSET] if len(self.raw) > mbap.BODY_OFFSET else None

    @property
    def body(self) -> bytes:
        """Unit and PDU: the frame from the unit byte on (what `dissect()` takes)."""
        return mbap.body(self.raw)

    @property
    def pdu(self) -> bytes:
        return self.body[1:]

    @property
    def problems(self) -> tuple[Problem, ...]:
        """What is wrong with the header (spans are offsets in the raw frame)."""
        return self.header.problems

    @property
    def check_ok(self) -> bool:
        return not self.header.problems and len(self.raw) > mbap.HEADER_SIZE

    @property
    def check_text(self) -> str:
        """The header's problems in words (`protocol id 1 (0x0001) is not 0 (Modbus)`);
        empty when the header is right."""
        if self.header.problems:
            return "; ".join(p.text for p in self.header.problems)
        if len(self.raw) <= mbap.HEADER_SIZE:
            return "no function code after the MBAP header"
        return ""

    @property
    def spans(self) -> tuple[tuple[str, tuple[int, int]], ...]:
        n = len(self.raw)
        parts = (("transaction", 0, 2), ("protocol", 2, 4), ("length", 4, 6), ("unit", 6, 7))
        out = [(name, (a, min(b, n))) for name, a, b in parts if a < n]
        if n > mbap.HEADER_SIZE:
            out.append(("pdu", (mbap.HEADER_SIZE, n)))
        return tuple(out)


def open_mbap(raw: bytes | bytearray | memoryview) -> MbapFrame:
    """The Modbus TCP envelope of a frame's raw bytes; never raises."""
    raw = bytes(raw)
    return MbapFrame(raw, mbap.parse(raw))
