"""The capture diff, on two synthetic captures of one bus built from byte literals."""

from __future__ import annotations

from dissectors.checks import with_crc
from sniffer.analysis.diff import diff_stores
from sniffer.framing.pipeline import frame_capture
from sniffer.framing.store import FrameStore
from sniffer.model import Chunk, LineSettings

LINE = LineSettings(19200, 8, "E", 1)


def read(unit: int, address: int, words: list[int], t: float, latency: float) -> list[Chunk]:
    request = with_crc(bytes([unit, 3, 0, address, 0, len(words)]))
    body = b"".join(w.to_bytes(2, "big") for w in words)
    answer = with_crc(bytes([unit, 3, 2 * len(words)]) + body)
    return [Chunk(request, t), Chunk(answer, t + latency)]


def bus(*, period_2: float, latency_3: float, value: int, unit_9: bool, extra: bool) -> FrameStore:
    chunks: list[Chunk] = []
    t = 0.0
    while t < 10:
        chunks += read(3, 0, [100 + int(t) % 3, value], t, latency_3)
        if unit_9:
            chunks += read(9, 5, [1], t + 0.05, 0.01)
        if extra:
            chunks += read(3, 40, [7], t + 0.1, latency_3)
        t += 0.5
    t = 0.2
    while t < 10:
        chunks += read(2, 8, [0], t, 0.01)
        t += period_2
    chunks.sort(key=lambda c: c.t_end)
    return frame_capture(chunks, LINE)


def test_same_bus_twice_shows_no_difference() -> None:
    a = bus(period_2=1.0, latency_3=0.01, value=50, unit_9=True, extra=False)
    b = bus(period_2=1.0, latency_3=0.01, value=50, unit_9=True, extra=False)
    result = diff_stores(a, b)
    assert result.same
    assert "no difference" in result.text()


def test_every_kind_of_change_is_found() -> None:
    a = bus(period_2=1.0, latency_3=0.01, value=50, unit_9=True, extra=False)
    b = bus(period_2=2.0, latency_3=0.03, value=80, unit_9=False, extra=True)
    result = diff_stores(a, b, "a.pcapng", "b.pcapng")
    assert result.units_gone == [9] and result.units_new == []
    assert [p.what for p in result.requests_new] == ["read holding 40"]
    ((pa, pb),) = result.periods
    assert (pa.unit, round(pa.period, 2), round(pb.period, 2)) == (2, 1.0, 2.0)
    ((unit, la, lb),) = result.latencies
    assert unit == 3 and lb > la
    (moved,) = result.moved
    assert (moved.unit, moved.address, moved.a_low, moved.a_high) == (3, 1, 50, 50)
    assert moved.b_low == 80 and moved.outside == moved.readings
    text = result.text()
    assert "unit 9: gone in B" in text
    assert "unit 3: holding 1 left its range: 50..50 in A, 80..80 in B" in text
    # register 0 moves within 100..102 in both: not reported
    assert "holding 0 " not in text
