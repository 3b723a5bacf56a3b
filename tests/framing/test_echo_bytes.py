"""An echo is told by its bytes where the wait cannot tell it.

The normal answer to FC 5, 6, 21 and 22 is an echo of the request (FC 8's repeats its
sub-function). Where stamps are coarse (a resolution of 100 ms here), a frame with the
request's unit and code that comes after the response timeout, but within the
resolution of it, may be a late echo or the master's next request: the wait cannot say.
Its bytes can. Found on the benchmark's mix 6 recorded one frame a packet (62 ms): a
write that got no answer, the master's next write to another register 504 ms later
(timeout 467 ms) was taken for the echo, that write's own echo for a request, and every
write to the unit after it was paired one frame off until another code came between.
"""

from __future__ import annotations

from types import ModuleType

import pytest

from dissectors.checks import lrc, with_crc
from sniffer import core
from sniffer.framing import serial as framing
from sniffer.framing.pipeline import Pipeline
from sniffer.model import Chunk, LineSettings, Stamp
from sniffer.vocab import Kind, Status
from tests.support.core import _compiled

RTU = LineSettings(baud=19200, parity="E", mode="rtu")
ASCII = LineSettings(baud=9600, bytesize=7, parity="E", mode="ascii")
RESOLUTION = 0.1  # the stamps' worth, as the source declares it


def _rtu(hex_body: str) -> bytes:
    return with_crc(bytes.fromhex(hex_body))


def _ascii(hex_body: str) -> bytes:
    body = bytes.fromhex(hex_body)
    return b":" + (body + bytes([lrc(body)])).hex().upper().encode() + b"\r\n"


def _verdicts(
    line: LineSettings, first: str, second: str, after: float, fast: ModuleType | None
) -> list[tuple[Kind, Status, int]]:
    """`first` to unit 1, then `second` `after` seconds past the end of the wait for its
    answer (as the framer counts it: the response timeout and the stamps' resolution
    from the first's end), that frame again 10 ms later (its echo, if it is a request),
    then a read, answered; each frame a read, stamped at its end. The kind, status and
    partner of each."""
    saved = core.FAST, framing.FAST_MIN_BYTES
    core.FAST, framing.FAST_MIN_BYTES = fast, 0
    make = _rtu if line.mode == "rtu" else _ascii
    try:
        pipeline = Pipeline(line, stamps=Stamp.READ_END, resolution=RESOLUTION)
        a, b = make(first), make(second)
        wait = pipeline.pairer.timeout + pipeline.store.resolution
        t = len(a) * line.char_time + wait + after
        frames = [(a, 0.0), (b, t)]
        t += len(b) * line.char_time + 0.01
        frames += [(b, t), (make("010300000001"), t + 0.5), (make("0103020007"), t + 0.52)]
        for raw, at in frames:
            pipeline.feed(Chunk(raw, 1000.0 + at + len(raw) * line.char_time))
        pipeline.finish()
    finally:
        core.FAST, framing.FAST_MIN_BYTES = saved
    s = pipeline.store
    assert len(s) == 5
    return [(Kind(s.kind[i]), Status(s.status[i]), s.partner[i]) for i in range(len(s))]


WRITE, OTHER = "010600100001", "010600200002"
REQ, ANS = Kind.REQUEST, Kind.RESPONSE
OK, TIMED_OUT = Status.OK, Status.TIMEOUT
NEXT = [(REQ, TIMED_OUT, -1), (REQ, OK, 2), (ANS, OK, 1)]  # the master's next request
ECHO = [(REQ, OK, 1), (ANS, OK, 0), (REQ, TIMED_OUT, -1)]  # its echo, then a retry
CASES = {
    # the second frame, how long past the end of the wait (within RESOLUTION before it:
    # the wait cannot tell) it comes: the first three frames' verdicts
    "another write near the end": (WRITE, OTHER, -0.05, NEXT),
    "its own bytes near the end": (WRITE, WRITE, -0.05, ECHO),  # a late echo, as it may be
    "another write past the end": (WRITE, OTHER, 0.05, NEXT),
    "its own bytes past the end": (WRITE, WRITE, 0.05, NEXT),  # the master's retry
    # sooner than the wait can be off by: its answer (a slave's odd echo), by the wait
    "another write in time": (WRITE, OTHER, -0.15, ECHO),
    # FC 8 repeats its sub-function: the same one with a counter's value is its answer...
    "a diagnostics counter near the end": ("0108000b0000", "0108000b0007", -0.05, ECHO),
    # ... another sub-function the master's next request
    "another diagnostics request near the end": ("0108000b0000", "0108000c0000", -0.05, NEXT),
    # a mask write (FC 22) repeats the whole request: another register's is the next one
    "another mask write near the end": ("011600040012000f", "011600050012000f", -0.05, NEXT),
}


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("core_", ["python", "compiled", "ascii"])
def test_an_echo_near_the_end_of_the_wait_is_told_by_its_bytes(case: str, core_: str) -> None:
    first, second, after, expected = CASES[case]
    fast = _compiled() if core_ == "compiled" else None
    line = ASCII if core_ == "ascii" else RTU
    got = _verdicts(line, first, second, after, fast)
    assert got[:3] == expected
    assert got[3:] == [(REQ, OK, 4), (ANS, OK, 3)]  # the read after, answered
