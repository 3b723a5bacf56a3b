"""Nested fields survive the JSONL and CSV listings (issue 10): FC 20/21 file records,
FC 23's read and write parts and FC 43/14 device identification objects are all there,
as `children` in JSONL and as dotted names in the CSV `fields` column."""

from __future__ import annotations

import csv
import io
import json
import struct
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from dissectors.dissect import Role, dissect
from sniffer.model import Chunk, LineSettings
from sniffer.outputs.listing import Lister, _values_text
from sniffer.session.session import Session
from sniffer.text import json_line

RTU = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
T0 = 1_750_000_000.0

READ_FILE = bytes.fromhex("0114 07 06 0004 0001 0002".replace(" ", ""))
READ_FILE_ANSWER = bytes.fromhex("0114 06 05 06 0df8 46e0".replace(" ", ""))
DEVICE_ID = bytes.fromhex("012b0e0100")
DEVICE_ID_ANSWER = bytes.fromhex(
    "012b0e01010000030006" + b"Vendor".hex() + "0104" + b"P123".hex() + "0203" + b"1.0".hex()
)


def session_of(bodies: list[bytes]) -> Session:
    s = Session(RTU, exact_timing=True, timeout=0.1)
    t = T0
    for body in bodies:
        raw = with_crc(body)
        s.feed(Chunk(raw, t + len(raw) * RTU.char_time, t_start=t))
        t += 0.03
    s.finish()
    return s


def listing(s: Session, fmt: str) -> str:
    out = io.StringIO()
    Lister(out, fmt, s.describer).write(range(len(s.store)))
    return out.getvalue()


def jsonl(s: Session) -> list[dict[str, Any]]:
    return [json.loads(line) for line in listing(s, "jsonl").splitlines()]


def csv_fields(s: Session) -> list[dict[str, str]]:
    rows = list(csv.DictReader(io.StringIO(listing(s, "csv"))))
    out = []
    for row in rows:
        pairs = [item.split("=", 1) for item in row["fields"].split("; ") if item]
        out.append(dict(pairs))
    return out


def by_name(fields: Any) -> dict[str, Any]:
    assert isinstance(fields, list)
    return {f["name"]: f for f in fields}


def test_file_records_keep_their_parts_in_jsonl() -> None:
    s = session_of([READ_FILE, READ_FILE_ANSWER])
    request, answer = jsonl(s)
    sub = by_name(request["fields"])["sub_requests"]
    (part,) = sub["children"]
    assert part["name"] == "sub_requests[0]"
    inner = by_name(part["children"])
    assert inner["file_number"]["value"] == 4
    assert inner["record_number"]["value"] == 1
    assert inner["record_length"]["value"] == 2
    assert inner["file_number"]["span"] == [4, 6]
    (got,) = by_name(answer["fields"])["sub_responses"]["children"]
    data = by_name(got["children"])["record_data"]
    assert data["value"] == [0x0DF8, 0x46E0]
    assert "children" not in data  # words are all in `value`


def test_device_identification_objects_in_jsonl_and_csv() -> None:
    s = session_of([DEVICE_ID, DEVICE_ID_ANSWER])
    answer = jsonl(s)[1]
    objects = by_name(answer["fields"])["objects"]
    assert [(o["name"], o["value"]) for o in objects["children"]] == [
        ("VendorName", "Vendor"),
        ("ProductCode", "P123"),
        ("MajorMinorRevision", "1.0"),
    ]
    flat = csv_fields(s)[1]
    assert flat["objects.VendorName"] == "Vendor"
    assert flat["objects.ProductCode.length"] == "4"
    assert flat["objects.MajorMinorRevision.value"] == b"1.0".hex()
    assert flat["number_of_objects"] == "3"


def test_csv_has_a_fields_column_with_dotted_names() -> None:
    s = session_of([READ_FILE, READ_FILE_ANSWER])
    header = listing(s, "csv").splitlines()[0].split(",")
    assert "fields" in header
    request, answer = csv_fields(s)
    assert request == {
        "byte_count": "7",
        "sub_requests.0.reference_type": "6",
        "sub_requests.0.file_number": "4",
        "sub_requests.0.record_number": "1",
        "sub_requests.0.record_length": "2",
    }
    assert answer["sub_responses.0.record_data"] == f"{0x0DF8} {0x46E0}"


RECORDS = st.lists(
    st.tuples(st.integers(0, 0xFFFF), st.integers(0, 0x270F), st.integers(1, 8)),
    min_size=1,
    max_size=6,
)


@settings(max_examples=40, deadline=None)
@given(RECORDS)
def test_every_file_record_asked_for_is_listed(records: list[tuple[int, int, int]]) -> None:
    parts = b"".join(struct.pack(">BHHH", 6, f, r, n) for f, r, n in records)
    s = session_of([bytes((1, 20, len(parts))) + parts])
    (request,) = jsonl(s)
    children = by_name(request["fields"])["sub_requests"]["children"]
    assert isinstance(children, list) and len(children) == len(records)
    for k, (child, (f, r, n)) in enumerate(zip(children, records, strict=True)):
        assert child["name"] == f"sub_requests[{k}]"
        inner = by_name(child["children"])
        assert (inner["file_number"]["value"], inner["record_number"]["value"]) == (f, r)
        assert inner["record_length"]["value"] == n
    flat = csv_fields(s)[0]
    for k, (f, r, n) in enumerate(records):
        assert flat[f"sub_requests.{k}.file_number"] == str(f)
        assert flat[f"sub_requests.{k}.record_number"] == str(r)
        assert flat[f"sub_requests.{k}.record_length"] == str(n)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=127))
def test_values_spliced_into_a_jsonl_line_are_written_as_the_record_writes_them(
    words: list[int],
) -> None:
    """`_values_text` (the values of an answer spliced into kept JSONL parts) says what
    `json_line` and the dissector's words field say of the same words."""
    data = struct.pack(f">{len(words)}H", *words)
    answer = with_crc(bytes((7, 3, len(data))) + data)
    d = dissect(answer[:-2], Role.RESPONSE, request=bytes((7, 3, 0, 0, 0, len(words))))
    values = d.field("values")
    assert values is not None
    said = json_line({"value": list(words), "text": values.text})
    assert said == '{"value": [' + _values_text(answer, 3, len(words), True) + '"}'


@settings(max_examples=300, deadline=None)
@given(st.binary(min_size=1, max_size=250), st.integers(0, 7))
def test_bits_spliced_into_a_jsonl_line_are_written_as_the_record_writes_them(
    data: bytes, short: int
) -> None:
    """The same for bits: an FC 15 write's values (its quantity short of the bytes' bits
    by up to 7) as `json_line` and the dissector's bits field say them."""
    quantity = 8 * len(data) - short
    write = with_crc(bytes((7, 15, 0, 0, quantity >> 8, quantity & 0xFF, len(data))) + data)
    values = dissect(write[:-2], Role.REQUEST).field("values")
    assert values is not None and isinstance(values.value, tuple)
    said = json_line({"value": list(values.value), "text": values.text})
    assert said == '{"value": [' + _values_text(write, 7, quantity, False) + '"}'
