"""Provides the file family: FC 20 Read File Record and 21 Write File Record, with their
layouts, framing rules and meaning."""

from __future__ import annotations

from typing import Any

from construct import this

from dissectors.pdu.schema import Octets, Record, Repeat, UInt8, UInt16, Words
from dissectors.pdu.spec import ECHO_ANSWER, AnswerRule, Buffer, FunctionSpec, counted, u16
from dissectors.pdu.work import ERROR, Work, echo, plural

FILE_REFERENCE_TYPE = 6
"""The only reference type the spec defines for file record sub-requests (FC 20, 21)."""

LAST_FILE_RECORD = 9999
"""Record numbers in a file run from 0 to 9999 (0x270F)."""

FILE_READ_ITEM = Record(
    "reference_type" / UInt8,
    "file_number" / UInt16,
    "record_number" / UInt16,
    "record_length" / UInt16,
)
FILE_READ_REQUEST = Record(
    "byte_count" / UInt8,
    "sub_requests" / Repeat(FILE_READ_ITEM, count=this.byte_count // 7),
)
FILE_READ_RESPONSE = Record(
    "byte_count" / UInt8,
    "sub_responses"
    / Repeat(
        Record(
            "length" / UInt8,
            "reference_type" / UInt8,
            "record_data" / Words(Octets(this.length - 1, exact=True)),
        ),
        within=this.byte_count,
    ),
)
FILE_WRITE = Record(
    "byte_count" / UInt8,
    "sub_requests"
    / Repeat(
        Record(
            "reference_type" / UInt8,
            "file_number" / UInt16,
            "record_number" / UInt16,
            "record_length" / UInt16,
            "record_data" / Words(Octets(this.record_length * 2, exact=True)),
        ),
        within=this.byte_count,
    ),
)


def _file_read_response(req: Buffer) -> int | None:
    # request: addr fc bytecount, then 7-byte sub-requests (ref type, file, record, length)
    if len(req) < 5:
        return None
    count = req[2]
    total = 0
    pos = 3
    end = min(len(req) - 2, 3 + count)
    while pos + 7 <= end:
        total += 2 + 2 * u16(req, pos + 5)
        pos += 7
    return 5 + total if total else None


def _check_file_items(w: Work, items: Any) -> None:
    """Reference type 6 and record numbers up to 9999, for every file sub-request."""
    if not isinstance(items, list):
        return
    for index, item in enumerate(items):
        spans: dict[str, tuple[int, int]] = item.get("_spans", {})
        reference = item.get("reference_type")
        if isinstance(reference, int) and reference != FILE_REFERENCE_TYPE:
            w.problem(
                "reference-type",
                ERROR,
                f"reference type {reference} is not {FILE_REFERENCE_TYPE} in item {index}",
                spans.get("reference_type"),
            )
        record = item.get("record_number")
        if isinstance(record, int) and record > LAST_FILE_RECORD:
            w.problem(
                "record-number",
                ERROR,
                f"record number {record} above the limit of {LAST_FILE_RECORD} in item {index}",
                spans.get("record_number"),
            )


def _describe_file_items(items: Any) -> str:
    parts = []
    for item in items if isinstance(items, list) else ():
        file_number, record, length = (
            item.get("file_number"),
            item.get("record_number"),
            item.get("record_length"),
        )
        if isinstance(file_number, int) and isinstance(record, int) and isinstance(length, int):
            parts.append(f"file {file_number} record {record} ({plural(length, 'register')})")
    return ", ".join(parts)


def file_read(w: Work) -> None:
    if w.is_request:
        items = w.parsed.values.get("sub_requests")
        byte_count = w.get("byte_count")
        if byte_count is not None and byte_count % 7:
            w.problem(
                "byte-count",
                ERROR,
                f"byte count {byte_count} is not a multiple of 7",
                w.span("byte_count"),
            )
        _check_file_items(w, items)
        described = _describe_file_items(items)
        w.summary = f"read file record: {described}" if described else "read file record"
        return
    items = w.parsed.values.get("sub_responses")
    _check_file_items(w, items)
    records = items if isinstance(items, list) else []
    words = sum(len(item.get("record_data") or ()) for item in records)
    w.summary = f"file records: {plural(len(records), 'record')}, {plural(words, 'register')}"


def file_write(w: Work) -> None:
    items = w.parsed.values.get("sub_requests")
    _check_file_items(w, items)
    if not w.is_request:
        echo(w)
    described = _describe_file_items(items)
    w.summary = f"write file record: {described}" if described else "write file record"


SPECS: tuple[FunctionSpec, ...] = (
    FunctionSpec(
        20,
        "Read File Record",
        request_length=counted(2, 5),
        response_length=counted(2, 5),
        answer=AnswerRule(0, walker=_file_read_response),
        request_schema=FILE_READ_REQUEST,
        response_schema=FILE_READ_RESPONSE,
        family="file_read",
        meaning=file_read,
    ),
    FunctionSpec(
        21,
        "Write File Record",
        request_length=counted(2, 5),
        response_length=counted(2, 5),
        answer=ECHO_ANSWER,
        echo=True,
        request_schema=FILE_WRITE,
        response_schema=FILE_WRITE,
        family="file_write",
        meaning=file_write,
    ),
)
"""The file family's codes."""
