"""The compiled listings (sniffer/_core.c: listing_rows, from `Lister.write`) write the
text and JSONL lines the pure-Python Lister writes, byte for byte: on random polling
traffic (FC 1-6, 15, 16 of random quantities and fresh values, exceptions, timeouts,
bad checks, echoes that differ, bound and unbound units), FC 5/6 writes repeated with
fresh values (coil values neither ON nor OFF, unit 0), random stray bytes, random
stamps and resolutions (values, bounds, none), content caches small enough that
contents are dropped and made again, and rows listed in several calls."""

from __future__ import annotations

import io
import itertools
import struct
from math import inf, nan

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer import core
from sniffer.meaning.describe import Describer
from sniffer.model import Chunk, Stamp
from sniffer.outputs.listing import Lister
from sniffer.session.session import Session
from tests.outputs.test_listing_fast import Exchange, exchanges
from tests.outputs.test_listing_single_writes import single, writes
from tests.support.describe import BINDINGS, LINE, T0, session

pytestmark = pytest.mark.skipif(core.FAST is None, reason="the compiled core is not built")
FAST = core.FAST


def listing(
    s: Session,
    fmt: str,
    compiled: bool,
    size: int,
    cuts: list[int],
    monkeypatch: pytest.MonkeyPatch,
) -> str:
    """`fmt`'s listing of every row of `s`, by a Lister on a fresh Describer that keeps
    `size` contents, the rows given in calls cut at `cuts`; with the compiled core or
    without."""
    monkeypatch.setattr(core, "FAST", FAST if compiled else None)
    out = io.StringIO()
    lister = Lister(out, fmt, Describer(s.store, s.annotator, shared_size=size))
    n = len(s.store)
    bounds = [0, *sorted(c % (n + 1) for c in cuts), n]
    for a, b in itertools.pairwise(bounds):
        lister.write(range(a, b), flush=False)
    return out.getvalue()


def same(s: Session, size: int, cuts: list[int], monkeypatch: pytest.MonkeyPatch) -> None:
    for fmt in ("text", "jsonl"):
        made = listing(s, fmt, True, size, cuts, monkeypatch)
        want = listing(s, fmt, False, size, cuts, monkeypatch)
        for n, (a, b) in enumerate(zip(made.splitlines(), want.splitlines(), strict=True)):
            assert a == b, (fmt, n)
        assert made == want


STAMPS = st.sampled_from([None, Stamp.FRAME_START, Stamp.FRAME_END, Stamp.PRINT, Stamp.NONE])
RESOLUTIONS = st.sampled_from([None, 0.0, 1e-7, 1e-6, 5e-5, 1e-3, 0.016, 0.25, 1.0, inf, nan])
DELAYS = st.floats(0.0, 0.3) | st.sampled_from([0.0, 1e-6, 0.016, 0.032, 0.0325, 1.0, 2.0])
SIZES = st.sampled_from([2, 16, 2048])
CUTS = st.lists(st.integers(0, 200), max_size=3)


def retimed(s: Session, stamps: Stamp | None, resolution: float | None) -> Session:
    """`s` with its store's stamps and resolution made others (None: as they were)."""
    if stamps is not None:
        s.store.stamps = stamps
    if resolution is not None:
        s.store.resolution = resolution
    return s


@settings(max_examples=120, deadline=None)
@given(
    st.lists(exchanges(), min_size=1, max_size=60), st.booleans(), STAMPS, RESOLUTIONS, SIZES, CUTS
)
def test_compiled_lines_are_python_lines(
    traffic: list[Exchange],
    bound: bool,
    stamps: Stamp | None,
    resolution: float | None,
    size: int,
    cuts: list[int],
) -> None:
    with pytest.MonkeyPatch.context() as monkeypatch:
        same(retimed(session(traffic, bound=bound), stamps, resolution), size, cuts, monkeypatch)


@st.composite
def polls(draw: st.DrawFn) -> list[Exchange]:
    """A polling master's few polls over and over, answers with fresh values and
    answered after any delay: the rows the compiled table finds (and splices), their
    latencies values and bounds of every size."""
    table = draw(st.lists(exchanges(), min_size=1, max_size=4))
    order = draw(st.lists(st.integers(0, len(table) - 1), min_size=5, max_size=80))
    out: list[Exchange] = []
    for k in order:
        request, answer, _ = table[k]
        delay = draw(DELAYS)
        if answer is not None and len(answer) > 5 and draw(st.booleans()):
            body = bytearray(answer[:-2])
            body[3:] = draw(st.binary(min_size=len(body) - 3, max_size=len(body) - 3))
            answer = with_crc(bytes(body))
        out.append((request, answer, delay))
    return out


@settings(max_examples=120, deadline=None)
@given(polls(), st.booleans(), STAMPS, RESOLUTIONS, SIZES, CUTS)
def test_compiled_lines_of_polls_are_python_lines(
    traffic: list[Exchange],
    bound: bool,
    stamps: Stamp | None,
    resolution: float | None,
    size: int,
    cuts: list[int],
) -> None:
    with pytest.MonkeyPatch.context() as monkeypatch:
        same(retimed(session(traffic, bound=bound), stamps, resolution), size, cuts, monkeypatch)


@settings(max_examples=80, deadline=None)
@given(
    st.lists(
        st.tuples(st.binary(min_size=1, max_size=40), st.floats(0.0, 0.5, allow_nan=False)),
        min_size=1,
        max_size=40,
    ),
    st.booleans(),
    SIZES,
    CUTS,
)
def test_compiled_lines_of_random_bytes_are_python_lines(
    reads: list[tuple[bytes, float]], bound: bool, size: int, cuts: list[int]
) -> None:
    """Any bytes at any times: noise, fragments, frames the framer finds by chance."""
    s = Session(LINE, bindings=BINDINGS if bound else {})
    t = T0
    for data, gap in reads:
        t += gap
        s.feed(Chunk(data, t))
    s.finish()
    with pytest.MonkeyPatch.context() as monkeypatch:
        same(s, size, cuts, monkeypatch)


def test_the_compiled_core_makes_the_lines_of_a_polling_capture(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """On a capture of one poll answered with other values each time, the compiled loop
    makes nearly every line itself: the Python Lister is asked for the first rows only."""
    traffic: list[Exchange] = []
    for k in range(300):
        request = with_crc(struct.pack(">BBHH", 9, 3, 100, 2))
        answer = with_crc(struct.pack(">BBBHH", 9, 3, 4, k, 3 * k))
        traffic.append((request, answer, 0.01))
    s = session(traffic, bound=False)
    asked: list[int] = []
    real = Lister._row_line

    def row_line(self: Lister, i: int, shared: object, peer: str) -> str | None:
        asked.append(i)
        return real(self, i, shared, peer)  # type: ignore[arg-type]

    monkeypatch.setattr(Lister, "_row_line", row_line)
    for fmt in ("text", "jsonl"):
        asked.clear()
        made = listing(s, fmt, True, 2048, [], monkeypatch)
        lines = [line for line in made.splitlines() if not line.startswith("# ")]
        assert len(lines) == len(s.store)
        assert 0 < len(asked) <= 4, (fmt, asked)
    assert made == listing(s, "jsonl", False, 2048, [], monkeypatch)


def revalued(frame: bytes, value: int) -> bytes:
    """`frame`, an FC 5/6 write or echo of 8 bytes, writing `value` instead, its check
    good or bad as it was; any other frame as it is."""
    if len(frame) != 8:
        return frame
    made = with_crc(frame[:4] + struct.pack(">H", value))
    return made if with_crc(frame[:-2]) == frame else made[:-1] + bytes([made[-1] ^ 0x01])


@st.composite
def setpoints(draw: st.DrawFn) -> list[Exchange]:
    """A master writing a few coils and registers over and over, each time another
    value (ON, OFF, and coil values that are neither; any register value): the rows
    whose shape the compiled table finds and whose value it splices in. An echo that
    differs keeps its difference; exceptions, timeouts, bad checks and frames of the
    wrong length as `writes` makes them."""
    table = draw(st.lists(writes(), min_size=1, max_size=4))
    order = draw(st.lists(st.integers(0, len(table) - 1), min_size=5, max_size=60))
    out: list[Exchange] = []
    for k in order:
        request, answer, delay = table[k]
        if request[1] == 5:
            value = draw(st.sampled_from([0xFF00, 0x0000, 0xFF00, 0x0000, 0x00FF, 0x1234]))
        else:
            value = draw(st.integers(0, 0xFFFF))
        if answer is not None and len(answer) == 8 and len(request) == 8:
            differs = int.from_bytes(answer[4:6]) ^ int.from_bytes(request[4:6])
            answer = revalued(answer, value ^ differs)
        out.append((revalued(request, value), answer, delay))
    return out


@settings(max_examples=60, deadline=None)
@given(setpoints(), st.booleans(), STAMPS, RESOLUTIONS, SIZES, CUTS)
def test_compiled_lines_of_single_writes_are_python_lines(
    traffic: list[Exchange],
    bound: bool,
    stamps: Stamp | None,
    resolution: float | None,
    size: int,
    cuts: list[int],
) -> None:
    with pytest.MonkeyPatch.context() as monkeypatch:
        same(retimed(session(traffic, bound=bound), stamps, resolution), size, cuts, monkeypatch)


def test_the_compiled_core_makes_the_lines_of_single_writes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A setpoint written with a fresh value each cycle and a coil switched on and off,
    each echoed: the compiled loop says each row's value itself (the text's summary,
    the JSONL's raw, summary and value field) and asks the Python Lister only for the
    first rows of each shape; a coil value neither ON nor OFF and a broadcast (unit 0,
    no echo) are the Python Lister's."""
    traffic: list[Exchange] = []
    for k in range(100):
        register = single(9, 6, 0x64, 0x64 if k == 50 else 655 * k)
        coil = single(9, 5, 10, 0xFF00 if k % 2 else 0x0000)
        traffic += [(register, register, 0.01), (coil, coil, 0.01)]
    odd = single(9, 5, 10, 0x1234)
    traffic += [(odd, odd, 0.01), (single(0, 6, 0x64, 7), None, 0.0)]
    s = session(traffic, bound=False)
    asked: list[int] = []
    real = Lister._row_line

    def row_line(self: Lister, i: int, shared: object, peer: str) -> str | None:
        asked.append(i)
        return real(self, i, shared, peer)  # type: ignore[arg-type]

    monkeypatch.setattr(Lister, "_row_line", row_line)
    for fmt in ("text", "jsonl"):
        asked.clear()
        made = listing(s, fmt, True, 2048, [], monkeypatch)
        lines = [line for line in made.splitlines() if not line.startswith("# ")]
        assert len(lines) == len(s.store) == 403
        # row 0 is listed before the loop (its note and origin), so row 4 is its shape's first
        assert asked == [0, 1, 2, 3, 4, 400, 401, 402], fmt
        assert made == listing(s, fmt, False, 2048, [], monkeypatch)
    made = listing(s, "text", True, 2048, [], monkeypatch)
    text = [line for line in made.splitlines() if not line.startswith("# ")]
    assert text[200].endswith("  write 0x0064 to register 0x0064")  # the value said first
    assert text[207].endswith("  coil 0x000A ON")
    assert text[396].endswith("  write 0xFD4D to register 0x0064")


FLOATS = (
    st.floats(allow_nan=False, allow_infinity=False)
    | st.floats(-3e9, 3e9)
    | st.floats(-1.0, 1.0)
    # times to the microsecond and half a step off it: the ties of round()
    | st.builds(
        lambda whole, micros, off: whole + micros / 1e6 + off,
        st.integers(0, 2_000_000_000),
        st.integers(0, 999_999),
        st.sampled_from([0.0, 5e-7, -5e-7, 5e-4, 1e-9]),
    )
)


@settings(max_examples=3000, deadline=None)
@given(FLOATS, st.sampled_from([0, 1, 3, 6, 9]))
def test_compiled_floats_are_python_floats(x: float, nd: int) -> None:
    """The compiled loop's `round(x, nd)` (to the bit), `repr` of it (JSONL's times and
    latencies) and `%12.{nd}f` (the text listing's time) are Python's."""
    assert FAST is not None
    got, text, time = FAST.listing_floats(x, nd)
    want = round(x, nd)
    assert struct.pack(">d", got) == struct.pack(">d", want)
    assert text == repr(want)
    assert time == f"{x:12.{nd}f}"
