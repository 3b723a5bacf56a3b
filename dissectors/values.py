"""Provides the values a dissection hands out: fields with byte spans, problems, register data.

These are what leaves `dissectors`: frozen, slotted, typed. construct's Containers stay
inside.

The `make_*` functions build the same objects as the constructors, several times faster,
for the dissector's hot path: a frozen dataclass's `__init__` must set every slot through
`object.__setattr__`, while these fill a plain object with the same slots and then give
it its class, which Python allows because the layouts are the same.

Why the swap (on the `benchmarks/bench_dissect.py` workload): frozen dataclasses built
by their constructors make a whole dissection a quarter to a third slower; plain
slotted classes that are not frozen cost a little more than the swap, and would let
whoever reads a kept dissection change it. The swap keeps them frozen at the cost of
plain ones.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any, Final


class Role(enum.Enum):
    """Which way a frame went: master to slave, or slave to master."""

    REQUEST = "request"
    RESPONSE = "response"


@dataclass(frozen=True, slots=True)
class Field:
    """One decoded field: its value, what it means in plain text, and where it lies.

    `span` is (start, end) byte offsets within the body given to `dissect` (unit byte at
    offset 0). Arrays and records have `children`, named `values[0]`, `objects[1]`, ...
    """

    name: str
    value: int | bool | str | bytes | tuple[Any, ...] | None
    text: str
    span: tuple[int, int]
    children: tuple[Field, ...] = ()


@dataclass(frozen=True, slots=True)
class Problem:
    """Something inconsistent in a frame, like Wireshark's expert info.

    `kind` is a stable code (`byte-count`, `quantity`, `truncated`, ...), `severity` one
    of error, warning or info, `span` the bytes concerned, if any.
    """

    kind: str
    severity: str
    text: str
    span: tuple[int, int] | None


@dataclass(frozen=True, slots=True)
class RegisterData:
    """Values a frame carries for one data table, from `address` on.

    `address` is None when a response's start address is known only from its request and
    none was given. `values` are 16-bit words, or 0/1 for coils and inputs. `write` tells
    values being written (requests, and responses dissected with their request) from
    values read.
    """

    table: str
    address: int | None
    values: tuple[int, ...]
    write: bool


@dataclass(frozen=True, slots=True)
class Dissection:
    """One frame taken apart: who, which function, its fields, problems and data."""

    unit: int
    function: int
    exception: bool
    role: Role
    name: str
    summary: str
    fields: tuple[Field, ...]
    problems: tuple[Problem, ...]
    data: tuple[RegisterData, ...]

    def field(self, name: str) -> Field | None:
        """The top-level field called `name`, if the frame has one."""
        for item in self.fields:
            if item.name == name:
                return item
        return None


def _shape(cls: type) -> Any:
    """A plain class with exactly the slots of `cls`, so its instances can become `cls`."""
    return type(f"_{cls.__name__}Shape", (), {"__slots__": cls.__dict__["__slots__"]})


_FIELD: Final = _shape(Field)
_PROBLEM: Final = _shape(Problem)
_REGISTER_DATA: Final = _shape(RegisterData)
_DISSECTION: Final = _shape(Dissection)


def make_field(
    name: str,
    value: int | bool | str | bytes | tuple[Any, ...] | None,
    text: str,
    span: tuple[int, int],
    children: tuple[Field, ...] = (),
) -> Field:
    """`Field(name, value, text, span, children)`, made faster."""
    made = _FIELD()
    made.name = name
    made.value = value
    made.text = text
    made.span = span
    made.children = children
    made.__class__ = Field
    result: Field = made
    return result


def make_lazy_field(
    cls: type[Field], name: str, value: tuple[Any, ...], span: tuple[int, int]
) -> Field:
    """A `cls` (a Field subclass adding no slots) with `text` and `children` left unset,
    for the class's `__getattr__` to fill in when they are first read."""
    made = _FIELD()
    made.name = name
    made.value = value
    made.span = span
    made.__class__ = cls
    result: Field = made
    return result


def make_problem(kind: str, severity: str, text: str, span: tuple[int, int] | None) -> Problem:
    """`Problem(kind, severity, text, span)`, made faster."""
    made = _PROBLEM()
    made.kind = kind
    made.severity = severity
    made.text = text
    made.span = span
    made.__class__ = Problem
    result: Problem = made
    return result


def make_register_data(
    table: str, address: int | None, values: tuple[int, ...], write: bool
) -> RegisterData:
    """`RegisterData(table, address, values, write)`, made faster."""
    made = _REGISTER_DATA()
    made.table = table
    made.address = address
    made.values = values
    made.write = write
    made.__class__ = RegisterData
    result: RegisterData = made
    return result


def make_dissection(
    unit: int,
    function: int,
    exception: bool,
    role: Role,
    name: str,
    summary: str,
    fields: tuple[Field, ...],
    problems: tuple[Problem, ...],
    data: tuple[RegisterData, ...],
) -> Dissection:
    """`Dissection(...)` with the same arguments, made faster."""
    made = _DISSECTION()
    made.unit = unit
    made.function = function
    made.exception = exception
    made.role = role
    made.name = name
    made.summary = summary
    made.fields = fields
    made.problems = problems
    made.data = data
    made.__class__ = Dissection
    result: Dissection = made
    return result
