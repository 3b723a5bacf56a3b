"""Provides the register family: FC 3 Read Holding Registers, 4 Read Input Registers,
6 Write Single Register, 16 Write Multiple Registers, 22 Mask Write Register, 23
Read/Write Multiple Registers, 24 Read FIFO Queue, each with its layouts, framing rules
and meaning."""

from __future__ import annotations

from construct import this

from dissectors.pdu.access import (
    ADDRESS_QUANTITY,
    ADDRESS_VALUE,
    checked_values,
    read,
    write_multiple,
    write_single,
)
from dissectors.pdu.schema import Octets, Record, UInt8, UInt16, Words
from dissectors.pdu.spec import (
    ECHO_ANSWER,
    AnswerRule,
    FunctionSpec,
    Limit,
    counted,
    fixed,
)
from dissectors.pdu.work import ERROR, Work, address_text, echo, plural

REGISTERS_ANSWER = AnswerRule(5, quantity_pos=4, per_item=2)

REGISTERS_RESPONSE = Record(
    "byte_count" / UInt8,
    "values" / Words(Octets(this.byte_count)),
)
WRITE_REGISTERS_REQUEST = Record(
    "address" / UInt16,
    "quantity" / UInt16,
    "byte_count" / UInt8,
    "values" / Words(Octets(this.byte_count)),
)
MASK_WRITE = Record("address" / UInt16, "and_mask" / UInt16, "or_mask" / UInt16)
READ_WRITE_REQUEST = Record(
    "read_address" / UInt16,
    "read_quantity" / UInt16,
    "write_address" / UInt16,
    "write_quantity" / UInt16,
    "byte_count" / UInt8,
    "values" / Words(Octets(this.byte_count)),
)
FIFO_REQUEST = Record("fifo_address" / UInt16)
FIFO_RESPONSE = Record(
    "byte_count" / UInt16,
    "fifo_count" / UInt16,
    "values" / Words(Octets(this.fifo_count * 2)),
)


def read_write(w: Work) -> None:
    if w.is_request:
        write_address = w.get("write_address")
        write_quantity = w.get("write_quantity")
        values = checked_values(w, write_quantity, "write_quantity", from_request=False)
        if "values" in w.fields:
            w.carries(write_address, values, True)
        read_address, read_quantity = w.get("read_address"), w.get("read_quantity")
        if None in (read_address, read_quantity, write_address, write_quantity):
            w.summary = "read and write registers"
            return
        assert read_address is not None and read_quantity is not None
        assert write_address is not None and write_quantity is not None
        w.summary = (
            f"read {plural(read_quantity, 'register')} from {address_text(read_address)}, "
            f"write {plural(write_quantity, 'register')} from {address_text(write_address)}"
        )
        return
    values = checked_values(w, w.asked("read_quantity"), "read_quantity", from_request=True)
    if "values" in w.fields:
        w.carries(w.asked("read_address"), values, False)
    written = w.request_fields.get("values")
    if written is not None and isinstance(written.value, tuple):
        w.carries(w.asked("write_address"), written.value, True)
    w.summary = plural(len(values), "value")


def mask_write(w: Work) -> None:
    if not w.is_request:
        echo(w, ("address", "and_mask", "or_mask"))
    address, and_mask, or_mask = w.get("address"), w.get("and_mask"), w.get("or_mask")
    if address is None or and_mask is None or or_mask is None:
        w.summary = "mask write register"
        return
    w.summary = (
        f"mask write register {address_text(address)}: AND 0x{and_mask:04X}, OR 0x{or_mask:04X}"
    )


def fifo(w: Work) -> None:
    if w.is_request:
        address = w.get("fifo_address")
        w.summary = (
            "read FIFO queue" if address is None else f"read FIFO queue at {address_text(address)}"
        )
        return
    byte_count, fifo_count = w.get("byte_count"), w.get("fifo_count")
    if byte_count is not None and fifo_count is not None and byte_count != 2 + 2 * fifo_count:
        w.problem(
            "byte-count",
            ERROR,
            f"byte count {byte_count} but fifo_count {fifo_count} needs {2 + 2 * fifo_count}",
            w.span("byte_count"),
        )
    w.summary = f"FIFO: {plural(len(w.values('values')), 'value')}"


SPECS: tuple[FunctionSpec, ...] = (
    FunctionSpec(
        3,
        "Read Holding Registers",
        request_length=fixed(8),
        response_length=counted(2, 5),
        answer=REGISTERS_ANSWER,
        request_schema=ADDRESS_QUANTITY,
        response_schema=REGISTERS_RESPONSE,
        family="read",
        table="holding_registers",
        limits=(Limit("quantity", 1, 125),),
        meaning=read,
    ),
    FunctionSpec(
        4,
        "Read Input Registers",
        request_length=fixed(8),
        response_length=counted(2, 5),
        answer=REGISTERS_ANSWER,
        request_schema=ADDRESS_QUANTITY,
        response_schema=REGISTERS_RESPONSE,
        family="read",
        table="input_registers",
        limits=(Limit("quantity", 1, 125),),
        meaning=read,
    ),
    FunctionSpec(
        6,
        "Write Single Register",
        request_length=fixed(8),
        response_length=fixed(8),
        answer=ECHO_ANSWER,
        echo=True,
        request_schema=ADDRESS_VALUE,
        response_schema=ADDRESS_VALUE,
        family="write_single",
        table="holding_registers",
        meaning=write_single,
    ),
    FunctionSpec(
        16,
        "Write Multiple Registers",
        request_length=counted(6, 9),
        response_length=fixed(8),
        answer=AnswerRule(8),
        request_schema=WRITE_REGISTERS_REQUEST,
        response_schema=ADDRESS_QUANTITY,
        family="write_multiple",
        table="holding_registers",
        limits=(Limit("quantity", 1, 123),),
        meaning=write_multiple,
    ),
    FunctionSpec(
        22,
        "Mask Write Register",
        request_length=fixed(10),
        response_length=fixed(10),
        answer=ECHO_ANSWER,
        echo=True,
        request_schema=MASK_WRITE,
        response_schema=MASK_WRITE,
        family="mask_write",
        table="holding_registers",
        meaning=mask_write,
    ),
    FunctionSpec(
        23,
        "Read/Write Multiple Registers",
        request_length=counted(10, 13),
        response_length=counted(2, 5),
        answer=REGISTERS_ANSWER,
        request_schema=READ_WRITE_REQUEST,
        response_schema=REGISTERS_RESPONSE,
        family="read_write",
        table="holding_registers",
        limits=(Limit("read_quantity", 1, 125), Limit("write_quantity", 1, 121)),
        meaning=read_write,
    ),
    FunctionSpec(
        24,
        "Read FIFO Queue",
        request_length=fixed(6),
        response_length=counted(2, 6, size=2),
        request_schema=FIFO_REQUEST,
        response_schema=FIFO_RESPONSE,
        family="fifo",
        table="holding_registers",
        limits=(Limit("fifo_count", 0, 31),),
        meaning=fifo,
    ),
)
"""The register family's codes."""
