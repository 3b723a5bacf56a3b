"""Provides the tests of the headless pump's gathering of reads (`LiveCapture(gather=)`).

A pump woken by a read or two waits a little for more, so that it frames ten reads for
the price of one; but the wait counts from the oldest read's arrival, not from the
wake-up, so a pump that woke late adds nothing to the delay its reads already had.
"""

from __future__ import annotations

import time

import pytest

from sniffer.live import engine as capture_module
from sniffer.live.engine import GATHER_READS, LiveCapture
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import Session
from tests.support.live import Batches, Played
from tests.support.live import Clock as FixedClock

LINE = LineSettings(baud=921600, parity="N", stopbits=1, mode="rtu")
T0 = 1768464000.0
GATHER = 0.010
READ = bytes.fromhex("010300000002c40b")  # a read of two holding registers, unit 1


class Clock(FixedClock):
    """The reader's clock, set by the test."""

    def __init__(self) -> None:
        self.t = T0

    def now(self) -> float:
        return self.t


class Scripted(Batches):
    """Hands out one prepared batch per `get` and counts the calls."""

    def __init__(self, batches: list[list[Chunk]]) -> None:
        super().__init__(batches)
        self.calls = 0

    def get(self, timeout: float | None = None) -> list[Chunk]:
        self.calls += 1
        return super().get(timeout)


class Reader(Played):
    """A reader of one scripted feed, on a clock the test sets."""

    def __init__(self, feed: Scripted, clock: Clock) -> None:
        super().__init__(LINE, [])
        self.clock = clock
        self.feed = feed


class _Time:
    """`time` as sniffer.live.engine sees it, with `sleep` only noted."""

    def __init__(self, slept: list[float]) -> None:
        self.sleep = slept.append
        self.monotonic = time.monotonic


def _pump(
    first: list[Chunk], later: list[Chunk], now: float, monkeypatch: pytest.MonkeyPatch
) -> tuple[list[float], int, int]:
    """One pump woken by `first` at clock time `now`, with `later` arriving meanwhile:
    the sleeps it asked for, the reads it fed and how often it asked the feed."""
    clock = Clock()
    clock.t = now
    feed = Scripted([first, later])
    session = Session(LINE, source="scripted")
    capture = LiveCapture(Reader(feed, clock), session, quiet=float("inf"), gather=GATHER)
    slept: list[float] = []
    monkeypatch.setattr(capture_module, "time", _Time(slept))
    fed: list[Chunk] = []
    feed_session = session.feed

    def feed_and_count(chunk: Chunk) -> None:
        fed.append(chunk)
        feed_session(chunk)

    monkeypatch.setattr(session, "feed", feed_and_count)
    capture.pump(0.0)
    return slept, len(fed), feed.calls


def test_a_fresh_read_waits_the_whole_gather_and_takes_what_came_meanwhile(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    first = [Chunk(READ, T0)]
    later = [Chunk(READ, T0 + 0.004), Chunk(READ, T0 + 0.008)]
    slept, fed, calls = _pump(first, later, T0, monkeypatch)
    assert slept == [pytest.approx(GATHER, abs=1e-6)]
    assert (fed, calls) == (3, 2)


def test_a_read_that_waited_already_gathers_only_the_rest(monkeypatch: pytest.MonkeyPatch) -> None:
    slept, fed, calls = _pump([Chunk(READ, T0)], [Chunk(READ, T0 + 0.005)], T0 + 0.006, monkeypatch)
    assert slept == [pytest.approx(GATHER - 0.006, abs=1e-6)]
    assert (fed, calls) == (2, 2)


def test_a_pump_that_woke_late_frames_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    # the oldest read arrived 40 ms ago (a loaded machine): no wait on top of that
    slept, fed, calls = _pump([Chunk(READ, T0)], [Chunk(READ, T0 + 0.03)], T0 + 0.040, monkeypatch)
    assert slept == []
    assert (fed, calls) == (2, 2)


def test_enough_reads_waiting_need_no_gathering(monkeypatch: pytest.MonkeyPatch) -> None:
    first = [Chunk(READ, T0 + 0.001 * k) for k in range(GATHER_READS)]
    slept, fed, calls = _pump(first, [Chunk(READ, T0 + 0.009)], T0 + 0.004, monkeypatch)
    assert slept == []
    assert (fed, calls) == (GATHER_READS, 1)


def test_a_clock_behind_the_reads_never_waits_longer_than_the_gather(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    slept, _, _ = _pump([Chunk(READ, T0 + 5)], [], T0, monkeypatch)
    assert slept == [pytest.approx(GATHER, abs=1e-6)]
