"""Tests linking both sides of a gateway: each injected fault gives its verdict, the clock
offset between the two captures is estimated, the gateway's delays are measured."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.analysis.gateway import Verdict, estimate_offset, link, transactions
from sniffer.analysis.gateway_report import gateway_table
from sniffer.framing.pipeline import frame_capture
from sniffer.framing.store import FrameStore
from sniffer.framing.tcp import NetPipeline
from sniffer.model import Chunk
from sniffer.sources import open_capture
from tests.support.gateway import (
    CASES,
    DELAY_IN,
    DELAY_OUT,
    EXC_0B,
    EXPECTED,
    LINE,
    RTU_TIME,
    SERIAL_CLOCK,
    mbap_frame,
    read_answer,
    read_request,
)
from tests.support.netbuild import Conversation, pcap


def build(tmp_path: Path) -> tuple[FrameStore, FrameStore]:
    conv = Conversation()
    packets: list[tuple[float, bytes]] = [
        (1000.0 + k * 0.001, p) for k, p in enumerate(conv.handshake())
    ]
    chunks: list[Chunk] = []
    for k, (_, tcp_answer, sent, rtu_answer) in enumerate(CASES):
        t = 1001.0 + k  # a transaction per second
        request = read_request(10 + k)
        packets.append((t, conv.client(mbap_frame(k + 1, request))))
        serial_end = t + DELAY_IN + RTU_TIME
        if sent:
            chunks.append(Chunk(with_crc(request), t_end=serial_end + SERIAL_CLOCK))
        answer_end = serial_end + 0.02 + RTU_TIME
        if rtu_answer is not None:
            chunks.append(Chunk(with_crc(rtu_answer), t_end=answer_end + SERIAL_CLOCK))
        if tcp_answer is not None:
            packets.append(
                (
                    answer_end + DELAY_OUT + 0.5 * (rtu_answer is None),
                    conv.server(mbap_frame(k + 1, tcp_answer)),
                )
            )
    path = tmp_path / "tcp.pcap"
    path.write_bytes(pcap(1, packets))
    capture = open_capture(path)
    pipeline = NetPipeline(LINE, channels=capture.info.channels)
    pipeline.feed_all(capture.chunks())
    pipeline.finish()
    return pipeline.store, frame_capture(chunks, LINE)


def test_each_injected_fault_gets_its_verdict(tmp_path: Path) -> None:
    tcp, serial = build(tmp_path)
    links = link(tcp, serial, offset=-SERIAL_CLOCK)
    assert [x.verdict for x in links] == EXPECTED
    assert "device answered" in links[5].text
    assert "nothing was sent" in links[6].text


def test_delays_are_measured_on_each_side(tmp_path: Path) -> None:
    tcp, serial = build(tmp_path)
    first = link(tcp, serial, offset=-SERIAL_CLOCK)[0]
    assert first.delay_in is not None and first.delay_out is not None
    # the serial request starts about one frame time before its last byte
    assert first.delay_in == pytest.approx(DELAY_IN + RTU_TIME - 7 * LINE.char_time, abs=2e-3)
    assert first.delay_out == pytest.approx(DELAY_OUT, abs=1e-3)


def test_clock_offset_is_estimated(tmp_path: Path) -> None:
    tcp, serial = build(tmp_path)
    found = estimate_offset(transactions(tcp), transactions(serial), window=200.0)
    assert found is not None
    offset, spread, samples = found
    assert samples == 4  # the transactions answered on both sides (cases 0, 5, 7, 8)
    assert offset == pytest.approx(-SERIAL_CLOCK, abs=0.02)
    assert [x.verdict for x in link(tcp, serial, offset=offset)] == EXPECTED
    assert spread < 0.02


def test_without_the_offset_nothing_links(tmp_path: Path) -> None:
    tcp, serial = build(tmp_path)
    assert {x.verdict for x in link(tcp, serial)} <= {Verdict.NOT_SENT, Verdict.GATEWAY_EXCEPTION}


FATES = ("ok", "dropped", "device silent", "answer lost")
FATE_VERDICT = {
    "ok": Verdict.OK,
    "dropped": Verdict.NOT_SENT,
    "device silent": Verdict.DEVICE_TIMEOUT,
    "answer lost": Verdict.ANSWER_LOST,
}


def polling(fates: list[str], period: float, tmp: Path) -> tuple[FrameStore, FrameStore]:
    """Three requests polled round-robin every `period` s, answers whose value changes
    every tenth poll, each transaction with its fate; the serial clock 37 s behind."""
    conv = Conversation()
    packets: list[tuple[float, bytes]] = []
    chunks: list[Chunk] = []
    for k, fate in enumerate(fates):
        t = 2000.0 + k * period
        request, answer = read_request(k % 3), read_answer(k // 10)
        packets.append((t, conv.client(mbap_frame(k % 65536, request))))
        if fate == "dropped":
            continue
        sent_end = t + DELAY_IN + 0.002 * (k % 2) + RTU_TIME
        chunks.append(Chunk(with_crc(request), t_end=sent_end - 37.0))
        if fate == "device silent":
            continue
        answer_end = sent_end + 0.005 + RTU_TIME
        chunks.append(Chunk(with_crc(answer), t_end=answer_end - 37.0))
        if fate == "ok":
            packets.append((answer_end + DELAY_OUT, conv.server(mbap_frame(k % 65536, answer))))
    path = tmp / "poll.pcap"
    path.write_bytes(pcap(1, packets))
    capture = open_capture(path)
    pipeline = NetPipeline(LINE, channels=capture.info.channels)
    pipeline.feed_all(capture.chunks())
    pipeline.finish()
    return pipeline.store, frame_capture(chunks, LINE)


def ambiguous(fates: list[str]) -> bool:
    """Whether another clock offset explains the answered polls as well: a shift by whole
    polls that maps every poll answered on both sides to one answered on the serial side
    with the same request (k % 3) and the same answer (k // 10). No estimator can tell
    such clocks apart; `--offset` is there for them."""
    answered = {k for k, f in enumerate(fates) if f in ("ok", "answer lost")}
    anchors = [k for k, f in enumerate(fates) if f == "ok"]
    for shift in range(-len(fates), len(fates)):
        if shift and all(
            k + shift in answered and (k + shift) % 3 == k % 3 and (k + shift) // 10 == k // 10
            for k in anchors
        ):
            return True
    return False


@settings(max_examples=30, deadline=None)
@given(st.lists(st.sampled_from(FATES), min_size=5, max_size=60).filter(lambda f: "ok" in f))
def test_fast_repeated_polls_link_one_for_one(fates: list[str]) -> None:
    """Polls faster than the gateway timeout repeat the same request: a dropped one must
    not take the next one's serial request, whatever the fates (estimated clocks), where
    the traffic tells the clocks apart at all."""
    from sniffer.analysis.gateway import coarse_offset

    assume(not ambiguous(fates))

    with tempfile.TemporaryDirectory() as folder:
        tcp, serial = polling(fates, 0.05, Path(folder))
    tcp_sides, serial_sides = transactions(tcp), transactions(serial)
    guess = coarse_offset(tcp_sides, serial_sides)
    assert guess is not None
    found = estimate_offset(tcp_sides, serial_sides, window=0.1, guess=guess)
    assert found is not None
    offset = found[0]
    assert offset == pytest.approx(37.0, abs=0.02)
    links = link(tcp, serial, offset=offset)
    assert [x.verdict for x in links] == [FATE_VERDICT[f] for f in fates]


# (TCP answer, the device's answer garbled on the serial line?, verdict)
GARBLED = [
    (EXC_0B, True, "line-error"),
    (None, True, "line-error"),
    (EXC_0B, False, "gateway-fault"),
    (None, False, "answer-lost"),
]


def test_an_answer_garbled_on_the_serial_line_is_a_line_error_not_a_gateway_fault(
    tmp_path: Path,
) -> None:
    """The device answered, but its CRC came garbled over the serial line: the gateway
    rightly refused it (0x0B, or nothing). That is a serial-side line error; a gateway
    exception although the device answered intact is the gateway's fault."""
    conv = Conversation()
    packets: list[tuple[float, bytes]] = []
    chunks: list[Chunk] = []
    for k, (tcp_answer, garbled, _) in enumerate(GARBLED):
        t = 3000.0 + k
        request = read_request(k)
        packets.append((t, conv.client(mbap_frame(k + 1, request))))
        sent_end = t + DELAY_IN + RTU_TIME
        chunks.append(Chunk(with_crc(request), t_end=sent_end))
        raw = with_crc(read_answer(40 + k))
        if garbled:
            assert raw[-1] != raw[-2]
            raw = raw[:-2] + raw[-1:] + raw[-2:-1]  # the CRC bytes swapped
        answer_end = sent_end + 0.005 + RTU_TIME
        chunks.append(Chunk(raw, t_end=answer_end))
        if tcp_answer is not None:
            packets.append((answer_end + 0.2, conv.server(mbap_frame(k + 1, tcp_answer))))
    path = tmp_path / "tcp.pcap"
    path.write_bytes(pcap(1, packets))
    capture = open_capture(path)
    pipeline = NetPipeline(LINE, channels=capture.info.channels)
    pipeline.feed_all(capture.chunks())
    pipeline.finish()
    links = link(pipeline.store, frame_capture(chunks, LINE))
    assert [x.verdict.value for x in links] == [v for _, _, v in GARBLED]
    assert "garbled on the serial line" in links[0].text and "0x0B" in links[0].text
    assert "garbled on the serial line" in links[1].text
    assert "intact" not in links[2].text and "device answered" in links[2].text
    table = gateway_table(links).splitlines()
    row = next(line for line in table if line.split()[:1] == ["line-error"])
    assert row.split(maxsplit=2)[1:] == ["2", "the device's answer was garbled on the serial line"]
