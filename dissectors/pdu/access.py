"""Provides reading and writing the data tables, which the bit and register families
share: the address-quantity and address-value layouts, the check of a values array
against its byte count and quantity, and the meaning of reads, single writes and multiple
writes (FC 1-6, 15, 16). Each family module names its codes and tables; this says what
their fields mean."""

from __future__ import annotations

from typing import Any

from dissectors.pdu.schema import Record, UInt16
from dissectors.pdu.work import (
    BIT_TABLES,
    ERROR,
    INFO,
    BitsField,
    Work,
    address_text,
    echo,
    plural,
)
from dissectors.values import make_lazy_field

ADDRESS_QUANTITY = Record("address" / UInt16, "quantity" / UInt16)
ADDRESS_VALUE = Record("address" / UInt16, "value" / UInt16)

_READ_NOUNS = {
    "coils": "coil",
    "discrete_inputs": "discrete input",
    "input_registers": "input register",
    "holding_registers": "holding register",
}
_WRITE_NOUNS = {"coils": "coil", "holding_registers": "register"}
COIL_STATES = {0xFF00: "ON", 0x0000: "OFF"}  # the values a write of one coil may carry


def checked_values(
    w: Work, quantity: int | None, quantity_name: str, *, from_request: bool
) -> tuple[int, ...]:
    """Check the `values` field against its byte count and the quantity that asked for it;
    cut coil and input bits to the quantity. Returns the real values."""
    found = w.fields.get("values")
    if found is None:
        return ()
    values = found.value if isinstance(found.value, tuple) else ()
    byte_count = w.get("byte_count")
    bits = w.table in BIT_TABLES
    need: int | None = None
    if bits:
        if quantity is not None:
            need = (quantity + 7) // 8
            if len(values) >= quantity:
                padding = values[quantity : need * 8]
                if any(padding):
                    start = found.span[0] + quantity // 8
                    w.problem(
                        "padding",
                        INFO,
                        f"padding bits after {plural(quantity, 'value')} are not zero",
                        (start, min(found.span[1], found.span[0] + need)),
                    )
                values = values[:quantity]
                w.fields["values"] = make_lazy_field(BitsField, "values", values, found.span)
    else:
        if quantity is not None:
            need = 2 * quantity
        if byte_count is not None and byte_count % 2:
            w.problem(
                "odd-byte-count",
                ERROR,
                f"byte count {byte_count} is odd: registers are 2 bytes each",
                w.span("byte_count"),
            )
    if byte_count is not None and need is not None and byte_count != need:
        whose = "the request's " if from_request else ""
        w.problem(
            "byte-count",
            ERROR,
            f"byte count {byte_count} but {whose}{quantity_name} {quantity} needs {need}",
            w.span("byte_count"),
        )
    return values


def read(w: Work) -> None:
    if w.is_request:
        noun = _READ_NOUNS.get(w.table, "value")
        values = w.record
        address, quantity = values.get("address"), values.get("quantity")
        if isinstance(address, int) and isinstance(quantity, int):
            w.summary = f"read {plural(quantity, noun)} from {address_text(address)}"
        else:
            w.summary = f"read {noun}s"
        return
    request = w.request
    asked = _NO_VALUES if request is None else request.values
    quantity = asked.get("quantity")
    if not isinstance(quantity, int):
        quantity = None
    values = checked_values(w, quantity, "quantity", from_request=True)
    if "values" in w.fields:
        address = asked.get("address")
        w.carries(address if isinstance(address, int) else None, values, False)
    w.summary = "1 value" if len(values) == 1 else f"{len(values)} values"


_NO_VALUES: dict[str, Any] = {}  # never written to


def write_single(w: Work) -> None:
    address, value = w.get("address"), w.get("value")
    if not w.is_request:
        echo(w, ("address", "value"))
    if address is None or value is None:
        w.summary = f"write {_WRITE_NOUNS.get(w.table, 'value')}"
        return
    if w.table in BIT_TABLES:
        state = COIL_STATES.get(value)
        if state is None:
            w.problem(
                "coil-value",
                ERROR,
                f"coil value 0x{value:04X} is not 0xFF00 (ON) or 0x0000 (OFF)",
                w.span("value"),
            )
            w.summary = f"coil {address_text(address)} 0x{value:04X}"
            return
        w.retext("value", state)
        w.summary = f"coil {address_text(address)} {state}"
        w.carries(address, (1 if state == "ON" else 0,), True)
        return
    w.summary = f"write 0x{value:04X} to register {address_text(address)}"
    w.carries(address, (value,), True)


def write_multiple(w: Work) -> None:
    noun = _WRITE_NOUNS.get(w.table, "value")
    address, quantity = w.get("address"), w.get("quantity")
    if w.is_request:
        values = checked_values(w, quantity, "quantity", from_request=False)
        if "values" in w.fields:
            w.carries(address, values, True)
        verb = "write"
    else:
        echo(w, ("address", "quantity"))
        if w.request is not None:
            written = w.request_fields.get("values")
            if written is not None and isinstance(written.value, tuple):
                asked_quantity = w.asked("quantity")
                values = written.value
                if w.table in BIT_TABLES and asked_quantity is not None:
                    values = values[:asked_quantity]
                w.carries(w.asked("address"), values, True)
        verb = "wrote"
    if address is None or quantity is None:
        w.summary = f"{verb} {noun}s"
    else:
        w.summary = f"{verb} {plural(quantity, noun)} from {address_text(address)}"
