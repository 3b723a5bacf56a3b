"""Provides dissect() under its first name: a facade over `dissectors.pdu.dissect`.

One frame body in; its fields, meaning, problems and register data out. The layouts and
meaning routines live with their function codes in the family modules of
`dissectors.pdu`.
"""

from __future__ import annotations

from collections.abc import Callable

from dissectors.pdu.dissect import dissect
from dissectors.pdu.exceptions import exception
from dissectors.pdu.registry import PUBLIC, Registry, raw
from dissectors.pdu.work import Work
from dissectors.values import Dissection, Field, Problem, RegisterData, Role

FAMILIES: dict[str, Callable[[Work], None]] = {
    **{spec.family: spec.meaning for spec in PUBLIC.values() if spec.meaning is not None},
    "exception": exception,
    "raw": raw,
}
"""The meaning routine of each public FunctionSpec.family (plus exception responses and
codes without a layout), by name."""

__all__ = [
    "FAMILIES",
    "Dissection",
    "Field",
    "Problem",
    "RegisterData",
    "Registry",
    "Role",
    "dissect",
]
