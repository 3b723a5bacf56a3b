"""Provides dissect(): one frame body in; its fields, meaning, problems and register data out.

The layouts are the construct schemas on each FunctionSpec of a registry; here a frame is
parsed with them, every parsed field becomes a `Field` with its byte span, and the spec's
meaning routine reads meaning into the fields. Whatever is wrong with the bytes becomes a
`Problem`; nothing here raises on bus data.

Speed: what depends only on the registry, the function code and the direction is worked
out once (a plan per code byte and direction, kept on the registry). The commonest frame
a capture has that was not seen before, a well-formed answer to an FC 3 or 4 read (the
values change, the requests repeat), is read straight from its bytes (`_words_answer`):
the same Dissection the schemas and the meaning routine give, which
`tests/dissectors/test_dissect_fast.py` holds to on arbitrary bytes.
"""

from __future__ import annotations

from dissectors.pdu.access import ADDRESS_QUANTITY, read
from dissectors.pdu.exceptions import EXCEPTION_SCHEMA, exception
from dissectors.pdu.registers import REGISTERS_RESPONSE
from dissectors.pdu.registry import PUBLIC, Registry, raw
from dissectors.pdu.schema import RAW_SCHEMA, WORD_FORMATS
from dissectors.pdu.work import (
    ERROR,
    SEEN,
    WARNING,
    Parsed,
    Plan,
    WordsField,
    Work,
    check_structure,
    keep,
    pair,
    plural,
)
from dissectors.values import (
    Dissection,
    Role,
    make_dissection,
    make_field,
    make_lazy_field,
    make_problem,
    make_register_data,
)

_REQUEST = Role.REQUEST


def _plan(code: int, role: Role, registry: Registry) -> Plan:
    is_exception = code >= 0x80
    function = code & 0x7F
    spec = registry.get(function)
    if is_exception:
        schema, family, routine = EXCEPTION_SCHEMA, "exception", exception
    elif spec is None or spec.meaning is None:
        schema, family, routine = RAW_SCHEMA, "raw", raw
    else:
        schema = spec.request_schema if role is Role.REQUEST else spec.response_schema
        family, routine = spec.family, spec.meaning
    keeps = role is Role.REQUEST and family not in ("exception", "raw")
    names = {sc.name for sc in schema.subcons}
    counted = "byte_count" in names
    limits = tuple(limit for limit in (spec.limits if spec else ()) if limit.field in names)
    return Plan(
        schema=schema,
        family=family,
        routine=routine,
        spec=spec,
        function=function,
        exception=is_exception,
        name=registry.function_name(function),
        table=(spec.table or "") if spec is not None else "",
        limits=limits,
        is_request=role is Role.REQUEST,
        keep=keeps,
        reuse=keeps or (spec is not None and schema is spec.request_schema),
        counted=counted,
        checked=counted or bool(limits),
        words_answer=(
            role is Role.RESPONSE
            and not is_exception
            and spec is not None
            and spec.meaning is read
            and spec.response_schema is REGISTERS_RESPONSE
            and spec.request_schema is ADDRESS_QUANTITY
        ),
    )


def plans(registry: Registry) -> tuple[tuple[Plan, ...], tuple[Plan, ...]]:
    """The plan for each code byte (function, with the exception bit), for requests and
    for responses, made once per registry."""
    made = registry.plans
    if made is None:
        made = registry.plans = (
            tuple(_plan(code, Role.REQUEST, registry) for code in range(256)),
            tuple(_plan(code, Role.RESPONSE, registry) for code in range(256)),
        )
    return made  # type: ignore[no-any-return]


_PUBLIC_PLANS = plans(PUBLIC)


def dissect(
    body: bytes,
    role: Role,
    *,
    request: bytes | None = None,
    registry: Registry | None = None,
) -> Dissection:
    """Take one frame apart.

    `body` is the unit byte and the PDU, without CRC or LRC. `request` is the paired
    request's body when a response is dissected: it tells how many coil bits are real,
    where read registers start, and what an echo should repeat. `registry` holds the
    function codes to know (the public ones when None; a session's registry adds the
    codes of the devices bound on its bus). Never raises on any bytes.
    """
    if type(body) is not bytes:
        body = bytes(body)
    if len(body) < 2:
        missing = "function" if body else "unit"
        return make_dissection(
            unit=body[0] if body else 0,
            function=0,
            exception=False,
            role=role,
            name="Truncated frame",
            summary=f"frame too short: {plural(len(body), 'byte')}",
            fields=(),
            problems=(
                make_problem("truncated", ERROR, f"frame ends before {missing}", (0, len(body))),
            ),
            data=(),
        )
    size = len(body)
    unit, code = body[0], body[1]
    table = _PUBLIC_PLANS if registry is None else plans(registry)
    plan = table[0 if role is _REQUEST else 1][code]
    if plan.words_answer and request is not None and unit:
        made = _words_answer(body, size, role, plan, request)
        if made is not None:
            return made
    parsed = SEEN.get(body) if plan.reuse else None
    if parsed is not None and parsed.schema is plan.schema:
        if plan.keep and parsed.dissection is not None:
            return parsed.dissection  # the same request again: the same dissection
        fields = parsed.fields.copy()  # the kept parse's own stay as they were parsed
    else:
        parsed = Parsed(plan.schema, body)
        if plan.keep:
            keep(body, parsed)
            fields = parsed.fields.copy()
        else:
            fields = parsed.fields
    w = Work(body, plan, parsed, fields)
    if plan.checked or parsed.cut is not None or parsed.end != size:
        check_structure(w, size)
    if request is not None and not plan.is_request:
        pair(w, request)
    plan.routine(w)
    summary = w.summary
    if unit == 0:
        if plan.is_request:
            summary = f"broadcast: {summary}"
        else:
            w.problem(
                "broadcast-response", WARNING, "response from the broadcast address 0", (0, 1)
            )
    result = make_dissection(
        unit,
        plan.function,
        plan.exception,
        role,
        plan.name,
        summary,
        tuple(fields.values()),
        w.problems,
        w.data,
    )
    if plan.keep:
        parsed.dissection = result
    return result


_NO_PROBLEMS: tuple[()] = ()


def _words_answer(
    body: bytes, size: int, role: Role, plan: Plan, request: bytes
) -> Dissection | None:
    """An answer to an FC 3 or 4 read (not from unit 0) whose byte count is the bytes
    that follow and twice the quantity its request (of the same code, address and
    quantity whole) asked for: what the schemas, `check_structure`, `pair` and `read`
    make of it, read straight from the bytes: a polling capture is mostly such answers,
    and the full path costs several times more. None for any other answer: the full
    path takes it."""
    if size < 3 or len(request) < 6 or request[1] != plan.function:
        return None
    byte_count = body[2]
    quantity = request[4] << 8 | request[5]
    if size != 3 + byte_count or byte_count != 2 * quantity:
        return None
    values: tuple[int, ...] = WORD_FORMATS[quantity].unpack_from(body, 3)
    return make_dissection(
        body[0],
        plan.function,
        False,
        role,
        plan.name,
        "1 value" if quantity == 1 else f"{quantity} values",
        (
            make_field("byte_count", byte_count, str(byte_count), (2, 3)),
            make_lazy_field(WordsField, "values", values, (3, size)),
        ),
        _NO_PROBLEMS,
        (make_register_data(plan.table, request[2] << 8 | request[3], values, False),),
    )
