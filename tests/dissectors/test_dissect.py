"""Dissection of every public function code: byte-literal vectors per code and direction,
parse -> build round trips, and the guarantee that no bytes make dissect() raise."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.dissect import FAMILIES, Dissection, Field, RegisterData, Role, dissect
from dissectors.functions import EXCEPTION_SCHEMA, FUNCTIONS, RAW_SCHEMA

REQ = Role.REQUEST
RSP = Role.RESPONSE


def h(text: str) -> bytes:
    return bytes.fromhex(text)


@dataclass(frozen=True)
class Case:
    """One frame body, the role it is dissected in, and what must come out."""

    id: str
    body: str
    role: Role
    summary: str
    fields: dict[str, Any]
    data: tuple[RegisterData, ...] = ()
    request: str | None = None
    texts: dict[str, str] = field(default_factory=dict)


def coils(*bits: int) -> tuple[int, ...]:
    return tuple(bits)


# The bit patterns of the spec's FC 1 and FC 2 examples, in address order.
BITS_CD6B05 = (1, 0, 1, 1, 0, 0, 1, 1, 1, 1, 0, 1, 0, 1, 1, 0, 1, 0, 1)
BITS_ACDB35 = (0, 0, 1, 1, 0, 1, 0, 1, 1, 1, 0, 1, 1, 0, 1, 1, 1, 0, 1, 0, 1, 1)

FC01_REQUESTS = [
    Case(
        "fc01-req",
        "01 01 0013 0013",
        REQ,
        "read 19 coils from 0x0013",
        {"address": 0x13, "quantity": 19},
        texts={"address": "0x0013", "quantity": "19"},
    ),
    Case("fc01-req-one", "11 01 0000 0001", REQ, "read 1 coil from 0x0000", {"quantity": 1}),
    Case("fc01-req-max", "11 01 FFFF 07D0", REQ, "read 2000 coils from 0xFFFF", {"quantity": 2000}),
]
FC01_RESPONSES = [
    Case(
        "fc01-rsp",
        "01 01 03 CD 6B 05",
        RSP,
        "19 values",
        {"byte_count": 3, "values": BITS_CD6B05},
        (RegisterData("coils", 0x13, BITS_CD6B05, False),),
        request="01 01 0013 0013",
    ),
    Case(
        "fc01-rsp-no-request",
        "01 01 01 05",
        RSP,
        "8 values",
        {"byte_count": 1, "values": coils(1, 0, 1, 0, 0, 0, 0, 0)},
        (RegisterData("coils", None, coils(1, 0, 1, 0, 0, 0, 0, 0), False),),
    ),
    Case(
        "fc01-rsp-one",
        "01 01 01 01",
        RSP,
        "1 value",
        {"values": (1,)},
        (RegisterData("coils", 7, (1,), False),),
        request="01 01 0007 0001",
    ),
]
FC02_REQUESTS = [
    Case(
        "fc02-req",
        "01 02 00C4 0016",
        REQ,
        "read 22 discrete inputs from 0x00C4",
        {"address": 0xC4, "quantity": 22},
    ),
]
FC02_RESPONSES = [
    Case(
        "fc02-rsp",
        "01 02 03 AC DB 35",
        RSP,
        "22 values",
        {"byte_count": 3, "values": BITS_ACDB35},
        (RegisterData("discrete_inputs", 0xC4, BITS_ACDB35, False),),
        request="01 02 00C4 0016",
    ),
]
FC03_REQUESTS = [
    Case(
        "fc03-req",
        "01 03 006B 0003",
        REQ,
        "read 3 holding registers from 0x006B",
        {"address": 0x6B, "quantity": 3},
    ),
    Case(
        "fc03-req-one",
        "01 03 000D 0001",
        REQ,
        "read 1 holding register from 0x000D",
        {"quantity": 1},
    ),
    Case("fc03-req-max", "01 03 0000 007D", REQ, "read 125 holding registers from 0x0000", {}),
    Case(
        "fc03-req-broadcast",
        "00 03 0000 0001",
        REQ,
        "broadcast: read 1 holding register from 0x0000",
        {"address": 0},
    ),
]
FC03_RESPONSES = [
    Case(
        "fc03-rsp",
        "01 03 06 022B 0000 0064",
        RSP,
        "3 values",
        {"byte_count": 6, "values": (0x022B, 0, 0x64)},
        (RegisterData("holding_registers", 0x6B, (0x022B, 0, 0x64), False),),
        request="01 03 006B 0003",
        texts={"values": "0x022B 0x0000 0x0064"},
    ),
    Case(
        "fc03-rsp-no-request",
        "01 03 02 FFFF",
        RSP,
        "1 value",
        {"values": (0xFFFF,)},
        (RegisterData("holding_registers", None, (0xFFFF,), False),),
    ),
]
FC04_REQUESTS = [
    Case(
        "fc04-req",
        "01 04 0008 0001",
        REQ,
        "read 1 input register from 0x0008",
        {"address": 8, "quantity": 1},
    ),
]
FC04_RESPONSES = [
    Case(
        "fc04-rsp",
        "01 04 02 000A",
        RSP,
        "1 value",
        {"byte_count": 2, "values": (10,)},
        (RegisterData("input_registers", 8, (10,), False),),
        request="01 04 0008 0001",
    ),
]
FC05_REQUESTS = [
    Case(
        "fc05-req-on",
        "01 05 00AC FF00",
        REQ,
        "coil 0x00AC ON",
        {"address": 0xAC, "value": 0xFF00},
        (RegisterData("coils", 0xAC, (1,), True),),
        texts={"value": "ON"},
    ),
    Case(
        "fc05-req-off",
        "01 05 00AC 0000",
        REQ,
        "coil 0x00AC OFF",
        {"value": 0},
        (RegisterData("coils", 0xAC, (0,), True),),
        texts={"value": "OFF"},
    ),
    Case(
        "fc05-req-broadcast",
        "00 05 0001 FF00",
        REQ,
        "broadcast: coil 0x0001 ON",
        {"address": 1},
        (RegisterData("coils", 1, (1,), True),),
    ),
]
FC05_RESPONSES = [
    Case(
        "fc05-rsp",
        "01 05 00AC FF00",
        RSP,
        "coil 0x00AC ON",
        {"address": 0xAC, "value": 0xFF00},
        (RegisterData("coils", 0xAC, (1,), True),),
        request="01 05 00AC FF00",
    ),
]
FC06_REQUESTS = [
    Case(
        "fc06-req",
        "01 06 0001 0003",
        REQ,
        "write 0x0003 to register 0x0001",
        {"address": 1, "value": 3},
        (RegisterData("holding_registers", 1, (3,), True),),
    ),
    Case(
        "fc06-req-broadcast",
        "00 06 0001 0003",
        REQ,
        "broadcast: write 0x0003 to register 0x0001",
        {"value": 3},
        (RegisterData("holding_registers", 1, (3,), True),),
    ),
]
FC06_RESPONSES = [
    Case(
        "fc06-rsp",
        "01 06 0001 0003",
        RSP,
        "write 0x0003 to register 0x0001",
        {"address": 1, "value": 3},
        (RegisterData("holding_registers", 1, (3,), True),),
        request="01 06 0001 0003",
    ),
]
FC07_REQUESTS = [Case("fc07-req", "01 07", REQ, "read exception status", {})]
FC07_RESPONSES = [
    Case(
        "fc07-rsp",
        "01 07 6D",
        RSP,
        "exception status 0x6D",
        {"status": 0x6D},
        texts={"status": "0x6D (bits 01101101)"},
    ),
]
FC08_REQUESTS = [
    Case(
        "fc08-req-query",
        "01 08 0000 A537",
        REQ,
        "diagnostics: return query data",
        {"sub_function": 0, "data": (0xA537,)},
        texts={"sub_function": "return query data", "data": "0xA537"},
    ),
    Case(
        "fc08-req-query-long",
        "01 08 0000 0102 0304",
        REQ,
        "diagnostics: return query data",
        {"data": (0x0102, 0x0304)},
    ),
    Case(
        "fc08-req-restart",
        "01 08 0001 FF00",
        REQ,
        "diagnostics: restart communications option",
        {"sub_function": 1, "data": (0xFF00,)},
        texts={"data": "clear the event log"},
    ),
    Case(
        "fc08-req-register",
        "01 08 0002 0000",
        REQ,
        "diagnostics: return diagnostic register",
        {"sub_function": 2},
    ),
    Case(
        "fc08-req-delimiter",
        "01 08 0003 0A00",
        REQ,
        "diagnostics: change ASCII input delimiter",
        {"sub_function": 3, "data": (0x0A00,)},
        texts={"data": "delimiter 0x0A"},
    ),
    Case(
        "fc08-req-listen-only",
        "01 08 0004 0000",
        REQ,
        "diagnostics: force listen only mode",
        {"sub_function": 4},
    ),
    Case(
        "fc08-req-clear",
        "01 08 000A 0000",
        REQ,
        "diagnostics: clear counters and diagnostic register",
        {"sub_function": 10},
    ),
    *[
        Case(
            f"fc08-req-{code:02d}",
            f"01 08 {code:04X} 0000",
            REQ,
            f"diagnostics: {name}",
            {"sub_function": code, "data": (0,)},
        )
        for code, name in (
            (11, "return bus message count"),
            (12, "return bus communication error count"),
            (13, "return bus exception error count"),
            (14, "return server message count"),
            (15, "return server no response count"),
            (16, "return server NAK count"),
            (17, "return server busy count"),
            (18, "return bus character overrun count"),
            (20, "clear overrun counter and flag"),
        )
    ],
    Case(
        "fc08-req-broadcast",
        "00 08 0001 0000",
        REQ,
        "broadcast: diagnostics: restart communications option",
        {"sub_function": 1},
        texts={"data": "keep the event log"},
    ),
]
FC08_RESPONSES = [
    Case(
        "fc08-rsp-query",
        "01 08 0000 A537",
        RSP,
        "diagnostics: return query data",
        {"sub_function": 0, "data": (0xA537,)},
        request="01 08 0000 A537",
    ),
    Case(
        "fc08-rsp-register",
        "01 08 0002 8001",
        RSP,
        "diagnostics: return diagnostic register: 0x8001",
        {"data": (0x8001,)},
        request="01 08 0002 0000",
    ),
    Case(
        "fc08-rsp-count",
        "01 08 000B 0108",
        RSP,
        "diagnostics: return bus message count: 264",
        {"sub_function": 11, "data": (264,)},
        request="01 08 000B 0000",
        texts={"data": "264"},
    ),
    Case(
        "fc08-rsp-clear-overrun",
        "01 08 0014 0000",
        RSP,
        "diagnostics: clear overrun counter and flag",
        {"sub_function": 20},
        request="01 08 0014 0000",
    ),
]
FC11_REQUESTS = [Case("fc11-req", "01 0B", REQ, "get comm event counter", {})]
FC11_RESPONSES = [
    Case(
        "fc11-rsp",
        "01 0B FFFF 0108",
        RSP,
        "event counter 264, busy",
        {"status": 0xFFFF, "event_count": 264},
        texts={"status": "busy"},
    ),
    Case("fc11-rsp-ready", "01 0B 0000 0000", RSP, "event counter 0, ready", {"status": 0}),
]
FC12_REQUESTS = [Case("fc12-req", "01 0C", REQ, "get comm event log", {})]
FC12_RESPONSES = [
    Case(
        "fc12-rsp",
        "01 0C 08 0000 0108 0121 20 00",
        RSP,
        "event log: ready, event count 264, message count 289, 2 events",
        {
            "byte_count": 8,
            "status": 0,
            "event_count": 264,
            "message_count": 289,
            "events": b"\x20\x00",
        },
    ),
]
FC15_REQUESTS = [
    Case(
        "fc15-req",
        "01 0F 0013 000A 02 CD 01",
        REQ,
        "write 10 coils from 0x0013",
        {
            "address": 0x13,
            "quantity": 10,
            "byte_count": 2,
            "values": (1, 0, 1, 1, 0, 0, 1, 1, 1, 0),
        },
        (RegisterData("coils", 0x13, (1, 0, 1, 1, 0, 0, 1, 1, 1, 0), True),),
    ),
    Case(
        "fc15-req-broadcast",
        "00 0F 0000 0001 01 01",
        REQ,
        "broadcast: write 1 coil from 0x0000",
        {"values": (1,)},
        (RegisterData("coils", 0, (1,), True),),
    ),
    Case(
        "fc15-req-max",
        "01 0F 0000 07B0 F6" + "FF" * 246,
        REQ,
        "write 1968 coils from 0x0000",
        {"quantity": 1968, "byte_count": 246, "values": (1,) * 1968},
        (RegisterData("coils", 0, (1,) * 1968, True),),
    ),
]
FC15_RESPONSES = [
    Case(
        "fc15-rsp",
        "01 0F 0013 000A",
        RSP,
        "wrote 10 coils from 0x0013",
        {"address": 0x13, "quantity": 10},
        (RegisterData("coils", 0x13, (1, 0, 1, 1, 0, 0, 1, 1, 1, 0), True),),
        request="01 0F 0013 000A 02 CD 01",
    ),
    Case("fc15-rsp-alone", "01 0F 0013 000A", RSP, "wrote 10 coils from 0x0013", {}),
]
FC16_REQUESTS = [
    Case(
        "fc16-req",
        "01 10 0001 0002 04 000A 0102",
        REQ,
        "write 2 registers from 0x0001",
        {"address": 1, "quantity": 2, "byte_count": 4, "values": (10, 0x0102)},
        (RegisterData("holding_registers", 1, (10, 0x0102), True),),
    ),
    Case(
        "fc16-req-broadcast",
        "00 10 0001 0001 02 0007",
        REQ,
        "broadcast: write 1 register from 0x0001",
        {"values": (7,)},
        (RegisterData("holding_registers", 1, (7,), True),),
    ),
    Case(
        "fc16-req-max",
        "01 10 0000 007B F6" + "0001" * 123,
        REQ,
        "write 123 registers from 0x0000",
        {"quantity": 123, "values": (1,) * 123},
        (RegisterData("holding_registers", 0, (1,) * 123, True),),
    ),
]
FC16_RESPONSES = [
    Case(
        "fc16-rsp",
        "01 10 0001 0002",
        RSP,
        "wrote 2 registers from 0x0001",
        {"address": 1, "quantity": 2},
        (RegisterData("holding_registers", 1, (10, 0x0102), True),),
        request="01 10 0001 0002 04 000A 0102",
    ),
]
FC17_REQUESTS = [Case("fc17-req", "01 11", REQ, "report server id", {})]
FC17_RESPONSES = [
    Case(
        "fc17-rsp",
        "01 11 05 0A FF 41 42 43",
        RSP,
        "server id 0A, run indicator ON",
        {"byte_count": 5, "server_id": b"\x0a", "run_indicator": 0xFF, "additional": b"ABC"},
        texts={"run_indicator": "ON", "additional": "41 42 43"},
    ),
    Case(
        "fc17-rsp-off",
        "01 11 02 49 00",
        RSP,
        "server id 49, run indicator OFF",
        {"run_indicator": 0, "additional": b""},
    ),
]
FC20_REQUESTS = [
    Case(
        "fc20-req",
        "01 14 0E 06 0004 0001 0002 06 0003 0009 0002",
        REQ,
        "read file record: file 4 record 1 (2 registers), file 3 record 9 (2 registers)",
        {"byte_count": 14},
    ),
]
FC20_RESPONSES = [
    Case(
        "fc20-rsp",
        "01 14 0C 05 06 0DFE 0020 05 06 33CD 0040",
        RSP,
        "file records: 2 records, 4 registers",
        {"byte_count": 12},
    ),
]
FC21_REQUESTS = [
    Case(
        "fc21-req",
        "01 15 0D 06 0004 0007 0003 06AF 04BE 100D",
        REQ,
        "write file record: file 4 record 7 (3 registers)",
        {"byte_count": 13},
    ),
]
FC21_RESPONSES = [
    Case(
        "fc21-rsp",
        "01 15 0D 06 0004 0007 0003 06AF 04BE 100D",
        RSP,
        "write file record: file 4 record 7 (3 registers)",
        {"byte_count": 13},
        request="01 15 0D 06 0004 0007 0003 06AF 04BE 100D",
    ),
]
FC22_REQUESTS = [
    Case(
        "fc22-req",
        "01 16 0004 00F2 0025",
        REQ,
        "mask write register 0x0004: AND 0x00F2, OR 0x0025",
        {"address": 4, "and_mask": 0xF2, "or_mask": 0x25},
    ),
]
FC22_RESPONSES = [
    Case(
        "fc22-rsp",
        "01 16 0004 00F2 0025",
        RSP,
        "mask write register 0x0004: AND 0x00F2, OR 0x0025",
        {"address": 4, "and_mask": 0xF2, "or_mask": 0x25},
        request="01 16 0004 00F2 0025",
    ),
]
FC23_REQUESTS = [
    Case(
        "fc23-req",
        "01 17 0003 0006 000E 0003 06 00FF 00FF 00FF",
        REQ,
        "read 6 registers from 0x0003, write 3 registers from 0x000E",
        {
            "read_address": 3,
            "read_quantity": 6,
            "write_address": 14,
            "write_quantity": 3,
            "byte_count": 6,
            "values": (0xFF, 0xFF, 0xFF),
        },
        (RegisterData("holding_registers", 14, (0xFF, 0xFF, 0xFF), True),),
    ),
    Case(
        "fc23-req-max",
        "01 17 0000 007D 0100 0079 F2" + "0002" * 121,
        REQ,
        "read 125 registers from 0x0000, write 121 registers from 0x0100",
        {"read_quantity": 125, "write_quantity": 121},
        (RegisterData("holding_registers", 0x100, (2,) * 121, True),),
    ),
]
FC23_VALUES = (0xFE, 0x0ACD, 1, 3, 0x0D, 0xFF)
FC23_RESPONSES = [
    Case(
        "fc23-rsp",
        "01 17 0C 00FE 0ACD 0001 0003 000D 00FF",
        RSP,
        "6 values",
        {"byte_count": 12, "values": FC23_VALUES},
        (
            RegisterData("holding_registers", 3, FC23_VALUES, False),
            RegisterData("holding_registers", 14, (0xFF, 0xFF, 0xFF), True),
        ),
        request="01 17 0003 0006 000E 0003 06 00FF 00FF 00FF",
    ),
    Case(
        "fc23-rsp-alone",
        "01 17 02 1234",
        RSP,
        "1 value",
        {"values": (0x1234,)},
        (RegisterData("holding_registers", None, (0x1234,), False),),
    ),
]
FC24_REQUESTS = [
    Case(
        "fc24-req",
        "01 18 04DE",
        REQ,
        "read FIFO queue at 0x04DE",
        {"fifo_address": 0x04DE},
    ),
]
FC24_RESPONSES = [
    Case(
        "fc24-rsp",
        "01 18 0006 0002 01B8 1284",
        RSP,
        "FIFO: 2 values",
        {"byte_count": 6, "fifo_count": 2, "values": (0x01B8, 0x1284)},
    ),
    Case("fc24-rsp-empty", "01 18 0002 0000", RSP, "FIFO: 0 values", {"fifo_count": 0}),
    Case(
        "fc24-rsp-max",
        "01 18 0040 001F" + "0003" * 31,
        RSP,
        "FIFO: 31 values",
        {"fifo_count": 31},
    ),
]
DEVICE_ID_RESPONSE = (
    "01 2B 0E 01 01 00 00 03"
    + " 00 16 "
    + b"Company identification".hex()
    + " 01 0F "
    + b"Product code XX".hex()
    + " 02 05 "
    + b"V2.11".hex()
)
FC43_REQUESTS = [
    Case(
        "fc43-req-device-id",
        "01 2B 0E 01 00",
        REQ,
        "device id request: basic, object VendorName",
        {"mei_type": 14, "read_device_id_code": 1, "object_id": 0},
        texts={"mei_type": "read device identification", "object_id": "VendorName"},
    ),
    Case(
        "fc43-req-one-object",
        "01 2B 0E 04 81",
        REQ,
        "device id request: one object, object private 0x81",
        {"read_device_id_code": 4, "object_id": 0x81},
    ),
    Case(
        "fc43-req-canopen",
        "01 2B 0D 00 01 02 03",
        REQ,
        "CANopen general reference: 4 data bytes",
        {"mei_type": 13, "data": h("00010203")},
        texts={"mei_type": "CANopen general reference"},
    ),
]
FC43_RESPONSES = [
    Case(
        "fc43-rsp-device-id",
        DEVICE_ID_RESPONSE,
        RSP,
        "device id: VendorName=Company identification, ProductCode=Product code XX, "
        "MajorMinorRevision=V2.11",
        {"mei_type": 14, "conformity_level": 1, "more_follows": 0, "number_of_objects": 3},
        request="01 2B 0E 01 00",
        texts={"conformity_level": "basic, stream only", "more_follows": "no"},
    ),
    Case(
        "fc43-rsp-more",
        "01 2B 0E 02 83 FF 05 02 04 03 " + b"ABC".hex() + " 80 02 0102",
        RSP,
        "device id: ProductName=ABC, private 0x80=\\x01\\x02; more follows from ModelName",
        {"more_follows": 0xFF, "next_object_id": 5},
        texts={
            "conformity_level": "extended, stream and individual",
            "next_object_id": "ModelName",
        },
    ),
    Case(
        "fc43-rsp-canopen",
        "01 2B 0D 0A0B",
        RSP,
        "CANopen general reference: 2 data bytes",
        {"mei_type": 13, "data": h("0A0B")},
    ),
]
EXCEPTION_NAMES = {
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "server device failure",
    5: "acknowledge",
    6: "server device busy",
    8: "memory parity error",
    10: "gateway path unavailable",
    11: "gateway target device failed to respond",
    7: "unknown exception",
    12: "unknown exception",
    0xFF: "unknown exception",
}
EXCEPTIONS = [
    Case(
        f"exception-fc{function:02d}-{code:02X}",
        f"0A {function | 0x80:02X} {code:02X}",
        RSP,
        f"exception {code:02X} {EXCEPTION_NAMES[code]}",
        {"exception_code": code},
        texts={"exception_code": EXCEPTION_NAMES[code]},
    )
    for function, code in zip(
        (1, 2, 3, 4, 5, 6, 7, 8, 11, 12, 15, 16, 17, 20, 21, 22, 23, 24, 43, 65, 9),
        (1, 2, 3, 4, 5, 6, 8, 10, 11, 7, 12, 255, 1, 2, 3, 4, 5, 6, 1, 1, 1),
        strict=True,
    )
]
RAW = [
    Case(
        "raw-user-65",
        "01 41 00 01",
        RSP,
        "user-defined function 65: 2 data bytes",
        {"data": h("0001")},
    ),
    Case("raw-user-100", "01 64", REQ, "user-defined function 100: 0 data bytes", {"data": b""}),
    Case("raw-user-110", "01 6E FF", REQ, "user-defined function 110: 1 data byte", {}),
]

TABLES: dict[str, list[Case]] = {
    "FC01_REQUESTS": FC01_REQUESTS,
    "FC01_RESPONSES": FC01_RESPONSES,
    "FC02_REQUESTS": FC02_REQUESTS,
    "FC02_RESPONSES": FC02_RESPONSES,
    "FC03_REQUESTS": FC03_REQUESTS,
    "FC03_RESPONSES": FC03_RESPONSES,
    "FC04_REQUESTS": FC04_REQUESTS,
    "FC04_RESPONSES": FC04_RESPONSES,
    "FC05_REQUESTS": FC05_REQUESTS,
    "FC05_RESPONSES": FC05_RESPONSES,
    "FC06_REQUESTS": FC06_REQUESTS,
    "FC06_RESPONSES": FC06_RESPONSES,
    "FC07_REQUESTS": FC07_REQUESTS,
    "FC07_RESPONSES": FC07_RESPONSES,
    "FC08_REQUESTS": FC08_REQUESTS,
    "FC08_RESPONSES": FC08_RESPONSES,
    "FC11_REQUESTS": FC11_REQUESTS,
    "FC11_RESPONSES": FC11_RESPONSES,
    "FC12_REQUESTS": FC12_REQUESTS,
    "FC12_RESPONSES": FC12_RESPONSES,
    "FC15_REQUESTS": FC15_REQUESTS,
    "FC15_RESPONSES": FC15_RESPONSES,
    "FC16_REQUESTS": FC16_REQUESTS,
    "FC16_RESPONSES": FC16_RESPONSES,
    "FC17_REQUESTS": FC17_REQUESTS,
    "FC17_RESPONSES": FC17_RESPONSES,
    "FC20_REQUESTS": FC20_REQUESTS,
    "FC20_RESPONSES": FC20_RESPONSES,
    "FC21_REQUESTS": FC21_REQUESTS,
    "FC21_RESPONSES": FC21_RESPONSES,
    "FC22_REQUESTS": FC22_REQUESTS,
    "FC22_RESPONSES": FC22_RESPONSES,
    "FC23_REQUESTS": FC23_REQUESTS,
    "FC23_RESPONSES": FC23_RESPONSES,
    "FC24_REQUESTS": FC24_REQUESTS,
    "FC24_RESPONSES": FC24_RESPONSES,
    "FC43_REQUESTS": FC43_REQUESTS,
    "FC43_RESPONSES": FC43_RESPONSES,
    "EXCEPTIONS": EXCEPTIONS,
    "RAW": RAW,
}
ALL_CASES = [case for table in TABLES.values() for case in table]


def run(case: Case) -> Dissection:
    request = h(case.request) if case.request is not None else None
    return dissect(h(case.body), case.role, request=request)


def test_every_public_code_has_both_tables() -> None:
    for code in FUNCTIONS:
        assert f"FC{code:02d}_REQUESTS" in TABLES
        assert f"FC{code:02d}_RESPONSES" in TABLES


def test_case_ids_are_unique() -> None:
    ids = [case.id for case in ALL_CASES]
    assert len(ids) == len(set(ids))


@pytest.mark.parametrize("case", ALL_CASES, ids=[case.id for case in ALL_CASES])
def test_vector(case: Case) -> None:
    body = h(case.body)
    result = run(case)
    assert result.unit == body[0]
    assert result.function == body[1] & 0x7F
    assert result.exception == bool(body[1] & 0x80)
    assert result.role is case.role
    assert result.problems == ()
    assert result.summary == case.summary
    for name, expected in case.fields.items():
        found = result.field(name)
        assert found is not None, name
        assert found.value == expected, name
    for name, text in case.texts.items():
        found = result.field(name)
        assert found is not None, name
        assert found.text == text, name
    assert result.data == case.data


def _spans_inside(fields: tuple[Field, ...], size: int) -> None:
    for item in fields:
        start, end = item.span
        assert 0 <= start <= end <= size, item
        _spans_inside(item.children, size)


@pytest.mark.parametrize("case", ALL_CASES, ids=[case.id for case in ALL_CASES])
def test_fields_cover_the_pdu(case: Case) -> None:
    """Top-level fields are in order, do not overlap, and cover every byte after the
    function code of a valid frame."""
    body = h(case.body)
    result = run(case)
    _spans_inside(result.fields, len(body))
    position = 2
    for item in result.fields:
        assert item.span[0] == position, item.name
        position = item.span[1]
    assert position == len(body)


def _schema(body: bytes, role: Role) -> Any:
    if body[1] & 0x80:
        return EXCEPTION_SCHEMA
    spec = FUNCTIONS.get(body[1])
    if spec is None:
        return RAW_SCHEMA
    return spec.request_schema if role is REQ else spec.response_schema


@pytest.mark.parametrize("case", ALL_CASES, ids=[case.id for case in ALL_CASES])
def test_parse_build_round_trip(case: Case) -> None:
    body = h(case.body)
    schema = _schema(body, case.role)
    parsed = schema.parse(body[2:])
    assert schema.build(parsed) == body[2:]


def test_spans_point_at_the_bytes() -> None:
    result = dissect(h("01 03 06 022B 0000 0064"), RSP)
    values = result.field("values")
    assert values is not None
    assert values.span == (3, 9)
    assert [child.span for child in values.children] == [(3, 5), (5, 7), (7, 9)]
    assert [child.name for child in values.children] == ["values[0]", "values[1]", "values[2]"]
    byte_count = result.field("byte_count")
    assert byte_count is not None and byte_count.span == (2, 3)


def test_device_objects_are_named_with_their_strings() -> None:
    result = dissect(h(DEVICE_ID_RESPONSE), RSP)
    objects = result.field("objects")
    assert objects is not None
    assert [(child.name, child.value) for child in objects.children] == [
        ("VendorName", "Company identification"),
        ("ProductCode", "Product code XX"),
        ("MajorMinorRevision", "V2.11"),
    ]
    assert objects.children[0].span == (8, 8 + 2 + 22)


def test_every_standard_object_name() -> None:
    names = [
        "VendorName",
        "ProductCode",
        "MajorMinorRevision",
        "VendorUrl",
        "ProductName",
        "ModelName",
        "UserApplicationName",
    ]
    body = "01 2B 0E 03 83 00 00 09" + "".join(f" {i:02X} 01 41" for i in (*range(7), 0x07, 0xFF))
    result = dissect(h(body), RSP)
    objects = result.field("objects")
    assert objects is not None
    assert [child.name for child in objects.children] == [
        *names,
        "reserved 0x07",
        "private 0xFF",
    ]


def test_file_record_items_are_children() -> None:
    result = dissect(h("01 14 0E 06 0004 0001 0002 06 0003 0009 0002"), REQ)
    items = result.field("sub_requests")
    assert items is not None
    assert [child.name for child in items.children] == ["sub_requests[0]", "sub_requests[1]"]
    first = items.children[0]
    assert [(f.name, f.value) for f in first.children] == [
        ("reference_type", 6),
        ("file_number", 4),
        ("record_number", 1),
        ("record_length", 2),
    ]
    assert first.span == (3, 10)
    response = dissect(h("01 14 0C 05 06 0DFE 0020 05 06 33CD 0040"), RSP)
    records = response.field("sub_responses")
    assert records is not None
    data = [f for f in records.children[1].children if f.name == "record_data"]
    assert data[0].value == (0x33CD, 0x0040)


def test_truncated_frame_keeps_what_it_had() -> None:
    result = dissect(h(DEVICE_ID_RESPONSE)[:-3], RSP)
    assert [(p.kind, p.text) for p in result.problems] == [
        ("truncated", "frame ends inside objects"),
    ]
    objects = result.field("objects")
    assert objects is not None
    assert [child.name for child in objects.children][:2] == ["VendorName", "ProductCode"]
    assert result.field("number_of_objects") is not None


def test_every_family_has_a_routine() -> None:
    for spec in FUNCTIONS.values():
        assert spec.family in FAMILIES, spec.code
        assert spec.request_schema is not None and spec.response_schema is not None


def test_names() -> None:
    assert dissect(h("01 03 0000 0001"), REQ).name == "Read Holding Registers"
    assert dissect(h("01 83 02"), RSP).name == "Read Holding Registers"
    assert dissect(h("01 41"), REQ).name == "User-defined 65"


# --- never raise ---------------------------------------------------------------------------

roles = st.sampled_from([REQ, RSP])
known_codes = st.sampled_from([*sorted(FUNCTIONS), 0x41, 0x09, 0x63, 0x83, 0xAB, 0x80, 0xFF])


def _check_sane(result: Dissection, body: bytes) -> None:
    assert isinstance(result, Dissection)
    _spans_inside(result.fields, len(body))
    for problem in result.problems:
        assert problem.severity in ("error", "warning", "info")
        if problem.span is not None:
            assert 0 <= problem.span[0] <= problem.span[1] <= len(body), problem
    str(result.summary)


@settings(max_examples=500, deadline=None)
@given(body=st.binary(max_size=300), role=roles, request=st.none() | st.binary(max_size=300))
def test_random_bytes_never_raise(body: bytes, role: Role, request: bytes | None) -> None:
    _check_sane(dissect(body, role, request=request), body)


@settings(max_examples=1500, deadline=None)
@given(
    unit=st.integers(0, 255),
    code=known_codes,
    tail=st.binary(max_size=260),
    role=roles,
    request_tail=st.none() | st.binary(max_size=260),
)
def test_random_frames_of_known_codes_never_raise(
    unit: int, code: int, tail: bytes, role: Role, request_tail: bytes | None
) -> None:
    body = bytes([unit, code]) + tail
    request = None if request_tail is None else bytes([unit, code & 0x7F]) + request_tail
    _check_sane(dissect(body, role, request=request), body)


@settings(max_examples=300, deadline=None)
@given(case=st.sampled_from(ALL_CASES), cut=st.integers(0, 300), role=roles)
def test_cut_valid_frames_never_raise(case: Case, cut: int, role: Role) -> None:
    body = h(case.body)[:cut]
    request = h(case.request)[: cut + 3] if case.request else None
    _check_sane(dissect(body, role, request=request), body)
