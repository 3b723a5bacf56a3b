"""Every problem kind dissect() reports, with its exact message, next to a valid twin
frame that reports nothing."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from dissectors.dissect import Role, dissect

REQ = Role.REQUEST
RSP = Role.RESPONSE


def h(text: str) -> bytes:
    return bytes.fromhex(text)


@dataclass(frozen=True)
class Bad:
    """A frame with problems, the problems as (kind, severity, text, span), and its twin."""

    id: str
    body: str
    role: Role
    problems: tuple[tuple[str, str, str, tuple[int, int] | None], ...]
    twin: str
    request: str | None = None
    twin_request: str | None = None


COILS_1969 = "01 0F 0000 07B1 F7" + "FF" * 246 + "01"
COILS_1968 = "01 0F 0000 07B0 F6" + "FF" * 246
REGISTERS_124 = "01 10 0000 007C F8" + "0000" * 124
REGISTERS_123 = "01 10 0000 007B F6" + "0000" * 123

CASES = [
    # byte-count
    Bad(
        "byte-count-short-data",
        "01 03 06 0001 0002",
        RSP,
        (("byte-count", "error", "byte count 6 but 4 data bytes follow", (2, 3)),),
        "01 03 04 0001 0002",
    ),
    Bad(
        "byte-count-long-data",
        "01 03 02 0001 0002",
        RSP,
        (
            ("byte-count", "error", "byte count 2 but 4 data bytes follow", (2, 3)),
            ("trailing-bytes", "warning", "2 trailing bytes after the PDU", (5, 7)),
        ),
        "01 03 04 0001 0002",
    ),
    Bad(
        "byte-count-odd-and-short",
        "01 03 05 0001 0002",
        RSP,
        (
            ("byte-count", "error", "byte count 5 but 4 data bytes follow", (2, 3)),
            ("odd-byte-count", "error", "byte count 5 is odd: registers are 2 bytes each", (2, 3)),
        ),
        "01 03 04 0001 0002",
    ),
    Bad(
        "byte-count-vs-request",
        "01 03 04 0001 0002",
        RSP,
        (("byte-count", "error", "byte count 4 but the request's quantity 3 needs 6", (2, 3)),),
        "01 03 06 0001 0002 0003",
        request="01 03 0000 0003",
        twin_request="01 03 0000 0003",
    ),
    Bad(
        "byte-count-coils-vs-request",
        "01 01 01 05",
        RSP,
        (("byte-count", "error", "byte count 1 but the request's quantity 10 needs 2", (2, 3)),),
        "01 01 02 05 00",
        request="01 01 0000 000A",
        twin_request="01 01 0000 000A",
    ),
    Bad(
        "byte-count-fc15-request",
        "01 0F 0013 000A 01 CD",
        REQ,
        (("byte-count", "error", "byte count 1 but quantity 10 needs 2", (6, 7)),),
        "01 0F 0013 000A 02 CD 01",
    ),
    Bad(
        "byte-count-fc16-request",
        "01 10 0001 0003 04 000A 0102",
        REQ,
        (("byte-count", "error", "byte count 4 but quantity 3 needs 6", (6, 7)),),
        "01 10 0001 0002 04 000A 0102",
    ),
    Bad(
        "byte-count-fc23-request",
        "01 17 0003 0006 000E 0002 06 00FF 00FF 00FF",
        REQ,
        (("byte-count", "error", "byte count 6 but write_quantity 2 needs 4", (10, 11)),),
        "01 17 0003 0006 000E 0003 06 00FF 00FF 00FF",
    ),
    Bad(
        "byte-count-fc23-response",
        "01 17 02 00FE",
        RSP,
        (
            (
                "byte-count",
                "error",
                "byte count 2 but the request's read_quantity 2 needs 4",
                (2, 3),
            ),
        ),
        "01 17 04 00FE 0001",
        request="01 17 0003 0002 000E 0001 02 00FF",
        twin_request="01 17 0003 0002 000E 0001 02 00FF",
    ),
    Bad(
        "byte-count-fc20-not-multiple-of-7",
        "01 14 08 06 0004 0001 0002 00",
        REQ,
        (
            ("trailing-bytes", "warning", "1 trailing byte after the PDU", (10, 11)),
            ("byte-count", "error", "byte count 8 is not a multiple of 7", (2, 3)),
        ),
        "01 14 07 06 0004 0001 0002",
    ),
    Bad(
        "byte-count-fc24",
        "01 18 0008 0002 01B8 1284",
        RSP,
        (
            ("byte-count", "error", "byte count 8 but 6 data bytes follow", (2, 4)),
            ("byte-count", "error", "byte count 8 but fifo_count 2 needs 6", (2, 4)),
        ),
        "01 18 0006 0002 01B8 1284",
    ),
    Bad(
        "byte-count-one-byte-follows",
        "01 04 02 00",
        RSP,
        (("byte-count", "error", "byte count 2 but 1 data byte follows", (2, 3)),),
        "01 04 02 0000",
    ),
    # quantity
    Bad(
        "quantity-fc03-above",
        "01 03 0000 007E",
        REQ,
        (("quantity", "error", "quantity 126 above the limit of 125", (4, 6)),),
        "01 03 0000 007D",
    ),
    Bad(
        "quantity-fc04-zero",
        "01 04 0000 0000",
        REQ,
        (("quantity", "error", "quantity 0 below the minimum of 1", (4, 6)),),
        "01 04 0000 0001",
    ),
    Bad(
        "quantity-fc01-above",
        "01 01 0000 07D1",
        REQ,
        (("quantity", "error", "quantity 2001 above the limit of 2000", (4, 6)),),
        "01 01 0000 07D0",
    ),
    Bad(
        "quantity-fc02-above",
        "01 02 0000 07D1",
        REQ,
        (("quantity", "error", "quantity 2001 above the limit of 2000", (4, 6)),),
        "01 02 0000 07D0",
    ),
    Bad(
        "quantity-fc15-above",
        COILS_1969,
        REQ,
        (("quantity", "error", "quantity 1969 above the limit of 1968", (4, 6)),),
        COILS_1968,
    ),
    Bad(
        "quantity-fc15-response",
        "01 0F 0000 07B1",
        RSP,
        (("quantity", "error", "quantity 1969 above the limit of 1968", (4, 6)),),
        "01 0F 0000 07B0",
    ),
    Bad(
        "quantity-fc16-above",
        REGISTERS_124,
        REQ,
        (("quantity", "error", "quantity 124 above the limit of 123", (4, 6)),),
        REGISTERS_123,
    ),
    Bad(
        "quantity-fc23-read",
        "01 17 0000 007E 0000 0001 02 0000",
        REQ,
        (("quantity", "error", "read_quantity 126 above the limit of 125", (4, 6)),),
        "01 17 0000 007D 0000 0001 02 0000",
    ),
    Bad(
        "quantity-fc23-write",
        "01 17 0000 0001 0000 007A F4" + "0000" * 122,
        REQ,
        (("quantity", "error", "write_quantity 122 above the limit of 121", (8, 10)),),
        "01 17 0000 0001 0000 0079 F2" + "0000" * 121,
    ),
    Bad(
        "quantity-fifo-count",
        "01 18 0042 0020" + "0000" * 32,
        RSP,
        (("quantity", "error", "fifo_count 32 above the limit of 31", (4, 6)),),
        "01 18 0040 001F" + "0000" * 31,
    ),
    # coil-value
    Bad(
        "coil-value",
        "01 05 00AC 1234",
        REQ,
        (("coil-value", "error", "coil value 0x1234 is not 0xFF00 (ON) or 0x0000 (OFF)", (4, 6)),),
        "01 05 00AC FF00",
    ),
    # odd-byte-count
    Bad(
        "odd-byte-count-registers",
        "01 03 03 0001 02",
        RSP,
        (("odd-byte-count", "error", "byte count 3 is odd: registers are 2 bytes each", (2, 3)),),
        "01 03 04 0001 0203",
    ),
    Bad(
        "odd-byte-count-fc16",
        "01 10 0000 0001 03 000102",
        REQ,
        (
            ("odd-byte-count", "error", "byte count 3 is odd: registers are 2 bytes each", (6, 7)),
            ("byte-count", "error", "byte count 3 but quantity 1 needs 2", (6, 7)),
        ),
        "01 10 0000 0001 02 0001",
    ),
    Bad(
        "odd-byte-count-diagnostics",
        "01 08 0000 A537 01",
        REQ,
        (("odd-byte-count", "error", "odd data length 3: not whole 16-bit words", (4, 7)),),
        "01 08 0000 A537 0100",
    ),
    # trailing-bytes
    Bad(
        "trailing-bytes",
        "01 06 0001 0003 0000",
        REQ,
        (("trailing-bytes", "warning", "2 trailing bytes after the PDU", (6, 8)),),
        "01 06 0001 0003",
    ),
    Bad(
        "trailing-bytes-exception",
        "01 83 02 00",
        RSP,
        (("trailing-bytes", "warning", "1 trailing byte after the PDU", (3, 4)),),
        "01 83 02",
    ),
    # truncated
    Bad(
        "truncated-inside",
        "01 03 00",
        REQ,
        (("truncated", "error", "frame ends inside address", (2, 3)),),
        "01 03 0000 0001",
    ),
    Bad(
        "truncated-before",
        "01 03 0000",
        REQ,
        (("truncated", "error", "frame ends before quantity", (4, 4)),),
        "01 03 0000 0001",
    ),
    Bad(
        "truncated-empty",
        "",
        REQ,
        (("truncated", "error", "frame ends before unit", (0, 0)),),
        "01 07",
    ),
    Bad(
        "truncated-unit-only",
        "01",
        RSP,
        (("truncated", "error", "frame ends before function", (0, 1)),),
        "01 07 00",
    ),
    Bad(
        "truncated-exception",
        "01 83",
        RSP,
        (("truncated", "error", "frame ends before exception_code", (2, 2)),),
        "01 83 04",
    ),
    Bad(
        "truncated-file-record",
        "01 15 0D 06 0004 0007 0003 06AF 04",
        REQ,
        (
            ("truncated", "error", "frame ends inside sub_requests", (3, 13)),
            ("byte-count", "error", "byte count 13 but 10 data bytes follow", (2, 3)),
        ),
        "01 15 0D 06 0004 0007 0003 06AF 04BE 100D",
    ),
    # unknown-function
    Bad(
        "unknown-function-reserved",
        "01 09 0102",
        REQ,
        (("unknown-function", "info", "function code 9 is reserved", (1, 2)),),
        "01 41 0102",
    ),
    Bad(
        "unknown-function-undefined",
        "01 63",
        RSP,
        (
            (
                "unknown-function",
                "warning",
                "function code 99 is not defined by the Modbus specification",
                (1, 2),
            ),
        ),
        "01 6E",
    ),
    # padding
    Bad(
        "padding",
        "01 01 03 CD 6B FD",
        RSP,
        (("padding", "info", "padding bits after 19 values are not zero", (5, 6)),),
        "01 01 03 CD 6B 05",
        request="01 01 0013 0013",
        twin_request="01 01 0013 0013",
    ),
    Bad(
        "padding-fc15",
        "01 0F 0013 000A 02 CD 81",
        REQ,
        (("padding", "info", "padding bits after 10 values are not zero", (8, 9)),),
        "01 0F 0013 000A 02 CD 01",
    ),
    # echo
    Bad(
        "echo-fc06",
        "01 06 0001 0004",
        RSP,
        (("echo", "warning", "echo of value is 0x0004, the request had 0x0003", (4, 6)),),
        "01 06 0001 0003",
        request="01 06 0001 0003",
        twin_request="01 06 0001 0003",
    ),
    Bad(
        "echo-fc05",
        "01 05 00AD FF00",
        RSP,
        (("echo", "warning", "echo of address is 0x00AD, the request had 0x00AC", (2, 4)),),
        "01 05 00AC FF00",
        request="01 05 00AC FF00",
        twin_request="01 05 00AC FF00",
    ),
    Bad(
        "echo-fc08",
        "01 08 0000 A538",
        RSP,
        (("echo", "warning", "echo of data[0] is 0xA538, the request had 0xA537", (4, 6)),),
        "01 08 0000 A537",
        request="01 08 0000 A537",
        twin_request="01 08 0000 A537",
    ),
    Bad(
        "echo-fc15",
        "01 0F 0013 000B",
        RSP,
        (("echo", "warning", "echo of quantity is 11, the request had 10", (4, 6)),),
        "01 0F 0013 000A",
        request="01 0F 0013 000A 02 CD 01",
        twin_request="01 0F 0013 000A 02 CD 01",
    ),
    Bad(
        "echo-fc16",
        "01 10 0002 0002",
        RSP,
        (("echo", "warning", "echo of address is 0x0002, the request had 0x0001", (2, 4)),),
        "01 10 0001 0002",
        request="01 10 0001 0002 04 000A 0102",
        twin_request="01 10 0001 0002 04 000A 0102",
    ),
    Bad(
        "echo-fc21",
        "01 15 0D 06 0004 0007 0003 06AF 04BF 100D",
        RSP,
        (
            (
                "echo",
                "warning",
                "echo of sub_requests[0].record_data[1] is 0x04BF, the request had 0x04BE",
                (12, 14),
            ),
        ),
        "01 15 0D 06 0004 0007 0003 06AF 04BE 100D",
        request="01 15 0D 06 0004 0007 0003 06AF 04BE 100D",
        twin_request="01 15 0D 06 0004 0007 0003 06AF 04BE 100D",
    ),
    Bad(
        "echo-fc22",
        "01 16 0004 00F2 0026",
        RSP,
        (("echo", "warning", "echo of or_mask is 0x0026, the request had 0x0025", (6, 8)),),
        "01 16 0004 00F2 0025",
        request="01 16 0004 00F2 0025",
        twin_request="01 16 0004 00F2 0025",
    ),
    # request-mismatch
    Bad(
        "request-mismatch",
        "01 03 02 0001",
        RSP,
        (("request-mismatch", "warning", "paired request is function 4, not 3", None),),
        "01 03 02 0001",
        request="01 04 0000 0001",
        twin_request="01 03 0000 0001",
    ),
    # reference-type and record-number
    Bad(
        "reference-type",
        "01 14 07 05 0004 0001 0002",
        REQ,
        (("reference-type", "error", "reference type 5 is not 6 in item 0", (3, 4)),),
        "01 14 07 06 0004 0001 0002",
    ),
    Bad(
        "reference-type-response",
        "01 14 06 05 07 0DFE 0020",
        RSP,
        (("reference-type", "error", "reference type 7 is not 6 in item 0", (4, 5)),),
        "01 14 06 05 06 0DFE 0020",
    ),
    Bad(
        "record-number",
        "01 15 09 06 0004 2710 0001 1234",
        REQ,
        (
            (
                "record-number",
                "error",
                "record number 10000 above the limit of 9999 in item 0",
                (6, 8),
            ),
        ),
        "01 15 09 06 0004 270F 0001 1234",
    ),
    # diagnostics
    Bad(
        "diagnostic-data-counter",
        "01 08 000B 0001",
        REQ,
        (
            (
                "diagnostic-data",
                "warning",
                "data 0x0001 should be 0x0000 for return bus message count",
                (4, 6),
            ),
        ),
        "01 08 000B 0000",
    ),
    Bad(
        "diagnostic-data-restart",
        "01 08 0001 1234",
        REQ,
        (
            (
                "diagnostic-data",
                "warning",
                "data 0x1234 should be 0x0000 or 0xFF00 for restart communications option",
                (4, 6),
            ),
        ),
        "01 08 0001 FF00",
    ),
    Bad(
        "sub-function",
        "01 08 0005 0000",
        REQ,
        (("sub-function", "info", "sub-function 0x0005 is reserved", (2, 4)),),
        "01 08 000A 0000",
    ),
    Bad(
        "unexpected-response",
        "01 08 0004 0000",
        RSP,
        (("unexpected-response", "warning", "force listen only mode gets no response", None),),
        "01 08 000A 0000",
    ),
    # FC 43
    Bad(
        "mei-type",
        "01 2B 05 01 02",
        REQ,
        (("mei-type", "info", "MEI type 0x05 is not defined", (2, 3)),),
        "01 2B 0D 01 02",
    ),
    Bad(
        "device-id-code",
        "01 2B 0E 05 00",
        REQ,
        (("device-id-code", "warning", "read device id code 5 is not 1-4", (3, 4)),),
        "01 2B 0E 04 00",
    ),
    # FC 17
    Bad(
        "run-indicator",
        "01 11 02 0A 12",
        RSP,
        (
            (
                "run-indicator",
                "warning",
                "run indicator 0x12 is not 0x00 (OFF) or 0xFF (ON)",
                (4, 5),
            ),
        ),
        "01 11 02 0A FF",
    ),
    # role and broadcast
    Bad(
        "role",
        "01 83 02",
        REQ,
        (("role", "warning", "exception response seen as a request", (1, 2)),),
        "01 83 02",
    ),
    Bad(
        "broadcast-response",
        "00 03 02 0001",
        RSP,
        (("broadcast-response", "warning", "response from the broadcast address 0", (0, 1)),),
        "01 03 02 0001",
    ),
]

KINDS = {
    "byte-count",
    "quantity",
    "coil-value",
    "odd-byte-count",
    "trailing-bytes",
    "truncated",
    "unknown-function",
    "padding",
    "echo",
    "request-mismatch",
    "reference-type",
    "record-number",
    "diagnostic-data",
    "sub-function",
    "unexpected-response",
    "mei-type",
    "device-id-code",
    "run-indicator",
    "role",
    "broadcast-response",
}


def _twin_role(case: Bad) -> Role:
    # The exception frame seen as a request has its twin in the right role.
    return RSP if case.id == "role" else case.role


def test_every_kind_is_tested() -> None:
    assert {kind for case in CASES for kind, *_ in case.problems} == KINDS


@pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
def test_problem(case: Bad) -> None:
    request = h(case.request) if case.request is not None else None
    result = dissect(h(case.body), case.role, request=request)
    got = [(p.kind, p.severity, p.text, p.span) for p in result.problems]
    assert got == list(case.problems)


@pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
def test_valid_twin(case: Bad) -> None:
    request = h(case.twin_request) if case.twin_request is not None else None
    result = dissect(h(case.twin), _twin_role(case), request=request)
    assert result.problems == ()
