"""The text and JSONL listings' fast path (rows of one content share what their lines
say, values spliced in: `Describer.contents(values=False, writes=True)`, `_json_line`,
`_text_line`) writes the lines the reference path writes (every row described on its
own by an uncached Describer and encoded whole), on random polling traffic: FC 1-6, 15
and 16 of random quantities and fresh values, exceptions, timeouts, bad checks, byte
counts that do not fit, padding bits set, echoes that differ, units with and without a
dictionary."""

from __future__ import annotations

import io
import struct
from math import inf, nan
from types import SimpleNamespace
from typing import cast

from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.framing.pairing import measure
from sniffer.framing.store import FrameStore
from sniffer.meaning.describe import Describer
from sniffer.model import Stamp
from sniffer.outputs.listing import Latencies, Lister
from sniffer.session.session import Session
from sniffer.vocab import Kind
from tests.support.describe import session

Exchange = tuple[bytes, bytes | None, float]

UNITS = st.sampled_from([0, 1, 2, 3, 7, 9, 200])  # 1-3 have dictionaries when bound
ADDRESSES = st.sampled_from([0, 10, 100, 0x1234, 0xFFF0])  # shapes repeat, values do not


def _spoil(frame: bytes, draw: st.DrawFn) -> bytes:
    """Now and then a frame with a bad check."""
    if draw(st.integers(0, 19)) == 0:
        return frame[:-1] + bytes([frame[-1] ^ 0x01])
    return frame


@st.composite
def exchanges(draw: st.DrawFn) -> Exchange:
    unit = draw(UNITS)
    fc = draw(st.sampled_from([1, 2, 3, 4, 5, 6, 15, 16]))
    address = draw(ADDRESSES)
    delay = draw(st.sampled_from([0.002, 0.01, 0.02, 0.5]))
    request: bytes
    answer: bytes
    if fc in (1, 2, 3, 4):
        quantity = draw(st.sampled_from([0, 1, 2, 8, 11, 60, 125, 200]))
        request = with_crc(struct.pack(">BBHH", unit, fc, address, quantity))
        size = (quantity + 7) // 8 if fc < 3 else 2 * quantity
        size = min(250, max(0, size + draw(st.sampled_from([0, 0, 0, 0, -1, 1]))))
        data = draw(st.binary(min_size=size, max_size=size))
        answer = with_crc(bytes([unit, fc, size]) + data)
    elif fc in (5, 6):
        value = draw(st.sampled_from([0xFF00, 0x0000, 0x1234])) if fc == 5 else None
        if value is None:
            value = draw(st.integers(0, 0xFFFF))
        request = with_crc(struct.pack(">BBHH", unit, fc, address, value))
        echo = draw(st.integers(0, 9))
        answer = request if echo else with_crc(struct.pack(">BBHH", unit, fc, address, value ^ 1))
    else:
        quantity = draw(st.sampled_from([0, 1, 3, 8, 9, 16, 60, 123, 137, 200]))
        need = (quantity + 7) // 8 if fc == 15 else 2 * quantity
        size = min(250, max(0, need + draw(st.sampled_from([0, 0, 0, 0, -1, 1]))))
        data = draw(st.binary(min_size=size, max_size=size))
        request = with_crc(struct.pack(">BBHHB", unit, fc, address, quantity, size) + data)
        echoed = draw(st.sampled_from([address, address, address ^ 1]))
        answer = with_crc(struct.pack(">BBHH", unit, fc, echoed, quantity))
    outcome = draw(st.integers(0, 19))
    if outcome == 0:
        return _spoil(request, draw), None, delay  # a timeout
    if outcome == 1:
        code = draw(st.sampled_from([1, 2, 3, 4, 6, 11]))
        answer = with_crc(bytes([unit, fc | 0x80, code]))
    return _spoil(request, draw), _spoil(answer, draw), delay


def listing(s: Session, describer: Describer, fmt: str, absolute: bool = False) -> str:
    out = io.StringIO()
    Lister(out, fmt, describer, absolute=absolute).write(range(len(s.store)), flush=False)
    return out.getvalue()


def same_lines(s: Session) -> None:
    """Each format's listing through the content cache (small, so contents are both
    found and made again) is the one an uncached Describer gives, row for row."""
    for fmt in ("text", "jsonl"):
        for size in (4, 64):
            fast = Describer(s.store, s.annotator, shared_size=size)
            reference = Describer(s.store, s.annotator, shared_size=0)
            made, want = listing(s, fast, fmt), listing(s, reference, fmt)
            for n, (a, b) in enumerate(zip(made.splitlines(), want.splitlines(), strict=True)):
                assert a == b, (fmt, size, n)


@settings(max_examples=150, deadline=None)
@given(st.lists(exchanges(), min_size=1, max_size=40), st.booleans())
def test_fast_lines_are_the_reference_lines(traffic: list[Exchange], bound: bool) -> None:
    same_lines(session(traffic, bound=bound))


def write_many(unit: int, fc: int, address: int, quantity: int, data: bytes) -> bytes:
    return with_crc(struct.pack(">BBHHB", unit, fc, address, quantity, len(data)) + data)


def test_writes_of_other_values_share_a_content() -> None:
    """FC 15 and 16 writes of a unit without dictionary that differ only in the values
    written share one content in the listings (their text lines show no value, their
    JSONL lines get their own values spliced in); not a write of another padding, byte
    count or quantity, nor a bound unit's, nor for a consumer that reads values."""
    traffic: list[Exchange] = [
        (write_many(9, 16, 100, 2, b"\x00\x01\x00\x02"), None, 0.01),
        (write_many(9, 16, 100, 2, b"\x12\x34\x56\x78"), None, 0.01),
        (write_many(9, 15, 10, 3, b"\x05"), None, 0.01),
        (write_many(9, 15, 10, 3, b"\x02"), None, 0.01),
        (write_many(9, 15, 10, 3, b"\xf2"), None, 0.01),  # padding bits set
        (write_many(9, 16, 100, 2, b"\x00\x01\x00\x02\x00\x03"), None, 0.01),  # count
        (write_many(9, 16, 100, 1, b"\x00\x01"), None, 0.01),
        (write_many(1, 16, 100, 2, b"\x00\x01\x00\x02"), None, 0.01),  # bound unit
        (write_many(1, 16, 100, 2, b"\x00\x03\x00\x04"), None, 0.01),
    ]
    s = session(traffic, bound=True)
    same_lines(s)
    free = dict(Describer(s.store, s.annotator).contents(range(len(s.store)), False, True))
    assert free[0] is free[1]  # FC 16, other values
    assert free[2] is free[3]  # FC 15, other values
    assert free[4] is not free[2]  # padding bits set
    assert free[5] is not free[0] and free[6] is not free[0]
    assert free[7] is not free[8]  # unit 1 has a dictionary: its values are named
    answers = dict(Describer(s.store, s.annotator).contents(range(len(s.store)), False))
    assert answers[0] is not answers[1]  # only the listings ask for writes to share


RESOLUTIONS = st.sampled_from([0.0, 1e-7, 1e-6, 5e-5, 1e-3, 0.016, 0.032, 1.0, 2.5, inf, nan])
TIMES = st.floats(-1.0, 5.0, allow_nan=False) | st.sampled_from([0.0, 1e-6, 2e-6, nan])


@settings(max_examples=400, deadline=None)
@given(
    st.sampled_from(list(Stamp)),
    RESOLUTIONS,
    st.floats(0, 2e9, allow_nan=False),
    TIMES,
    TIMES,
    st.booleans(),
)
def test_latencies_are_measure(
    stamps: Stamp, resolution: float, t0: float, wire: float, gap: float, answer: bool
) -> None:
    """`Latencies` gives the figures `pairing.measure` gives, to the bit, and a text
    line's latency as `Latency.text` says it, on any times and timing."""
    t = [t0, t0 + wire + gap]
    store = cast(
        FrameStore,
        SimpleNamespace(
            stamps=stamps,
            resolution=resolution,
            partner=[1, 0],
            kind=[int(Kind.REQUEST), int(Kind.RESPONSE)],
            t=t,
            t_end=[t0 + wire, t[1] + 0.001],
        ),
    )
    i = 1 if answer else 0
    measured = measure(store, i)
    latencies = Latencies()
    for _ in range(2):  # made, then its text found again
        got = latencies.ms(store, i)
        if measured is None:
            assert got is None and latencies.text(store, i) == ""
            continue
        assert got is not None
        assert struct.pack(">d", got[0]) == struct.pack(">d", measured.ms)
        assert got[1] == measured.bound
        assert latencies.text(store, i) == f" {measured.text():>9}"
