"""Provides entry places: refs read through the file's spaces, addresses and PDU numbers."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from .errors import nearest
from .model import BIT_TABLES, REGISTER_TABLES, RefMatch, Space
from .reader import Table
from .values import table_name


@dataclass(frozen=True, slots=True)
class Place:
    """Where a value is: table, PDU address, bit, the ref as written, and its space."""

    table: str
    address: int
    bit: int | None
    ref: str
    space: Space | None

    def ref_at(self, address: int) -> str:
        """The ref of a repeated copy at `address`, written the space's way."""
        if self.space is None:
            return f"pdu {address}"
        return self.space.format(address, self.bit)


class Places:
    """The declared spaces and default space, and the checks of places written with them."""

    def __init__(self, spaces: Mapping[str, Space], default_space: str | None) -> None:
        self.spaces = dict(spaces)
        self.default_space = default_space

    def space_fix(self, name: str) -> str:
        if not self.spaces:
            return f"declare it: [spaces.{name}] with table = ..., or remove the reference"
        close = nearest(name, self.spaces)
        if close is not None:
            return f"write '{close}' instead of '{name}'"
        return f"use one of the declared spaces: {', '.join(self.spaces)}"

    def match_ref(self, table: Table, key: str, ref: str, only: str | None) -> RefMatch:
        if not self.spaces:
            raise table.error(
                key,
                f"{table.what}: ref '{ref}' but the file declares no spaces",
                'declare how the manual numbers registers, e.g. [spaces.4x] table = "holding", '
                'prefix = "4", width = 4, first = 1; or use pdu = N with table = "..."',
            )
        if only is not None:
            if only not in self.spaces:
                raise table.error(
                    "space", f"{table.what}: unknown space '{only}'", self.space_fix(only)
                )
            candidates = [self.spaces[only]]
        else:
            candidates = list(self.spaces.values())
        matches = [m for m in (space.match(ref) for space in candidates) if m is not None]
        if not matches:
            examples = ", ".join(f"{s.name} ({s.example()})" for s in candidates)
            raise table.error(
                key,
                f"{table.what}: no space reads the ref '{ref}'",
                f"write it the way a space does: {examples}; or declare a [spaces.NAME] for it",
            )
        best = max((m.prefix_length, m.suffix_length) for m in matches)
        top = [m for m in matches if (m.prefix_length, m.suffix_length) == best]
        if len(top) > 1:
            names = " and ".join(f"'{m.space.name}'" for m in top)
            raise table.error(
                key,
                f"{table.what}: ref '{ref}' is read equally well by spaces {names}",
                f'add space = "{top[0].space.name}" to choose one, or give the spaces '
                "distinct prefixes or suffixes",
            )
        found = top[0]
        if not 0 <= found.address <= 65535:
            raise table.error(
                key,
                f"{table.what}: ref '{ref}' is PDU address {found.address} in space "
                f"'{found.space.name}', outside 0-65535",
                f"check the number, and first/pdu of [spaces.{found.space.name}]",
            )
        return found

    def place(self, table: Table) -> Place:
        given = [key for key in ("ref", "address", "pdu") if table.has(key)]
        if not given:
            raise table.error(
                None,
                f"{table.what} does not say where it is",
                'add ref = "..." as the manual prints it, address = N (with space), '
                'or pdu = N with table = "..."',
            )
        if len(given) > 1:
            raise table.error(
                given[1],
                f"{table.what} gives both {given[0]} and {given[1]}",
                f"keep one of {' / '.join(given)}",
            )
        declared = table_name(table, "table")
        if given[0] == "ref":
            ref = table.need_text("ref", 'ref = "40001"')
            found = self.match_ref(table, "ref", ref, table.opt_text("space"))
            result = Place(found.space.table, found.address, found.bit, ref.strip(), found.space)
            if found.bit is not None:
                if result.table in BIT_TABLES:
                    raise table.error(
                        "ref",
                        f"{table.what}: ref '{ref}' selects a bit of a coil or input",
                        "coils and discrete inputs are single bits: drop the .N",
                    )
                if not 0 <= found.bit <= 15:
                    first = found.space.bit_first
                    raise table.error(
                        "ref",
                        f"{table.what}: bit {found.bit + first} of ref '{ref}' "
                        "is outside the register",
                        f"space '{found.space.name}' numbers bits {first}-{15 + first}",
                    )
        elif given[0] == "address":
            number = table.integer("address")
            if number is None:
                raise table.missing("address", "address = N")
            name = table.opt_text("space") or self.default_space
            if name is None:
                raise table.error(
                    "address",
                    f"{table.what}: address = {number} but no space says how to count it",
                    'add space = "NAME", or default_space = "NAME" in [device]; '
                    'or write pdu = N with table = "..."',
                )
            if name not in self.spaces:
                key = "space" if table.has("space") else "address"
                raise table.error(
                    key, f"{table.what}: unknown space '{name}'", self.space_fix(name)
                )
            space = self.spaces[name]
            address = space.pdu + number - space.first
            if not 0 <= address <= 65535:
                raise table.error(
                    "address",
                    f"{table.what}: address {number} is PDU address {address} in space "
                    f"'{name}', outside 0-65535",
                    f"check the number, and first/pdu of [spaces.{name}]",
                )
            result = Place(space.table, address, None, space.format(address), space)
        else:
            address = table.need_integer("pdu", 0, 65535)
            if declared is None:
                raise table.error(
                    "pdu",
                    f"{table.what}: pdu = {address} without a table",
                    'add table = "holding" (or coils, discrete_inputs, input_registers)',
                )
            if table.has("space"):
                raise table.error(
                    "space",
                    f"{table.what}: space is used with address, not pdu",
                    "remove space, or write address = N instead of pdu",
                )
            return Place(declared, address, None, f"pdu {address}", None)
        if declared is not None and declared != result.table:
            raise table.error(
                "table",
                f"{table.what}: table = '{declared}' but its place is in {result.table}",
                "remove table (the space decides it), or fix the ref",
            )
        return result

    def register(self, table: Table, key: str) -> Place:
        """A window's select or value register: a ref, or an address in the default space."""
        value = table.get(key)
        if value is None:
            raise table.missing(key, f'{key} = "..." (a ref, as the manual prints it)')
        if isinstance(value, str):
            found = self.match_ref(table, key, value, None)
            if found.space.table not in REGISTER_TABLES or found.bit is not None:
                raise table.error(
                    key,
                    f"{table.what}: {key} '{value}' is not a whole register",
                    "give the ref of a holding or input register, without .N",
                )
            return Place(found.space.table, found.address, None, value.strip(), found.space)
        number = table.integer(key)
        assert number is not None
        if self.default_space is None:
            raise table.error(
                key,
                f"{table.what}: {key} = {number} but no default_space says how to count it",
                f'write it as a ref string, e.g. {key} = "5002h"',
            )
        space = self.spaces[self.default_space]
        address = space.pdu + number - space.first
        if not 0 <= address <= 65535:
            raise table.error(key, f"{table.what}: {key} is outside 0-65535", "check the number")
        return Place(space.table, address, None, space.format(address), space)
