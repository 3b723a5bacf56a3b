"""The RTU and ASCII envelopes: unit, PDU, the check carried and the one expected, and
where each part lies, for the seed manuals' worked examples and for any bytes."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st

from dissectors.checks import ascii_frame, with_crc
from dissectors.envelope import Envelope, ascii_body, open_ascii, open_rtu, rtu_frame
from tests.support.seedvectors import frame_body, load_examples, wire_bytes

EXAMPLES = load_examples()


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda e: str(e["id"]))
def test_seed_examples_open_with_their_check(example: dict[str, object]) -> None:
    raw = wire_bytes(example)
    ascii_mode = example.get("mode") == "ascii"
    envelope: Envelope = open_ascii(raw) if ascii_mode else open_rtu(raw)
    assert envelope.transport == ("ascii" if ascii_mode else "rtu")
    assert envelope.body == frame_body(example)
    assert envelope.unit == example["unit"]
    assert envelope.pdu[0] & 0x7F == example["function"]  # exceptions carry 0x80
    assert envelope.check_ok == bool(example["check_ok"])
    expected = str(example["expected_check"]).replace(" ", "").upper()
    if example["check_ok"]:
        assert envelope.check_text == ""
    elif ascii_mode:
        assert envelope.check_text.endswith(f"expected 0x{expected}")
    else:
        assert f"expected {expected[:2]} {expected[2:]}" in envelope.check_text


def test_rtu_parts_and_wrong_crc() -> None:
    # FC 3 request from the Modbus over serial line guide: 11 03 006B 0003, CRC 76 87
    raw = bytes.fromhex("11 03 00 6B 00 03 76 87")
    good = open_rtu(raw)
    assert (good.unit, good.pdu, good.sent, good.expected) == (
        0x11,
        bytes.fromhex("03 00 6B 00 03"),
        0x8776,
        0x8776,
    )
    assert good.spans == (("unit", (0, 1)), ("pdu", (1, 6)), ("crc", (6, 8)))
    bad = open_rtu(raw[:-2] + b"\x00\x00")
    assert not bad.check_ok
    assert bad.check_text == "CRC 00 00 wrong, expected 76 87 (0x0000 vs 0x8776)"
    assert rtu_frame(good.body) == raw
    short = open_rtu(b"\x11\x03")
    assert (short.unit, short.body, short.check_ok) == (None, b"", False)
    assert short.check_text == "too short for a CRC"


def test_ascii_parts_lrc_and_non_hex() -> None:
    raw = b":0103006B0003" + b"8E" + b"\r\n"  # LRC of 01 03 00 6B 00 03 is 8E
    good = open_ascii(raw)
    assert good.check_ok and good.check_text == ""
    assert (good.unit, good.pdu, good.sent, good.expected) == (
        1,
        bytes.fromhex("03 00 6B 00 03"),
        0x8E,
        0x8E,
    )
    assert good.spans == (
        ("start", (0, 1)),
        ("unit", (1, 3)),
        ("pdu", (3, 13)),
        ("lrc", (13, 15)),
        ("end", (15, 17)),
    )
    bad = open_ascii(b":0103006B000389\r\n")
    assert bad.check_text == "LRC 0x89 wrong, expected 0x8E"
    not_hex = open_ascii(b":01XY\r\n")
    assert not not_hex.hex_ok and not not_hex.check_ok and not_hex.unit is None
    assert not_hex.check_text == "characters other than hex digits: no LRC to check"
    assert not_hex.spans == (("start", (0, 1)), ("text", (1, 5)), ("end", (5, 7)))
    lone = open_ascii(b":FF\n")
    assert lone.check_text == "too short for an LRC"
    no_function = open_ascii(b":01FF\r\n")  # unit 01 and its LRC FF, nothing else
    assert not no_function.check_ok
    assert no_function.check_text == "too short: no function code before the LRC"
    assert ascii_body(b":0103\n") == b"\x01\x03"


@given(st.binary(min_size=0, max_size=40))
def test_rtu_envelope_of_any_bytes(data: bytes) -> None:
    envelope = open_rtu(data)
    assert envelope.check_ok == (len(data) >= 3 and with_crc(data[:-2]) == data)
    spans = [span for _, span in envelope.spans]
    assert spans[0][0] == 0 and spans[-1][1] == len(data)
    assert all(a[1] == b[0] for a, b in itertools.pairwise(spans))
    if envelope.unit is not None:
        assert rtu_frame(envelope.body)[:-2] == data[:-2]


@given(st.binary(min_size=2, max_size=40))
def test_ascii_envelope_round_trip(body: bytes) -> None:
    envelope = open_ascii(ascii_frame(body))
    assert envelope.check_ok and envelope.body == body and envelope.unit == body[0]
    assert envelope.check_text == ""
    spans = [span for _, span in envelope.spans]
    assert spans[0][0] == 0 and spans[-1][1] == len(envelope.raw)
    assert all(a[1] == b[0] for a, b in itertools.pairwise(spans))


@given(st.binary(max_size=30))
def test_ascii_envelope_of_any_characters(text: bytes) -> None:
    envelope = open_ascii(b":" + text)
    assert isinstance(envelope.check_text, str)
    assert envelope.check_ok == (envelope.check_text == "")
