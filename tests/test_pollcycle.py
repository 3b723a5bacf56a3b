"""The poll cycle: periods, jitter and gaps of repeating requests, from byte literals."""

from __future__ import annotations

import pytest

from dissectors.checks import with_crc
from sniffer.model import Chunk, LineSettings
from sniffer.pipeline import frame_capture
from sniffer.pollcycle import cycle_table, poll_cycles

LINE = LineSettings(19200, 8, "E", 1)
READ_3 = with_crc(bytes.fromhex("0303000a0002"))  # unit 3: holding 10-11
READ_7 = with_crc(bytes.fromhex("070400000001"))  # unit 7: input 0


def answer(unit: int, fc: int, words: int) -> bytes:
    return with_crc(bytes([unit, fc, 2 * words]) + bytes(2 * words))


def test_period_jitter_and_gap() -> None:
    chunks: list[Chunk] = []
    # unit 3 every 0.5 s, +-10 ms, with a pause of 3 s after the 10th poll
    t = 0.0
    for k in range(20):
        t += 0.5 + (0.01 if k % 2 else -0.01)
        if k == 10:
            t += 2.5
        chunks += [Chunk(READ_3, t), Chunk(answer(3, 3, 2), t + 0.02)]
        if k % 5 == 0:  # unit 7 every 2.5 s
            chunks += [Chunk(READ_7, t + 0.1), Chunk(answer(7, 4, 1), t + 0.12)]
    cycles = poll_cycles(frame_capture(chunks, LINE))
    (poll,) = cycles[3].polls
    assert poll.what == "read holding 10-11" and poll.count == 20
    assert poll.period == pytest.approx(0.5, abs=0.011)
    assert poll.jitter == pytest.approx(0.02, abs=0.001)  # waits of 0.49 and 0.51 s
    (gap,) = poll.gaps
    assert gap.length == pytest.approx(3.0, abs=0.011)
    assert cycles[7].polls[0].period == pytest.approx(2.5, abs=0.03)
    table = cycle_table(cycles, {3: "Pump 1"})
    assert "read holding 10-11" in table and "Pump 1" in table
    assert "gap at " in table and "without polls" in table


def test_writes_with_different_values_are_one_poll_and_rare_requests_are_counted() -> None:
    chunks: list[Chunk] = []
    for k in range(4):
        write = with_crc(bytes([3, 6, 0, 20, 0, k]))
        chunks += [Chunk(write, k * 1.0), Chunk(write, k * 1.0 + 0.02)]
    chunks += [Chunk(READ_7, 10.0), Chunk(answer(7, 4, 1), 10.02)]
    cycles = poll_cycles(frame_capture(chunks, LINE))
    (poll,) = cycles[3].polls
    assert poll.what == "write holding 20" and poll.count == 4
    assert cycles[7].polls == [] and cycles[7].once == 1
    assert "(no request repeated 3 times)" in cycle_table(cycles)


def test_retries_are_counted_and_do_not_move_the_period() -> None:
    chunks = [Chunk(READ_3, 0.0), Chunk(READ_3, 0.1)]  # no answer: the second is a retry
    for k in range(1, 8):
        chunks += [Chunk(READ_3, k * 2.0), Chunk(answer(3, 3, 2), k * 2.0 + 0.02)]
    cycles = poll_cycles(frame_capture(chunks, LINE, timeout=0.05))
    (poll,) = cycles[3].polls
    assert poll.count == 9 and poll.retries >= 1
    assert poll.period == pytest.approx(2.0, abs=0.01)
