"""Provides the values a dissection hands out: fields with byte spans, problems, register data.

These are what leaves `dissectors`: frozen, slotted, typed. construct's Containers stay
inside.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any


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
