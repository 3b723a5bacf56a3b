"""The compiled poll cycle and tallies (sniffer/_core.c: poll_table, poll_block,
waits_count, tally_latencies, tally_gaps) give what their Python references give, bit for bit.

`PollCycles.add` is fed random stores in parts (one store growing, or a new store for
each segment as a windowed replay feeds it; blocks of a few rows): RTU reads and
writes (the same write with other values, damaged bodies, FC 8), ASCII and Modbus TCP
rows (their keys are tuples), retries, bad checks, answers, noise and events, one
stream or two, rows cut short by the end of their stream, NaN and far-apart times.
`Tallies` counts random latencies and request times, with values on the rounding ties
and next to them, NaN, infinities, huge and tiny values. Everything each keeps is
compared, floats by repr (so 0.0 and -0.0 differ). Without the extension these tests
skip, unless MODSCOPE_REQUIRE_COMPILED=1 (check.sh sets it): then they fail. The
poll cycle's table (`cycles()`: its quantiles picked by selection in C) is compared too.
"""

from __future__ import annotations

import math
import random
from array import array
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dissectors.checks import lrc, with_crc
from sniffer.analysis import pollcycle, stats
from sniffer.analysis.pollcycle import PollCycles, _Sent, cycle_table
from sniffer.analysis.polls import FRAMED_APART, RULES, Form, core_rules, plain_identity
from sniffer.analysis.stats import Tallies
from sniffer.framing.store import FrameStore
from sniffer.vocab import BAD_CHECK, Flag, Kind
from tests.support.core import _compiled, running


@contextmanager
def patched(module: ModuleType, name: str, value: int) -> Iterator[None]:
    """Run the block with `module.name` set to `value` (a block size, a window)."""
    saved = getattr(module, name)
    setattr(module, name, value)
    try:
        yield
    finally:
        setattr(module, name, saved)


# -- the poll cycle --------------------------------------------------------------------------

Row = tuple[int, bytes, int, int, float, int]  # channel, raw, kind, flags, t, extra length


def _request_body(rng: random.Random) -> bytes:
    unit = rng.choice((1, 1, 2, 7, 0, 247))
    what = rng.random()
    if what < 0.5:  # a read of a few places
        fc = rng.choice((1, 2, 3, 4))
        return bytes([unit, fc, 0, rng.choice((0, 1, 100)), 0, rng.choice((1, 2, 10))])
    if what < 0.65:  # a single write, its value changing
        fc = rng.choice((5, 6))
        value = rng.choice((b"\xff\x00", b"\x00\x00", b"\x12\x34", bytes([rng.getrandbits(8)] * 2)))
        return bytes([unit, fc, 0, rng.choice((4, 5))]) + value
    if what < 0.8:  # a multiple write, its values changing; a quantity out of range
        fc = rng.choice((15, 16))
        most = 123 if fc == 16 else 1968
        count = rng.choice((1, 2, 3, 17, 0, most, most + 1))
        need = 2 * count if fc == 16 else (count + 7) // 8
        data = bytes(rng.getrandbits(8) for _ in range(need % 256))
        size = len(data) if rng.random() < 0.9 else len(data) + 1
        return bytes([unit, fc, 0, 9, count >> 8, count & 0xFF, size % 256]) + data
    if what < 0.9:
        return bytes([unit, 8, 0, 0, rng.getrandbits(8), rng.getrandbits(8)])
    return bytes([unit, rng.choice((3, 16, 0x41))]) + bytes(rng.randrange(0, 5))  # damaged


def _write_body(rng: random.Random) -> bytes:
    """A write of a code the same-poll rule reads (sniffer.analysis.polls.RULES), at and
    next to the edges of what the rule takes: quantities one below, at and one above the
    registry's limits, byte counts that fit or are one off (or wrapped past 255), the
    values a single write may carry and their neighbours. Few units and addresses, so
    that the same write comes again with other values."""
    rule = rng.choice([r for r in RULES.values() if r.form != Form.READ])
    head = bytes([rng.choice((1, 2, 0)), rule.code, 0, rng.choice((4, 5))])
    if rule.form == Form.SINGLE:
        allowed = sorted(rule.values or ())
        near = [v + d for v in allowed for d in (-1, 0, 0, 1) if 0 <= v + d <= 0xFFFF]
        value = rng.choice((*near, 0xFFFF, rng.getrandbits(16)) if near else (rng.getrandbits(16),))
        return head + value.to_bytes(2, "big")
    low, high = rule.low, rule.high
    count = rng.choice(
        (low - 1, low, low + 1, high - 1, high, high + 1, 0xFFFF, rng.randrange(low, high + 1))
    )
    count = max(0, min(count, 0xFFFF))
    need = rule.value_bytes(count)
    size = rng.choice((need, need, need, need + 1, need - 1, 0)) % 256
    data = bytes(rng.getrandbits(8) for _ in range(size))
    if rng.random() < 0.1:  # the bytes that follow are not what the byte count says
        data = data[:-1] if data and rng.random() < 0.5 else data + b"\x00"
    return head + count.to_bytes(2, "big") + bytes([size]) + data


def _raw(rng: random.Random, body: bytes) -> tuple[bytes, int]:
    """The bytes of a request row and its framing flags."""
    how = rng.random()
    if how < 0.1:
        return b":" + (body + bytes([lrc(body)])).hex().upper().encode() + b"\r\n", int(Flag.ASCII)
    if how < 0.2:  # Modbus TCP: the transaction id makes keys of one request differ
        head = rng.getrandbits(16).to_bytes(2, "big") + b"\x00\x00"
        return head + (len(body)).to_bytes(2, "big") + body, int(Flag.MBAP)
    return with_crc(body), 0


def _poll_rows(
    rng: random.Random, n: int, channels: int, nan: bool, writes: bool = False
) -> list[Row]:
    rows: list[Row] = []
    t = 1_700_000_000.0
    body_of = _write_body if writes else _request_body
    bodies = [body_of(rng) for _ in range(rng.randrange(1, 12))]
    for _ in range(n):
        t += rng.choice((0.0, 0.001, 0.02, 0.1, 0.1, 0.1, 0.25, 1.0))
        if rng.random() < 0.02:
            t += rng.choice((1e6, -5.0))  # far apart, or the clock set back
        when = math.nan if nan and rng.random() < 0.05 else t
        channel = rng.randrange(channels)
        what = rng.random()
        if what < 0.1:
            raw = bytes(rng.getrandbits(8) for _ in range(rng.randrange(1, 5)))
            rows.append((channel, raw, int(Kind.NOISE), 0, when, 0))
            continue
        if what < 0.13:
            rows.append((channel, b"", int(Kind.EVENT), int(Flag.LINE_EVENT), when, 0))
            continue
        body = rng.choice(bodies) if rng.random() < 0.8 - 0.5 * writes else body_of(rng)
        raw, flags = _raw(rng, body)
        kind = Kind.REQUEST if what < 0.85 else rng.choice((Kind.RESPONSE, Kind.UNKNOWN))
        if rng.random() < 0.15:
            flags |= int(Flag.RETRY)
        if rng.random() < 0.05:
            flags |= rng.choice((int(Flag.CHECK_BAD), int(Flag.NON_HEX), int(Flag.ENVELOPE_BAD)))
        if rng.random() < 0.05:
            flags |= int(Flag.LATE)
        extra = 3 if rng.random() < 0.03 else 0  # reaches past its stream's end (for now)
        rows.append((channel, raw, int(kind), flags, when, extra))
    return rows


def _grow(store: FrameStore, rows: list[Row]) -> None:
    for channel, raw, kind, flags, t, extra in rows:
        stream = store.stream(channel)
        offset = len(stream)
        stream += raw
        store.add_row(channel, offset, len(raw) + extra, t, t, kind, flags)
    store.sync()


def _sendings(s: _Sent) -> tuple[object, ...]:
    """What a request's sendings keep (`pollcycle._Sent`): its times while it keeps them,
    else its waits counted."""
    times = None if s.times is None else s.times.tolist()
    w = s.waits
    waits = w and (w.quantum, w.dense.tolist(), sorted(w.far.items()), w.exact, w.unknown)
    kept = w and (w.starts.tolist(), w.lengths.tolist(), w.cut)
    return (s.count, s.first, s.last, times, waits, kept)


def _poll_state(found: PollCycles) -> str:
    kept = [
        (unit, [(key, s.what, s.fc, _sendings(s), s.retries) for key, s in r.items()])
        for unit, r in found.sendings.items()
    ]
    cycles = found.cycles()
    return repr(kept) + repr(cycles) + cycle_table(cycles)


def _poll_run(
    fast: ModuleType | None, rows: list[Row], steps: list[int], segments: list[bool]
) -> list[str]:
    seen: list[str] = []
    with running(fast):
        found = PollCycles()
        store = FrameStore()
        at = 0
        for k, step in enumerate(steps):
            if segments[k % len(segments)] and len(store):  # a windowed replay's next segment
                store = FrameStore()
            start = len(store)
            _grow(store, rows[at : at + step])
            at += step
            found.add(store, start)
            seen.append(_poll_state(found))
            more = FrameStore()  # a live window's rows, counted but not added
            _grow(more, rows[at : at + step])
            seen.append(repr(found.cycles(more)))
            seen.append(_poll_state(found))  # as it was
            if at >= len(rows):
                break
    return seen


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 10**6),
    n=st.integers(0, 150),
    channels=st.sampled_from((1, 1, 2)),
    nan=st.booleans(),
    steps=st.lists(st.integers(1, 40), min_size=1, max_size=12),
    segments=st.lists(st.booleans(), min_size=1, max_size=5),
    block=st.sampled_from((1, 3, 16, 1 << 16)),
)
def test_the_poll_cycle_is_the_same_with_either_core(
    seed: int,
    n: int,
    channels: int,
    nan: bool,
    steps: list[int],
    segments: list[bool],
    block: int,
) -> None:
    fast = _compiled()
    rows = _poll_rows(random.Random(seed), n, channels, nan)
    with patched(pollcycle, "BLOCK", block):
        assert _poll_run(fast, rows, steps, segments) == _poll_run(None, rows, steps, segments)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 10**6),
    n=st.integers(0, 200),
    steps=st.lists(st.integers(1, 60), min_size=1, max_size=8),
    block=st.sampled_from((1, 5, 1 << 16)),
)
def test_writes_at_the_edges_of_the_rule_are_grouped_as_python_groups_them(
    seed: int, n: int, steps: list[int], block: int
) -> None:
    """Mostly writes of FC 5, 6, 15 and 16 at the edges of the rule (`_write_body`), their
    values changing: the compiled groups are the Python walk's."""
    fast = _compiled()
    rows = _poll_rows(random.Random(seed), n, 1, False, writes=True)
    with patched(pollcycle, "BLOCK", block):
        assert _poll_run(fast, rows, steps, [False]) == _poll_run(None, rows, steps, [False])


def test_the_poll_cycle_of_many_rows_is_the_same_with_either_core() -> None:
    fast = _compiled()
    rows = _poll_rows(random.Random(5), 20_000, 1, False)
    states = [_poll_run(module, rows, [7000, 1, 13000], [False]) for module in (fast, None)]
    assert states[0] == states[1]
    assert "retries" in states[0][-1] and "write holding" in states[0][-1]


def _waits_state(waits: pollcycle._Waits) -> str:
    """Everything a `_Waits` keeps, floats by repr."""
    return repr(
        (
            waits.span,
            waits.quantum,
            list(waits.dense),
            sorted(waits.far.items()),
            waits.exact,
            waits.unknown,
            sorted(map(repr, waits.top)),
            list(map(repr, waits.starts)),
            list(map(repr, waits.lengths)),
            waits.cut,
        )
    )


_WAIT = st.one_of(
    st.integers(0, 40).map(lambda k: k * 2.0**-8),  # whole numbers of a quantum
    st.floats(0, 2.0, allow_nan=False),
    st.floats(-3.0, 0.0, allow_nan=False),  # a clock set back
    st.sampled_from((math.nan, math.inf, -math.inf, 1e10, -7e9, 2.0**-31)),
)


@settings(max_examples=200, deadline=None)
@given(
    start=st.sampled_from((0.0, 1768464000.0)),
    parts=st.lists(st.lists(_WAIT, min_size=1, max_size=60), min_size=1, max_size=8),
    span=st.sampled_from((0, 0, 4, 64)),
    shift=st.integers(-30, 4),
)
def test_the_waits_are_counted_the_same_with_either_core(
    start: float, parts: list[list[float]], span: int, shift: int
) -> None:
    """`_Waits.count` on sendings at random waits (exact multiples of a quantum, not,
    negative, NaN, infinite, past 63 bits of buckets), in parts, sparse or already in
    buckets: the compiled counting (`waits_count`) keeps what the Python one keeps."""
    fast = _compiled()
    seen = []
    for module in (fast, None):
        with running(module):
            waits = pollcycle._Waits(span=max(span, 4))
            waits.quantum = 2.0**shift
            if span:
                waits.dense = array("I", bytes(4 * span))
            t, states = start, []
            for part in parts:
                seq = array("d", [t])
                for w in part:
                    t = t + w if math.isfinite(t + w) else start
                    seq.append(t if w == w else math.nan)
                waits.count(seq)
                states.append(_waits_state(waits))
            seen.append(states)
    assert seen[0] == seen[1]


def _poll(fast: ModuleType, table: object, store: FrameStore, hi: int, resolve: Any) -> Any:
    """`poll_block` over rows 0..hi with the flags `PollCycles.add` gives it."""
    return fast.poll_block(
        table,
        store,
        0,
        hi,
        resolve,
        int(Kind.REQUEST),
        BAD_CHECK,
        int(Flag.RETRY),
        FRAMED_APART,
    )


def test_poll_block_keys_rows_as_the_python_keys_do() -> None:
    """The keys handed to `resolve`: the row's bytes, or the tuple of its framing and
    bytes for ASCII and Modbus TCP rows; each distinct key once, at its first row."""
    fast = _compiled()
    store = FrameStore()
    body = bytes([1, 3, 0, 0, 0, 2])
    ascii_raw, ascii_flags = _raw(_Always(0.05), body)
    mbap_raw, mbap_flags = _raw(_Always(0.15), body)
    rtu = with_crc(body)
    _grow(
        store,
        [
            (0, rtu, int(Kind.REQUEST), 0, 1.0, 0),
            (0, ascii_raw, int(Kind.REQUEST), ascii_flags, 2.0, 0),
            (0, rtu, int(Kind.REQUEST), int(Flag.RETRY), 3.0, 0),
            (0, mbap_raw, int(Kind.REQUEST), mbap_flags | int(Flag.RETRY), 4.0, 0),
            (0, rtu, int(Kind.REQUEST), int(Flag.CHECK_BAD), 5.0, 0),
            (0, rtu, int(Kind.RESPONSE), 0, 6.0, 0),
        ],
    )
    met: list[tuple[object, int]] = []

    def resolve(key: object, i: int) -> int:
        met.append((key, i))
        return 0 if isinstance(key, bytes) else 1

    table = fast.poll_table(core_rules())
    got = _poll(fast, table, store, len(store), resolve)
    assert met == [(rtu, 0), ((int(Flag.ASCII), ascii_raw), 1), ((int(Flag.MBAP), mbap_raw), 3)]
    assert [(g, array("d", times).tolist(), r) for g, times, r in got] == [
        (0, [1.0, 3.0], 1),
        (1, [2.0, 4.0], 1),
    ]
    # a key met before (in the same table) is not handed over again
    met.clear()
    again = _poll(fast, table, store, 3, resolve)
    assert met == [] and [g for g, _, _ in again] == [0, 1]


class _Always(random.Random):
    """A Random whose random() always says `x` (to pick one framing in `_raw`)."""

    def __init__(self, x: float) -> None:
        super().__init__(0)
        self.x = x

    def random(self) -> float:
        return self.x


def test_an_error_in_resolve_comes_back_from_poll_block() -> None:
    fast = _compiled()
    store = FrameStore()
    _grow(store, [(0, with_crc(bytes([1, 3, 0, 0, 0, 1])), int(Kind.REQUEST), 0, 1.0, 0)])

    def resolve(key: object, i: int) -> int:
        raise KeyError("no")

    args = (int(Kind.REQUEST), BAD_CHECK, int(Flag.RETRY), FRAMED_APART)
    with pytest.raises(KeyError):
        fast.poll_block(fast.poll_table(core_rules()), store, 0, 1, resolve, *args)
    with pytest.raises(ValueError):
        fast.poll_block(fast.poll_table(core_rules()), store, 0, 1, lambda key, i: -1, *args)


# -- the tallies -----------------------------------------------------------------------------

# latencies whose milliseconds lie on a tie of the tenths, or next to one (0.25 ms is a
# tie in binary: round(0.25, 1) == 0.2; 0.35 is not one, 0.35 lies just under it)
_near_ties = st.integers(-20_000, 20_000).flatmap(
    lambda m: st.sampled_from(
        (
            (2 * m + 1) / 4000,
            math.nextafter((2 * m + 1) / 4000, math.inf),
            math.nextafter((2 * m + 1) / 4000, -math.inf),
            m / 20_000,
            m / 2000,  # request times half a millisecond apart: ties of round()
        )
    )
)
_values = st.one_of(
    _near_ties,
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-1e3, 1e3),
    st.floats(-1e-3, 1e-3),
    st.sampled_from(
        (0.0, -0.0, 5e-324, -5e-324, 2.0**49 / 1000, 2.0**46, -(2.0**52), 1e300, 1.7e308, math.nan)
    ),
)


def _tallies_state(t: Tallies) -> str:
    return repr(
        (
            list(t.latency_ms.items()),
            list(t.gap_ms.items()),
            t.latencies,
            t.requests,
            t.last_request,
            list(t.recent_latencies),
            list(t.recent_requests),
        )
    )


def _tallies_run(fast: ModuleType | None, parts: list[list[float]], times: bool) -> list[str]:
    seen = []
    with running(fast):
        tallies = Tallies()
        for part in parts:
            try:
                if times:
                    tallies.add_requests(array("d", part))
                else:
                    tallies.add_latencies(array("d", part))
            except (ValueError, OverflowError) as exc:  # round() of NaN and infinities
                seen.append(repr(exc))
            seen.append(_tallies_state(tallies))
    return seen


@settings(max_examples=300, deadline=None)
@given(
    parts=st.lists(st.lists(_values, max_size=40), max_size=6),
    recent=st.sampled_from((1, 3, 1024)),
    times=st.booleans(),
)
def test_the_tallies_are_the_same_with_either_core(
    parts: list[list[float]], recent: int, times: bool
) -> None:
    fast = _compiled()
    with patched(stats, "RECENT", recent):
        assert _tallies_run(fast, parts, times) == _tallies_run(None, parts, times)


@settings(max_examples=200, deadline=None)
@given(start=st.integers(-(10**6), 10**6), steps=st.lists(st.integers(0, 400), max_size=60))
def test_request_times_on_half_milliseconds_are_tallied_as_round_does(
    start: int, steps: list[int]
) -> None:
    """Times half a millisecond apart put many gaps on the ties of round()."""
    fast = _compiled()
    at, values = start, []
    for step in steps:
        at += step
        values.append(1_700_000_000.0 + at / 2000)
    assert _tallies_run(fast, [values], True) == _tallies_run(None, [values], True)


def test_the_compiled_tallies_round_ties_to_even_and_keep_the_first_zero() -> None:
    fast = _compiled()
    counted: Counter[float] = Counter()
    # 0.00025 s * 1000 is 0.25 exactly in binary: half to even, 0.2; 0.00075: 0.8; under
    # 0.1 ms to the microsecond (-0.00001 s: -0.01 ms), and -1e-9 s to a negative zero
    values = [0.00025, 0.00075, math.nan, -0.00001, -1e-9, 0.00003]
    assert fast.tally_latencies(counted, array("d", values)) == 5
    assert list(counted.items()) == [(0.2, 1), (0.8, 1), (-0.01, 1), (-0.0, 1), (0.03, 1)]
    assert math.copysign(1.0, next(k for k in counted if k == 0)) == -1.0
    fast.tally_latencies(counted, array("d", [0.0]))
    assert repr(list(counted)) == "[0.2, 0.8, -0.01, -0.0, 0.03]" and counted[0.0] == 2
    with running(None):  # the Python reference counts the same figures, signs and all
        python = Tallies()
        python.add_latencies(array("d", [*values, 0.0]))
    assert repr(list(python.latency_ms.items())) == repr(list(counted.items()))
    gaps: Counter[int] = Counter()
    # from 0: 0.5, 1.5, 2.5 ms exactly, ties to the even one: 0, 2, 2
    assert fast.tally_gaps(gaps, array("d", [0.0005, 0.0, 0.0015, 0.0, 0.0025]), 0, 0.0) == 0.0025
    # gaps of 0.5, -0.5, 1.5, -1.5 and 2.5 ms exactly: ties, each to the even integer
    assert list(gaps.items()) == [(0, 2), (2, 2), (-2, 1)]
    with pytest.raises(ValueError, match="NaN"):
        fast.tally_gaps(gaps, array("d", [math.nan]), 0, 1.0)


def test_poll_block_hands_over_a_write_once_whatever_values_it_writes() -> None:
    """A well-formed write (FC 5 of FF00 or 0000, FC 6, FC 15/16 with a quantity in range
    and a byte count that fits) is one key whatever it writes: `resolve` sees its first
    row only. A write `plain_identity` does not read (FC 5 of another value) keeps its
    own bytes as its key."""
    fast = _compiled()
    store = FrameStore()
    bodies = [
        bytes([1, 6, 0, 4, 0, 1]),
        bytes([1, 6, 0, 4, 0, 2]),  # the same register, another value
        bytes([1, 5, 0, 4, 0xFF, 0]),
        bytes([1, 5, 0, 4, 0, 0]),
        bytes([1, 5, 0, 4, 0x12, 0x34]),  # not a coil value: its own key
        bytes([1, 16, 0, 9, 0, 1, 2, 0, 1]),
        bytes([1, 16, 0, 9, 0, 1, 2, 0, 2]),
        bytes([1, 15, 0, 9, 0, 3, 1, 5]),
        bytes([1, 15, 0, 9, 0, 3, 1, 2]),
        bytes([2, 6, 0, 4, 0, 1]),  # another unit
        bytes([1, 6, 0, 4, 0, 1]),
    ]
    _grow(
        store,
        [(0, with_crc(b), int(Kind.REQUEST), 0, float(k), 0) for k, b in enumerate(bodies)],
    )
    met: list[int] = []

    def resolve(key: object, i: int) -> int:
        assert key == with_crc(bodies[i])
        met.append(i)
        return len(met) - 1

    got = _poll(fast, fast.poll_table(core_rules()), store, len(store), resolve)
    assert met == [0, 2, 4, 5, 7, 9]
    assert [(g, array("d", times).tolist()) for g, times, _ in got] == [
        (0, [0.0, 1.0, 10.0]),
        (1, [2.0, 3.0]),
        (2, [4.0]),
        (3, [5.0, 6.0]),
        (4, [7.0, 8.0]),
        (5, [9.0]),
    ]


_WRITES = [
    bytes([1, 6, 0, 4, 0, 1]),
    bytes([1, 6, 0, 4, 0, 2]),
    bytes([1, 5, 0, 4, 0xFF, 0]),
    bytes([1, 5, 0, 4, 0, 0]),
    bytes([1, 16, 0, 9, 0, 1, 2, 0, 1]),
    bytes([1, 16, 0, 9, 0, 1, 2, 0, 2]),
]


def _met(rules: object) -> list[int]:
    """The rows of `_WRITES` whose keys `poll_block` hands over under `rules`."""
    fast = _compiled()
    store = FrameStore()
    _grow(store, [(0, with_crc(b), int(Kind.REQUEST), 0, 0.0, 0) for b in _WRITES])
    met: list[int] = []

    def resolve(key: object, i: int) -> int:
        met.append(i)
        return len(met) - 1

    _poll(fast, fast.poll_table(rules), store, len(store), resolve)
    return met


def test_the_compiled_core_keys_writes_by_the_rules_it_is_given() -> None:
    """The rule comes from Python: no rules, and every write keeps its own bytes; a rule
    of FC 6 that allows only the value 1, and FC 6 of 2 keeps its own; no rule of FC 16
    (a read is already its identity), and FC 16 writes keep theirs."""
    assert _met(core_rules()) == [0, 2, 4]
    assert _met(()) == [0, 1, 2, 3, 4, 5]
    six = [(6, False, 0, 0xFFFF, False, (1,))]
    assert _met(six) == [0, 1, 2, 3, 4, 5]
    assert _met([*six, *(r for r in core_rules() if r[0] != 6)]) == [0, 1, 2, 4]
    # FC 16 of quantity 1 out of a rule's range (2-123): each its own key
    sixteen = [r if r[0] != 16 else (16, True, 2, 123, False, None) for r in core_rules()]
    assert _met(sixteen) == [0, 2, 4, 5]


@pytest.mark.parametrize(
    ("rules", "error"),
    [
        ([(6, False, 0, 0xFFFF, False, None)] * 2, ValueError),  # a code twice
        ([(256, False, 0, 0xFFFF, False, None)], ValueError),
        ([(16, True, 5, 4, False, None)], ValueError),  # low above high
        ([(16, True, 0, 0x10000, False, None)], ValueError),
        ([(5, False, 0, 0xFFFF, True, tuple(range(9)))], ValueError),  # too many values
        ([(5, False, 0, 0xFFFF, True, ())], ValueError),
        ([(5, False, 0, 0xFFFF, True, (0x10000,))], ValueError),
        ([(5, False, 0, 0xFFFF, True, ("a",))], TypeError),
        ([(5, False, 0)], TypeError),
        ([[5, False, 0, 0xFFFF, True, None]], TypeError),
        (5, TypeError),
    ],
)
def test_poll_table_refuses_rules_it_cannot_follow(rules: object, error: type[Exception]) -> None:
    with pytest.raises(error):
        _compiled().poll_table(rules)


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(1, 120))
def test_poll_block_hands_over_each_write_as_the_python_rule_reads_it(seed: int, n: int) -> None:
    """The keys `resolve` hears of are those of the Python rule: one for each identity of
    a write `plain_identity` reads (whatever it writes), and one for each other frame's
    bytes. (The groups alone would not tell: Python puts a write the core keys by its
    bytes in the same group all the same.)"""
    fast = _compiled()
    rng = random.Random(seed)
    pool = [_write_body(rng) for _ in range(rng.randrange(1, 10))]
    bodies = [rng.choice(pool) if rng.random() < 0.5 else _write_body(rng) for _ in range(n)]
    store = FrameStore()
    _grow(store, [(0, with_crc(b), int(Kind.REQUEST), 0, 0.0, 0) for b in bodies])
    met: list[int] = []

    def resolve(key: object, i: int) -> int:
        met.append(i)
        return 0

    _poll(fast, fast.poll_table(core_rules()), store, len(store), resolve)
    first: dict[object, int] = {}
    for i, body in enumerate(bodies):
        plain = plain_identity(body)
        key: object = (body[0], plain[0]) if plain is not None else with_crc(body)
        first.setdefault(key, i)
    assert met == sorted(first.values())
