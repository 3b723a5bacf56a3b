"""Provides masks over a store's columns: one byte a row, 1 where a row is wanted, 0
elsewhere, made and combined in C (`bytes.translate`, big-int bit operations) and used
with `itertools.compress` to pick rows, or their values, out of a column.

A million rows a time the statistics, the poll cycle, the baud check and the annotator
look at: a mask costs about a millisecond, a Python loop over the rows a second.
"""

from __future__ import annotations

import sys
from array import array
from collections.abc import Iterable
from functools import cache


def marking(on: Iterable[int]) -> bytes:
    """A `bytes.translate` table that makes a mask: the byte values `on` to 1, every other
    one to 0."""
    table = bytearray(256)
    for b in on:
        if 0 <= b < 256:
            table[b] = 1
    return bytes(table)  # cheap for a few values; a test of all 256 is not (see _any_of)


def both(a: bytes, b: bytes) -> bytes:
    """1 where both masks are."""
    return (int.from_bytes(a, "big") & int.from_bytes(b, "big")).to_bytes(len(a), "big")


def but_not(a: bytes, b: bytes) -> bytes:
    """1 where `a` is and `b` is not."""
    return (int.from_bytes(a, "big") & ~int.from_bytes(b, "big")).to_bytes(len(a), "big")


def flag_mask(flags: array[int], bits: int, start: int = 0, end: int | None = None) -> bytes:
    """1 for each row of `flags[start:end]` with any of `bits` set.

    Read from the column's bytes a byte position at a time (`bytes.translate` on every
    fourth byte), so the work per row is done in C rather than by `map(and_, ...)` over
    the ints."""
    end = len(flags) if end is None else end
    raw = flags[start:end].tobytes()
    size = flags.itemsize
    found = 0
    for k in range(size):
        shift = 8 * (k if sys.byteorder == "little" else size - 1 - k)
        part = (bits >> shift) & 0xFF
        if part:
            found |= int.from_bytes(raw[k::size].translate(_any_of(part)), "big")
    return found.to_bytes(end - start, "big")


@cache
def _any_of(bits: int) -> bytes:
    """The `marking` of the byte values with any of `bits` (at most 255 tables): made
    once, not on every call. A live capture asks for a mask of a few rows about a
    thousand times a second (the statistics, per pump): making the table would be
    nearly all of such a call's cost."""
    return marking(b for b in range(256) if b & bits)
