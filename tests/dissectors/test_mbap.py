"""Tests the MBAP envelope: header fields, and problems as values for bad headers."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from dissectors import mbap
from dissectors.dissect import dissect
from dissectors.values import Role

READ = bytes.fromhex("1234 0000 0006 11 03 006B 0003")  # tid 0x1234, unit 17, FC 3
ANSWER = bytes.fromhex("1234 0000 0009 11 03 06 022B 0000 0064")


def test_header_fields_and_body() -> None:
    head = mbap.parse(READ)
    assert (head.transaction, head.protocol, head.length, head.unit) == (0x1234, 0, 6, 0x11)
    assert head.problems == ()
    assert head.frame_length == len(READ)
    assert mbap.body(READ) == bytes.fromhex("11 03 006B 0003")


def test_body_goes_through_the_serial_dissector() -> None:
    d = dissect(mbap.body(ANSWER), Role.RESPONSE, request=mbap.body(READ))
    assert (d.unit, d.function, d.exception) == (0x11, 3, False)
    assert d.data[0].address == 0x6B
    assert d.data[0].values == (0x022B, 0x0000, 0x0064)


def test_protocol_id_not_zero() -> None:
    frame = READ[:2] + b"\x00\x01" + READ[4:]
    kinds = {p.kind: p for p in mbap.parse(frame).problems}
    assert set(kinds) == {"mbap-protocol"}
    assert kinds["mbap-protocol"].span == (2, 4)
    assert not mbap.plausible(frame)


def test_length_disagrees_with_bytes() -> None:
    longer = READ + b"\x00"
    problems = mbap.parse(longer).problems
    assert [p.kind for p in problems] == ["mbap-length"]
    assert "announces 12 bytes, the frame has 13" in problems[0].text
    shorter = READ[:-1]
    assert [p.kind for p in mbap.parse(shorter).problems] == ["mbap-length"]


def test_length_out_of_range() -> None:
    frame = READ[:4] + b"\x01\x00" + READ[6:]
    assert {p.kind for p in mbap.parse(frame).problems} == {"mbap-length-range", "mbap-length"}
    assert not mbap.plausible(frame)


def test_short_header() -> None:
    for cut in range(7):
        problems = mbap.parse(READ[:cut]).problems
        assert problems[0].kind == "mbap-short"
        assert problems[0].span == (0, cut)


def test_consistent_accepts_frames_back_to_back_and_a_split_tail() -> None:
    assert mbap.consistent(READ)
    assert mbap.consistent(READ + ANSWER)
    assert mbap.consistent(READ + ANSWER[:5])  # the next segment holds the rest
    assert mbap.consistent(READ + ANSWER[:9])
    assert not mbap.consistent(bytes.fromhex("01030000000AC5CD"))  # an RTU frame
    # ... though some RTU frames read as MBAP too (carrier detection counts neither)
    assert mbap.consistent(bytes.fromhex("010300000002C40B"))
    assert not mbap.consistent(b"")
    assert not mbap.consistent(ANSWER[:10])  # a lone first frame must be whole


@given(st.binary(max_size=300))
def test_parse_never_raises_and_flags_any_disagreement(data: bytes) -> None:
    head = mbap.parse(data)
    fine = (
        len(data) >= 7
        and head.protocol == 0
        and 2 <= head.length <= 254
        and len(data) == 6 + head.length
    )
    assert (head.problems == ()) == fine
