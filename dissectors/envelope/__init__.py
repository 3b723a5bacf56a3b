"""Provides the envelopes around a Modbus PDU: what a transport wraps around the function
code and its data, and how that wrapping is checked.

The framer finds where a frame starts and ends; an envelope says what is inside those
bytes: the unit, the PDU, the check the frame carries and the one it should carry, and
where each part lies in the raw bytes. `dissect()` then takes the body (unit and PDU)
apart, whatever envelope it came in.

- `rtu`: unit byte, PDU, CRC-16 (low byte first).
- `ascii`: `:`, the hex of unit, PDU and LRC, CR LF.
- `mbap`: Modbus TCP's header (transaction id, protocol id, length, unit), then the PDU.

RTU over TCP or UDP is the `rtu` envelope. A new transport is a new module here with a
frozen class that has the attributes of `Envelope` and a function that opens raw bytes
into it; nothing in the PDU dissector changes.
"""

from __future__ import annotations

from typing import Protocol

from dissectors.envelope.ascii import AsciiFrame, ascii_body, ascii_frame, open_ascii
from dissectors.envelope.mbap import MbapFrame, open_mbap
from dissectors.envelope.rtu import RtuFrame, open_rtu, rtu_frame

Span = tuple[int, int]


class Envelope(Protocol):
    """What every envelope tells about one frame's raw bytes.

    `unit` is None when the frame is too short (or, in ASCII, not hex) to hold one;
    `pdu` is the function code and data; `body` is unit and PDU, what `dissect()` takes.
    `check_ok` says whether the check the frame carries is the one it should, and
    `check_text` says so in words (empty when it is right). `spans` names the parts by
    their (start, end) offsets in the raw bytes, in order.
    """

    @property
    def transport(self) -> str: ...

    @property
    def raw(self) -> bytes: ...

    @property
    def unit(self) -> int | None: ...

    @property
    def pdu(self) -> bytes: ...

    @property
    def body(self) -> bytes: ...

    @property
    def check_ok(self) -> bool: ...

    @property
    def check_text(self) -> str: ...

    @property
    def spans(self) -> tuple[tuple[str, Span], ...]: ...


__all__ = [
    "AsciiFrame",
    "Envelope",
    "MbapFrame",
    "RtuFrame",
    "Span",
    "ascii_body",
    "ascii_frame",
    "open_ascii",
    "open_mbap",
    "open_rtu",
    "rtu_frame",
]
