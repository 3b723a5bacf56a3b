"""Tests the time the network decoder gives chunks, and their order: a packet's bytes all
at its capture time, chunks in time order over every connection whatever the carrier
detection holds back, connection events at their times, a refused connection read."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.model import Chunk
from sniffer.sources import ReadOptions, open_capture
from sniffer.sources.net import parse_label
from tests.support.gateway import mbap_frame
from tests.support.netbuild import TCP_ACK, TCP_RST, TCP_SYN, Conversation, pcap

T0 = 1_750_000_000.0
RTU_REQ = with_crc(bytes.fromhex("0103 0000 0002"))
RTU_ANS = with_crc(bytes.fromhex("0103 04 0007 0008"))
MB_REQ = mbap_frame(1, bytes.fromhex("0103000a0002"))
MB_ANS = mbap_frame(1, bytes.fromhex("01030400010002"))


def chunks_of(
    tmp_path: Path, packets: list[tuple[float, bytes]]
) -> tuple[list[Chunk], dict[int, str]]:
    path = tmp_path / "c.pcap"
    path.write_bytes(pcap(1, packets))
    capture = open_capture(path, ReadOptions())
    return list(capture.chunks()), capture.info.channels


def times(chunks: list[Chunk]) -> list[float]:
    return [c.t_end for c in chunks]


def test_a_payload_has_its_packet_time_for_every_byte(tmp_path: Path) -> None:
    """No line speed applies to a payload: the bytes are not dated before their packet."""
    conv = Conversation(server_port=4001)
    packets = [(T0, conv.client(RTU_REQ)), (T0 + 0.0005, conv.server(RTU_ANS))]
    chunks, _ = chunks_of(tmp_path, packets)
    data = [c for c in chunks if c.data]
    assert [(c.t_start, c.t_end) for c in data] == [(T0, T0), (T0 + 0.0005, T0 + 0.0005)]


def test_a_refused_connection_is_read_not_a_crash(tmp_path: Path) -> None:
    """SYN answered by RST ACK: the server's first segment is its reset."""
    probe = Conversation(client_port=50400)
    packets = [(T0, probe.client(b"", TCP_SYN)), (T0 + 0.001, probe.server(b"", TCP_RST | TCP_ACK))]
    chunks, _ = chunks_of(tmp_path, packets)
    assert [(c.t_end, c.note) for c in chunks] == [
        (T0, "opened (SYN)"),
        (T0 + 0.001, "reset (RST)"),
    ]


def test_a_connection_opened_early_and_silent_keeps_its_place(tmp_path: Path) -> None:
    """B opens at 0 and speaks at 5 s; A polls all along. B's carrier is decided by its
    payloads at 5 s, yet its SYN leaves first, at its time, and nothing is out of order."""
    a = Conversation()
    b = Conversation(client_port=50300, server_ip="192.168.1.30")
    packets = [(T0, b.client(b"", TCP_SYN)), (T0 + 0.001, b.server(b"", TCP_SYN | TCP_ACK))]
    for k in range(12):
        t = T0 + 0.5 + k * 0.5
        packets += [(t, a.client(MB_REQ)), (t + 0.002, a.server(MB_ANS))]
        if k >= 9:
            packets += [(t + 0.01, b.client(MB_REQ)), (t + 0.012, b.server(MB_ANS))]
    chunks, channels = chunks_of(tmp_path, packets)
    assert times(chunks) == sorted(times(chunks))
    assert chunks[0].note == "opened (SYN)" and chunks[0].t_end == T0
    assert parse_label(channels[chunks[0].channel]).sender == "192.168.1.10:50300"  # type: ignore[union-attr]
    assert sum(len(c.data) for c in chunks) == 15 * (len(MB_REQ) + len(MB_ANS))


def test_a_port_probe_is_listed_at_its_time(tmp_path: Path) -> None:
    """A health check (SYN, RST) on port 502 in the middle of polling: its events come
    where they happened, not when the capture ends."""
    a = Conversation()
    probe = Conversation(client_port=50400)
    packets = []
    for k in range(6):
        t = T0 + k * 0.5
        packets += [(t, a.client(MB_REQ)), (t + 0.002, a.server(MB_ANS))]
        if k == 2:
            packets += [
                (t + 0.1, probe.client(b"", TCP_SYN)),
                (t + 0.101, probe.server(b"", TCP_RST | TCP_ACK)),
            ]
    chunks, _ = chunks_of(tmp_path, packets)
    assert times(chunks) == sorted(times(chunks))
    notes = [(c.t_end, c.note) for c in chunks if c.event]
    assert notes == [(T0 + 1.1, "opened (SYN)"), (T0 + 1.101, "reset (RST)")]


def test_a_silent_rtu_connection_gives_its_events_then_its_frames(tmp_path: Path) -> None:
    """Opened on port 4001, silent for longer than the decoder holds chunks back, then
    RTU over TCP: the SYN is not held up to the first payload (the others flow on), and
    the payload still decides the carrier."""
    from sniffer.sources.net.decoder import HOLD_SPAN

    a = Conversation()
    rtu = Conversation(client_port=50500, server_ip="192.168.1.50", server_port=4001)
    packets = [(T0, rtu.client(b"", TCP_SYN)), (T0 + 0.001, rtu.server(b"", TCP_SYN | TCP_ACK))]
    last = T0 + HOLD_SPAN + 5
    t = T0 + 0.5
    while t < last:
        packets += [(t, a.client(MB_REQ)), (t + 0.002, a.server(MB_ANS))]
        t += 0.5
    packets += [(last, rtu.client(RTU_REQ)), (last + 0.001, rtu.server(RTU_ANS))]
    path = tmp_path / "c.pcap"
    path.write_bytes(pcap(1, packets))
    capture = open_capture(path, ReadOptions())
    chunks: list[Chunk] = []
    first_data_at = None
    for c in capture.chunks():
        chunks.append(c)
        if c.data and first_data_at is None:
            first_data_at = len(chunks)
    assert times(chunks) == sorted(times(chunks))
    assert chunks[0].note == "opened (SYN)"
    label = parse_label(capture.info.channels[chunks[-1].channel])
    assert label is not None and label.carrier == "rtu-over-tcp"
    assert chunks[-1].data == RTU_ANS


@settings(max_examples=60, deadline=None)
@given(
    starts=st.lists(st.floats(0, 30), min_size=1, max_size=4),
    polls=st.lists(st.integers(1, 8), min_size=4, max_size=4),
    period=st.sampled_from([0.05, 0.5, 3.0]),
)
def test_chunks_leave_in_time_order_over_any_connections(
    tmp_path_factory: pytest.TempPathFactory, starts: list[float], polls: list[int], period: float
) -> None:
    """Connections opening at any time, silent for a while, then polling (Modbus TCP and
    RTU over TCP mixed): chunks leave in time order and no byte is lost."""
    packets: list[tuple[float, bytes]] = []
    expected = 0
    for n, start in enumerate(starts):
        rtu = n % 2 == 1
        conv = Conversation(
            client_port=50000 + n,
            server_ip=f"192.168.1.{30 + n}",
            server_port=4001 if rtu else 502,
        )
        req, ans = (RTU_REQ, RTU_ANS) if rtu else (MB_REQ, MB_ANS)
        t = T0 + start
        packets += [
            (t, conv.client(b"", TCP_SYN)),
            (t + 0.001, conv.server(b"", TCP_SYN | TCP_ACK)),
        ]
        t += 2 * n + 0.01  # a silence before the first request
        for _ in range(polls[n]):
            packets += [(t, conv.client(req)), (t + 0.001, conv.server(ans))]
            expected += len(req) + len(ans)
            t += period
    packets.sort(key=lambda p: p[0])
    path = tmp_path_factory.mktemp("order") / "c.pcap"
    path.write_bytes(pcap(1, packets))
    chunks = list(open_capture(path, ReadOptions()).chunks())
    assert times(chunks) == sorted(times(chunks))
    assert sum(len(c.data) for c in chunks) == expected
