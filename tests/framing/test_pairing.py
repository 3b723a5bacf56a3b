"""Pairing: which request each answer belongs to, and what became of each request."""

from __future__ import annotations

import pytest

from dissectors.checks import with_crc
from sniffer.framing.pairing import latency
from sniffer.framing.pipeline import Pipeline, frame_capture
from sniffer.framing.store import FrameStore
from sniffer.model import Chunk, LineSettings
from sniffer.vocab import STATUS_NAMES, Flag, Kind, Status

LINE = LineSettings(baud=19200, parity="E", mode="rtu")
REQ = with_crc(bytes.fromhex("0103000a0002"))
RESP = with_crc(bytes.fromhex("01030400010002"))
REQ2 = with_crc(bytes.fromhex("0203000a0001"))
RESP2 = with_crc(bytes.fromhex("0203020007"))
EXC = with_crc(bytes.fromhex("018302"))


def capture(*frames: tuple[float, bytes], timeout: float = 0.5) -> FrameStore:
    """Frames delivered as separate reads at the given times (when the read returned)."""
    chunks = [Chunk(data, t_end=t) for t, data in frames]
    return frame_capture(chunks, LINE, timeout=timeout)


def statuses(store: FrameStore) -> list[str]:
    return [STATUS_NAMES[s] for s in store.status]


def test_answer_pairs_with_its_request_and_latency_is_end_to_start() -> None:
    store = capture((1.000, REQ), (1.020, RESP))
    assert statuses(store) == ["ok", "ok"]
    assert store.partner[0] == 1 and store.partner[1] == 0
    gap = store.t[1] - store.t_end[0]
    assert latency(store, 0) == latency(store, 1) == pytest.approx(gap)
    assert 0.01 < gap < 0.02


def test_exception_answer() -> None:
    store = capture((1.0, REQ), (1.01, EXC))
    assert statuses(store) == ["exception", "exception"]


def test_no_answer_within_the_timeout_is_a_timeout_and_the_repeat_a_retry() -> None:
    store = capture((1.0, REQ), (2.0, REQ), (2.02, RESP))
    assert statuses(store) == ["timeout", "ok", "ok"]
    assert store.flags[1] & Flag.RETRY and not store.flags[0] & Flag.RETRY


def test_a_different_request_after_a_silent_slave_is_not_a_retry() -> None:
    store = capture((1.0, REQ), (1.1, REQ2), (1.12, RESP2))
    assert statuses(store) == ["timeout", "ok", "ok"]
    assert not store.flags[1] & Flag.RETRY


def test_interleaved_timeouts() -> None:
    store = capture(
        (1.0, REQ), (1.02, RESP), (1.1, REQ2), (1.7, REQ), (1.72, RESP), (1.8, REQ2), (1.82, RESP2)
    )
    assert statuses(store) == ["ok", "ok", "timeout", "ok", "ok", "ok", "ok"]


def test_answer_with_no_request_is_an_orphan() -> None:
    store = capture((1.0, RESP2))
    assert [Kind(k) for k in store.kind] == [Kind.RESPONSE]
    assert statuses(store) == ["orphan"]


def test_broadcast_expects_no_answer_and_an_answer_to_it_is_a_problem() -> None:
    broadcast = with_crc(bytes.fromhex("000600010003"))
    answer = with_crc(bytes.fromhex("008302"))
    store = capture((1.0, broadcast), (1.2, REQ), (1.22, RESP), (1.3, broadcast), (1.31, answer))
    assert statuses(store)[:3] == ["broadcast", "ok", "ok"]
    assert statuses(store)[3] == "broadcast"
    assert statuses(store)[4] == "orphan" and store.flags[4] & Flag.ANSWERED_BROADCAST


def test_echo_of_a_write_pairs_by_order() -> None:
    w = with_crc(bytes.fromhex("010600010003"))
    store = capture((1.0, w), (1.01, w), (1.1, w), (1.11, w))
    assert [Kind(k) for k in store.kind] == [Kind.REQUEST, Kind.RESPONSE] * 2
    assert list(store.partner) == [1, 0, 3, 2]


def test_late_answer_is_paired_and_flagged() -> None:
    store = capture((1.0, REQ), (1.8, RESP), timeout=0.5)
    assert store.flags[1] & Flag.LATE


def test_answer_with_a_bad_crc_makes_a_bad_answer() -> None:
    bad = bytearray(RESP)
    bad[3] ^= 1
    store = capture((1.0, REQ), (1.01, bytes(bad)), (1.2, REQ2), (1.21, RESP2))
    assert statuses(store)[:2] == ["bad answer", "bad answer"]


def test_live_request_times_out_when_the_line_stays_quiet() -> None:
    pipeline = Pipeline(LINE, timeout=0.3)
    pipeline.feed(Chunk(REQ, t_end=10.0))
    pipeline.idle(10.1)
    assert pipeline.store.status[0] == Status.OPEN
    pipeline.idle(10.5)
    assert pipeline.store.status[0] == Status.TIMEOUT


def test_answer_arriving_in_a_later_read_still_pairs() -> None:
    pipeline = Pipeline(LINE)
    pipeline.feed(Chunk(REQ, t_end=10.0))
    pipeline.sync()
    assert pipeline.store.status[0] == Status.OPEN
    pipeline.feed(Chunk(RESP[:3], t_end=10.01))
    pipeline.feed(Chunk(RESP[3:], t_end=10.012))
    pipeline.feed(Chunk(REQ2, t_end=10.1))
    pipeline.sync()
    assert statuses(pipeline.store) == ["ok", "ok", "open"]
