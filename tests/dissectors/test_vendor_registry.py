"""Vendor function codes from device dictionaries go through the same registry and the
same dissect() as the public codes: fields with byte spans, named values, problems, and
framing rules from the registry."""

from __future__ import annotations

import json
from types import MappingProxyType

from dissectors.checks import with_crc
from dissectors.dictionary import VendorField, VendorFunction, load_model
from dissectors.dissect import Role, dissect
from dissectors.functions import FUNCTIONS, fixed
from sniffer.meaning.annotate import Binding
from sniffer.model import Chunk, LineSettings
from sniffer.outputs.listing import record
from sniffer.session.session import Session
from sniffer.vocab import Kind, Status

# VED903B manual (seed 000, lines 754-766), "Get Slave Address": the master broadcasts
# address 0, function 65 (41h); the unit answers with its address, 41h, and its address
# again as data. The manual prints no CRC: with_crc computes it (C1 80 and D1 90).
GET_SLAVE_ADDRESS_REQUEST = bytes.fromhex("00 41")
GET_SLAVE_ADDRESS_ANSWER = bytes.fromhex("01 41 01")


def _ved903b_session() -> Session:
    ved = load_model("ved903b")
    session = Session(LineSettings(mode="rtu"), bindings={1: Binding(1, "Exciter", ved)})
    stream = with_crc(GET_SLAVE_ADDRESS_REQUEST) + with_crc(GET_SLAVE_ADDRESS_ANSWER)
    session.feed(Chunk(stream, t_end=1.0))
    session.finish()
    return session


def test_crc_of_the_manual_frames() -> None:
    assert with_crc(GET_SLAVE_ADDRESS_REQUEST).hex(" ") == "00 41 c1 80"
    assert with_crc(GET_SLAVE_ADDRESS_ANSWER).hex(" ") == "01 41 01 d1 90"


def test_ved903b_answer_jsonl_fields_hold_the_slave_address_with_its_span() -> None:
    session = _ved903b_session()
    store = session.store
    assert [Kind(store.kind[i]) for i in range(len(store))] == [Kind.REQUEST, Kind.RESPONSE]
    assert store.status[1] == Status.OK
    rec = json.loads(json.dumps(record(session.describer.detail(1))))
    assert rec["name"] == "Get Slave Address"
    assert rec["fields"] == [
        {"name": "Slave address", "value": 1, "text": "1 (0x01)", "span": [2, 3]}
    ]
    assert rec["summary"] == "Slave address = 1 (0x01)"
    assert rec["problems"] == []


def test_ved903b_broadcast_request_is_named_after_the_dictionary_function() -> None:
    session = _ved903b_session()
    rec = record(session.describer.detail(0))
    assert rec["unit"] == 0
    assert rec["name"] == "Get Slave Address"
    assert rec["summary"] == "broadcast: Get Slave Address"
    assert rec["fields"] == []


def test_vendor_codes_frame_from_the_registry() -> None:
    ved = load_model("ved903b")
    registry = FUNCTIONS.with_vendor(ved.functions)
    spec = registry[0x41]
    assert spec.name == "Get Slave Address" and spec.klass == "user"
    assert spec.request_length == fixed(4)  # unit, function, CRC
    assert spec.response_length == fixed(5)  # unit, function, address, CRC
    assert registry.answered_broadcasts == frozenset({0x41})
    assert FUNCTIONS.answered_broadcasts == frozenset()
    assert 0x41 not in FUNCTIONS  # the public registry is left as it was
    assert dissect(GET_SLAVE_ADDRESS_REQUEST, Role.REQUEST).name == "User-defined 65"


STATUS_FUNCTION = VendorFunction(
    code=0x64,
    name="Read Drive State",
    request=(VendorField("Channel", "u8"),),
    response=(
        VendorField("State", "u16", enum=MappingProxyType({0: "stopped", 1: "running"})),
        VendorField("Serial", "bytes", length=3),
        VendorField("Note", "bytes"),
    ),
)
"""A made-up vendor code with every field type: an enumerated u16, fixed-length bytes
and the rest of the frame."""


def test_vendor_fields_get_spans_named_values_and_the_rest_of_the_frame() -> None:
    registry = FUNCTIONS.with_vendor({0x64: STATUS_FUNCTION})
    d = dissect(bytes.fromhex("07 64 0001 AABBCC 4849"), Role.RESPONSE, registry=registry)
    assert d.name == "Read Drive State" and d.problems == ()
    assert [(f.name, f.value, f.text, f.span) for f in d.fields] == [
        ("State", 1, "running (0x0001)", (2, 4)),
        ("Serial", b"\xaa\xbb\xcc", "AA BB CC", (4, 7)),
        ("Note", b"HI", "48 49", (7, 9)),
    ]
    assert d.summary == "State = running (0x0001), Serial = AA BB CC, Note = 48 49"
    # the variable-length answer has no fixed length: silence frames it
    assert registry[0x64].response_length is None
    assert registry[0x64].request_length == fixed(5)


def test_vendor_frames_report_problems_like_every_other_frame() -> None:
    registry = FUNCTIONS.with_vendor({0x64: STATUS_FUNCTION})
    odd = dissect(bytes.fromhex("07 64 0005 AABBCC"), Role.RESPONSE, registry=registry)
    assert [(p.kind, p.severity, p.text, p.span) for p in odd.problems] == [
        (
            "undocumented-value",
            "warning",
            "State value 5 is not one of the documented values",
            (2, 4),
        )
    ]
    state = odd.field("State")
    assert state is not None and state.text == "5 (0x0005)"
    cut = dissect(bytes.fromhex("07 64 0001 AA"), Role.RESPONSE, registry=registry)
    assert [(p.kind, p.text, p.span) for p in cut.problems] == [
        ("truncated", "frame ends inside Serial", (4, 5))
    ]
    extra = dissect(bytes.fromhex("07 64 02 FF"), Role.REQUEST, registry=registry)
    assert [(p.kind, p.text, p.span) for p in extra.problems] == [
        ("trailing-bytes", "1 trailing byte after the PDU", (3, 4))
    ]
    channel = extra.field("Channel")
    assert channel is not None and channel.span == (2, 3)
