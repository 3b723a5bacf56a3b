"""FC 5 and 6 writes of other values share a content in the listings
(`Describer.contents(values=False, writes=True)`, `_single_write`), their own value
spliced into the text and JSONL lines kept for it (`_text_spliced`, `_single_spliced`):
every line, and every CSV record and exported packet, is the one an uncached Describer
gives, on random traffic of fresh values, values equal to the address, coil values that
are neither ON nor OFF, echoes that differ, exceptions, timeouts, bad checks, frames of
the wrong length, bound and unbound units."""

from __future__ import annotations

import io
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.framing.store import FrameView
from sniffer.meaning.describe import Describer, FrameDetail, Shared
from sniffer.outputs import listing
from sniffer.outputs.listing import Lister, _json_parts, _single_spliced, _text_spliced
from sniffer.session.session import Session
from tests.meaning.test_describe_shared import same_as_uncached
from tests.support.describe import session

Exchange = tuple[bytes, bytes | None, float]

UNITS = st.sampled_from([0, 1, 2, 3, 9, 9, 9, 200])  # 1-3 have dictionaries when bound
ADDRESSES = st.sampled_from([0, 10, 0x64, 0xFF00, 0x1234])


def single(unit: int, fc: int, address: int, value: int) -> bytes:
    return with_crc(struct.pack(">BBHH", unit, fc, address, value))


@st.composite
def writes(draw: st.DrawFn) -> Exchange:
    unit = draw(UNITS)
    fc = draw(st.sampled_from([5, 6, 6]))
    address = draw(ADDRESSES)
    if fc == 5:
        value = draw(st.sampled_from([0xFF00, 0x0000, 0xFF00, 0x0000, 0x00FF, 0x1234]))
    else:  # fresh values, and values the address says too (`write 0x0064 to ... 0x0064`)
        value = draw(st.integers(0, 0xFFFF) | st.sampled_from([address, 0, 0xFFFF, 0xFF00]))
    request = single(unit, fc, address, value)
    shape = draw(st.integers(0, 19))
    if shape == 0:  # a frame one byte long or short
        request = with_crc(request[:-2] + b"\x00") if draw(st.booleans()) else request[:-3]
    elif shape == 1:
        request = request[:-1] + bytes([request[-1] ^ 0x01])  # a bad check
    outcome = draw(st.integers(0, 19))
    delay = draw(st.sampled_from([0.002, 0.01, 0.02, 0.5]))
    if outcome == 0:
        return request, None, delay  # a timeout
    if outcome == 1:
        code = draw(st.sampled_from([1, 2, 3, 4]))
        return request, with_crc(bytes([unit, fc | 0x80, code])), delay
    if outcome == 2:  # an echo of another value or address
        other = single(unit, fc, address ^ draw(st.sampled_from([0, 1])), value ^ 1)
        return request, other, delay
    if outcome == 3:
        return request, request[:-1] + bytes([request[-1] ^ 0x80]), delay  # bad check
    return request, request, delay


def listing_of(s: Session, describer: Describer, fmt: str, absolute: bool = False) -> str:
    out = io.StringIO()
    Lister(out, fmt, describer, absolute=absolute).write(range(len(s.store)), flush=False)
    return out.getvalue()


def same_lines(s: Session) -> None:
    """Text, JSONL and CSV through a small and a large content cache are the reference
    path's (every row described alone by an uncached Describer), line for line."""
    for fmt in ("text", "jsonl", "csv"):
        want = listing_of(s, Describer(s.store, s.annotator, shared_size=0), fmt).splitlines()
        for size in (4, 64):
            made = listing_of(s, Describer(s.store, s.annotator, shared_size=size), fmt)
            for n, (a, b) in enumerate(zip(made.splitlines(), want, strict=True)):
                assert a == b, (fmt, size, n)


@settings(max_examples=150, deadline=None)
@given(st.lists(writes(), min_size=1, max_size=40), st.booleans())
def test_single_writes_of_any_value_list_as_the_reference_lists_them(
    traffic: list[Exchange], bound: bool
) -> None:
    same_lines(session(traffic, bound=bound))


@settings(max_examples=25, deadline=None)
@given(st.lists(writes(), min_size=1, max_size=20))
def test_single_writes_say_the_same_with_and_without_the_cache(traffic: list[Exchange]) -> None:
    """Details, every listing (relative and absolute times) and both export styles."""
    same_as_uncached(session(traffic, bound=False), shared_size=4)


def contents(s: Session, writes: bool = True) -> dict[int, Shared | None]:
    rows = range(len(s.store))
    return dict(Describer(s.store, s.annotator).contents(rows, values=False, writes=writes))


def test_writes_of_other_values_share_a_content() -> None:
    """Well-formed FC 5 and 6 writes and their echoes of a unit without dictionary share
    one content across values; not a coil value that is neither ON nor OFF, an echo
    that differs from its request, another address, a bound unit's writes, nor for a
    consumer that does not splice the value in (the export)."""
    traffic: list[Exchange] = [
        (single(9, 6, 0x64, 0x1234), single(9, 6, 0x64, 0x1234), 0.01),
        (single(9, 6, 0x64, 0x0064), single(9, 6, 0x64, 0x0064), 0.01),  # value = address
        (single(9, 5, 10, 0xFF00), single(9, 5, 10, 0xFF00), 0.01),
        (single(9, 5, 10, 0x0000), single(9, 5, 10, 0x0000), 0.01),
        (single(9, 5, 10, 0x1234), single(9, 5, 10, 0x1234), 0.01),  # neither ON nor OFF
        (single(9, 6, 0x64, 7), single(9, 6, 0x64, 8), 0.01),  # the echo differs
        (single(9, 6, 0x65, 7), single(9, 6, 0x65, 7), 0.01),  # another address
        (single(1, 6, 0x64, 1), single(1, 6, 0x64, 1), 0.01),  # unit 1 has a dictionary
        (single(1, 6, 0x64, 2), single(1, 6, 0x64, 2), 0.01),
    ]
    s = session(traffic, bound=True)
    same_lines(s)
    free = contents(s)
    assert free[0] is free[2] and free[1] is free[3]  # FC 6 requests, echoes
    assert free[0] is not free[1]
    assert free[4] is free[6] and free[5] is free[7]  # FC 5: ON and OFF
    assert free[8] is not free[4] and free[9] is not free[5]
    assert free[10] is free[0] and free[11] is not free[1]
    assert free[12] is not free[0] and free[13] is not free[1]
    assert free[14] is not free[16] and free[15] is not free[17]
    answers = contents(s, writes=False)
    assert answers[0] is not answers[2] and answers[1] is not answers[3]
    text = listing_of(s, Describer(s.store, s.annotator), "text").splitlines()
    assert text[2].endswith("write 0x0064 to register 0x0064")
    assert text[6].endswith("coil 0x000A OFF")


def test_a_value_the_template_cannot_take_lists_the_row_alone(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Where the kept text or JSONL parts do not say the value as the splice expects
    (here: neither splice made), rows of other values are listed on their own."""
    traffic: list[Exchange] = [
        (single(9, 6, 0x64, v), single(9, 6, 0x64, v), 0.01) for v in (1, 2, 0x64, 0xBEEF)
    ]
    traffic += [(single(9, 5, 3, v), single(9, 5, 3, v), 0.01) for v in (0xFF00, 0, 0xFF00)]
    s = session(traffic, bound=False)
    monkeypatch.setattr(listing, "_text_spliced", lambda tail, shared: ())
    monkeypatch.setattr(listing, "_single_spliced", lambda first, second, d: None)
    same_lines(s)


def _parts(s: Session, i: int) -> tuple[str, str, str, Shared]:
    """Row `i`'s JSONL parts and text tail, and its own content."""
    d = Describer(s.store, s.annotator, shared_size=0).detail(i)
    first, second, _ = _json_parts(d)
    _, tail = listing._text_parts(d)
    shared = Shared(d.name, d.summary, d.dissection, (), d.problems, "", raw=d.view.raw)
    return first, second, tail, shared


def test_the_splices_are_checked_against_the_parts() -> None:
    """`_text_spliced` and `_single_spliced` give a splice only where making the parts
    again from it gives them: not for parts that do not say the value where expected."""
    s = session([(single(9, 6, 0x64, 0x1234), None, 0.0)], bound=False)
    first, second, tail, shared = _parts(s, 0)
    view: FrameView = s.store.view(0)
    d = Describer(s.store, s.annotator, shared_size=0).detail(0)
    assert tail.startswith("  write 0x1234 to register 0x0064")
    assert _text_spliced(tail, shared) == ("  write ", tail[len("  write 0x1234") :])
    assert _single_spliced(first, second, d) is not None
    other = Shared(d.name, "write to register", d.dissection, (), d.problems, "", raw=view.raw)
    assert _text_spliced(tail, other) == ()  # the summary says no value
    assert _single_spliced(first, second.replace("4660", "4661"), d) is None
    assert _single_spliced(first.replace(view.raw.hex(), "00"), second, d) is None
    coil = session([(single(9, 5, 3, 0x1234), None, 0.0)], bound=False)
    first, second, tail, shared = _parts(coil, 0)
    assert _text_spliced(tail, shared) == ()  # neither ON nor OFF
    assert _single_spliced(first, second, Describer(coil.store, coil.annotator).detail(0)) is None


def test_writes_of_fresh_values_are_listed_from_one_content(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A setpoint written every cycle with a fresh value: the requests and the echoes
    are described once each, and every line is spliced from what they keep (no row
    listed on its own), in both listings."""
    values = [0x64, *range(0, 0xFFFF, 1361)]  # the first is the address's too
    traffic: list[Exchange] = [(single(9, 6, 0x64, v), single(9, 6, 0x64, v), 0.01) for v in values]
    traffic += [(single(9, 5, 7, v), single(9, 5, 7, v), 0.01) for v in (0, 0xFF00) * 5]
    s = session(traffic, bound=False)
    same_lines(s)
    described: list[int] = []
    alone: list[int] = []
    content, line = Describer._content, Lister._line

    def counted_content(self: Describer, view: FrameView, request: bytes | None = None) -> Shared:
        described.append(view.index)
        return content(self, view, request)

    def counted_line(self: Lister, d: FrameDetail, peer: str) -> str | None:
        alone.append(d.view.index)
        return line(self, d, peer)

    monkeypatch.setattr(Describer, "_content", counted_content)
    monkeypatch.setattr(Lister, "_line", counted_line)
    for fmt in ("text", "jsonl"):
        described.clear()
        listing_of(s, Describer(s.store, s.annotator), fmt)
        assert described == [0, 1, 2 * len(values), 2 * len(values) + 1], fmt
        assert alone == [], fmt
