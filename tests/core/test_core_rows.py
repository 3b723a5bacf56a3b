"""The compiled passes over the rows (sniffer/_core.c: pair_rows, pair_update,
stats_scan, sunspec_rows, mask_rows) give what their Python references give, bit for bit.

Stores are built row by row from random traffic (requests, answers, exceptions,
broadcasts, unknown frames, noise, events; bad checks, ASCII rows, NaN and far-apart
times, answers the framer paired as it framed them) and grown a few rows at a time, as a
capture or a live port grows them: after each step the pairer updates (or ticks with a
clock), the statistics update (bounded from some step on, under every kind of stamps),
the SunSpec tracker follows, and every column and every piece of state is compared with
the compiled core and without it. Without the extension these tests skip, unless
MODSCOPE_REQUIRE_COMPILED=1 (check.sh sets it): then they fail.
"""

from __future__ import annotations

import math
import random
from array import array
from itertools import compress, pairwise
from types import ModuleType
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dissectors.checks import lrc, with_crc
from dissectors.dictionary.sunspec import MARKER
from sniffer.analysis.stats import Stats, UnitStats, median_gap, nearest_rank
from sniffer.framing import pipeline
from sniffer.framing.pairing import Pairer
from sniffer.framing.pipeline import Pipeline, _joined
from sniffer.framing.store import COLUMNS, FrameStore
from sniffer.meaning import sunspec
from sniffer.meaning.sunspec import BASES, SunSpecTracker
from sniffer.model import Chunk, Direction, LineSettings, Stamp
from sniffer.sources.reads import Reads
from sniffer.vocab import Flag, Kind
from tests.support.core import _compiled, running

TIMEOUT = 0.05
LINE = LineSettings(baud=115200, parity="N", mode="rtu")
ANSWERED_BROADCASTS = frozenset({0x41})


# -- random rows --------------------------------------------------------------------------

Row = tuple[bytes, int, int, float, float]  # raw, kind, flags, t, t_end


def _ascii(body: bytes) -> bytes:
    return b":" + (body + bytes([lrc(body)])).hex().upper().encode() + b"\r\n"


def _rows(rng: random.Random, n: int, nan: bool) -> tuple[list[Row], list[tuple[int, int]]]:
    """`n` exchanges' rows, and the (request, answer) pairs a framer pairs as it frames."""
    rows: list[Row] = []
    inline: list[tuple[int, int]] = []
    t = 1_700_000_000.0

    def add(raw: bytes, kind: Kind, flags: int = 0) -> int:
        nonlocal t
        t += rng.choice((0.001, 0.004, 0.02, 0.049, 0.05, 0.051, 0.2))
        if rng.random() < 0.03:
            t += 1.0
        if rng.random() < 0.05:
            flags |= rng.choice((int(Flag.CHECK_BAD), int(Flag.NON_HEX), int(Flag.ENVELOPE_BAD)))
        start = math.nan if nan and rng.random() < 0.05 else t
        rows.append((raw, int(kind), flags, start, t + len(raw) * 0.0005))
        return len(rows) - 1

    for _ in range(n):
        unit = rng.choice((1, 2, 2, 7, 0))
        what = rng.random()
        fc = rng.choice((3, 3, 4, 6, 0x41))
        req = with_crc(bytes([unit, fc, 0, rng.randrange(4), 0, 1]))
        if what < 0.05:
            add(bytes(rng.getrandbits(8) for _ in range(rng.randrange(1, 9))), Kind.NOISE)
        elif what < 0.08:
            add(b"", Kind.EVENT, int(Flag.LINE_EVENT))
        elif what < 0.11:
            add(with_crc(bytes([unit, 0x41, 1])), Kind.UNKNOWN)
        elif what < 0.14:  # an answer nobody asked for, or of another unit
            add(with_crc(bytes([rng.choice((1, 0, 9)), fc, 2, 0, 1])), Kind.RESPONSE)
        elif what < 0.17:  # an ASCII exchange
            r = add(_ascii(bytes([unit, fc, 0, 1, 0, 1])), Kind.REQUEST, int(Flag.ASCII))
            a = add(_ascii(bytes([unit, fc | 0x80, 2])), Kind.EXCEPTION, int(Flag.ASCII))
            if rng.random() < 0.3:
                inline.append((r, a))
        else:
            for _ in range(rng.choice((1, 1, 1, 2, 3))):  # retries of the same request
                r = add(req, Kind.REQUEST)
            answer = rng.random()
            if answer < 0.6:
                a = add(with_crc(bytes([unit, fc, 2, 0, rng.randrange(3)])), Kind.RESPONSE)
            elif answer < 0.75:
                code = rng.randrange(0, 5)
                a = add(
                    with_crc(bytes([unit, fc | 0x80, code]))[: rng.choice((5, 4))], Kind.EXCEPTION
                )
            else:
                continue  # no answer
            if rng.random() < 0.5:
                inline.append((r, a))
    return rows, inline


def _grow(store: FrameStore, rows: list[Row], inline: list[tuple[int, int]], upto: int) -> None:
    """Append rows until `upto`, and pair those the framer paired (answers among them)."""
    start = len(store)
    stream = store.stream(0)
    for raw, kind, flags, t0, t1 in rows[start:upto]:
        offset = len(stream)
        stream += raw
        store.add_row(0, offset, len(raw), t0, t1, kind, flags)
    store.sync()
    pairs = array("q")
    for req, answer in inline:
        if start <= answer < upto:
            pairs.extend((req, answer))
    if pairs:
        store.pair_rows(pairs)


def _state(obj: Any) -> str:
    """Everything of a store, pairer, statistics or tracker, exactly (floats by repr,
    NaN included; dicts in their order)."""
    if isinstance(obj, FrameStore):
        return repr([(name, getattr(obj, name)) for name in COLUMNS])
    return repr(obj)


def _stats_state(stats: Stats) -> str:
    units = []
    for u, unit in stats.units.items():
        tallies = unit.tallies
        kept = None
        if tallies is not None:
            kept = (
                list(tallies.latency_ms.items()),
                list(tallies.gap_ms.items()),
                tallies.latencies,
                tallies.requests,
                tallies.last_request,
                list(tallies.recent_latencies),
                list(tallies.recent_requests),
            )
        units.append(
            (
                u,
                unit.requests,
                unit.responses,
                list(unit.exceptions.items()),
                unit.timeouts,
                unit.check_errors,
                unit.latencies,
                unit.request_times,
                unit.last_seen,
                unit.below_resolution,
                unit.unmeasured,
                kept,
            )
        )
    return repr(
        (units, stats.next, stats.noise_bytes, stats.noise_spans, stats.events, sorted(stats._open))
    )


STAMPS = [Stamp.READ_END, Stamp.EXACT, Stamp.NONE, Stamp.FRAME_START, Stamp.PRINT]


def _run(
    fast: ModuleType | None,
    rows: list[Row],
    inline: list[tuple[int, int]],
    steps: list[int],
    ticks: list[float | None],
    stamps: Stamp,
    resolution: float,
    bound_at: int,
) -> list[str]:
    """The states after each step of growing the store, with one core."""
    seen: list[str] = []
    with running(fast):
        store = FrameStore()
        store.stamps, store.resolution = stamps, resolution
        pairer = Pairer(store, TIMEOUT, ANSWERED_BROADCASTS)
        stats = Stats(store)
        upto = 0
        for k, step in enumerate(steps):
            upto = min(len(rows), upto + step)
            _grow(store, rows, inline, upto)
            tick = ticks[k % len(ticks)]
            if tick is None or not len(store):
                pairer.update()
            else:
                pairer.tick(store.t_end[len(store) - 1] + tick)
            if k == bound_at:
                stats.bound()
            stats.update()
            seen.append(_state(store) + _state((pairer.open, pairer.last_timed_out, pairer.next)))
            seen.append(_stats_state(stats))
            if upto == len(rows):
                break
        _grow(store, rows, inline, len(rows))
        pairer.end_time = rows[-1][4] + (ticks[0] or 0.0) if rows else pairer.end_time
        pairer.finish()
        stats.update()
        seen.append(_state(store) + _state((pairer.open, pairer.last_timed_out, pairer.next)))
        seen.append(_stats_state(stats) + stats.table())
    return seen


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 10**6),
    n=st.integers(0, 80),
    nan=st.booleans(),
    steps=st.lists(st.integers(1, 12), min_size=1, max_size=30),
    ticks=st.lists(st.one_of(st.none(), st.sampled_from((0.0, 0.01, 0.06, 2.0))), min_size=1),
    stamps=st.sampled_from(STAMPS),
    resolution=st.sampled_from((0.0, 0.016)),
    bound_at=st.integers(-1, 10),
)
def test_pairing_and_statistics_are_the_same_with_either_core_step_by_step(
    seed: int,
    n: int,
    nan: bool,
    steps: list[int],
    ticks: list[float | None],
    stamps: Stamp,
    resolution: float,
    bound_at: int,
) -> None:
    fast = _compiled()
    rows, inline = _rows(random.Random(seed), n, nan)
    if nan:
        bound_at = -1  # bounded statistics are live ones: times from the clock, never NaN
    args = (rows, inline, steps, ticks, stamps, resolution, bound_at)
    assert _run(fast, *args) == _run(None, *args)


def test_the_whole_statistics_table_is_the_same_with_either_core_on_many_rows() -> None:
    fast = _compiled()
    for nan, bound_at in ((True, -1), (False, 2)):
        rows, inline = _rows(random.Random(11), 3000, nan)
        for stamps in STAMPS:
            args = (rows, inline, [500, 1, 2000, 7], [None, 0.06], stamps, 0.016, bound_at)
            assert _run(fast, *args) == _run(None, *args)


@settings(max_examples=100, deadline=None)
@given(
    rows=st.integers(1, 60),
    pairs=st.lists(st.tuples(st.integers(0, 59), st.integers(0, 59)), max_size=40),
    codes=st.lists(st.integers(0, 255), min_size=60, max_size=60),
)
def test_pair_rows_is_the_same_with_either_core(
    rows: int, pairs: list[tuple[int, int]], codes: list[int]
) -> None:
    fast = _compiled()
    flat = array("q", [row % rows for pair in pairs for row in pair])
    states = []
    for module in (fast, None):
        with running(module):
            store = FrameStore()
            stream = store.stream(0)
            for i in range(rows):
                stream += bytes([1, codes[i]])
                store.add_row(0, 2 * i, 2, float(i), float(i), int(Kind.REQUEST), 0)
            store.pair_rows(flat)
            states.append(_state(store))
    assert states[0] == states[1]


# -- SunSpec's tracker ---------------------------------------------------------------------


def _sunspec_rows(rng: random.Random, n: int) -> list[Row]:
    """FC 3 and FC 4 reads (and others) near the SunSpec base addresses, with the marker
    and model headers in their answers now and then, each answer paired with its request,
    in every envelope: RTU, ASCII (opened by ':' or a vendor's '>'), Modbus TCP."""
    rows: list[Row] = []
    t = 1_700_000_000.0
    for _ in range(n):
        unit = rng.choice((1, 2, 3, 5, 0))
        base = rng.choice(BASES)
        start = (
            max(0, base + rng.randrange(-3, 4)) if rng.random() < 0.8 else rng.randrange(0x10000)
        )
        count = rng.randrange(1, 12)
        words = [rng.choice((0, 1, 2, 0xFFFF, 7, rng.getrandbits(16))) for _ in range(count)]
        k = base - start
        if rng.random() < 0.6 and k >= 0 and k + 1 < count:
            words[k], words[k + 1] = MARKER
            if k + 3 < count:
                words[k + 2], words[k + 3] = rng.choice(((1, 66), (0xFFFF, 0), (103, 50)))
        fc = rng.choice((3, 3, 3, 4, 4, 0x83, 6))
        request = bytes([unit, fc]) + start.to_bytes(2, "big") + count.to_bytes(2, "big")
        data = b"".join(w.to_bytes(2, "big") for w in words)
        answer = bytes([unit, fc, len(data) if rng.random() < 0.9 else 2]) + data
        flags = 0
        envelope = rng.random()
        if envelope < 0.1:
            flags = int(Flag.ASCII)
            req_raw, ans_raw = _ascii(request), _ascii(answer)
            if rng.random() < 0.5:
                ans_raw = b">" + ans_raw[1:]
        elif envelope < 0.3:
            flags = int(Flag.MBAP)
            tid = rng.randrange(0x10000).to_bytes(2, "big")
            req_raw, ans_raw = (
                tid + b"\0\0" + len(body).to_bytes(2, "big") + body for body in (request, answer)
            )
            if rng.random() < 0.05:
                req_raw = req_raw[:10]  # a request too short to read
        else:
            req_raw, ans_raw = with_crc(request), with_crc(answer)
            if rng.random() < 0.05:
                req_raw = req_raw[:6]  # a request too short to read
        bad = int(Flag.CHECK_BAD) if rng.random() < 0.05 else 0
        t += 0.1
        rows.append((req_raw, int(Kind.REQUEST), flags, t, t + 0.004))
        rows.append((ans_raw, int(Kind.RESPONSE), flags | bad, t + 0.01, t + 0.02))
    return rows


def _tracker_state(tracker: SunSpecTracker) -> str:
    return repr(
        [
            (
                u,
                su.base,
                su.function,
                list(su.image.items()),
                [(m.id, m.start, m.length, m.definition is None) for m in su.models],
                su.complete,
                list(su.layouts),
                [(a, h.rows, h.values) for a, h in su.scale.items()],
            )
            for u, su in tracker.units.items()
        ]
    )


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 10**6),
    n=st.integers(0, 60),
    steps=st.lists(st.integers(1, 15), min_size=1, max_size=20),
    skip=st.sets(st.sampled_from((1, 2, 3, 5, 0)), max_size=2),
    only_answers=st.booleans(),
    unpaired=st.floats(0.0, 0.3),
)
def test_sunspec_follows_the_same_rows_with_either_core(
    seed: int,
    n: int,
    steps: list[int],
    skip: set[int],
    only_answers: bool,
    unpaired: float,
) -> None:
    fast = _compiled()
    rng = random.Random(seed)
    rows = _sunspec_rows(rng, n)
    inline = [(i, i + 1) for i in range(0, len(rows), 2) if rng.random() >= unpaired]
    states = []
    for module in (fast, None):
        seen = []
        with running(module):
            store = FrameStore()
            tracker = SunSpecTracker(skip=frozenset(skip))
            upto = 0
            for step in steps * 3:
                start, upto = upto, min(len(rows), upto + step)
                _grow(store, rows, inline, upto)
                wanted = range(start, upto)
                if only_answers:  # as the annotator hands them on: a mask of the rows
                    answers = bytes(store.kind[i] == Kind.RESPONSE for i in wanted)
                    tracker.follow_mask(store, start, answers)
                else:
                    tracker.follow_rows(store, wanted)
                seen.append(_tracker_state(tracker))
        states.append(seen)
    assert states[0] == states[1]


@given(mask=st.binary(max_size=300), start=st.integers(0, 2**40))
def test_the_rows_of_a_mask_are_those_compress_takes(mask: bytes, start: int) -> None:
    """mask_rows gives, as int64, the rows `start + k` whose byte k of the mask is not
    0 (the annotator's masks hold 0 and 1; any other byte counts as compress counts it)."""
    got = array("q")
    got.frombytes(_compiled().mask_rows(mask, start))
    assert list(got) == list(compress(range(start, start + len(mask)), mask))


def test_a_unit_found_in_the_middle_of_a_batch_has_all_its_later_reads_taken() -> None:
    """The compiled filter picks the reads of units it knows; one whose marker shows in
    the middle of the rows handed over has its later reads (outside any base range)
    taken too, as the Python loop takes them."""
    fast = _compiled()
    image = {40000 + k: w for k, w in enumerate((*MARKER, 1, 4, 10, 11, 12, 13, 0xFFFF, 0))}
    reads = [(100, 2), (40000, 2), (40002, 2), (40004, 4), (40006, 2), (40008, 2)]
    rows: list[Row] = []
    t = 1.0
    for start, count in reads:
        words = [image.get(start + k, 0) for k in range(count)]
        data = b"".join(w.to_bytes(2, "big") for w in words)
        req = with_crc(bytes([4, 3]) + start.to_bytes(2, "big") + count.to_bytes(2, "big"))
        rows.append((req, int(Kind.REQUEST), 0, t, t + 0.004))
        rows.append((with_crc(bytes([4, 3, len(data)]) + data), int(Kind.RESPONSE), 0, t, t))
        t += 0.1
    inline = [(i, i + 1) for i in range(0, len(rows), 2)]
    states = []
    for module in (fast, None):
        with running(module):
            store = FrameStore()
            _grow(store, rows, inline, len(rows))
            tracker = SunSpecTracker()
            tracker.follow_rows(store, range(len(rows)))
            states.append(_tracker_state(tracker))
            assert tracker.units[4].complete
            assert tracker.units[4].image[40009] == 0
    assert states[0] == states[1]


def test_the_compiled_first_look_reads_each_envelope_where_the_rule_says() -> None:
    """Given the rule's numbers, the compiled filter reads a Modbus TCP request's range
    after its MBAP header and an RTU request's after its unit byte, and takes FC 3 and 4
    alike: a read that cannot hold a marker is left out in every envelope (read at the
    wrong place, an MBAP header would seem to read from 0, where a base lies)."""
    fast = _compiled()
    rows: list[Row] = []
    t = 1.0
    for fc, start, mbap in [
        (3, 40000, True),
        (3, 100, True),
        (4, 40000, True),
        (4, 100, False),
        (4, 50000, False),
        (6, 40000, False),
    ]:
        request = bytes([5, fc]) + start.to_bytes(2, "big") + b"\x00\x02"
        answer = bytes([5, fc, 4, *MARKER[0].to_bytes(2, "big"), *MARKER[1].to_bytes(2, "big")])
        if mbap:
            req_raw, ans_raw = (
                b"\x00\x01\x00\x00" + len(b).to_bytes(2, "big") + b for b in (request, answer)
            )
        else:
            req_raw, ans_raw = with_crc(request), with_crc(answer)
        flags = int(Flag.MBAP) if mbap else 0
        rows.append((req_raw, int(Kind.REQUEST), flags, t, t + 0.004))
        rows.append((ans_raw, int(Kind.RESPONSE), flags, t + 0.01, t + 0.02))
        t += 0.1
    store = FrameStore()
    _grow(store, rows, [(i, i + 1) for i in range(0, len(rows), 2)], len(rows))
    answers = array("q", range(1, len(rows), 2))
    picked = array("q")
    picked.frombytes(
        fast.sunspec_rows(
            store, answers, 0, bytes(256), bytes(256), sunspec._BASES_ARRAY,
            sunspec._READS_MASK, sunspec._FRAMES,
        )
    )  # fmt: skip
    assert [answers[k] for k in picked] == [1, 5, 9]
    with running(None):
        tracker = SunSpecTracker()
        tracker.follow_rows(store, answers)
    assert set(tracker.units) == {5} and tracker.units[5].function == 3


# -- batches of reads held by the pipeline -----------------------------------------------


def _batch(reads: list[tuple[bytes, float, float]], channel: int) -> Reads:
    ends: array[int] = array("q")
    at = 0
    for data, _, _ in reads:
        at += len(data)
        ends.append(at)
    return Reads(
        b"".join(r[0] for r in reads),
        reads[-1][2],
        None,
        channel,
        Direction.UNKNOWN,
        ends=ends,
        t_starts=array("d", [r[1] for r in reads]),
        t_ends=array("d", [r[2] for r in reads]),
    )


read = st.tuples(
    st.binary(min_size=1, max_size=20),
    st.one_of(st.just(math.nan), st.floats(0, 1e10)),
    st.floats(0, 1e10),
)


@settings(max_examples=100, deadline=None)
@given(batches=st.lists(st.lists(read, min_size=1, max_size=8), min_size=1, max_size=8))
def test_batches_held_by_the_pipeline_join_the_same_with_either_core(
    batches: list[list[tuple[bytes, float, float]]],
) -> None:
    fast = _compiled()
    given_batches = [_batch(b, 3) for b in batches]
    joined = []
    for module in (fast, None):
        with running(module):
            joined.append(_joined(given_batches))
    assert repr(joined[0]) == repr(joined[1])
    whole = joined[1]
    assert whole.data == b"".join(b.data for b in given_batches)
    assert list(whole.ends) == list(_batch([r for b in batches for r in b], 3).ends)
    assert (whole.t_start, whole.t_end, whole.channel) == (None, batches[-1][-1][2], 3)


def test_reads_held_by_the_pipeline_frame_as_the_reads_one_by_one() -> None:
    """Batches of reads are held (`HOLD_BYTES`) and framed together: the rows, pairs and
    statistics are those of the same reads fed one by one, with either core, whatever
    is held (nothing, a little, everything)."""
    fast = _compiled()
    rng = random.Random(4)
    stream = b"".join(
        with_crc(bytes([1, 3, 0, 0, 0, 2])) + with_crc(bytes([1, 3, 4, 0, 1, 0, 2]))
        if rng.random() < 0.9
        else bytes(rng.getrandbits(8) for _ in range(3))
        for _ in range(3000)
    )
    reads: list[tuple[bytes, float, float]] = []
    pos, t = 0, 1_700_000_000.0
    while pos < len(stream):
        n = rng.randrange(1, 200)
        t += n * LINE.char_time + rng.choice((0.0, 0.0, 0.016, 0.3))
        reads.append((stream[pos : pos + n], math.nan, t))
        pos += n
    one_by_one = Pipeline(LINE)
    for data, _, t_end in reads:
        one_by_one.feed(Chunk(data, t_end))
    one_by_one.finish()
    want = _state(one_by_one.store)
    saved = pipeline.HOLD_BYTES
    try:
        for module in (fast, None):
            for hold in (0, 1000, 1 << 19):
                pipeline.HOLD_BYTES = hold
                with running(module):
                    held = Pipeline(LINE)
                    for k in range(0, len(reads), 7):
                        held.feed(_batch(reads[k : k + 7], 0))
                        if k % 70 == 0:
                            held.sync()
                    held.finish()
                assert _state(held.store) == want, (module, hold)
    finally:
        pipeline.HOLD_BYTES = saved


# -- nearest-rank quantiles by selection -------------------------------------------------

value = st.one_of(
    st.floats(allow_nan=False, allow_infinity=True),
    st.sampled_from((0.0, 0.0, 1.0, 1.0, 2.5, 0.016, 0.001, 1e-7)),
    st.sampled_from((math.nan, -0.0)),  # where only a sort says
)


@settings(max_examples=300, deadline=None)
@given(
    values=st.lists(value, min_size=0, max_size=300),
    qs=st.lists(st.floats(0, 1), min_size=1, max_size=5),
)
def test_quantiles_are_those_of_the_sorted_values_with_either_core(
    values: list[float], qs: list[float]
) -> None:
    fast = _compiled()
    times = array("d", values)
    unit = UnitStats(1)
    unit.latencies.extend(values)
    unit.request_times.extend(values)
    got = []
    for module in (fast, None):
        with running(module):
            got.append(
                repr(
                    (
                        [nearest_rank(times, q) for q in qs],
                        median_gap(times),
                        unit.latencies_ms(*qs),
                        unit.polling_period(),
                    )
                )
            )
    assert got[0] == got[1]
    if values and not any(math.isnan(x) for x in values):
        ordered = sorted(values)
        for q in qs:  # by selection or by a sort, the value sorted() puts at the rank
            at = ordered[min(len(values) - 1, max(0, round(q * (len(values) - 1))))]
            assert repr(nearest_rank(times, q)) == repr(at)


def test_the_selection_picks_each_rank_of_large_arrays_of_repeated_values() -> None:
    fast = _compiled()
    rng = random.Random(8)
    for n in (1, 2, 3, 10, 1000, 50_001):
        values = array("d", (rng.choice((0.001, 0.002, 0.016, rng.random())) for _ in range(n)))
        ordered = sorted(values)
        ranks = tuple(sorted({0, n // 3, n // 2, n // 2, (19 * n) // 20, n - 1}))
        assert fast.ranked(values, ranks, False) == tuple(ordered[k] for k in ranks)
        if n > 1:
            gaps = sorted(b - a for a, b in pairwise(values))
            ranks = tuple(sorted({0, (n - 1) // 2, n - 2}))
            assert fast.ranked(values, ranks, True) == tuple(gaps[k] for k in ranks)


def test_a_pairer_whose_answered_broadcasts_are_replaced_pairs_alike_with_either_core() -> None:
    fast = _compiled()
    rows = [
        (with_crc(bytes([0, 0x41, 1])), int(Kind.REQUEST), 0, 1.0, 1.001),
        (with_crc(bytes([0, 0x41, 2])), int(Kind.RESPONSE), 0, 1.01, 1.011),
    ]
    states = []
    for module in (fast, None):
        with running(module):
            store = FrameStore()
            _grow(store, rows, [], 1)
            pairer = Pairer(store, TIMEOUT)
            pairer.update()
            pairer.answered_broadcasts = ANSWERED_BROADCASTS  # a vendor code learnt late
            _grow(store, rows, [], 2)
            pairer.update()
            _grow(store, rows + rows, [], 4)
            pairer.finish()
            states.append(_state(store))
    assert states[0] == states[1]
    assert "array('B', [5, 4, 1, 1])" in states[1]  # broadcast, orphan; then answered
