"""Fuzz: the dissector over every function code, both roles, with and without the
request it answers; bodies random or cut from real frames."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from dissectors.pdu.dissect import dissect
from dissectors.values import Role
from sniffer.sources.synth import polling_frames
from tests.fuzz.harness import budget, mutated, no_hang

pytestmark = [pytest.mark.fuzz, pytest.mark.slow]

# PDU bodies (unit, function, data; no CRC) of real polls
BODIES = [f.raw[:-2] for f in polling_frames(60, seed=5)]


@budget(2500)
@given(
    st.integers(0, 255),
    st.one_of(st.binary(max_size=300), mutated(BODIES)),
    st.sampled_from(list(Role)),
    st.one_of(st.none(), st.binary(max_size=260), mutated(BODIES)),
)
def test_dissect_never_raises_and_spans_stay_inside(
    fc: int, rest: bytes, role: Role, request: bytes | None
) -> None:
    body = bytes([rest[0] if rest else 1, fc]) + rest[2:]
    if request is not None and len(request) >= 2:
        request = request[:1] + bytes([fc & 0x7F]) + request[2:]
    with no_hang():
        found = dissect(body, role, request=request)
    for field in found.fields:
        start, end = field.span
        assert 0 <= start <= end <= len(body), (field.name, field.span, len(body))
        assert isinstance(field.text, str)
    for problem in found.problems:
        if problem.span is not None:
            assert 0 <= problem.span[0] <= problem.span[1] <= len(body)
