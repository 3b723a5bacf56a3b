"""The capture diff, on two synthetic captures of one bus built from byte literals: what
changed in values, periods and latencies, and first what changed in the answers (a unit
that went silent, a poll that began failing), with and without direction labels, stamped
at the read's end or at both ends of each frame."""

from __future__ import annotations

import pytest

from dissectors.checks import with_crc
from sniffer.analysis.diff import Change, Fared, diff_stores
from sniffer.framing.pipeline import frame_capture
from sniffer.framing.store import FrameStore
from sniffer.model import Chunk, Direction, LineSettings
from sniffer.vocab import BAD_CHECK, Kind

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


# -- answers: units that went silent or came back, polls that began failing or recovered -----


def chunk(data: bytes, t: float, sender: Direction, *, labelled: bool, exact: bool) -> Chunk:
    """`data` read at `t`: stamped at its last byte (a host read) or with both ends
    (`exact`, a logic analyser), labelled with its sender or not."""
    end = t + len(data) * LINE.char_time
    return Chunk(
        data,
        t_end=end,
        t_start=t if exact else None,
        direction=sender if labelled else Direction.UNKNOWN,
    )


def polled(
    fate_9: str,
    fate_3: list[str] | None = None,
    *,
    value: int = 50,
    labelled: bool = False,
    exact: bool = False,
) -> FrameStore:
    """24 rounds: unit 3 read (holding 0-1), then unit 9 read (holding 5), each answered
    ("ok"), answered with exception 02 ("exc"), or not at all ("none"); unit 9's
    requests may come with a wrong CRC from the fifth on ("damaged": none answered, as
    a slave must do)."""
    chunks: list[Chunk] = []
    how = {"labelled": labelled, "exact": exact}
    for k in range(24):
        t = 0.5 * k
        fate = fate_3[k] if fate_3 is not None else "ok"
        chunks.append(chunk(with_crc(bytes([3, 3, 0, 0, 0, 2])), t, Direction.MASTER, **how))
        if fate == "ok":
            answer = with_crc(bytes([3, 3, 4, 0, 100, 0, value]))
            chunks.append(chunk(answer, t + 0.02, Direction.SLAVE, **how))
        elif fate == "exc":
            chunks.append(chunk(with_crc(bytes([3, 0x83, 2])), t + 0.02, Direction.SLAVE, **how))
        request = with_crc(bytes([9, 3, 0, 5, 0, 1]))
        if fate_9 == "damaged" and k >= 4:  # the first four good (the unit is known)
            request = request[:-1] + bytes([request[-1] ^ 0xFF])
        chunks.append(chunk(request, t + 0.1, Direction.MASTER, **how))
        if fate_9 == "ok":
            answer = with_crc(bytes([9, 3, 2, 0, 1]))
            chunks.append(chunk(answer, t + 0.12, Direction.SLAVE, **how))
    # a last poll of unit 3: unit 9's last request is followed by another, so it is
    # known to have gone unanswered (a capture that ends on a request leaves it open)
    chunks.append(chunk(with_crc(bytes([3, 3, 0, 0, 0, 2])), 12.0, Direction.MASTER, **how))
    chunks.append(
        chunk(with_crc(bytes([3, 3, 4, 0, 100, 0, value])), 12.02, Direction.SLAVE, **how)
    )
    return frame_capture(chunks, LINE, exact_timing=exact)


@pytest.mark.parametrize("labelled", [False, True])
@pytest.mark.parametrize("exact", [False, True])
def test_a_unit_that_stopped_answering_is_said_first(labelled: bool, exact: bool) -> None:
    a = polled("ok", labelled=labelled, exact=exact)
    b = polled("none", value=80, labelled=labelled, exact=exact)
    result = diff_stores(a, b)
    assert not result.same
    assert result.silent == [Change(9, "", Fared(answered=24), Fared(timeouts=24))]
    assert result.back == [] and result.failing == [] and result.units_gone == []
    lines = result.text().splitlines()
    silent = (
        "unit 9: silent in B: none of 24 requests answered (24 timeouts); "
        "24 of 24 requests answered (100 %) in A"
    )
    assert lines[2] == silent  # before the value that moved
    assert any(line.startswith("unit 3: holding 1 left its range") for line in lines[3:])


def test_a_unit_that_answers_again() -> None:
    result = diff_stores(polled("none"), polled("ok"))
    assert result.back == [Change(9, "", Fared(timeouts=24), Fared(answered=24))]
    assert result.silent == []
    assert (
        "unit 9: answers again in B: 24 of 24 requests answered (100 %); "
        "none of 24 in A (24 timeouts)"
    ) in result.text()


FAILING = ["exc" if k % 2 else "ok" for k in range(24)]
FAILING[4] = FAILING[10] = FAILING[16] = "none"


def test_a_poll_that_began_failing_and_one_that_recovered() -> None:
    steady, failing = polled("ok"), polled("ok", FAILING)
    result = diff_stores(steady, failing)
    ((change,),) = [result.failing]
    assert (change.unit, change.what) == (3, "read holding 0-1")
    assert change.b == Fared(answered=10, exceptions=12, timeouts=3)  # and the last poll
    assert result.silent == [] and result.recovered == []
    assert (
        "unit 3: read holding 0-1 began failing in B: 15 of 25 failed "
        "(60 %: 3 timeouts, 12 exceptions); 0 of 25 in A (0 %)"
    ) in result.text()
    result = diff_stores(failing, steady)
    assert [(c.unit, c.what) for c in result.recovered] == [(3, "read holding 0-1")]
    assert (
        "unit 3: read holding 0-1 recovered in B: 0 of 25 failed (0 %); "
        "15 of 25 in A (60 %: 3 timeouts, 12 exceptions)"
    ) in result.text()


def test_an_odd_timeout_is_not_a_change() -> None:
    once = ["ok"] * 24
    once[7] = "none"
    result = diff_stores(polled("ok"), polled("ok", once))
    assert result.same, result.text()


@pytest.mark.parametrize("exact", [False, True])
def test_damaged_requests_are_not_counted_as_unanswered(exact: bool) -> None:
    """A slave must not answer a request with a wrong CRC: no answer to it says nothing
    about the slave. Only the four good requests count."""
    b = polled("damaged", exact=exact)
    damaged = [i for i in range(len(b)) if b.unit[i] == 9 and b.flags[i] & BAD_CHECK]
    assert len(damaged) == 20 and all(b.kind[i] == Kind.REQUEST for i in damaged)
    result = diff_stores(polled("ok", exact=exact), b)
    assert result.silent == [Change(9, "", Fared(answered=24), Fared(timeouts=4))]
    assert "unit 9: silent in B: none of 4 requests answered (4 timeouts)" in result.text()
