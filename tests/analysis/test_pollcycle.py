"""The poll cycle: periods, jitter and gaps of repeating requests, from byte literals."""

from __future__ import annotations

import random
from dataclasses import replace
from itertools import pairwise

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from dissectors.functions import FUNCTIONS, Limit, Registry
from sniffer.analysis import pollcycle
from sniffer.analysis.pollcycle import (
    Gap,
    Poll,
    UnitCycle,
    cycle_table,
    poll_cycles,
)
from sniffer.analysis.polls import (
    FRAMED_APART,
    RULES,
    Form,
    core_rules,
    dissected_identity,
    frame_body,
    plain_identity,
    rules,
)
from sniffer.analysis.stats import nearest_rank
from sniffer.framing.pipeline import frame_capture
from sniffer.framing.store import COLUMNS, FrameStore
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import DEMO_CAPTURE, replay_file
from sniffer.vocab import BAD_CHECK, Flag, Kind
from tests.support.random_rows import random_store

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
    cycles = poll_cycles(unresolved(frame_capture(chunks, LINE)))
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


# -- the column-wise poll cycle against its definition ---------------------------------


def unresolved(store: FrameStore) -> FrameStore:
    """`store` with its stamps taken as exact: the definition below is of the waits as
    the row times give them (how the stamps' resolution bounds them is tested apart)."""
    store.resolution = 0.0
    return store


def cycles_row_by_row(store: FrameStore) -> dict[int, UnitCycle]:
    """The poll cycle as defined: every request with a good check taken apart by the
    dissector, grouped by unit and identity, its times in row order."""
    sendings: dict[int, dict[tuple[object, ...], tuple[str, int, list[float], int]]] = {}
    for i in range(len(store)):
        if store.kind[i] != Kind.REQUEST or store.flags[i] & BAD_CHECK:
            continue
        identity, what = dissected_identity(store.view(i).body())
        found = sendings.setdefault(store.unit[i], {}).setdefault(
            identity, (what, store.fc[i], [], 0)
        )
        found[2].append(store.t[i])
        if store.flags[i] & Flag.RETRY:
            sendings[store.unit[i]][identity] = (*found[:3], found[3] + 1)
    out: dict[int, UnitCycle] = {}
    for unit, requests in sorted(sendings.items()):
        cycle = out[unit] = UnitCycle(unit)
        for what, fc, times, retries in requests.values():
            if len(times) < 3:
                cycle.once += 1
                continue
            waits = [b - a for a, b in pairwise(times)]
            period = nearest_rank(waits, 0.5)
            p95, p5 = nearest_rank(waits, 0.95), nearest_rank(waits, 0.05)
            assert period is not None and p95 is not None and p5 is not None
            gaps = tuple(Gap(a, b - a) for a, b in pairwise(times) if b - a > 2.0 * period)
            cycle.polls.append(
                Poll(
                    unit, fc, what, len(times), period, p95 - p5, gaps, times[0], times[-1], retries
                )
            )
        cycle.polls.sort(key=lambda p: (p.period, p.what))
    return out


@pytest.mark.parametrize("seed", range(16))
def test_random_requests_make_the_cycle_of_the_definition(seed: int) -> None:
    rng = random.Random(seed)
    store = random_store(
        rng, 1500, channels=1 + seed % 3, odd_framing=seed % 2 == 1, resolution=0.0
    )
    assert poll_cycles(store) == cycles_row_by_row(store)


@pytest.mark.parametrize("block", [1, 7, 64])
def test_rows_looked_at_in_blocks_make_the_same_cycle(
    block: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    rng = random.Random(block)
    store = random_store(rng, 1500, channels=1 + block % 3, odd_framing=True, resolution=0.0)
    monkeypatch.setattr(pollcycle, "BLOCK", block)
    assert poll_cycles(store) == cycles_row_by_row(store)
    demo = unresolved(replay_file(DEMO_CAPTURE).store)
    assert poll_cycles(demo) == cycles_row_by_row(demo)


def test_repeated_and_differing_requests_on_the_demo() -> None:
    store = unresolved(replay_file(DEMO_CAPTURE).store)
    cycles = poll_cycles(store)
    assert cycles == cycles_row_by_row(store)
    assert sum(p.count for c in cycles.values() for p in c.polls) > 500


def test_the_same_write_with_other_values_and_damaged_ones() -> None:
    """Writes of other values are one request; a damaged write is what the dissector
    reads in it (an odd coil value: no coil written)."""
    chunks: list[Chunk] = []
    bodies = [bytes([3, 6, 0, 20, 0, k]) for k in range(4)]
    bodies += [bytes([3, 5, 0, 7, 0xFF, 0]), bytes([3, 5, 0, 7, 0, 0]), bytes([3, 5, 0, 7, 1, 2])]
    bodies += [
        bytes.fromhex("03100014000204") + bytes(4),
        bytes.fromhex("03100014000203") + bytes(3),
    ]
    for k in range(5):
        for n, body in enumerate(bodies):
            t = k * 10.0 + n * 0.5
            chunks += [Chunk(with_crc(body), t)]
    store = unresolved(frame_capture(chunks, LINE))
    cycles = poll_cycles(store)
    assert cycles == cycles_row_by_row(store)
    whats = {p.what: p.count for p in cycles[3].polls}
    assert whats["write holding 20"] == 20
    assert whats["write coil 7"] == 10 and whats["FC 5"] == 5
    # the dissector still reads address and quantity when the byte count is off
    assert whats["write holding 20-21"] == 10


@given(
    st.sampled_from((1, 2, 3, 4, 5, 6, 15, 16)),
    st.binary(min_size=0, max_size=40),
    st.integers(0, 255),
)
@settings(max_examples=3000, deadline=None)
def test_requests_read_straight_from_their_bytes_as_the_dissector_reads_them(
    function: int, tail: bytes, unit: int
) -> None:
    body = bytes([unit, function]) + tail
    found = plain_identity(body)
    if found is not None:
        assert found == dissected_identity(body)


@pytest.mark.parametrize("function", [1, 2, 3, 4, 5, 6, 15, 16])
def test_well_formed_requests_are_read_straight_from_their_bytes(function: int) -> None:
    rng = random.Random(function)
    for _ in range(400):
        address = rng.choice((0, 1, 9999, 0xFFFF, rng.randrange(0x10000)))
        if function <= 4:
            tail = address.to_bytes(2, "big") + rng.randrange(0x10000).to_bytes(2, "big")
        elif function in (5, 6):
            value = rng.choice((b"\xff\x00", b"\x00\x00")) if function == 5 else rng.randbytes(2)
            tail = address.to_bytes(2, "big") + value
        else:
            most = 123 if function == 16 else 1968
            quantity = rng.choice((1, most, rng.randrange(1, most + 1)))
            need = 2 * quantity if function == 16 else (quantity + 7) // 8
            tail = address.to_bytes(2, "big") + quantity.to_bytes(2, "big") + bytes([need])
            tail += rng.randbytes(need)
        body = bytes([rng.randrange(256), function]) + tail
        assert plain_identity(body) is not None
        assert plain_identity(body) == dissected_identity(body)


@pytest.mark.parametrize("seed", range(8))
def test_requests_counted_in_parts_make_the_cycle_of_the_whole(seed: int) -> None:
    """`PollCycles` given the rows a part at a time, each in a store of its own (the
    segments of a windowed replay), gives what `poll_cycles` of the whole store gives;
    and so does the cycle of the parts before with the last one added on the side (a
    live summary, its window's rows still in memory)."""
    rng = random.Random(seed)
    store = random_store(
        rng, 1500, channels=1 + seed % 3, odd_framing=seed % 2 == 1, resolution=0.0
    )
    cuts = sorted(rng.sample(range(1, len(store)), rng.randrange(1, 40)))
    parts = [_part(store, a, b) for a, b in pairwise([0, *cuts, len(store)])]
    found = pollcycle.PollCycles()
    for part in parts[:-1]:
        found.add(part)
    assert found.cycles(parts[-1]) == poll_cycles(store) == cycles_row_by_row(store)
    found.add(parts[-1])
    assert found.cycles() == poll_cycles(store)


def _part(store: FrameStore, a: int, b: int) -> FrameStore:
    """Rows `a` to `b` of `store` in a store of their own (the same bytes)."""
    part = FrameStore(store.streams)
    part.stamps, part.resolution = store.stamps, store.resolution
    for name in COLUMNS:
        getattr(part, name).extend(getattr(store, name)[a:b])
    return part


@pytest.mark.parametrize("seed", range(4))
def test_a_rows_body_is_the_one_the_store_gives_whatever_its_envelope(seed: int) -> None:
    """`frame_body` of a row's bytes and flags is `FrameView.body` (RTU, ASCII, Modbus
    TCP frames, damaged ones among them)."""
    store = random_store(random.Random(seed), 1500, channels=2, odd_framing=True)
    framed = {0: 0, int(Flag.ASCII): 0, int(Flag.MBAP): 0}
    for i in range(len(store)):
        if store.kind[i] in (Kind.NOISE, Kind.EVENT):
            continue
        assert frame_body(store.raw(i), store.flags[i]) == store.view(i).body()
        framed[store.flags[i] & FRAMED_APART] += 1
    assert min(framed.values()) > 10


def test_the_rule_is_the_registrys() -> None:
    """The rules follow the specs they are made from: a registry whose FC 16 takes at
    most 60 registers, or that knows no FC 5, makes rules that say so."""
    assert {code: r.form for code, r in RULES.items()} == {
        1: Form.READ,
        2: Form.READ,
        3: Form.READ,
        4: Form.READ,
        5: Form.SINGLE,
        6: Form.SINGLE,
        15: Form.MULTIPLE,
        16: Form.MULTIPLE,
    }
    assert (RULES[15].high, RULES[16].high, RULES[5].values) == (1968, 123, frozenset({0xFF00, 0}))
    narrow = replace(FUNCTIONS[16], limits=(Limit("quantity", 1, 60),))
    fewer = Registry(spec for code, spec in FUNCTIONS.items() if code != 5).with_specs([narrow])
    found = rules(fewer)
    assert 5 not in found and (found[16].low, found[16].high) == (1, 60)
    assert (16, True, 1, 60, False, None) in core_rules(found)
