"""The shortcut dissect() takes for well-formed answers to FC 3 and 4 reads gives exactly
what the schemas and meaning routines give, on any bytes: well-formed answers, answers
off by a byte, a count or a code, broadcasts, requests of every shape."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import dissectors.pdu.dissect as pdu
from dissectors.dissect import Dissection, Role, dissect
from dissectors.pdu.registry import PUBLIC


def _full(body: bytes, role: Role, request: bytes | None) -> Dissection:
    """The dissection without the shortcut."""
    shortcut = pdu._words_answer
    pdu._words_answer = lambda *args: None
    try:
        return dissect(body, role, request=request)
    finally:
        pdu._words_answer = shortcut


def _shown(d: Dissection) -> tuple[Any, ...]:
    """Everything a view reads of a dissection, lazy field texts and children included."""
    fields = tuple((type(f), f.name, f.value, f.text, f.span, f.children) for f in d.fields)
    return (d, fields, tuple(map(type, d.fields)), tuple(type(x.values) for x in d.data))


def _same(body: bytes, request: bytes | None) -> None:
    fast = dissect(body, Role.RESPONSE, request=request)
    assert _shown(fast) == _shown(_full(body, Role.RESPONSE, request))


@st.composite
def read_pairs(draw: st.DrawFn) -> tuple[bytes, bytes]:
    """A read request and its answer, well-formed or spoilt in one way or another."""
    unit = draw(st.sampled_from((1, 17, 247, 255, 0)))
    code = draw(st.sampled_from((3, 4, 3, 4, 1, 2, 23, 0x83)))
    address = draw(st.integers(0, 0xFFFF))
    quantity = draw(st.one_of(st.integers(0, 130), st.sampled_from((0x100, 0x8001, 0xFFFF))))
    request = bytes((unit, code, address >> 8, address & 0xFF, quantity >> 8, quantity & 0xFF))
    count = 2 * quantity if draw(st.booleans()) else draw(st.integers(0, 255))
    data = draw(st.binary(min_size=min(count, 254), max_size=min(count, 254)))
    answer = bytes((unit, code, count & 0xFF)) + data
    spoil = draw(st.sampled_from(("none", "none", "cut", "extra", "unit", "code", "request")))
    if spoil == "cut":
        answer = answer[: draw(st.integers(0, len(answer)))]
    elif spoil == "extra":
        answer += draw(st.binary(min_size=1, max_size=3))
    elif spoil == "unit":
        answer = bytes((draw(st.integers(0, 255)),)) + answer[1:]
    elif spoil == "code":
        answer = answer[:1] + bytes((draw(st.integers(0, 255)),)) + answer[2:]
    elif spoil == "request":
        request = request[: draw(st.integers(0, 7))] + draw(st.binary(max_size=2))
    return request, answer


@settings(max_examples=1500, deadline=None)
@given(read_pairs())
def test_answers_to_reads(pair: tuple[bytes, bytes]) -> None:
    request, answer = pair
    _same(answer, request)


@settings(max_examples=500, deadline=None)
@given(st.binary(max_size=40), st.one_of(st.none(), st.binary(max_size=12)))
def test_any_bytes(answer: bytes, request: bytes | None) -> None:
    _same(answer, request)


@pytest.mark.parametrize("count", [1, 2, 10, 125, 127])
def test_the_shortcut_is_taken(count: int) -> None:
    """Well-formed answers do go the short way (else the tests above prove nothing)."""
    request = bytes((17, 3, 0x10, 0, 0, count))
    answer = bytes((17, 3, 2 * count)) + bytes(range(2 * count % 256)) * 2
    answer = answer[: 3 + 2 * count]
    plan = pdu.plans(PUBLIC)[1][3]
    assert plan.words_answer
    made = pdu._words_answer(answer, len(answer), Role.RESPONSE, plan, request)
    assert made is not None
    assert _shown(made) == _shown(_full(answer, Role.RESPONSE, request))
    assert made.summary == ("1 value" if count == 1 else f"{count} values")
    assert made.data[0].address == 0x1000 and len(made.data[0].values) == count


def test_vendor_registry_plans() -> None:
    """Only the public read answers' plans take the shortcut."""
    responses = pdu.plans(PUBLIC)[1]
    assert [code for code in range(256) if responses[code].words_answer] == [3, 4]
    assert not any(plan.words_answer for plan in pdu.plans(PUBLIC)[0])
