"""The compiled export (sniffer/_core.c: export_rows) writes the same packets as the
pure-Python PcapExporter, byte for byte, on random stores made to meet its shortcuts:
rows that share a packet template (the same bytes, an FC 3 or 4 answer with other values,
and the writes, echoes, reads and exceptions whose packet differs only in the bytes
spliced in) next to rows that look alike and must not share one (a coil value that is
not ON or OFF, padding bits that are set, a byte count that is wrong, an echo that
differs, an answer to another function code, unit 0, a unit with a dictionary or
parameter windows, a SunSpec unit, a bad check, ASCII and Modbus TCP frames, a slow
answer, notes, events, noise, times before 1970 or late)."""

from __future__ import annotations

import io
import random
from collections.abc import Iterable, Sequence

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dissectors.checks import ascii_frame, with_crc
from sniffer import core
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.meaning.annotate import Annotator, load_bindings
from sniffer.meaning.describe import Describer
from sniffer.meaning.sunspec import SunSpecUnit
from sniffer.model import LineSettings
from sniffer.outputs import export
from sniffer.outputs.export import PcapExporter
from sniffer.outputs.listing import FORMATS, Lister
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, replay_file
from sniffer.vocab import Flag, Kind, Status
from tests.support.core import running
from tests.support.describe import session

FAST = core.FAST
compiled = pytest.mark.skipif(FAST is None, reason="the compiled core is not built")

LINE = LineSettings(baud=19200, bytesize=8, parity="E", stopbits=1, mode="rtu")
BINDINGS = load_bindings(DEMO_BUS)  # 1 ved903b, 2 dcrl (parameter windows), 3 rvs-dn
UNITS = (1, 2, 3, 7, 7, 9, 9, 0, 44)  # 7, 9, 44: no dictionary (44: SunSpec, see below)
STYLES = ("modbus-tcp", "rtu")


def _request(rng: random.Random, unit: int) -> bytes:
    """A read or a write, most of them well formed, with few addresses and quantities."""
    fc = rng.choice((1, 2, 3, 4, 5, 6, 15, 16, 16, 8))
    head = bytes([unit, fc, 0, rng.choice((0, 1, 9))])
    if fc in (1, 2, 3, 4):
        quantity = rng.choice((1, 2, 8, 9, 17, 0, 126, 2001))
        return head + quantity.to_bytes(2, "big")
    if fc == 5:
        return head + rng.choice((b"\xff\x00", b"\x00\x00", b"\x12\x34"))
    if fc == 6:
        return head + rng.randbytes(2)
    if fc == 8:
        return head + rng.randbytes(rng.randrange(0, 3))
    quantity = rng.choice((1, 2, 3, 7, 9, 16, 0, 124, 1969))
    need = 2 * quantity if fc == 16 else (quantity + 7) // 8
    count = need if rng.random() < 0.8 else rng.randrange(0, 12)
    data = rng.randbytes(min(count, 40))
    if rng.random() < 0.08:
        data = data[:-1] if rng.random() < 0.5 else data + b"\x00"
    body = head + quantity.to_bytes(2, "big") + bytes([count & 0xFF]) + data
    if rng.random() < 0.03:
        body = body[: rng.randrange(2, len(body))]
    return body


def _answer(rng: random.Random, asked: bytes) -> bytes:
    """An answer to the request body `asked`: mostly what it asks for, some not."""
    unit, fc = asked[0], asked[1]
    roll = rng.random()
    if roll < 0.1:
        return bytes([unit, (fc | 0x80) & 0xFF, rng.choice((1, 2, 3, 4, 11))])
    if roll < 0.14:
        fc = rng.choice((3, 16, 0x83))  # an answer to another function code
    quantity = int.from_bytes(asked[4:6], "big") if len(asked) >= 6 else 0
    if fc in (1, 2):
        need = (quantity + 7) // 8 if rng.random() < 0.85 else rng.randrange(0, 4)
        data = bytearray(rng.randbytes(min(need, 40)))
        if data and quantity % 8 and rng.random() < 0.6:
            data[-1] &= (1 << (quantity % 8)) - 1  # the padding bits clear, mostly
        return bytes([unit, fc, need & 0xFF]) + bytes(data)
    if fc in (3, 4):
        need = 2 * quantity if rng.random() < 0.85 else rng.randrange(0, 5)
        return bytes([unit, fc, need & 0xFF]) + rng.randbytes(min(need, 40))
    if fc in (5, 6):
        echo = bytearray(asked[:6])
        if rng.random() < 0.15 and len(echo) == 6:
            echo[rng.randrange(2, 6)] ^= 1
        return bytes(echo)
    if fc in (15, 16):
        echo = bytearray(asked[:6])
        if rng.random() < 0.15 and len(echo) == 6:
            echo[rng.randrange(2, 6)] ^= 1
        return bytes([unit, fc]) + bytes(echo[2:])
    return bytes([unit, fc & 0xFF]) + rng.randbytes(rng.randrange(0, 4))


def random_capture(seed: int, rows: int, odd: bool) -> tuple[FrameStore, Annotator]:
    """A store of `rows` random rows (see the module's docstring) and its annotator.
    `odd`: some frames are ASCII or Modbus TCP, some rows have notes."""
    rng = random.Random(seed)
    store = FrameStore()
    stream = store.stream(0)
    t = rng.choice((1_700_000_000.0, -5.0, 9_999_999_990.0, 0.0))
    waiting = -1

    def add(raw: bytes, kind: Kind, flags: int, t0: float, t1: float) -> int:
        offset = len(stream)
        stream.extend(raw)
        store.add_row(0, offset, len(raw), t0, t1, int(kind), flags)
        return len(store) - 1

    while len(store) < rows:
        t += rng.choice((0.0, 1e-7, 0.002, 0.01, 0.3, 1.234567891))
        roll = rng.random()
        if roll < 0.02:
            store.add_event(t, "reconnected")
            continue
        if roll < 0.05:
            add(rng.randbytes(rng.randrange(1, 9)), Kind.NOISE, 0, t, t)
            continue
        answering = waiting >= 0 and rng.random() < 0.75
        if answering:
            asked = store.view(waiting).body()
            body = _answer(rng, asked) if len(asked) >= 2 else bytes([store.unit[waiting], 3])
            kind = Kind.EXCEPTION if body[1] & 0x80 else Kind.RESPONSE
        else:
            body = _request(rng, rng.choice(UNITS))
            kind = Kind.REQUEST
        if rng.random() < 0.02:
            kind = Kind.UNKNOWN
        flags = 0
        how = rng.random() if odd else 1.0
        if how < 0.05:
            raw = ascii_frame(body)
            flags |= Flag.ASCII
        elif how < 0.1:
            raw = b"\x00\x01\x00\x00" + len(body).to_bytes(2, "big") + body
            flags |= Flag.MBAP
        else:
            raw = with_crc(body)
        if rng.random() < 0.04:
            flags |= Flag.CHECK_BAD
            raw = raw[:-1] + bytes([raw[-1] ^ 0x55])
        for flag in (Flag.LINE_ERROR, Flag.RETRY, Flag.DEVICE_SLOW):
            if rng.random() < 0.03:
                flags |= flag
        end = t + len(raw) * LINE.char_time
        row = add(raw, kind, int(flags), t, end)
        if odd and rng.random() < 0.03:
            store.notes[row] = "a note"
        if kind == Kind.REQUEST:
            waiting = row
            store.status[row] = rng.choice((Status.OK, Status.TIMEOUT, Status.OPEN))
        elif answering:
            if rng.random() < 0.93:
                store.partner[row], store.partner[waiting] = waiting, row
            status = Status.EXCEPTION if body[1] & 0x80 else Status.OK
            store.status[row] = store.status[waiting] = status
            waiting = -1
    store.sync()
    annotator = Annotator(BINDINGS)
    annotator.update(store)
    annotator.sunspec.units[44] = SunSpecUnit(44, 40000)
    return store, annotator


def packets(
    store: FrameStore,
    annotator: Annotator,
    style: str,
    fast: object,
    runs: Sequence[Iterable[int]],
    shared_size: int | None = None,
) -> bytes:
    """The export of each of `runs` in turn by one exporter (one table of templates)
    with the core `fast` (None: pure Python)."""
    out = io.BytesIO()
    size = {} if shared_size is None else {"shared_size": shared_size}
    with running(fast):  # type: ignore[arg-type]
        exporter = PcapExporter(out, Describer(store, annotator, **size), LINE, style=style)
        for rows in runs:
            exporter.write(rows)
    return out.getvalue()


def rows_orders(n: int) -> list[Iterable[int]]:
    return [range(n), reversed(range(n)), (i for i in range(0, n, 3)), [n - 1, 0, 0, n - 1]]


@compiled
@settings(max_examples=16, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), odd=st.booleans(), run=st.sampled_from((1, 7, 4096)))
def test_both_cores_export_the_same_bytes(seed: int, odd: bool, run: int) -> None:
    store, annotator = random_capture(seed, 600, odd)
    n = len(store)
    saved = export.EXPORT_RUN
    export.EXPORT_RUN = run  # rows a call of the compiled loop takes: its seams
    try:
        for style in STYLES:
            want = packets(store, annotator, style, None, rows_orders(n))
            assert packets(store, annotator, style, FAST, rows_orders(n)) == want
            # against an uncached Describer: every row described, nothing shared
            whole = [range(n)]
            plain = packets(store, annotator, style, None, whole, 0)
            assert packets(store, annotator, style, FAST, whole) == plain
    finally:
        export.EXPORT_RUN = saved


@compiled
def test_many_rows_share_templates_and_say_what_the_python_export_says() -> None:
    store, annotator = random_capture(11, 8_000, False)
    for style in STYLES:
        rows = [range(len(store))]
        assert packets(store, annotator, style, FAST, rows) == packets(
            store, annotator, style, None, rows, 0
        )


@compiled
def test_more_contents_than_the_table_keeps_export_as_in_python() -> None:
    """The compiled table of templates starts small (1,024 slots) and doubles as
    contents come: reads of a unit with a dictionary (whose packets share no template
    across addresses) at 3,000 addresses, each twice, take it through three doublings
    (its keys moved to their new slots, then found there) and export as the Python
    exporter writes them."""
    store = FrameStore()
    stream = store.stream(0)
    t = 1_700_000_000.0
    for address in [*range(3_000), *range(3_000)]:
        raw = with_crc(bytes([1, 3]) + address.to_bytes(2, "big") + b"\x00\x01")
        stream.extend(raw)
        store.add_row(0, len(stream) - len(raw), len(raw), t, t + 0.004, int(Kind.REQUEST), 0)
        t += 0.01
    store.sync()
    annotator = Annotator(BINDINGS)
    annotator.update(store)
    rows = [range(len(store))]
    for style in STYLES:
        assert packets(store, annotator, style, FAST, rows) == packets(
            store, annotator, style, None, rows, 0
        )


@compiled
def test_the_demo_exports_the_same_with_either_core() -> None:
    s = replay_file(DEMO_CAPTURE, bindings=BINDINGS)
    n = len(s.store)
    for style in STYLES:
        want = packets(s.store, s.annotator, style, None, rows_orders(n))
        assert packets(s.store, s.annotator, style, FAST, rows_orders(n)) == want


def test_the_listings_say_the_same_with_and_without_shared_contents() -> None:
    """Exceptions of units with no dictionary share a content (describe.py:
    `_explained`): the listings and the details say what an uncached Describer says."""
    store, annotator = random_capture(5, 2_000, True)
    cached = Describer(store, annotator, shared_size=64)
    plain = Describer(store, annotator, shared_size=0)
    for i in range(len(store)):
        assert cached.detail(i) == plain.detail(i), i
    for fmt in FORMATS:
        said = []
        for d in (cached, plain):
            out = io.StringIO()
            Lister(out, fmt, d).write(range(len(store)))
            said.append(out.getvalue())
        assert said[0] == said[1]
    exceptions = [
        i
        for i in range(len(store))
        if store.kind[i] == Kind.EXCEPTION
        and store.partner[i] != NO_PARTNER
        and store.unit[i] in (7, 9)
        and i not in store.notes
    ]
    fresh = Describer(store, annotator)  # fewer lookups than the guard's window
    assert exceptions and all(fresh.shared(i) is not None for i in exceptions[:100])


@compiled
def test_a_row_number_the_store_does_not_hold_fails_as_in_python() -> None:
    store, annotator = random_capture(3, 50, False)
    for fast in (None, FAST):
        with pytest.raises(IndexError):
            packets(store, annotator, "modbus-tcp", fast, [[0, len(store) + 5]])


def _rtu(*parts: int | bytes) -> bytes:
    """A body (unit, code, ...) from bytes and single byte values."""
    return b"".join(p if isinstance(p, bytes) else bytes([p]) for p in parts)


ALIKE_BUT_NOT_THE_SAME = [
    # FC 1: the padding bits after the quantity clear, then set; another quantity
    (_rtu(7, 1, b"\x00\x10\x00\x01"), _rtu(7, 1, 1, 0x01)),
    (_rtu(7, 1, b"\x00\x20\x00\x01"), _rtu(7, 1, 1, 0x03)),
    (_rtu(7, 1, b"\x00\x20\x00\x07"), _rtu(7, 1, 1, 0x03)),
    (_rtu(9, 1, b"\x00\x20\x00\x07"), _rtu(9, 1, 1, 0x43)),
    # FC 5: ON, then a value that is neither ON nor OFF, elsewhere
    (_rtu(7, 5, b"\x00\x01\xff\x00"), _rtu(7, 5, b"\x00\x01\xff\x00")),
    (_rtu(7, 5, b"\x00\x02\x12\x34"), _rtu(7, 5, b"\x00\x02\x12\x34")),
    # FC 6: an echo, then one that differs; unit 0 (no answer)
    (_rtu(7, 6, b"\x00\x01\x00\x05"), _rtu(7, 6, b"\x00\x01\x00\x05")),
    (_rtu(7, 6, b"\x00\x01\x00\x06"), _rtu(7, 6, b"\x00\x01\x00\x07")),
    (_rtu(0, 6, b"\x00\x01\x00\x06"), None),
    (_rtu(9, 6, b"\x00\x01\x00\x08"), _rtu(9, 6, b"\x00\x01\x00\x08")),
    # FC 15: padding clear, then set; a byte count that is not the bytes that follow
    (_rtu(7, 15, b"\x00\x00\x00\x03\x01\x05"), _rtu(7, 15, b"\x00\x00\x00\x03")),
    (_rtu(7, 15, b"\x00\x08\x00\x03\x01\x0d"), _rtu(7, 15, b"\x00\x08\x00\x03")),
    (_rtu(7, 15, b"\x00\x00\x00\x07\x01\x72\x00"), _rtu(7, 15, b"\x00\x00\x00\x07")),
    (_rtu(7, 15, b"\x00\x00\x00\x07\x01\x72\x80"), _rtu(7, 15, b"\x00\x00\x00\x08")),
    # FC 15: a byte count that is the bytes that follow, not what the quantity needs
    (_rtu(7, 15, b"\x00\x00\x00\x07\x02\x72\x00"), None),
    (_rtu(7, 15, b"\x00\x00\x00\x07\x02\xf2\x00"), None),
    # FC 16: well formed, then a byte count the quantity does not need; an echo that
    # names another address
    (_rtu(7, 16, b"\x00\x00\x00\x01\x02\x00\x01"), _rtu(7, 16, b"\x00\x00\x00\x01")),
    (_rtu(7, 16, b"\x00\x05\x00\x01\x02\x00\x02"), _rtu(7, 16, b"\x00\x06\x00\x01")),
    (_rtu(7, 16, b"\x00\x05\x00\x02\x02\x00\x02"), _rtu(7, 16, b"\x00\x05\x00\x02")),
    # exceptions: to a request, then one that does not pair with its request
    (_rtu(7, 3, b"\x00\x00\x00\x01"), _rtu(7, 0x83, 2)),
    (_rtu(7, 4, b"\x00\x00\x00\x01"), _rtu(7, 0x83, 2)),
    (_rtu(9, 3, b"\x00\x00\x00\x01"), _rtu(9, 0x83, 2)),
    # FC 3: the words the quantity needs, then a byte count that is odd
    (_rtu(7, 3, b"\x00\x00\x00\x01"), _rtu(7, 3, 2, b"\x00\x01")),
    (_rtu(7, 3, b"\x00\x00\x00\x01"), _rtu(7, 3, 2, b"\x00\x02")),
    (_rtu(7, 3, b"\x00\x00\x00\x01"), _rtu(7, 3, 1, b"\x00")),
]


@compiled
def test_rows_whose_packets_look_alike_but_say_other_problems() -> None:
    """Each pair of rows here shares all but a byte or two with a row before it, and
    says another problem (or none): neither core lets them share a packet."""
    exchanges = [
        (with_crc(q), None if a is None else with_crc(a), 0.01) for q, a in ALIKE_BUT_NOT_THE_SAME
    ]
    s = session(exchanges * 2, bound=False)
    n = len(s.store)
    for style in STYLES:
        want = packets(s.store, s.annotator, style, None, [range(n)], 0)
        assert packets(s.store, s.annotator, style, FAST, [range(n)]) == want
    said = [p for i in range(n) for p in s.describer.detail(i).problem_texts]
    for text in ("padding bits", "coil value", "echo of", "byte count", "is odd"):
        assert any(text in p for p in said), text
