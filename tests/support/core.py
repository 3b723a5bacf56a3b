"""Provides helpers shared by tests (moved from test_core.py)."""

from __future__ import annotations

import os
import random
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType

import pytest

from dissectors.checks import with_crc
from sniffer import core


def _compiled() -> ModuleType:
    try:
        from sniffer import _core  # type: ignore[attr-defined]
    except ImportError as exc:
        if os.environ.get("MODSCOPE_REQUIRE_COMPILED") == "1":
            pytest.fail(f"MODSCOPE_REQUIRE_COMPILED=1 but the compiled core is not built: {exc}")
        pytest.skip(f"the compiled core is not built here ({exc}); pip install -e . builds it")
    module: ModuleType = _core
    return module


def _frame(rng: random.Random, what: str) -> list[bytes]:
    """One exchange (request and answer, or a lone frame or junk) of the kind `what`."""
    unit = rng.choice((1, 2, 7, 247))
    if what == "read":
        count = rng.randrange(1, 20)
        req = with_crc(bytes([unit, 3, 0, rng.randrange(256), 0, count]))
        data = bytes(rng.getrandbits(8) for _ in range(2 * count))
        return [req, with_crc(bytes([unit, 3, 2 * count]) + data)]
    if what == "exception":
        req = with_crc(bytes([unit, 4, 0, 1, 0, 2]))
        return [req, with_crc(bytes([unit, 0x84, rng.randrange(1, 5)]))]
    if what == "echo":
        fc = rng.choice((5, 6, 8))
        req = with_crc(bytes([unit, fc, 0, rng.randrange(256), 0xFF, 0]))
        return [req, req] if rng.random() < 0.8 else [req, req, req]  # a retry
    if what == "write":  # FC 16: a counted request, a fixed answer
        n = rng.randrange(1, 5)
        body = bytes([unit, 16, 0, 10, 0, n, 2 * n]) + bytes(2 * n)
        return [with_crc(body), with_crc(bytes([unit, 16, 0, 10, 0, n]))]
    if what == "broadcast":
        return [with_crc(bytes([0, 6, 0, 1, 0, rng.randrange(256)]))]
    if what == "unknown":
        return [with_crc(bytes([unit, 0x41]) + bytes(rng.randrange(0, 6)))]
    if what == "crc":
        frame = bytearray(with_crc(bytes([unit, 3, 0, 0, 0, 1])))
        frame[-1] ^= 0x55
        return [bytes(frame)]
    if what == "flip":
        frame = bytearray(with_crc(bytes([unit, 3, 2, 0, rng.randrange(256)])))
        frame[rng.randrange(len(frame))] ^= 1 << rng.randrange(8)
        return [bytes(frame)]
    if what == "zeros":
        return [with_crc(bytes([unit, 6, 0, 2, 0, 0])) + bytes(rng.randrange(1, 3))]
    if what == "silent":  # a request nobody answers
        return [with_crc(bytes([unit, 1, 0, 0, 0, rng.randrange(1, 16)]))]
    return [bytes(rng.getrandbits(8) for _ in range(rng.randrange(1, 6)))]  # noise


KINDS = ["read"] * 6 + [
    "exception",
    "echo",
    "write",
    "broadcast",
    "unknown",
    "crc",
    "flip",
    "zeros",
    "silent",
    "noise",
]


@contextmanager
def running(module: ModuleType | None) -> Iterator[None]:
    """Run the block with the compiled core (a module) or the pure-Python one (None)."""
    saved = core.FAST
    core.FAST = module
    try:
        yield
    finally:
        core.FAST = saved
