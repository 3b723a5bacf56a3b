"""Masks over a store's columns (`sniffer.framing.columns`): the rows they mark are the rows a
test of each one picks."""

from __future__ import annotations

import random
from array import array

from sniffer.framing.columns import both, but_not, flag_mask, marking
from sniffer.vocab import BAD_CHECK, Flag


def test_flag_mask_marks_the_rows_with_any_of_the_bits() -> None:
    rng = random.Random(5)
    values = (0, 1, 1 << 4, 1 << 8, 1 << 17, 1 << 25, 1 << 31, 0xFFFFFFFF)
    flags = array("I", [rng.choice(values) for _ in range(999)])
    for bits in (BAD_CHECK, int(Flag.LINE_ERROR), int(Flag.MBAP | Flag.RETRY), 1 << 31, 0):
        want = bytes(int(f & bits != 0) for f in flags)
        assert flag_mask(flags, bits) == want
        assert flag_mask(flags, bits, 10, 400) == want[10:400]
        assert flag_mask(flags, bits, 7, 7) == b""


def test_masks_combine_byte_by_byte() -> None:
    rng = random.Random(6)
    a = bytes(rng.randrange(2) for _ in range(300))
    b = bytes(rng.randrange(2) for _ in range(300))
    assert both(a, b) == bytes(x & y for x, y in zip(a, b, strict=True))
    assert but_not(a, b) == bytes(x & (1 - y) for x, y in zip(a, b, strict=True))
    assert both(b"\x00\x00\x01", b"\x00\x01\x01") == b"\x00\x00\x01"  # leading zeros kept
    column = bytes(rng.randrange(256) for _ in range(300))
    assert column.translate(marking((3, 250))) == bytes(int(c in (3, 250)) for c in column)
