"""Provides the registry of function codes: every public code's spec, collected from the
family modules, and registries that add a device's own codes (`Registry.with_vendor`).

A registry is what the framer reads its length rules from and what `dissect()` takes a
frame apart with; one per capture session, holding the codes of the devices bound on
the bus. Codes no registry knows are dissected as raw data.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from typing import TYPE_CHECKING, Any

from dissectors.pdu import bits, diagnostics, files, identification, registers
from dissectors.pdu.spec import FunctionSpec
from dissectors.pdu.work import INFO, WARNING, Work, plural

if TYPE_CHECKING:
    from dissectors.dictionary.vendor import VendorFunction

FUNCTION_CLASSES: dict[str, str] = {
    "public": "public",
    "user": "user-defined",
    "reserved": "reserved",
    "unknown": "unknown",
}
"""What each function code class is called in plain text."""

_RESERVED = frozenset((9, 10, 13, 14, 41, 42, 90, 125, 126, 127))


def range_class(code: int) -> str:
    """The class the Modbus specification gives a code it does not define: user (65-72,
    100-110), reserved, or unknown."""
    if 65 <= code <= 72 or 100 <= code <= 110:
        return "user"
    if code in _RESERVED:
        return "reserved"
    return "unknown"


class Registry(Mapping[int, FunctionSpec]):
    """Function codes by code (without the exception bit), each with its spec.

    Read-only once made; `with_vendor` and `with_specs` make a new one. `plans` is where
    `dissect()` keeps what it worked out for this registry's code bytes."""

    __slots__ = ("_specs", "plans")

    def __init__(self, specs: Iterable[FunctionSpec]) -> None:
        self._specs: dict[int, FunctionSpec] = {spec.code: spec for spec in specs}
        self.plans: Any = None

    def __getitem__(self, code: int) -> FunctionSpec:
        return self._specs[code]

    def __iter__(self) -> Iterator[int]:
        return iter(self._specs)

    def __len__(self) -> int:
        return len(self._specs)

    def __contains__(self, code: object) -> bool:
        return code in self._specs

    def get(self, code: int, default: Any = None) -> Any:  # the dict's, without Mapping's try
        return self._specs.get(code, default)

    def __repr__(self) -> str:
        return f"Registry({sorted(self._specs)})"

    def with_specs(self, specs: Iterable[FunctionSpec]) -> Registry:
        """This registry with `specs` added; a spec replaces one with the same code."""
        return Registry([*self._specs.values(), *specs])

    def with_vendor(self, functions: Mapping[int, VendorFunction]) -> Registry:
        """This registry with a device dictionary's own function codes compiled in."""
        from dissectors.pdu.vendor import compile_vendor

        if not functions:
            return self
        return self.with_specs(compile_vendor(function) for function in functions.values())

    @property
    def answered_broadcasts(self) -> frozenset[int]:
        """Codes whose broadcast requests get an answer (device-specific)."""
        return frozenset(code for code, spec in self._specs.items() if spec.broadcast_answered)

    def function_class(self, code: int) -> str:
        """public, user, reserved or unknown, for a code without the exception bit."""
        spec = self._specs.get(code)
        return spec.klass if spec is not None else range_class(code)

    def function_name(self, code: int) -> str:
        """A readable name for any function code (without the exception bit)."""
        spec = self._specs.get(code)
        if spec is not None:
            return spec.name
        klass = range_class(code)
        return {"user": "User-defined", "reserved": "Reserved"}.get(klass, "Unknown") + f" {code}"


PUBLIC = Registry(
    (
        *bits.SPECS,
        *registers.SPECS,
        *diagnostics.SPECS,
        *files.SPECS,
        *identification.SPECS,
    )
)
"""Every public function code modscope knows."""


def function_class(code: int) -> str:
    """public, user (65-72, 100-110), reserved, or unknown, for a code without 0x80."""
    return PUBLIC.function_class(code)


def function_name(code: int) -> str:
    """A readable name for any function code (without the exception bit)."""
    return PUBLIC.function_name(code)


def raw(w: Work) -> None:
    """A code without a layout: its data as it is, and what class of code it is."""
    klass = range_class(w.function) if w.plan.spec is None else w.plan.spec.klass
    data = w.fields.get("data")
    size = data.span[1] - data.span[0] if data is not None else 0
    w.summary = f"{FUNCTION_CLASSES[klass]} function {w.function}: {plural(size, 'data byte')}"
    if klass == "reserved":
        w.problem("unknown-function", INFO, f"function code {w.function} is reserved", (1, 2))
    elif klass == "unknown":
        w.problem(
            "unknown-function",
            WARNING,
            f"function code {w.function} is not defined by the Modbus specification",
            (1, 2),
        )
