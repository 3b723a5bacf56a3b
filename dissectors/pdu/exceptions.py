"""Provides exception responses (function | 0x80): their layout, the standard exception
codes and their meaning."""

from __future__ import annotations

from dissectors.pdu.schema import Record, UInt8
from dissectors.pdu.work import WARNING, Work

EXCEPTION_SCHEMA = Record("exception_code" / UInt8)
"""An exception response (function | 0x80): one exception code byte."""

EXCEPTION_LENGTH = 5
"""An exception response: address, function | 0x80, exception code, CRC."""

EXCEPTION_CODES: dict[int, str] = {
    0x01: "illegal function",
    0x02: "illegal data address",
    0x03: "illegal data value",
    0x04: "server device failure",
    0x05: "acknowledge",
    0x06: "server device busy",
    0x08: "memory parity error",
    0x0A: "gateway path unavailable",
    0x0B: "gateway target device failed to respond",
}
"""The standard exception codes."""


def exception_name(code: int) -> str:
    """The standard name of an exception code, or "unknown exception"."""
    return EXCEPTION_CODES.get(code, "unknown exception")


def exception(w: Work) -> None:
    code = w.get("exception_code")
    if w.is_request:
        w.problem("role", WARNING, "exception response seen as a request", (1, 2))
    if code is None:
        w.summary = "exception"
        return
    name = exception_name(code)
    w.retext("exception_code", name)
    w.summary = f"exception {code:02X} {name}"
