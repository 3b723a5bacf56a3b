"""The capture diff, on two synthetic captures of one bus built from byte literals: what
changed in values, periods and latencies, and first what changed in the answers (a unit
that went silent, a poll that began failing), with and without direction labels, stamped
at the read's end or at both ends of each frame."""

from __future__ import annotations

import random
from collections.abc import Mapping, Sequence
from math import ceil
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.analysis.diff import Change, Fared, _apart, diff_stores, readings
from sniffer.analysis.draft import observe
from sniffer.framing.pairing import duration
from sniffer.framing.pipeline import Pipeline, frame_capture
from sniffer.framing.store import FrameStore
from sniffer.model import Chunk, Direction, LineSettings, Stamp
from sniffer.sources.synth import polling_frames
from sniffer.vocab import BAD_CHECK, Kind
from tests.support.random_rows import random_store

LINE = LineSettings(19200, 8, "E", 1)


def read(unit: int, address: int, words: list[int], t: float, latency: float) -> list[Chunk]:
    """A read sent at `t` and answered `latency` after its last byte, stamped exactly (a
    logic analyser's both ends)."""
    request = with_crc(bytes([unit, 3, 0, address, 0, len(words)]))
    body = b"".join(w.to_bytes(2, "big") for w in words)
    answer = with_crc(bytes([unit, 3, 2 * len(words)]) + body)
    end = t + len(request) * LINE.char_time
    return [
        Chunk(request, t_end=end, t_start=t),
        Chunk(answer, t_end=end + latency + len(answer) * LINE.char_time, t_start=end + latency),
    ]


def host_reads(chunks: list[Chunk], every: float) -> list[Chunk]:
    """The same bytes as a program reading the port every `every` seconds gets them: each
    read stamped when it returned, holding what came since the last one."""
    reads: dict[int, bytearray] = {}
    for c in sorted(chunks, key=lambda c: c.t_end):
        reads.setdefault(ceil(c.t_end / every), bytearray()).extend(c.data)
    return [Chunk(bytes(data), k * every) for k, data in sorted(reads.items())]


def bus(
    *,
    period_2: float,
    latency_3: float,
    value: int,
    unit_9: bool,
    extra: bool,
    reads: float = 0.0,
) -> FrameStore:
    """10 s of a bus: units 3 and 9 polled every 0.5 s, unit 2 every `period_2`; stamped
    exactly, or as host reads every `reads` seconds."""
    chunks: list[Chunk] = []
    t = 0.0
    while t < 10:
        chunks += read(3, 0, [100 + int(t) % 3, value], t, latency_3)
        if unit_9:
            chunks += read(9, 5, [1], t + 0.25, 0.01)
        if extra:
            chunks += read(3, 40, [7], t + 0.1, latency_3)
        t += 0.5
    t = 0.2
    while t < 10:
        chunks += read(2, 8, [0], t, 0.01)
        t += period_2
    chunks.sort(key=lambda c: c.t_end)
    if reads:
        return frame_capture(host_reads(chunks, reads), LINE)
    pipeline = Pipeline(LINE, exact_timing=True, stamps=Stamp.EXACT)  # a logic analyser's
    pipeline.feed_all(chunks)
    pipeline.finish()
    return pipeline.store


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
    assert unit == 3 and (la.raw, lb.raw) == pytest.approx((0.01, 0.03), abs=2e-3)
    (moved,) = result.moved
    assert (moved.unit, moved.address, moved.a_low, moved.a_high) == (3, 1, 50, 50)
    assert moved.b_low == 80 and moved.outside == moved.readings
    text = result.text()
    assert "unit 9: gone in B" in text
    assert "unit 3: holding 1 left its range: 50..50 in A, 80..80 in B" in text
    # register 0 moves within 100..102 in both: not reported
    assert "holding 0 " not in text


def test_answer_times_are_compared_only_as_far_as_the_stamps_tell() -> None:
    """A day read every 16 ms (the reads' resolution measured from their rhythm: some
    30 ms on this sparse bus) bounds a 2 ms answer time only: under twice the resolution,
    plus the resolution each stamp may be off by (`<96ms`): against 30 ms on an exact
    day that is no change (30 ms is allowed), against 170 ms it is; 2 ms against 30 ms
    both exact is."""
    same = {"period_2": 1.0, "value": 50, "unit_9": True, "extra": False}
    coarse = bus(latency_3=0.002, reads=0.016, **same)  # type: ignore[arg-type]
    exact_2, exact_30, exact_170 = (
        bus(latency_3=x, **same)  # type: ignore[arg-type]
        for x in (0.002, 0.03, 0.17)
    )
    resolution = coarse.resolution
    assert 0.016 <= resolution < 0.05
    bound = f"<{ceil(3 * resolution * 1000 - 1e-6)}ms"

    result = diff_stores(coarse, exact_30)
    assert result.latencies == [] and result.same
    why = (
        "A: median answer times of 3 units (2, 3, 9) only bounded by its stamps (end of "
        f"each host read, resolution {duration(resolution)}): compared where they still tell"
    )
    assert result.untimed == [why]
    assert result.text().splitlines()[-1] == why
    far = diff_stores(coarse, exact_170)
    ((unit, la, lb),) = far.latencies
    assert (unit, la.text(), lb.text()) == (3, bound, "170ms")
    assert f"unit 3: median answer time {bound} in A, 170ms in B" in far.text()
    ((unit, la, lb),) = diff_stores(exact_2, exact_30).latencies
    assert (unit, la.text(), lb.text()) == (3, "2ms", "30ms")
    assert diff_stores(exact_2, exact_30).untimed == []


def test_answer_times_a_log_cannot_measure_are_unknown() -> None:
    """A log's print times measure no answer time (`--stats` shows none): the diff
    compares none and says why, rather than calling 10 ms against 30 ms a change."""
    same = {"period_2": 1.0, "value": 50, "unit_9": True, "extra": False}
    logged = bus(latency_3=0.01, **same)  # type: ignore[arg-type]
    logged.stamps = Stamp.PRINT
    result = diff_stores(logged, bus(latency_3=0.03, **same))  # type: ignore[arg-type]
    assert result.latencies == [] and result.same
    assert result.untimed == [
        "A: answer times of 3 units (2, 3, 9) unknown: its stamps (when each line was "
        "logged) cannot measure them"
    ]
    assert result.text().splitlines()[2:] == [
        "no difference in units, answers, polls, register ranges, or the answer times "
        "both captures' stamps measure",
        *result.untimed,
    ]


@pytest.mark.parametrize(
    ("a", "b", "apart"),
    [
        ((10.0, 10.0), (13.0, 13.0), True),  # a value each, 30 % apart
        ((10.0, 10.0), (11.0, 11.0), False),
        ((0.0, 10.0), (11.0, 11.0), False),  # at most 10 against 11: within 20 %
        ((0.0, 10.0), (13.0, 13.0), True),  # at most 10 against 13: no time fits both
        ((10.0, 10.0), (0.0, 5.0), True),  # 10 against at most 5
        ((10.0, 10.0), (0.0, 9.0), False),
        ((0.0, 10.0), (0.0, 1000.0), False),  # two bounds: the same small times fit both
        ((24.0, 56.0), (46.0, 78.0), False),  # 40 and 62, each give or take 16: both 50?
        ((24.0, 56.0), (70.0, 102.0), True),  # 40 and 86, each give or take 16
    ],
)
def test_times_are_apart_only_where_no_time_fits_both(
    a: tuple[float, float], b: tuple[float, float], apart: bool
) -> None:
    assert _apart(a, b, lambda x: 0.2 * x) is apart


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


# -- the values read: one pass for every unit, as `observe` finds them unit by unit ------


def _observed(store: FrameStore) -> dict[tuple[int, str, int], list[int]]:
    """What `observe` keeps as reads, unit by unit: the reference `readings` is held to."""
    found: dict[tuple[int, str, int], list[int]] = {}
    for unit in sorted({store.unit[i] for i in range(len(store))}):
        for (table, address), place in observe(store, unit).places.items():
            if place.reads:
                found[(unit, table, address)] = [v for _t, v in place.reads]
    return found


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32), rows=st.integers(0, 400))
def test_the_values_read_are_those_observe_finds(seed: int, rows: int) -> None:
    """Random rows (answers of any length, exceptions, damaged frames, ASCII and Modbus
    TCP among RTU), and a polling bus of reads of registers and bits."""
    store = random_store(random.Random(seed), rows, odd_framing=True)
    assert _sorted(readings(store)) == _sorted(_observed(store))
    frames = polling_frames(rows, seed=seed, line=LINE)
    chunks = [Chunk(f.raw, f.t + len(f.raw) * LINE.char_time) for f in frames]
    polled = frame_capture(chunks, LINE)
    assert _sorted(readings(polled)) == _sorted(_observed(polled))


def _sorted(found: Mapping[tuple[int, str, int], Sequence[int]]) -> dict[Any, list[int]]:
    """Each place's values as a sorted list (`readings` keeps no order)."""
    return {where: sorted(values) for where, values in found.items()}
