"""Provides the Modbus RTU envelope: unit byte, PDU, CRC-16/MODBUS (low byte first)."""

from __future__ import annotations

from dataclasses import dataclass

from dissectors.checks import crc16, with_crc

CHECK_SIZE = 2


@dataclass(frozen=True, slots=True)
class RtuFrame:
    """One RTU frame's raw bytes, opened: unit, PDU, the CRC sent and the one expected.

    `sent` and `expected` are None when the frame is too short to carry a CRC after at
    least the unit byte (fewer than 3 bytes)."""

    raw: bytes
    sent: int | None
    expected: int | None

    transport = "rtu"

    @property
    def unit(self) -> int | None:
        return self.raw[0] if len(self.raw) > CHECK_SIZE else None

    @property
    def body(self) -> bytes:
        """Unit and PDU: the raw bytes without the CRC."""
        return self.raw[:-CHECK_SIZE] if len(self.raw) > CHECK_SIZE else b""

    @property
    def pdu(self) -> bytes:
        return self.body[1:]

    @property
    def check_ok(self) -> bool:
        return self.sent is not None and self.sent == self.expected

    @property
    def check_text(self) -> str:
        """`CRC 34 12 wrong, expected 78 56 (0x1234 vs 0x5678)`; empty when right."""
        if self.sent is None or self.expected is None:
            return "too short for a CRC"
        if self.sent == self.expected:
            return ""
        sent, want = self.sent, self.expected
        return (
            f"CRC {sent & 0xFF:02X} {sent >> 8:02X} wrong, expected {want & 0xFF:02X} "
            f"{want >> 8:02X} (0x{sent:04X} vs 0x{want:04X})"
        )

    @property
    def spans(self) -> tuple[tuple[str, tuple[int, int]], ...]:
        n = len(self.raw)
        if n <= CHECK_SIZE:
            return (("data", (0, n)),)
        return (("unit", (0, 1)), ("pdu", (1, n - CHECK_SIZE)), ("crc", (n - CHECK_SIZE, n)))


def open_rtu(raw: bytes | bytearray | memoryview) -> RtuFrame:
    """The RTU envelope of a frame's raw bytes (unit, PDU, CRC); never raises."""
    raw = bytes(raw)
    if len(raw) <= CHECK_SIZE:
        return RtuFrame(raw, None, None)
    return RtuFrame(raw, raw[-2] | raw[-1] << 8, crc16(raw[:-CHECK_SIZE]))


def rtu_frame(body: bytes) -> bytes:
    """The RTU frame of a body (unit and PDU): the body and its CRC."""
    return with_crc(body)
