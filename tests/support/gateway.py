"""Provides helpers shared by tests (moved from test_gateway.py)."""

from __future__ import annotations

from sniffer.analysis.gateway import Verdict
from sniffer.model import LineSettings

EXC_0B = bytes([1, 0x83, 0x0B])

SERIAL_CLOCK = -100.0  # the serial recorder's clock is 100 s behind the network capture's


DELAY_IN = 0.004  # the gateway forwards a request 4 ms after it arrives


DELAY_OUT = 0.003


RTU_TIME = 0.010  # a request or answer takes about 10 ms on the line


LINE = LineSettings(baud=19200, parity="N", stopbits=2)


def mbap_frame(tid: int, body: bytes) -> bytes:
    return tid.to_bytes(2, "big") + b"\0\0" + len(body).to_bytes(2, "big") + body


def read_request(address: int) -> bytes:
    return bytes([1, 3]) + address.to_bytes(2, "big") + b"\x00\x01"


def read_answer(value: int) -> bytes:
    return bytes([1, 3, 2]) + value.to_bytes(2, "big")


# (TCP answer, serial request sent, serial answer): one transaction per injected fate
CASES = [
    ("ok", read_answer(10), True, read_answer(10)),
    ("dropped", None, False, None),
    ("slow device", None, True, None),
    ("answer lost", None, True, read_answer(13)),
    ("0x0B, device silent", EXC_0B, True, None),
    ("0x0B, device answered", EXC_0B, True, read_answer(15)),
    ("0x0B, never sent", EXC_0B, False, None),
    ("different answer", read_answer(17), True, read_answer(18)),
    ("ok again", read_answer(19), True, read_answer(19)),
]


EXPECTED = [
    Verdict.OK,
    Verdict.NOT_SENT,
    Verdict.DEVICE_TIMEOUT,
    Verdict.ANSWER_LOST,
    Verdict.GATEWAY_EXCEPTION,
    Verdict.GATEWAY_FAULT,
    Verdict.GATEWAY_EXCEPTION,
    Verdict.MISMATCH,
    Verdict.OK,
]
