"""The content cache of the Describer (`Describer.shared`) and the listing and export
fast paths built on it say exactly what an uncached Describer says, row by row: rows
with the same bytes whose details differ (another request answered, another window
parameter selected, a slow answer, a SunSpec unit, an exception its request explains,
another unit's dictionary, a note) are told apart."""

from __future__ import annotations

import io
import struct

from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.framing.store import FrameStore
from sniffer.meaning.describe import Describer
from sniffer.model import Chunk
from sniffer.outputs.export import PcapExporter
from sniffer.outputs.listing import FORMATS, Lister
from sniffer.session.session import DEMO_CAPTURE, Session, replay_file
from tests.support.describe import BINDINGS, LINE, T0, session
from tests.support.sunspec import device_image, discovery, frames_of, session_of


def read(unit: int, fc: int, address: int, count: int) -> bytes:
    return with_crc(struct.pack(">BBHH", unit, fc, address, count))


def answer(unit: int, fc: int, words: list[int]) -> bytes:
    data = b"".join(w.to_bytes(2, "big") for w in words)
    return with_crc(bytes([unit, fc, len(data)]) + data)


def write1(unit: int, address: int, value: int) -> bytes:
    return with_crc(struct.pack(">BBHH", unit, 6, address, value))


def same_as_uncached(s: Session, shared_size: int = 16) -> Describer:
    """Check every row's details, listing lines and packets with a content cache of
    `shared_size` against an uncached Describer's; returns the cached Describer."""
    store = s.store
    cached = Describer(store, s.annotator, shared_size=shared_size)
    plain = Describer(store, s.annotator, shared_size=0)
    rows = range(len(store))
    for i in rows:
        assert cached.detail(i) == plain.detail(i), i
    for fmt in FORMATS:
        for absolute in (False, True):
            assert _listing(store, cached, fmt, absolute) == _listing(store, plain, fmt, absolute)
    for style in ("modbus-tcp", "rtu"):
        assert _packets(s, cached, style) == _packets(s, plain, style)
    return cached


def _listing(store: FrameStore, describer: Describer, fmt: str, absolute: bool) -> str:
    out = io.StringIO()
    # a fresh Describer each time, so the fast paths meet contents both new and known
    fresh = Describer(store, describer.annotator, shared_size=describer.shared_size)
    Lister(out, fmt, fresh, absolute=absolute).write(range(len(store)), flush=False)
    Lister(out, fmt, describer, absolute=absolute).write(range(len(store)))
    return out.getvalue()


def _packets(s: Session, describer: Describer, style: str) -> bytes:
    out = io.BytesIO()
    fresh = Describer(s.store, describer.annotator, shared_size=describer.shared_size)
    PcapExporter(out, fresh, s.line, style=style).write(range(len(s.store)))
    exporter = PcapExporter(out, describer, s.line, style=style)
    exporter.write(range(len(s.store)))
    exporter.write(reversed(range(len(s.store))))
    return out.getvalue()


def shares(describer: Describer, rows: list[int]) -> bool:
    return all(describer.shared(i) is not None for i in rows)


def test_the_demo_says_the_same_with_and_without_the_cache() -> None:
    s = replay_file(DEMO_CAPTURE, bindings=BINDINGS)
    cached = same_as_uncached(s, shared_size=64)
    found = sum(cached.shared(i) is not None for i in range(len(s.store)))
    assert found > len(s.store) // 2  # most rows are cacheable, so the cache was used


def test_one_answer_to_two_requests() -> None:
    reply = answer(9, 3, [1, 2])
    s = session([(read(9, 3, 100, 2), reply, 0.01), (read(9, 3, 200, 2), reply, 0.01)])
    d = same_as_uncached(s)
    assert d.detail(1).dissection != d.detail(3).dissection  # registers 100- and 200-
    assert d.shared(1) is not d.shared(3)


def test_a_window_parameter_selected_between_two_same_reads() -> None:
    value = (read(2, 4, 0x5003, 2), answer(2, 4, [0, 250]), 0.01)
    select = [(write1(2, 0x5001, n), write1(2, 0x5001, n), 0.01) for n in (1, 30)]
    s = session([select[0], value, select[1], value])
    d = same_as_uncached(s)
    first, second = d.detail(3), d.detail(7)
    assert s.store.raw(3) == s.store.raw(7)
    assert "P.01" in first.summary and "P.30" in second.summary
    assert shares(d, [3, 7]) and d.shared(3) is not d.shared(7)


def test_a_slow_answer_with_the_bytes_of_a_prompt_one() -> None:
    ask, reply = read(3, 3, 0, 2), answer(3, 3, [5, 6])
    s = session([(ask, reply, 0.01), (ask, reply, 0.1), (ask, reply, 0.01)])
    d = same_as_uncached(s)
    slow = [p for p in d.detail(3).problem_texts if "normally answers within" in p]
    assert slow and not any("normally" in p for p in d.detail(1).problem_texts)
    assert d.shared(1) is d.shared(3) is d.shared(5)  # the slow part is per row


def test_an_exception_explained_by_one_request_and_not_by_the_other() -> None:
    refused = with_crc(bytes([3, 0x86, 3]))
    s = session([(write1(3, 0x0D, 700), refused, 0.01), (write1(3, 0x0D, 500), refused, 0.01)])
    d = same_as_uncached(s)
    assert "explained by the request" in d.detail(1).summary
    assert "explained by the request" not in d.detail(3).summary


def test_an_exception_to_the_same_write_through_a_window_that_selected_another_parameter() -> None:
    # P.49 (node address) is documented 1-255, P.30 has no range: 300 is out of range
    # only for the first, which explains the refusal
    write = with_crc(struct.pack(">BBHHBH", 2, 16, 0x5003, 1, 2, 300))
    refused = with_crc(bytes([2, 0x90, 3]))
    select = [(write1(2, 0x5001, n), write1(2, 0x5001, n), 0.01) for n in (49, 30)]
    s = session([select[0], (write, refused, 0.01), select[1], (write, refused, 0.01)])
    d = same_as_uncached(s)
    assert s.store.raw(3) == s.store.raw(7)
    assert "explained by the request" in d.detail(3).summary
    assert "explained by the request" not in d.detail(7).summary


def test_the_same_request_answered_and_not() -> None:
    ask, other = read(9, 3, 0, 1), read(9, 3, 5, 1)
    s = session([(ask, answer(9, 3, [7]), 0.01), (ask, None, 0.0), (other, None, 0.0)])
    d = same_as_uncached(s)
    assert s.store.flags[0] == s.store.flags[2]
    assert d.detail(0).problems != d.detail(2).problems  # the second timed out


def test_the_same_frame_on_units_with_other_dictionaries() -> None:
    exchanges = [(read(u, 3, 0, 2), answer(u, 3, [0x41, 0x42]), 0.01) for u in (1, 2, 3, 9)]
    s = session(exchanges * 2)
    d = same_as_uncached(s)
    assert len({(d.detail(k).summary, d.detail(k).label) for k in (1, 3, 5, 7)}) == 4
    assert d.shared(1) is d.shared(9)


def test_a_sunspec_unit_is_described_row_by_row() -> None:
    reg = device_image()
    polls = [(40072, 50), (40124, 53)] * 3
    s = session_of(frames_of(reg, [*discovery(reg, 40000), *polls]))
    d = same_as_uncached(s)
    store = s.store
    assert store.unit[len(store) - 1] in s.annotator.sunspec.units
    assert d.shared(len(store) - 1) is None


def test_rows_with_notes_and_status_changes() -> None:
    ask, reply = read(9, 3, 0, 1), answer(9, 3, [7])
    s = session([(ask, reply, 0.01), (ask, None, 0.0), (ask, reply, 0.01)])
    s.store.notes[2] = "a note on a frame"
    d = same_as_uncached(s)
    assert d.shared(2) is None
    assert d.shared(0) is not d.shared(3)  # the same bytes, but row 3 is a retry
    assert d.shared(1) is d.shared(4)
    assert d.detail(0).status != d.detail(2).status  # answered, then timed out


def test_the_cache_stops_when_it_does_not_pay() -> None:
    exchanges = [(read(9, 3, k, 1), answer(9, 3, [k]), 0.01) for k in range(3000)]
    s = session(exchanges, bound=False)
    d = Describer(s.store, s.annotator)
    found = [d.shared(i) for i in range(len(s.store))]
    assert found[0] is not None
    assert found[-1] is None  # paused: every row new
    plain = Describer(s.store, s.annotator, shared_size=0)
    assert all(d.detail(i) == plain.detail(i) for i in range(0, len(s.store), 97))


REQUESTS = [
    read(1, 3, 0, 2),
    read(2, 4, 0x5003, 2),
    write1(2, 0x5001, 1),
    write1(2, 0x5001, 30),
    read(3, 3, 0, 2),
    write1(3, 0x0D, 700),
    write1(3, 0x0D, 500),
    read(9, 3, 100, 2),
    read(9, 3, 200, 2),
    read(9, 4, 200, 2),
    read(9, 4, 200, 0),
    read(0, 3, 7, 1),
]


def _reply(request: bytes, kind: int, words: list[int]) -> bytes | None:
    unit, fc = request[0], request[1]
    if kind == 0:
        return None
    if kind == 1:
        return with_crc(bytes([unit, fc | 0x80, 3]))
    if fc == 6:
        return request
    return answer(unit, fc, words)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from(REQUESTS),
            st.sampled_from([0, 1, 2, 2, 2, 2]),  # silent, exception, answer
            st.one_of(
                st.sampled_from([[0, 250], [1, 2], [0x41, 0x42]]),
                st.lists(st.integers(0, 0xFFFF), max_size=3),  # other values, other counts
            ),
            st.sampled_from([0.005, 0.01, 0.15]),
            st.booleans(),  # a bit flipped in the answer
            st.binary(max_size=3),  # noise before the request
        ),
        max_size=40,
    )
)
def test_random_polling_says_the_same_with_and_without_the_cache(
    polls: list[tuple[bytes, int, list[int], float, bool, bytes]],
) -> None:
    s = Session(LINE, bindings=BINDINGS)
    t = T0
    for request, kind, words, delay, flip, noise in polls:
        t += 0.3
        if noise:
            s.feed(Chunk(noise, t - 0.1))
        end = t + len(request) * LINE.char_time
        s.feed(Chunk(request, end))
        reply = _reply(request, kind, words)
        if reply is not None:
            if flip:
                reply = bytes([reply[0], reply[1] ^ 0x10, *reply[2:]])
            s.feed(Chunk(reply, end + delay + len(reply) * LINE.char_time))
    s.finish()
    same_as_uncached(s, shared_size=4)


def test_answers_that_differ_only_in_their_values_share_a_text_line() -> None:
    """The text listing gives answers to the same read of a unit without dictionary
    that differ only in their values one content (`contents(values=False)`); the lines
    are those of an uncached Describer. Not so for a bound unit, a bad CRC, another
    byte count, or a consumer that reads values."""
    ask, other = read(9, 3, 100, 2), read(9, 4, 100, 2)

    def bad(words: list[int]) -> bytes:
        spoilt = bytearray(answer(9, 3, words))
        spoilt[-1] ^= 1
        return bytes(spoilt)

    exchanges = [
        (ask, answer(9, 3, [1, 2]), 0.01),
        (ask, answer(9, 3, [3, 4]), 0.02),
        (ask, bad([5, 6]), 0.01),
        (ask, answer(9, 3, [7]), 0.01),
        (other, answer(9, 4, [1, 2]), 0.01),
        (other, answer(9, 4, [8, 9]), 0.01),
        (read(3, 3, 0, 2), answer(3, 3, [1, 2]), 0.01),
        (read(3, 3, 0, 2), answer(3, 3, [3, 4]), 0.01),
        (ask, bad([7, 8]), 0.01),  # its CRC's sentence is not the other's
    ]
    s = session(exchanges)
    same_as_uncached(s, shared_size=64)
    d = Describer(s.store, s.annotator)
    free = dict(d.contents(range(len(s.store)), values=False))
    assert free[1] is free[3] and free[9] is free[11]
    assert free[5] is not free[1] and free[7] is not free[1]  # bad CRC, one value
    assert free[5] is not free[17]
    assert free[13] is not free[15]  # unit 3 has a dictionary: its values are named
    every = dict(Describer(s.store, s.annotator).contents(range(len(s.store))))
    assert every[1] is not every[3] and every[1] is not None


def write_many(unit: int, fc: int, address: int, quantity: int, data: bytes) -> bytes:
    head = struct.pack(">BBHHB", unit, fc, address, quantity, len(data))
    return with_crc(head + data)


def written(unit: int, fc: int, address: int, quantity: int) -> bytes:
    return with_crc(struct.pack(">BBHH", unit, fc, address, quantity))


def test_answers_to_writes_of_other_values_share_a_content() -> None:
    """The answers to FC 15 and 16 writes of a unit without dictionary that differ only
    in the values written share one content for consumers that read no value (the
    listings, the Modbus/TCP export): fresh values in every write no longer make every
    answer a content to describe. The lines and packets are an uncached Describer's.
    Not shared: an FC 15 write whose padding bits differ (a problem of the write), a
    write whose byte count is not its quantity's, another quantity."""
    ok16 = written(9, 16, 100, 2)
    ok15 = written(9, 15, 10, 3)
    exchanges = [
        (write_many(9, 16, 100, 2, b"\x00\x01\x00\x02"), ok16, 0.01),
        (write_many(9, 16, 100, 2, b"\x12\x34\x56\x78"), ok16, 0.01),
        (write_many(9, 15, 10, 3, b"\x05"), ok15, 0.01),
        (write_many(9, 15, 10, 3, b"\x02"), ok15, 0.01),
        (write_many(9, 15, 10, 3, b"\xf2"), ok15, 0.01),  # padding bits set
        (write_many(9, 16, 100, 2, b"\x00\x01\x00\x02\x00\x03"), ok16, 0.01),  # count
        (write_many(9, 16, 100, 1, b"\x00\x01"), written(9, 16, 100, 1), 0.01),
        (write_many(9, 16, 100, 1, b"\x00\x07"), written(9, 16, 100, 1), 0.01),
    ]
    s = session(exchanges, bound=False)
    same_as_uncached(s, shared_size=64)
    d = Describer(s.store, s.annotator)
    free = dict(d.contents(range(len(s.store)), values=False))
    assert free[1] is free[3]  # FC 16, other values
    assert free[5] is free[7]  # FC 15, other values
    assert free[9] is not free[5]  # FC 15 with its padding bits set
    assert free[11] is not free[1]  # a byte count that is not the quantity's
    assert free[13] is free[15] and free[13] is not free[1]
    every = dict(Describer(s.store, s.annotator).contents(range(len(s.store))))
    assert every[1] is not every[3]  # a consumer of values gets the row's own content


def bits(unit: int, fc: int, data: bytes) -> bytes:
    return with_crc(bytes([unit, fc, len(data)]) + data)


def test_answers_to_bit_reads_of_other_values_share_a_content() -> None:
    """As answers to FC 3/4 reads: the answers to an FC 1 or 2 read of a unit without
    dictionary that differ only in their values share one content for the listings and
    the Modbus/TCP export, and their lines and packets are an uncached Describer's.
    Not shared: an answer whose padding bits are set (a problem), another byte count."""
    coils, inputs = read(9, 1, 10, 11), read(9, 2, 10, 8)
    exchanges = [
        (coils, bits(9, 1, b"\x05\x03"), 0.01),
        (coils, bits(9, 1, b"\xff\x01"), 0.01),
        (coils, bits(9, 1, b"\x05\x83"), 0.01),  # padding bits set
        (coils, bits(9, 1, b"\x05"), 0.01),  # too few bytes
        (inputs, bits(9, 2, b"\x01"), 0.01),
        (inputs, bits(9, 2, b"\xfe"), 0.01),
    ]
    s = session(exchanges, bound=False)
    same_as_uncached(s, shared_size=64)
    d = Describer(s.store, s.annotator)
    free = dict(d.contents(range(len(s.store)), values=False))
    assert free[1] is free[3]
    assert free[5] is not free[1] and free[7] is not free[1]
    assert free[9] is free[11] and free[9] is not free[1]
    every = dict(Describer(s.store, s.annotator).contents(range(len(s.store))))
    assert every[1] is not every[3]
