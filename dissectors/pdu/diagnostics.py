"""Provides the diagnostics family: FC 7 Read Exception Status, 8 Diagnostics, 11 Get
Comm Event Counter, 12 Get Comm Event Log, 17 Report Server ID, each with its layouts,
framing rules and meaning, and the FC 8 sub-function table."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from construct import Bytes, GreedyBytes, this

from dissectors.pdu.schema import Octets, Record, UInt8, UInt16, Words
from dissectors.pdu.spec import ECHO_ANSWER, AnswerRule, FunctionSpec, counted, fixed
from dissectors.pdu.work import ERROR, INFO, WARNING, Work, echo, plural

EMPTY = Record()
EXCEPTION_STATUS_RESPONSE = Record("status" / UInt8)
DIAGNOSTICS = Record("sub_function" / UInt16, "data" / Words(GreedyBytes))
EVENT_COUNTER_RESPONSE = Record("status" / UInt16, "event_count" / UInt16)
EVENT_LOG_RESPONSE = Record(
    "byte_count" / UInt8,
    "status" / UInt16,
    "event_count" / UInt16,
    "message_count" / UInt16,
    "events" / Octets(this.byte_count - 6),
)
SERVER_ID_RESPONSE = Record(
    "byte_count" / UInt8,
    "server_id" / Bytes(1),  # device specific; one byte is what devices and pymodbus send
    "run_indicator" / UInt8,
    "additional" / Octets(this.byte_count - 2),
)

_RUN_STATES = {0xFF: "ON", 0x00: "OFF"}
_STATUS_WORDS = {0x0000: "ready", 0xFFFF: "busy"}


@dataclass(frozen=True, slots=True)
class SubFunction:
    """One FC 8 diagnostics sub-function: its name, the request data the spec allows
    (None: any), and what the response carries: `echo` (the request again), `count`
    (a counter), `register` (the diagnostic register) or `none` (no response)."""

    code: int
    name: str
    request_data: tuple[int, ...] | None = (0x0000,)
    answer: str = "echo"


DIAGNOSTIC_SUB_FUNCTIONS: dict[int, SubFunction] = {
    sub.code: sub
    for sub in (
        SubFunction(0x00, "return query data", request_data=None),
        SubFunction(0x01, "restart communications option", request_data=(0x0000, 0xFF00)),
        SubFunction(0x02, "return diagnostic register", answer="register"),
        SubFunction(0x03, "change ASCII input delimiter", request_data=None),
        SubFunction(0x04, "force listen only mode", answer="none"),
        SubFunction(0x0A, "clear counters and diagnostic register"),
        SubFunction(0x0B, "return bus message count", answer="count"),
        SubFunction(0x0C, "return bus communication error count", answer="count"),
        SubFunction(0x0D, "return bus exception error count", answer="count"),
        SubFunction(0x0E, "return server message count", answer="count"),
        SubFunction(0x0F, "return server no response count", answer="count"),
        SubFunction(0x10, "return server NAK count", answer="count"),
        SubFunction(0x11, "return server busy count", answer="count"),
        SubFunction(0x12, "return bus character overrun count", answer="count"),
        SubFunction(0x14, "clear overrun counter and flag"),
    )
}
"""The FC 8 sub-functions the spec defines; every other sub-function code is reserved."""


def exception_status(w: Work) -> None:
    status = w.get("status")
    if w.is_request:
        w.summary = "read exception status"
    elif status is None:
        w.summary = "exception status"
    else:
        w.retext("status", f"0x{status:02X} (bits {status:08b})")
        w.summary = f"exception status 0x{status:02X}"


def _restart_text(data: int) -> str:
    return {0xFF00: "clear the event log", 0x0000: "keep the event log"}.get(data, f"0x{data:04X}")


def _delimiter_text(data: int) -> str:
    return f"delimiter 0x{data >> 8:02X}"


_DIAGNOSTIC_DATA_TEXT: dict[int, Callable[[int], str]] = {
    0x01: _restart_text,
    0x03: _delimiter_text,
}


def diagnostics(w: Work) -> None:
    code = w.get("sub_function")
    if code is None:
        w.summary = "diagnostics"
        return
    sub = DIAGNOSTIC_SUB_FUNCTIONS.get(code)
    name = sub.name if sub is not None else f"reserved sub-function 0x{code:04X}"
    w.retext("sub_function", name)
    if sub is None:
        w.problem(
            "sub-function", INFO, f"sub-function 0x{code:04X} is reserved", w.span("sub_function")
        )
    data = w.fields.get("data")
    words = w.values("data")
    if data is not None and (data.span[1] - data.span[0]) % 2:
        w.problem(
            "odd-byte-count",
            ERROR,
            f"odd data length {data.span[1] - data.span[0]}: not whole 16-bit words",
            data.span,
        )
    w.summary = f"diagnostics: {name}"
    describe = _DIAGNOSTIC_DATA_TEXT.get(code)
    if describe is not None and len(words) == 1:
        w.retext("data", describe(words[0]))
    if w.is_request:
        allowed = sub.request_data if sub is not None else None
        if (
            allowed is not None
            and data is not None
            and (len(words) != 1 or words[0] not in allowed)
        ):
            choices = " or ".join(f"0x{value:04X}" for value in allowed)
            w.problem(
                "diagnostic-data",
                WARNING,
                f"data {data.text} should be {choices} for {name}",
                data.span,
            )
        return
    answer = sub.answer if sub is not None else "unknown"
    if answer == "none":
        w.problem("unexpected-response", WARNING, f"{name} gets no response", None)
    echo(w, None if answer == "echo" else ("sub_function",))
    if answer == "count" and len(words) == 1:
        w.retext("data", str(words[0]))
        w.summary = f"diagnostics: {name}: {words[0]}"
    elif answer == "register" and len(words) == 1:
        w.summary = f"diagnostics: {name}: 0x{words[0]:04X}"


def event_counter(w: Work) -> None:
    if w.is_request:
        w.summary = "get comm event counter"
        return
    status, count = w.get("status"), w.get("event_count")
    if status is not None:
        w.retext("status", _STATUS_WORDS.get(status, f"0x{status:04X}"))
    if status is None or count is None:
        w.summary = "comm event counter"
        return
    w.summary = f"event counter {count}, {_STATUS_WORDS.get(status, f'status 0x{status:04X}')}"


def event_log(w: Work) -> None:
    if w.is_request:
        w.summary = "get comm event log"
        return
    status = w.get("status")
    if status is not None:
        w.retext("status", _STATUS_WORDS.get(status, f"0x{status:04X}"))
    count, messages = w.get("event_count"), w.get("message_count")
    events = w.fields.get("events")
    if status is None or count is None or messages is None:
        w.summary = "comm event log"
        return
    stored = len(events.value) if events is not None and isinstance(events.value, bytes) else 0
    w.summary = (
        f"event log: {_STATUS_WORDS.get(status, f'status 0x{status:04X}')}, "
        f"event count {count}, message count {messages}, {plural(stored, 'event')}"
    )


def server_id(w: Work) -> None:
    if w.is_request:
        w.summary = "report server id"
        return
    server = w.fields.get("server_id")
    run = w.get("run_indicator")
    state = None if run is None else _RUN_STATES.get(run)
    if run is not None and state is None:
        w.problem(
            "run-indicator",
            WARNING,
            f"run indicator 0x{run:02X} is not 0x00 (OFF) or 0xFF (ON)",
            w.span("run_indicator"),
        )
    if state is not None:
        w.retext("run_indicator", state)
    if server is None or run is None:
        w.summary = "server id"
        return
    w.summary = f"server id {server.text}, run indicator {state or f'0x{run:02X}'}"


SPECS: tuple[FunctionSpec, ...] = (
    FunctionSpec(
        7,
        "Read Exception Status",
        request_length=fixed(4),
        response_length=fixed(5),
        answer=AnswerRule(5),
        request_schema=EMPTY,
        response_schema=EXCEPTION_STATUS_RESPONSE,
        family="exception_status",
        meaning=exception_status,
    ),
    FunctionSpec(
        8,
        "Diagnostics",
        request_length=fixed(8),
        response_length=fixed(8),
        answer=ECHO_ANSWER,
        echo=True,
        request_schema=DIAGNOSTICS,
        response_schema=DIAGNOSTICS,
        family="diagnostics",
        meaning=diagnostics,
    ),
    FunctionSpec(
        11,
        "Get Comm Event Counter",
        request_length=fixed(4),
        response_length=fixed(8),
        answer=AnswerRule(8),
        request_schema=EMPTY,
        response_schema=EVENT_COUNTER_RESPONSE,
        family="event_counter",
        meaning=event_counter,
    ),
    FunctionSpec(
        12,
        "Get Comm Event Log",
        request_length=fixed(4),
        response_length=counted(2, 5),
        request_schema=EMPTY,
        response_schema=EVENT_LOG_RESPONSE,
        family="event_log",
        meaning=event_log,
    ),
    FunctionSpec(
        17,
        "Report Server ID",
        request_length=fixed(4),
        response_length=counted(2, 5),
        request_schema=EMPTY,
        response_schema=SERVER_ID_RESPONSE,
        family="server_id",
        meaning=server_id,
    ),
)
"""The diagnostics family's codes."""
