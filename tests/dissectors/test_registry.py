"""Every length rule in the registry agrees with its code's schema: a frame of the length
the rule gives parses with the schema to its last byte, no more and no less."""

from __future__ import annotations

from typing import Any

import pytest
from construct import SizeofError

from dissectors.dictionary import load_model
from dissectors.dissect import FAMILIES
from dissectors.functions import FUNCTIONS, FunctionSpec, LengthRule, Registry
from dissectors.pdu.work import Parsed

VED903B = FUNCTIONS.with_vendor(load_model("ved903b").functions)


def _rules(registry: Registry) -> list[tuple[str, FunctionSpec, str, LengthRule]]:
    out = []
    for spec in registry.values():
        for direction, rule in (
            ("request", spec.request_length),
            ("response", spec.response_length),
        ):
            if rule is not None and rule.walker is None:
                out.append((f"{spec.code}-{direction}", spec, direction, rule))
    return out


RULES: dict[str, tuple[FunctionSpec, str, LengthRule]] = {
    name: (spec, direction, rule) for name, spec, direction, rule in _rules(VED903B)
}


def _schema(spec: FunctionSpec, direction: str) -> Any:
    return spec.request_schema if direction == "request" else spec.response_schema


def _clean(parsed: Parsed) -> bool:
    return parsed.cut is None and parsed.end == len(parsed.body)


def test_the_rules_cover_the_public_fixed_codes() -> None:
    fixed = {name for name, (_, _, rule) in RULES.items() if rule.fixed}
    assert {"3-request", "5-response", "8-request", "22-response", "65-response"} <= fixed
    assert len(RULES) >= 2 * len(FUNCTIONS) - 2  # all but FC 43's walkers


@pytest.mark.parametrize("name", sorted(n for n, (_, _, r) in RULES.items() if r.fixed))
def test_fixed_length_agrees_with_schema(name: str) -> None:
    spec, direction, rule = RULES[name]
    schema = _schema(spec, direction)
    body = bytes([1, spec.code]) + bytes(rule.base - 4)  # the length less the CRC
    assert _clean(Parsed(schema, body)), f"{name}: {rule.base} bytes do not parse exactly"
    try:
        size = schema.sizeof()
    except SizeofError:  # a layout ending in the rest of the frame (FC 8 data)
        size = None
    if size is not None:
        assert rule.base == 2 + size + 2, name
        assert not _clean(Parsed(schema, body[:-1])), f"{name}: one byte less still parses"


@pytest.mark.parametrize("name", sorted(n for n, (_, _, r) in RULES.items() if not r.fixed))
def test_counted_length_agrees_with_schema(name: str) -> None:
    """A frame whose byte count is `n` and whose length the rule reads from it parses
    exactly, for the counts a zero-filled frame of that layout can have."""
    spec, direction, rule = RULES[name]
    schema = _schema(spec, direction)
    clean = []
    for count in range(16):
        frame = bytearray(rule.base + count)
        frame[0], frame[1] = 1, spec.code
        frame[rule.count_pos : rule.count_pos + rule.count_size] = count.to_bytes(
            rule.count_size, "big"
        )
        assert rule.length(frame, 0, len(frame)) == len(frame)
        if _clean(Parsed(schema, bytes(frame[:-2]))):
            clean.append(count)
    assert clean, f"{name}: no byte count gives a frame the schema reads exactly"


def test_every_family_has_a_routine_in_the_registry() -> None:
    for spec in FUNCTIONS.values():
        assert spec.meaning is FAMILIES[spec.family], spec.code
