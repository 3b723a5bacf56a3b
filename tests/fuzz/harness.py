"""Provides what the fuzz tests share: the example budget, a per-example time limit, the
corpus seeded from the test captures and dictionaries, mutations, and the invariants
(no undocumented exception, no hang, every byte in exactly one row).

Budget: `MODSCOPE_FUZZ_SCALE` multiplies every test's example count (default 1: the
whole set in about a minute on two cores; 10 or 100 for a long run before a release).
"""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from sniffer.framing.store import FrameStore
from sniffer.model import Chunk
from sniffer.vocab import Kind

ROOT = Path(__file__).resolve().parents[2]
CAPTURES = ROOT / "tests" / "captures"
DICTIONARIES = ROOT / "tests" / "fixtures" / "dictionaries"
DEVICES = ROOT / "dissectors" / "devices"
SCALE = float(os.environ.get("MODSCOPE_FUZZ_SCALE", "1"))
HANG_SECONDS = 20.0  # one example taking this much CPU time is a hang, whatever the load


def budget(examples: int) -> settings:
    """Hypothesis settings for a fuzz test of `examples` examples (times the scale)."""
    return settings(
        max_examples=max(1, int(examples * SCALE)),
        deadline=None,
        suppress_health_check=[
            HealthCheck.too_slow,
            HealthCheck.data_too_large,
            HealthCheck.large_base_example,
        ],
        # a developer's run explores new inputs each time; CI (CI=true) replays one fixed
        # set, so that a submission lands or not on its own merits, and an input a local run
        # finds becomes a regression test beside the reader it broke
        derandomize=bool(os.environ.get("CI")),
    )


class HangError(Exception):
    """An example ran past HANG_SECONDS of CPU time."""


@contextmanager
def no_hang(seconds: float = HANG_SECONDS) -> Iterator[None]:
    """Fail the example (not the whole run) if it takes more than `seconds` of CPU time.

    CPU time (`ITIMER_PROF`), not the clock: a loop that never ends spends CPU time, and
    an example's CPU time does not grow with the machine's load, where its wall-clock time
    does (the slowest Saleae examples took 1.1 s of wall-clock time for 0.08 s of CPU at
    a load average of 17). Nor does it touch `SIGALRM` and the real-time timer, which
    pytest-timeout (`timeout` in pyproject.toml) arms for the whole test: the clock limit
    this used to set cancelled it at the first example, so a test stuck waiting (no CPU
    spent) now ends at pytest-timeout's limit instead of never."""

    def alarm(signum: int, frame: FrameType | None) -> None:
        raise HangError(f"one example took more than {seconds:g} s of CPU time")

    previous = signal.signal(signal.SIGPROF, alarm)
    signal.setitimer(signal.ITIMER_PROF, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, previous)


@st.composite
def mutated(draw: st.DrawFn, seeds: list[bytes]) -> bytes:
    """One seed, cut short or grown, with bytes flipped, inserted, deleted or repeated:
    the damage a file meets on a flaky disk, a cut transfer or an attacker's hands."""
    data = bytearray(draw(st.sampled_from(seeds)))
    for _ in range(draw(st.integers(0, 6))):
        op = draw(st.sampled_from(["flip", "set", "insert", "delete", "repeat", "cut"]))
        at = draw(st.integers(0, max(len(data) - 1, 0)))
        if op == "flip" and data:
            data[at] ^= 1 << draw(st.integers(0, 7))
        elif op == "set" and data:
            data[at] = draw(st.sampled_from([0x00, 0xFF, 0x7F, 0x80, draw(st.integers(0, 255))]))
        elif op == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=16))
        elif op == "delete":
            del data[at : at + draw(st.integers(1, 16))]
        elif op == "repeat":
            piece = data[at : at + draw(st.integers(1, 64))]
            data[at:at] = piece * draw(st.integers(1, 4))
        elif op == "cut":
            del data[at:]
    return bytes(data)


def conserved(store: FrameStore, read: dict[int, bytes]) -> None:
    """Every byte read on each channel is in exactly one row of that channel, in order,
    none left out, and the store holds exactly the bytes read."""
    store.sync()
    position: dict[int, int] = {}
    for i in range(len(store)):
        if store.kind[i] == Kind.EVENT:
            continue
        channel = store.channel[i]
        assert store.offset[i] == position.get(channel, 0), f"row {i} starts out of order"
        assert store.length[i] > 0, f"row {i} is empty"
        position[channel] = store.offset[i] + store.length[i]
    for channel, data in read.items():
        assert position.get(channel, 0) == len(data), f"channel {channel}: bytes left out"
        assert bytes(store.stream(channel)) == data, f"channel {channel}: bytes changed"


def bytes_by_channel(chunks: list[Chunk]) -> dict[int, bytes]:
    found: dict[int, bytearray] = {}
    for chunk in chunks:
        if chunk.data:
            found.setdefault(chunk.channel, bytearray()).extend(chunk.data)
    return {channel: bytes(data) for channel, data in found.items()}
