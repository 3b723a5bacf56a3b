"""Cross-check with pymodbus, an implementation nobody here wrote: frames that pymodbus
encodes from random values dissect to the same values, for every function code pymodbus
can encode."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymodbus.pdu import bit_message, diag_message, file_message, mei_message, other_message
from pymodbus.pdu import register_message as reg
from pymodbus.pdu.exceptionresponse import ExceptionResponse

from dissectors.dissect import Dissection, Role, dissect

REQ = Role.REQUEST
RSP = Role.RESPONSE

units = st.integers(1, 247)
addresses = st.integers(0, 0xFFFF)
words = st.integers(0, 0xFFFF)
CROSS = settings(max_examples=60, deadline=None)


def body(unit: int, pdu: Any) -> bytes:
    """unit byte, function code, then what pymodbus encodes."""
    encoded: bytes = pdu.encode()
    return bytes([unit, pdu.function_code]) + encoded


def clean(result: Dissection) -> Dissection:
    assert result.problems == (), result.problems
    return result


def value(result: Dissection, name: str) -> Any:
    found = result.field(name)
    assert found is not None, f"{name} missing from {[f.name for f in result.fields]}"
    return found.value


READ_REQUESTS = [
    (bit_message.ReadCoilsRequest, 1, 2000),
    (bit_message.ReadDiscreteInputsRequest, 2, 2000),
    (reg.ReadHoldingRegistersRequest, 3, 125),
    (reg.ReadInputRegistersRequest, 4, 125),
]


@pytest.mark.parametrize(("cls", "code", "limit"), READ_REQUESTS)
@CROSS
@given(data=st.data(), unit=units, address=addresses)
def test_read_requests(cls: Any, code: int, limit: int, data: Any, unit: int, address: int) -> None:
    count = data.draw(st.integers(1, limit))
    frame = body(unit, cls(address=address, count=count, dev_id=unit))
    result = clean(dissect(frame, REQ))
    assert (result.unit, result.function) == (unit, code)
    assert value(result, "address") == address
    assert value(result, "quantity") == count


@pytest.mark.parametrize(
    ("cls", "request_cls", "table"),
    [
        (bit_message.ReadCoilsResponse, bit_message.ReadCoilsRequest, "coils"),
        (
            bit_message.ReadDiscreteInputsResponse,
            bit_message.ReadDiscreteInputsRequest,
            "discrete_inputs",
        ),
    ],
)
@CROSS
@given(unit=units, address=addresses, bits=st.lists(st.booleans(), min_size=1, max_size=2000))
def test_bit_responses(
    cls: Any, request_cls: Any, table: str, unit: int, address: int, bits: list[bool]
) -> None:
    request = body(unit, request_cls(address=address, count=len(bits), dev_id=unit))
    frame = body(unit, cls(bits=bits, dev_id=unit))
    result = clean(dissect(frame, RSP, request=request))
    expected = tuple(int(bit) for bit in bits)
    assert value(result, "values") == expected
    assert value(result, "byte_count") == (len(bits) + 7) // 8
    assert result.data[0].table == table
    assert result.data[0].address == address
    assert result.data[0].values == expected


@pytest.mark.parametrize(
    ("cls", "request_cls", "table"),
    [
        (reg.ReadHoldingRegistersResponse, reg.ReadHoldingRegistersRequest, "holding_registers"),
        (reg.ReadInputRegistersResponse, reg.ReadInputRegistersRequest, "input_registers"),
    ],
)
@CROSS
@given(unit=units, address=addresses, registers=st.lists(words, min_size=1, max_size=125))
def test_register_responses(
    cls: Any, request_cls: Any, table: str, unit: int, address: int, registers: list[int]
) -> None:
    request = body(unit, request_cls(address=address, count=len(registers), dev_id=unit))
    frame = body(unit, cls(registers=registers, dev_id=unit))
    result = clean(dissect(frame, RSP, request=request))
    assert value(result, "values") == tuple(registers)
    assert result.data[0].table == table
    assert result.data[0].address == address


@CROSS
@given(unit=units, address=addresses, state=st.booleans(), role=st.sampled_from([REQ, RSP]))
def test_write_single_coil(unit: int, address: int, state: bool, role: Role) -> None:
    cls = bit_message.WriteSingleCoilRequest if role is REQ else bit_message.WriteSingleCoilResponse
    frame = body(unit, cls(address=address, bits=[state], dev_id=unit))
    result = clean(dissect(frame, role, request=frame if role is RSP else None))
    assert value(result, "address") == address
    assert value(result, "value") == (0xFF00 if state else 0x0000)
    assert result.data[0].values == (int(state),)


@CROSS
@given(unit=units, address=addresses, register=words, role=st.sampled_from([REQ, RSP]))
def test_write_single_register(unit: int, address: int, register: int, role: Role) -> None:
    cls = reg.WriteSingleRegisterRequest if role is REQ else reg.WriteSingleRegisterResponse
    frame = body(unit, cls(address=address, registers=[register], dev_id=unit))
    result = clean(dissect(frame, role, request=frame if role is RSP else None))
    assert value(result, "address") == address
    assert value(result, "value") == register


@CROSS
@given(unit=units, address=addresses, bits=st.lists(st.booleans(), min_size=1, max_size=1968))
def test_write_multiple_coils(unit: int, address: int, bits: list[bool]) -> None:
    request = body(unit, bit_message.WriteMultipleCoilsRequest(address, bits, dev_id=unit))
    result = clean(dissect(request, REQ))
    expected = tuple(int(bit) for bit in bits)
    assert value(result, "address") == address
    assert value(result, "quantity") == len(bits)
    assert value(result, "values") == expected
    response_pdu = bit_message.WriteMultipleCoilsResponse(
        address=address, count=len(bits), dev_id=unit
    )
    answer = clean(dissect(body(unit, response_pdu), RSP, request=request))
    assert value(answer, "quantity") == len(bits)
    assert answer.data[0].values == expected


@CROSS
@given(unit=units, address=addresses, registers=st.lists(words, min_size=1, max_size=123))
def test_write_multiple_registers(unit: int, address: int, registers: list[int]) -> None:
    request_pdu = reg.WriteMultipleRegistersRequest(
        address=address, registers=registers, dev_id=unit
    )
    request = body(unit, request_pdu)
    result = clean(dissect(request, REQ))
    assert value(result, "values") == tuple(registers)
    assert value(result, "byte_count") == 2 * len(registers)
    response_pdu = reg.WriteMultipleRegistersResponse(
        address=address, count=len(registers), dev_id=unit
    )
    answer = clean(dissect(body(unit, response_pdu), RSP, request=request))
    assert (value(answer, "address"), value(answer, "quantity")) == (address, len(registers))


@CROSS
@given(unit=units, address=addresses, and_mask=words, or_mask=words)
def test_mask_write(unit: int, address: int, and_mask: int, or_mask: int) -> None:
    request = body(unit, reg.MaskWriteRegisterRequest(address, and_mask, or_mask, unit))
    response = body(unit, reg.MaskWriteRegisterResponse(address, and_mask, or_mask, unit))
    for role, frame in ((REQ, request), (RSP, response)):
        result = clean(dissect(frame, role, request=request if role is RSP else None))
        assert value(result, "address") == address
        assert value(result, "and_mask") == and_mask
        assert value(result, "or_mask") == or_mask


@CROSS
@given(
    unit=units,
    read_address=addresses,
    read_count=st.integers(1, 125),
    write_address=addresses,
    written=st.lists(words, min_size=1, max_size=121),
    read_values=st.data(),
)
def test_read_write_registers(
    unit: int,
    read_address: int,
    read_count: int,
    write_address: int,
    written: list[int],
    read_values: Any,
) -> None:
    request_pdu = reg.ReadWriteMultipleRegistersRequest(
        read_address=read_address,
        read_count=read_count,
        write_address=write_address,
        write_registers=written,
        dev_id=unit,
    )
    request = body(unit, request_pdu)
    result = clean(dissect(request, REQ))
    assert value(result, "read_address") == read_address
    assert value(result, "read_quantity") == read_count
    assert value(result, "write_address") == write_address
    assert value(result, "write_quantity") == len(written)
    assert value(result, "values") == tuple(written)
    registers = read_values.draw(st.lists(words, min_size=read_count, max_size=read_count))
    response = body(unit, reg.ReadWriteMultipleRegistersResponse(registers=registers, dev_id=unit))
    answer = clean(dissect(response, RSP, request=request))
    assert value(answer, "values") == tuple(registers)
    assert [(d.address, d.write) for d in answer.data] == [
        (read_address, False),
        (write_address, True),
    ]


@CROSS
@given(unit=units, address=addresses, queued=st.lists(words, max_size=31))
def test_fifo(unit: int, address: int, queued: list[int]) -> None:
    request = clean(dissect(body(unit, file_message.ReadFifoQueueRequest(address, unit)), REQ))
    assert value(request, "fifo_address") == address
    response_pdu = file_message.ReadFifoQueueResponse(values=queued, dev_id=unit)
    result = clean(dissect(body(unit, response_pdu), RSP))
    assert value(result, "fifo_count") == len(queued)
    assert value(result, "values") == tuple(queued)


@CROSS
@given(unit=units, status=st.integers(0, 255))
def test_exception_status(unit: int, status: int) -> None:
    clean(dissect(body(unit, other_message.ReadExceptionStatusRequest(dev_id=unit)), REQ))
    response_pdu = other_message.ReadExceptionStatusResponse(status=status, dev_id=unit)
    result = clean(dissect(body(unit, response_pdu), RSP))
    assert value(result, "status") == status


DIAGNOSTICS = [
    (getattr(diag_message, f"{name}Request"), getattr(diag_message, f"{name}Response"))
    for name in (
        "ReturnQueryData",
        "RestartCommunicationsOption",
        "ReturnDiagnosticRegister",
        "ChangeAsciiInputDelimiter",
        "ClearCounters",
        "ReturnBusMessageCount",
        "ReturnBusCommunicationErrorCount",
        "ReturnBusExceptionErrorCount",
        "ReturnDeviceMessageCount",
        "ReturnDeviceNoResponseCount",
        "ReturnDeviceNAKCount",
        "ReturnDeviceBusyCount",
        "ReturnDeviceBusCharacterOverrunCount",
        "ReturnIopOverrunCount",
        "ClearOverrunCount",
    )
]
ECHOED_SUB_FUNCTIONS = {0x00, 0x01, 0x03, 0x0A, 0x14}  # the others answer with a value
RESERVED_SUB_FUNCTIONS = {0x13}  # pymodbus still knows the IOP overrun count; the spec reserves it


@pytest.mark.parametrize(("request_cls", "response_cls"), DIAGNOSTICS)
@CROSS
@given(unit=units, answer=words)
def test_diagnostics(request_cls: Any, response_cls: Any, unit: int, answer: int) -> None:
    sub = request_cls.sub_function_code
    request_data = {0x00: answer, 0x01: 0xFF00 if answer & 1 else 0x0000}.get(sub, 0x0000)
    if sub == 0x03:
        request_data = (answer & 0xFF) << 8
    request = body(unit, request_cls(message=request_data, dev_id=unit))
    response_data = request_data if sub in ECHOED_SUB_FUNCTIONS else answer
    response = body(unit, response_cls(message=response_data, dev_id=unit))
    for role, frame, data in ((REQ, request, request_data), (RSP, response, response_data)):
        result = dissect(frame, role, request=request if role is RSP else None)
        if sub in RESERVED_SUB_FUNCTIONS:
            assert [p.kind for p in result.problems] == ["sub-function"]
        else:
            clean(result)
        assert value(result, "sub_function") == sub
        assert value(result, "data") == (data,)


def test_force_listen_only() -> None:
    request = body(1, diag_message.ForceListenOnlyModeRequest(message=0, dev_id=1))
    result = clean(dissect(request, REQ))
    assert value(result, "sub_function") == 4
    assert result.summary == "diagnostics: force listen only mode"


@CROSS
@given(unit=units, count=words, busy=st.booleans())
def test_comm_event_counter(unit: int, count: int, busy: bool) -> None:
    clean(dissect(body(unit, other_message.GetCommEventCounterRequest(dev_id=unit)), REQ))
    response_pdu = other_message.GetCommEventCounterResponse(count=count, status=not busy)
    result = clean(dissect(body(unit, response_pdu), RSP))
    assert value(result, "event_count") == count
    assert value(result, "status") == (0xFFFF if busy else 0x0000)


@CROSS
@given(
    unit=units,
    ready=st.booleans(),
    messages=words,
    events_counted=words,
    events=st.lists(st.integers(0, 255), max_size=64),
)
def test_comm_event_log(
    unit: int, ready: bool, messages: int, events_counted: int, events: list[int]
) -> None:
    clean(dissect(body(unit, other_message.GetCommEventLogRequest(dev_id=unit)), REQ))
    response_pdu = other_message.GetCommEventLogResponse(
        status=ready,
        message_count=messages,
        event_count=events_counted,
        events=events,
        dev_id=unit,
    )
    result = clean(dissect(body(unit, response_pdu), RSP))
    assert value(result, "status") == (0x0000 if ready else 0xFFFF)
    assert value(result, "message_count") == messages
    assert value(result, "event_count") == events_counted
    assert value(result, "events") == bytes(events)


@CROSS
@given(unit=units, server_id=st.binary(min_size=1, max_size=1), running=st.booleans())
def test_report_server_id(unit: int, server_id: bytes, running: bool) -> None:
    clean(dissect(body(unit, other_message.ReportDeviceIdRequest(dev_id=unit)), REQ))
    response_pdu = other_message.ReportDeviceIdResponse(
        identifier=server_id, status=running, dev_id=unit
    )
    result = clean(dissect(body(unit, response_pdu), RSP))
    assert value(result, "server_id") == server_id
    assert value(result, "run_indicator") == (0xFF if running else 0x00)


file_numbers = st.integers(1, 0xFFFF)
record_numbers = st.integers(0, 9999)


@CROSS
@given(
    unit=units,
    items=st.lists(
        st.tuples(file_numbers, record_numbers, st.integers(1, 8)), min_size=1, max_size=5
    ),
)
def test_read_file_record(unit: int, items: list[tuple[int, int, int]]) -> None:
    records = [
        file_message.FileRecord(file_number=f, record_number=r, record_length=2 * n)
        for f, r, n in items
    ]
    request_pdu = file_message.ReadFileRecordRequest(records=records, dev_id=unit)
    result = clean(dissect(body(unit, request_pdu), REQ))
    found = value(result, "byte_count")
    assert found == 7 * len(items)
    sub_requests = result.field("sub_requests")
    assert sub_requests is not None
    got = [
        tuple(child.value for child in item.children if child.name != "reference_type")
        for item in sub_requests.children
    ]
    assert got == items
    payloads = [bytes(range(2 * n)) for _, _, n in items]
    response_pdu = file_message.ReadFileRecordResponse(
        records=[file_message.FileRecord(record_data=data) for data in payloads], dev_id=unit
    )
    answer = clean(dissect(body(unit, response_pdu), RSP))
    sub_responses = answer.field("sub_responses")
    assert sub_responses is not None
    decoded = [
        bytes(b"".join(w.to_bytes(2, "big") for w in child.value))
        for item in sub_responses.children
        for child in item.children
        if child.name == "record_data" and isinstance(child.value, tuple)
    ]
    assert decoded == payloads


@CROSS
@given(
    unit=units,
    items=st.lists(
        st.tuples(file_numbers, record_numbers, st.lists(words, min_size=1, max_size=8)),
        min_size=1,
        max_size=4,
    ),
)
def test_write_file_record(unit: int, items: list[tuple[int, int, list[int]]]) -> None:
    records = [
        file_message.FileRecord(
            file_number=f, record_number=r, record_data=b"".join(w.to_bytes(2, "big") for w in ws)
        )
        for f, r, ws in items
    ]
    request = body(unit, file_message.WriteFileRecordRequest(records=records, dev_id=unit))
    response = body(unit, file_message.WriteFileRecordResponse(records=records, dev_id=unit))
    for role, frame in ((REQ, request), (RSP, response)):
        result = clean(dissect(frame, role, request=request if role is RSP else None))
        sub_requests = result.field("sub_requests")
        assert sub_requests is not None
        got = []
        for item in sub_requests.children:
            parts: dict[str, Any] = {child.name: child.value for child in item.children}
            got.append((parts["file_number"], parts["record_number"], list(parts["record_data"])))
            assert parts["record_length"] == len(parts["record_data"])
        assert got == items


printable = st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=20)


@CROSS
@given(
    unit=units,
    read_code=st.integers(1, 4),
    object_id=st.integers(0, 0xFF),
    information=st.dictionaries(st.integers(0, 0xFF), printable, max_size=6),
)
def test_read_device_information(
    unit: int, read_code: int, object_id: int, information: dict[int, str]
) -> None:
    request_pdu = mei_message.ReadDeviceInformationRequest(read_code, object_id, dev_id=unit)
    result = clean(dissect(body(unit, request_pdu), REQ))
    assert value(result, "mei_type") == 0x0E
    assert value(result, "read_device_id_code") == read_code
    assert value(result, "object_id") == object_id
    encoded = {key: text.encode() for key, text in information.items()}
    response_pdu = mei_message.ReadDeviceInformationResponse(read_code, encoded, dev_id=unit)
    answer = clean(dissect(body(unit, response_pdu), RSP))
    assert value(answer, "number_of_objects") == len(information)
    objects = answer.field("objects")
    assert objects is not None
    assert [child.value for child in objects.children] == list(information.values())
    if information:
        assert f"={next(iter(information.values()))}" in answer.summary


@CROSS
@given(
    unit=units,
    function=st.sampled_from([1, 2, 3, 4, 5, 6, 7, 8, 11, 12, 15, 16, 17, 20, 21, 22, 23, 24, 43]),
    code=st.integers(0, 255),
)
def test_exception_responses(unit: int, function: int, code: int) -> None:
    frame = body(unit, ExceptionResponse(function, code, device_id=unit))
    result = clean(dissect(frame, RSP))
    assert result.exception
    assert result.function == function
    assert value(result, "exception_code") == code
    assert result.summary.startswith(f"exception {code:02X} ")
