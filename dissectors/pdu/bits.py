"""Provides the bit family: FC 1 Read Coils, 2 Read Discrete Inputs, 5 Write Single Coil,
15 Write Multiple Coils, each with its layouts, framing rules and meaning."""

from __future__ import annotations

from construct import this

from dissectors.pdu.access import (
    ADDRESS_QUANTITY,
    ADDRESS_VALUE,
    read,
    write_multiple,
    write_single,
)
from dissectors.pdu.schema import Bits, Octets, Record, UInt8, UInt16
from dissectors.pdu.spec import (
    ECHO_ANSWER,
    AnswerRule,
    FunctionSpec,
    Limit,
    counted,
    fixed,
)

BITS_ANSWER = AnswerRule(5, quantity_pos=4, round_up=7, per_byte=8)

BITS_RESPONSE = Record(
    "byte_count" / UInt8,
    "values" / Bits(Octets(this.byte_count)),
)
WRITE_COILS_REQUEST = Record(
    "address" / UInt16,
    "quantity" / UInt16,
    "byte_count" / UInt8,
    "values" / Bits(Octets(this.byte_count)),
)

SPECS: tuple[FunctionSpec, ...] = (
    FunctionSpec(
        1,
        "Read Coils",
        request_length=fixed(8),
        response_length=counted(2, 5),
        answer=BITS_ANSWER,
        request_schema=ADDRESS_QUANTITY,
        response_schema=BITS_RESPONSE,
        family="read",
        table="coils",
        limits=(Limit("quantity", 1, 2000),),
        meaning=read,
    ),
    FunctionSpec(
        2,
        "Read Discrete Inputs",
        request_length=fixed(8),
        response_length=counted(2, 5),
        answer=BITS_ANSWER,
        request_schema=ADDRESS_QUANTITY,
        response_schema=BITS_RESPONSE,
        family="read",
        table="discrete_inputs",
        limits=(Limit("quantity", 1, 2000),),
        meaning=read,
    ),
    FunctionSpec(
        5,
        "Write Single Coil",
        request_length=fixed(8),
        response_length=fixed(8),
        answer=ECHO_ANSWER,
        echo=True,
        request_schema=ADDRESS_VALUE,
        response_schema=ADDRESS_VALUE,
        family="write_single",
        table="coils",
        meaning=write_single,
    ),
    FunctionSpec(
        15,
        "Write Multiple Coils",
        request_length=counted(6, 9),
        response_length=fixed(8),
        answer=AnswerRule(8),
        request_schema=WRITE_COILS_REQUEST,
        response_schema=ADDRESS_QUANTITY,
        family="write_multiple",
        table="coils",
        limits=(Limit("quantity", 1, 1968),),
        meaning=write_multiple,
    ),
)
"""The bit family's codes."""
