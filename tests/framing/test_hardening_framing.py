"""Faults the fuzz harness found in framing and merging, each pinned by a byte literal."""

from __future__ import annotations

from dissectors.checks import with_crc
from sniffer.framing.pipeline import frame_capture
from sniffer.model import Chunk, LineSettings
from sniffer.vocab import Kind

RTU = LineSettings(baud=19200, parity="E", mode="rtu")
REQUEST_3 = with_crc(bytes.fromhex("030302b80028"))
REQUEST_1 = with_crc(bytes.fromhex("010300000002"))
ANSWER_4 = with_crc(bytes.fromhex("040302a10002"))


def test_rows_framed_before_a_second_channel_appears_keep_their_channel() -> None:
    # channel 1 is heard first; its rows went into the store by the framer's fast path
    # and were labelled channel 0 when channel 0 appeared and merging began, so the
    # listing showed channel 0's bytes at their place
    chunks = [
        Chunk(REQUEST_3 + REQUEST_1, t_end=0.999, channel=1),
        Chunk(ANSWER_4 + b"\xff\xff", t_end=1.0, channel=0),
        Chunk(REQUEST_1, t_end=1.5, channel=1),
    ]
    store = frame_capture(chunks, RTU)
    rows = [(store.channel[i], store.raw(i)) for i in range(len(store))]
    assert sorted(r for r in rows if r[0] == 1) == sorted(
        [(1, REQUEST_3), (1, REQUEST_1), (1, REQUEST_1)]
    )
    assert (0, ANSWER_4) in rows
    for i in range(len(store)):
        if store.kind[i] != Kind.NOISE:
            assert store.raw(i) in (REQUEST_3, REQUEST_1, ANSWER_4)


def test_rows_completed_by_an_event_get_their_framers_channel() -> None:
    # a framing-error event on channel 1 completed the fast path's pending rows with the
    # store's default channel 0 before the framer had said which channel they were on
    chunks = [
        Chunk(REQUEST_1 + b"\x01\x03\x50", t_end=1.0, channel=1),
        Chunk(b"", t_end=1.0, channel=1, event="framing error"),
        Chunk(ANSWER_4, t_end=1.1, channel=0),
    ]
    store = frame_capture(chunks, RTU)
    rows = [(store.channel[i], store.raw(i)) for i in range(len(store)) if store.length[i]]
    assert (1, REQUEST_1) in rows
    assert (0, ANSWER_4) in rows
