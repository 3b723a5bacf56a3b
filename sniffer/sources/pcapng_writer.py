"""Provides the pcapng writer for recordings and exports, and the serial link payloads.

Blocks are little-endian: one section header (with `shb_userappl`), interface
descriptions (`if_name`, `if_description`, `if_tsresol`), and enhanced packet blocks
(`epb_flags`, `opt_comment`). The stream is flushed after every block, so a recording
cut short loses at most the block being written, and readers report the cut.

To record line settings, give `add_interface` the description `describe_interface(line)`
(`modscope 19200 8E1 rtu`, optionally ` master` or ` slave`); the reader takes them back.
"""

from __future__ import annotations

import math
import struct
from typing import BinaryIO

from sniffer.sources.linktypes import (
    BLOCK_EPB,
    BLOCK_IDB,
    BLOCK_SHB,
    BYTE_ORDER_MAGIC,
    EPB_FLAG_CRC_ERROR,
    EPB_FLAG_INBOUND,
    EPB_FLAG_OUTBOUND,
    EPB_FLAGS,
    IF_DESCRIPTION,
    IF_NAME,
    IF_TSRESOL,
    LINKTYPE_RTAC_SERIAL,
    LINKTYPE_USER0,
    LINKTYPE_WIRESHARK_UPPER_PDU,
    OPT_COMMENT,
    OPT_ENDOFOPT,
    RTAC_CAPTURE_DATA_LOST,
    RTAC_DATA_RX_START,
    RTAC_DATA_TX_START,
    RTAC_FRAMING_ERROR,
    RTAC_PARITY_ERROR,
    RTAC_SERIAL_BREAK,
    RTAC_STATUS_CHANGE,
    SHB_USERAPPL,
    build_rtac,
    build_upper_pdu,
    describe_interface,
)

__all__ = [
    "EPB_FLAG_CRC_ERROR",
    "EPB_FLAG_INBOUND",
    "EPB_FLAG_OUTBOUND",
    "LINKTYPE_RTAC_SERIAL",
    "LINKTYPE_USER0",
    "LINKTYPE_WIRESHARK_UPPER_PDU",
    "RTAC_CAPTURE_DATA_LOST",
    "RTAC_DATA_RX_START",
    "RTAC_DATA_TX_START",
    "RTAC_FRAMING_ERROR",
    "RTAC_PARITY_ERROR",
    "RTAC_SERIAL_BREAK",
    "RTAC_STATUS_CHANGE",
    "PcapngWriter",
    "describe_interface",
    "rtac_record",
    "upper_pdu_record",
]


def time_ticks(t: float, per_second: int) -> int:
    """`t` seconds in ticks, rounded to the nearest (whole seconds kept exact)."""
    whole = math.floor(t)
    return whole * per_second + round((t - whole) * per_second)


def _option(code: int, value: bytes) -> bytes:
    return struct.pack("<HH", code, len(value)) + value + b"\0" * (-len(value) % 4)


def _options(options: list[bytes]) -> bytes:
    if not options:
        return b""
    return b"".join(options) + struct.pack("<HH", OPT_ENDOFOPT, 0)


def _block(block_type: int, body: bytes) -> bytes:
    total = 12 + len(body)
    return struct.pack("<II", block_type, total) + body + struct.pack("<I", total)


class PcapngWriter:
    """Writes a pcapng section to `stream`: interfaces, then packets as they come."""

    def __init__(self, stream: BinaryIO, *, application: str = "modscope") -> None:
        self._stream = stream
        self._ticks: list[int] = []  # ticks per second of each interface
        options = [_option(SHB_USERAPPL, application.encode("utf-8"))] if application else []
        body = struct.pack("<IHHq", BYTE_ORDER_MAGIC, 1, 0, -1) + _options(options)
        self._write(_block(BLOCK_SHB, body))

    def add_interface(
        self, linktype: int, *, name: str = "", description: str = "", tsresol_ns: bool = True
    ) -> int:
        """Describe an interface; returns its id for `write_packet`."""
        options = []
        if name:
            options.append(_option(IF_NAME, name.encode("utf-8")))
        if description:
            options.append(_option(IF_DESCRIPTION, description.encode("utf-8")))
        options.append(_option(IF_TSRESOL, bytes((9 if tsresol_ns else 6,))))
        body = struct.pack("<HHI", linktype, 0, 0) + _options(options)
        self._write(_block(BLOCK_IDB, body))
        self._ticks.append(1_000_000_000 if tsresol_ns else 1_000_000)
        return len(self._ticks) - 1

    def write_packet(
        self,
        interface: int,
        t: float,
        data: bytes,
        *,
        flags: int | None = None,
        comment: str | None = None,
    ) -> None:
        """One enhanced packet block at Unix time `t` (seconds) on `interface`."""
        if not 0 <= interface < len(self._ticks):
            raise ValueError(f"no interface {interface}; add_interface first")
        if t < 0:
            raise ValueError(f"packet time must not be negative, not {t}")
        ticks = time_ticks(t, self._ticks[interface])
        options = []
        if comment:
            options.append(_option(OPT_COMMENT, comment.encode("utf-8")))
        if flags is not None:
            options.append(_option(EPB_FLAGS, struct.pack("<I", flags)))
        body = (
            struct.pack("<IIIII", interface, ticks >> 32, ticks & 0xFFFFFFFF, len(data), len(data))
            + data
            + b"\0" * (-len(data) % 4)
            + _options(options)
        )
        self._write(_block(BLOCK_EPB, body))

    def flush(self) -> None:
        self._stream.flush()

    def _write(self, block: bytes) -> None:
        self._stream.write(block)
        self._stream.flush()


def rtac_record(
    t: float, data: bytes, *, event: int = RTAC_DATA_RX_START, control_lines: int = 0
) -> bytes:
    """A link type 250 packet: RTAC header (time `t`, when the first byte began) + data."""
    return build_rtac(t, data, event, control_lines)


def upper_pdu_record(frame: bytes, dissector: str = "mbrtu") -> bytes:
    """A link type 252 packet: exported-PDU tags naming `dissector`, then the frame."""
    return build_upper_pdu(frame, dissector)
