"""The numbers the compiled core says itself (sniffer/_core.c: constants()) are the
numbers of the Python they restate: the vocabulary of rows (sniffer.vocab), the function
codes' families, tables and lengths (the registry of dissectors.pdu), and the limits of
the pcap walks and the RTU fast paths. A number changed on one side only fails here.
Without the extension these tests skip, unless MODSCOPE_REQUIRE_COMPILED=1."""

from __future__ import annotations

from typing import Any

import pytest

from dissectors.dissect import dissect
from dissectors.functions import EXCEPTION_LENGTH, FUNCTIONS, AnswerRule, counted, fixed
from dissectors.pdu.work import BIT_TABLES
from dissectors.values import Role
from sniffer.framing import lengths
from sniffer.sources import linktypes, pcap
from sniffer.sources.base import MAX_TIME
from sniffer.sources.reads import MAX_BATCH_BYTES, MAX_BATCH_SPAN
from sniffer.vocab import BAD_CHECK, Flag, Kind, Status
from tests.support.core import _compiled


@pytest.fixture(scope="module")
def said() -> dict[str, Any]:
    constants: dict[str, Any] = _compiled().constants()
    return constants


def _codes(family: str, tables: frozenset[str] | None = None) -> tuple[int, ...]:
    """The public codes of `family` (of a table among `tables`, if given), in order."""
    return tuple(
        sorted(
            code
            for code, spec in FUNCTIONS.items()
            if spec.family == family and (tables is None or spec.table in tables)
        )
    )


REGISTERS = frozenset({"holding_registers", "input_registers"})


# the vocabulary of the rows the passes read and write, as sniffer.vocab says it
VOCABULARY = {
    **{k.name: int(k) for k in Kind},
    **{f"S_{s.name}": int(s) for s in Status if s != Status.NONE},
    **{
        str(f.name): int(f)
        for f in (
            Flag.CHECK_BAD,
            Flag.NON_HEX,
            Flag.ENVELOPE_BAD,
            Flag.ASCII,
            Flag.MBAP,
            Flag.RETRY,
            Flag.LATE,
            Flag.ANSWERED_BROADCAST,
        )
    },
    "BAD_CHECK": int(BAD_CHECK),
}


def test_the_vocabulary_of_rows_is_sniffer_vocab(said: dict[str, Any]) -> None:
    assert {name: said.get(name) for name in VOCABULARY} == VOCABULARY


def test_the_exception_bit_is_the_one_the_dissector_reads(said: dict[str, Any]) -> None:
    bit = said["EXCEPTION_BIT"]
    for code in FUNCTIONS:
        answer = dissect(bytes([1, code | bit, 2]), Role.RESPONSE)
        assert answer.exception and answer.function == code
        assert not dissect(bytes([1, code, 2]), Role.RESPONSE).exception


def test_the_function_code_tests_are_the_registry_families(said: dict[str, Any]) -> None:
    assert said["FC_READ"] == _codes("read")
    assert said["FC_READ_BITS"] == _codes("read", BIT_TABLES)
    assert said["FC_READ_REGISTERS"] == _codes("read", REGISTERS)
    assert said["FC_WRITE_SINGLE"] == _codes("write_single")
    assert said["FC_WRITE_COIL"] == _codes("write_single", BIT_TABLES)
    assert said["FC_WRITE_MULTIPLE"] == _codes("write_multiple")
    assert said["FC_WRITE_COILS"] == _codes("write_multiple", BIT_TABLES)


def test_the_lengths_of_requests_and_answers_are_the_registry_rules(said: dict[str, Any]) -> None:
    for code in (*said["FC_READ"], *said["FC_WRITE_SINGLE"]):
        assert FUNCTIONS[code].request_length == fixed(said["TABLE_REQUEST_LENGTH"])
    for code in said["FC_WRITE_MULTIPLE"]:
        assert FUNCTIONS[code].request_length == counted(
            said["MULTIPLE_COUNT_AT"], said["MULTIPLE_BASE"]
        )
    for code in said["FC_READ"]:
        assert FUNCTIONS[code].response_length == counted(2, said["READ_ANSWER_BASE"])
    assert said["EXCEPTION_LENGTH"] == EXCEPTION_LENGTH


def test_the_rtu_fast_paths_limits_are_the_framers(said: dict[str, Any]) -> None:
    assert (said["MIN_RTU"], said["MAX_RTU"]) == (lengths.MIN_RTU, lengths.MAX_RTU)
    assert (said["FIXED"], said["ECHO"]) == (AnswerRule.FIXED, AnswerRule.ECHO)
    assert said["WALKED"] == lengths.WALKED


def test_the_pcap_walks_limits_are_the_readers(said: dict[str, Any]) -> None:
    assert said["BLOCK_EPB"] == linktypes.BLOCK_EPB
    assert said["EPB_FLAGS"] == linktypes.EPB_FLAGS
    assert said["RTAC_HEADER_LEN"] == linktypes.RTAC_HEADER_LEN
    assert said["RTAC_DATA_RX_START"] == linktypes.RTAC_DATA_RX_START
    assert said["MAX_BLOCK"] == pcap.MAX_BLOCK
    assert said["RTAC_MAX_LEAD"] == pcap.RTAC_MAX_LEAD
    assert said["MAX_TIME"] == MAX_TIME
    assert (said["MAX_BATCH_SPAN"], said["MAX_BATCH_BYTES"]) == (MAX_BATCH_SPAN, MAX_BATCH_BYTES)


def test_every_number_said_is_held_to_python_here(said: dict[str, Any]) -> None:
    """A number added to constants() needs its test above (this file names each)."""
    with open(__file__, encoding="utf-8") as f:
        source = f.read()
    unheld = [name for name in said if name not in VOCABULARY and f'"{name}"' not in source]
    assert unheld == []


def test_the_functions_the_python_calls_are_the_compiled_cores() -> None:
    """`sniffer.core.FUNCTIONS` names every function the compiled module has (a new one
    must be named there, or an extension built before it would be taken for current),
    and an extension that lacks one is refused, naming it and the fix."""
    from types import SimpleNamespace

    from sniffer import core

    module = _compiled()
    assert {n for n in dir(module) if not n.startswith("_")} == core.FUNCTIONS
    assert core.stale(module) == ""
    older = SimpleNamespace(**{n: getattr(module, n) for n in core.FUNCTIONS - {"waits_densify"}})
    why = core.stale(older)  # type: ignore[arg-type]
    assert "lacks waits_densify" in why and "pip install -e ." in why
