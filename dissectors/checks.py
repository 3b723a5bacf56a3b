"""Provides the Modbus error checks: CRC-16/MODBUS for RTU and LRC for ASCII."""

from __future__ import annotations

from collections.abc import Callable


def _make_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return tuple(table)


_TABLE = _make_table()


def crc16_py(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/MODBUS (poly 0xA001 reflected, init 0xFFFF, no final XOR), pure Python."""
    crc = 0xFFFF
    table = _TABLE
    for byte in bytes(data):
        crc = (crc >> 8) ^ table[(crc ^ byte) & 0xFF]
    return crc


def _pick_fast() -> Callable[[bytes | bytearray], int]:
    try:
        from fastcrc import crc16  # Rust implementation, about 25x the pure-Python table
    except ImportError:  # pragma: no cover - fastcrc has wheels for the usual platforms
        return crc16_py
    fast: Callable[[bytes | bytearray], int] = crc16.modbus
    if fast(b"123456789") != 0x4B37:  # pragma: no cover - guards against a wrong variant
        return crc16_py
    return fast


crc16: Callable[[bytes | bytearray], int] = _pick_fast()
"""CRC-16/MODBUS of `bytes`; the frame carries it low byte first."""


def crc_bytes(data: bytes) -> bytes:
    """The two CRC bytes to append to `data` (low byte first)."""
    return crc16(bytes(data)).to_bytes(2, "little")


def with_crc(data: bytes) -> bytes:
    """`data` followed by its CRC: a complete RTU frame."""
    return bytes(data) + crc_bytes(data)


def lrc(data: bytes | bytearray) -> int:
    """Modbus ASCII LRC: two's complement of the 8-bit sum of the bytes."""
    return (-sum(data)) & 0xFF


def ascii_frame(data: bytes) -> bytes:
    """`:`, the hex of `data` and its LRC in upper case, CR LF: a complete ASCII frame."""
    body = bytes(data) + bytes([lrc(data)])
    return b":" + body.hex().upper().encode("ascii") + b"\r\n"
