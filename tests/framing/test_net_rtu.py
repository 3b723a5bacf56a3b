"""Tests RTU over TCP/UDP framing and pairing: no serial baud applies to a payload (times
are packet times at any `--baud`), pairing is per connection and in order, a garbled CRC
in a payload is a frame with a bad check, never noise, and rows are stored in time
order."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.framing.pairing import measure, timing_note
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.framing.tcp import TCP_TIMEOUT, NetPipeline
from sniffer.model import LineSettings, Stamp
from sniffer.sources import ReadOptions, open_capture
from sniffer.vocab import Flag, Kind, Status
from tests.support.netbuild import Conversation, ethernet, ipv4, pcap, udp

T0 = 1_750_000_000.0
REQUEST = with_crc(bytes.fromhex("1103 006B 0003"))  # (01 03 0000 0002 reads as MBAP too)


def answer(a: int, b: int) -> bytes:
    return with_crc(bytes([0x11, 3, 6]) + a.to_bytes(2, "big") + b.to_bytes(2, "big") + b"\0\0")


def swapped(frame: bytes) -> bytes:
    """The frame with its two CRC bytes swapped (as a buggy gateway sends them)."""
    return frame[:-2] + frame[-1:] + frame[-2:-1]


def frame(
    tmp_path: Path,
    packets: list[tuple[float, bytes]],
    baud: int | None = None,
    port: int | None = None,
) -> FrameStore:
    """Framed and paired as `modscope replay` does (the capture's stamps and labels)."""
    path = tmp_path / "c.pcap"
    path.write_bytes(pcap(1, packets))
    options = ReadOptions(baud=baud, port=port)
    capture = open_capture(path, options)
    info = capture.info
    pipeline = NetPipeline(
        options.line(info.line),
        channels=info.channels,
        stamps=info.stamps,
        resolution=info.resolution,
        labels=info.labels,
    )
    pipeline.feed_all(capture.chunks())
    pipeline.finish()
    return pipeline.store


def rows(store: FrameStore) -> list[int]:
    return [i for i in range(len(store)) if store.kind[i] not in (Kind.NOISE, Kind.EVENT)]


def polls(delays: list[float], period: float = 0.1) -> list[tuple[float, bytes]]:
    """One gateway on port 4001 answering each poll `delay` after it."""
    conv = Conversation(server_port=4001)
    packets = []
    for k, delay in enumerate(delays):
        t = T0 + k * period
        packets += [(t, conv.client(REQUEST)), (t + delay, conv.server(answer(k, 2 * k)))]
    return packets


@settings(max_examples=40, deadline=None)
@given(
    baud=st.sampled_from([1200, 9600, 19200, 115200]),
    delays=st.lists(st.integers(500, 3000).map(lambda us: us / 1e6), min_size=1, max_size=8),
)
# every stamp within 6 µs of a millisecond: once taken for a 1 ms clock (clock_step)
@example(baud=1200, delays=[0.000994] * 4)
def test_answers_follow_their_requests_at_any_baud(
    tmp_path_factory: pytest.TempPathFactory, baud: int, delays: list[float]
) -> None:
    """A native RTU-over-TCP device answers 0.5-3 ms after the request: each answer is
    stored after its request, paired with it, and measured from packet to packet."""
    store = frame(tmp_path_factory.mktemp("rtu"), polls(delays), baud)
    found = rows(store)
    assert [store.kind[i] for i in found] == [Kind.REQUEST, Kind.RESPONSE] * len(delays)
    assert list(store.t) == sorted(store.t)
    for k, delay in enumerate(delays):
        req, ans = found[2 * k], found[2 * k + 1]
        assert store.t[req] == store.t_end[req] == pytest.approx(T0 + k * 0.1, abs=1e-6)
        assert store.partner[ans] == req and store.status[ans] == Status.OK
        latency = measure(store, ans)
        assert latency is not None and not latency.bound
        assert latency.seconds == pytest.approx(delay, abs=2e-6)


def test_rows_are_the_same_at_any_baud(tmp_path: Path) -> None:
    """`--baud` means nothing to a network payload: framing, times and pairing agree."""
    packets = polls([0.0005, 0.001, 0.003, 0.002])

    def table(baud: int) -> list[tuple[float, float, int, int, int]]:
        store = frame(tmp_path, packets, baud)
        return [
            (store.t[i], store.t_end[i], store.kind[i], store.status[i], store.partner[i])
            for i in range(len(store))
        ]

    assert table(1200) == table(9600) == table(115200)


def test_two_connections_interleaved_pair_per_connection(tmp_path: Path) -> None:
    """Two gateways polled for the same unit and registers at once; the second answers
    first. Each answer pairs with the request of its own connection."""
    a = Conversation(server_ip="192.168.1.20", server_port=4001)
    b = Conversation(client_port=50300, server_ip="192.168.1.30", server_port=4001)
    packets = []
    for k in range(3):
        t = T0 + k * 0.2
        packets += [
            (t, a.client(REQUEST)),
            (t + 0.0002, b.client(REQUEST)),
            (t + 0.0008, b.server(answer(3, 4))),
            (t + 0.0015, a.server(answer(1, 2))),
        ]
    store = frame(tmp_path, packets, 9600)
    answers = [i for i in rows(store) if store.kind[i] == Kind.RESPONSE]
    assert len(answers) == 6
    for i in answers:
        req = store.partner[i]
        assert req != NO_PARTNER and store.channel[req] >> 1 == store.channel[i] >> 1
        assert store.status[i] == Status.OK
        latency = measure(store, i)
        assert latency is not None
        expected = 0.0015 if store.raw(i) == answer(1, 2) else 0.0006
        assert latency.seconds == pytest.approx(expected, abs=2e-6)
    assert list(store.t) == sorted(store.t)


@pytest.mark.parametrize("baud", [1200, 19200])
def test_a_swapped_crc_is_a_frame_with_a_bad_check_at_its_packet_time(
    tmp_path: Path, baud: int
) -> None:
    """The first answer of the capture has its CRC bytes swapped: it is the answer, with a
    bad check, at its packet's time, paired with its request; never noise."""
    conv = Conversation(server_port=4001)
    packets = [
        (T0, conv.client(REQUEST)),
        (T0 + 0.0005, conv.server(swapped(answer(7, 8)))),
        (T0 + 0.2, conv.client(REQUEST)),
        (T0 + 0.2005, conv.server(answer(7, 8))),
    ]
    store = frame(tmp_path, packets, baud)
    assert Kind.NOISE not in list(store.kind)
    bad = next(i for i in range(len(store)) if store.flags[i] & Flag.CHECK_BAD)
    assert store.kind[bad] == Kind.RESPONSE
    assert store.raw(bad) == swapped(answer(7, 8))
    assert store.t[bad] == pytest.approx(T0 + 0.0005, abs=1e-6)
    assert store.status[bad] == Status.BAD_ANSWER
    assert store.partner[bad] == 0 and store.kind[0] == Kind.REQUEST


def test_a_garbled_packet_is_not_run_together_with_line_noise_before_it(tmp_path: Path) -> None:
    """A transparent serial server forwards three bytes of line noise, then an answer with
    a garbled CRC in the next packet: the noise is noise, the answer a frame with a bad
    check (each packet is what the server read off its line as one piece)."""
    conv = Conversation(server_port=4001)
    garbled = answer(7, 8)[:-1] + b"\x00"
    packets = [
        (T0, conv.client(REQUEST)),
        (T0 + 0.0003, conv.server(b"\x00\xff\x00")),
        (T0 + 0.0009, conv.server(garbled)),
        (T0 + 0.2, conv.client(REQUEST)),
        (T0 + 0.2009, conv.server(answer(7, 8))),
    ]
    store = frame(tmp_path, packets)
    server = [i for i in range(len(store)) if store.channel[i] == 1]
    assert [(store.kind[i], store.raw(i)) for i in server] == [
        (Kind.NOISE, b"\x00\xff\x00"),
        (Kind.RESPONSE, garbled),
        (Kind.RESPONSE, answer(7, 8)),
    ]
    assert store.flags[server[1]] & Flag.CHECK_BAD
    assert store.status[server[1]] == Status.BAD_ANSWER


def test_an_answer_split_over_two_segments_is_one_frame(tmp_path: Path) -> None:
    """A serial server that forwards what it has every few milliseconds: the answer comes
    in two segments; it starts with the first packet and ends with the second."""
    conv = Conversation(server_port=4001)
    full = answer(5, 6)
    packets = [
        (T0, conv.client(REQUEST)),
        (T0 + 0.002, conv.server(full[:4])),
        (T0 + 0.004, conv.server(full[4:])),
    ]
    store = frame(tmp_path, packets, 1200)
    ans = next(i for i in range(len(store)) if store.kind[i] == Kind.RESPONSE)
    assert store.raw(ans) == full
    assert (store.t[ans], store.t_end[ans]) == pytest.approx((T0 + 0.002, T0 + 0.004), abs=1e-6)
    latency = measure(store, ans)
    assert latency is not None and latency.seconds == pytest.approx(0.002, abs=2e-6)


def test_rtu_over_udp_answers_follow_their_requests(tmp_path: Path) -> None:
    def dgram(to_server: bool, payload: bytes) -> bytes:
        if to_server:
            return ethernet(ipv4("10.0.0.1", "10.0.0.3", 17, udp(40001, 4001, payload)))
        return ethernet(ipv4("10.0.0.3", "10.0.0.1", 17, udp(4001, 40001, payload)))

    packets = []
    for k in range(3):
        t = T0 + k * 0.1
        packets += [(t, dgram(True, REQUEST)), (t + 0.001, dgram(False, answer(k, k)))]
    store = frame(tmp_path, packets, 1200)
    answers = [i for i in rows(store) if store.kind[i] == Kind.RESPONSE]
    assert [store.status[i] for i in answers] == [Status.OK] * 3
    for i in answers:
        latency = measure(store, i)
        assert latency is not None and latency.seconds == pytest.approx(0.001, abs=2e-6)


def test_a_garbled_answer_whose_request_the_capture_missed_is_still_a_frame(
    tmp_path: Path,
) -> None:
    """The capture starts between a request and its answer, and that answer's CRC is
    garbled: no unit is known yet, but the packet has the length its function code gives
    (a byte count of 6: 11 bytes), so it is an answer with a bad check. (`--port` says
    which side is the server: the capture saw no SYN.)"""
    conv = Conversation(server_port=4001)
    packets = [
        (T0, conv.server(swapped(answer(7, 8)))),
        (T0 + 0.2, conv.client(REQUEST)),
        (T0 + 0.2005, conv.server(answer(7, 8))),
    ]
    store = frame(tmp_path, packets, port=4001)
    assert [(store.kind[i], bool(store.flags[i] & Flag.CHECK_BAD)) for i in range(len(store))] == [
        (Kind.RESPONSE, True),
        (Kind.REQUEST, False),
        (Kind.RESPONSE, False),
    ]
    assert store.t[0] == pytest.approx(T0, abs=1e-6) and store.status[0] == Status.ORPHAN


def test_whole_second_stamps_bound_every_latency(tmp_path: Path) -> None:
    """A capture whose clock kept whole seconds (a pcap written by a tool that dropped the
    fraction): 600 polls 0.1 s apart, answered 5 ms later, so the first 64 packets show
    only 4 instants. The clock is told from distinct stamps (a request and its answer
    stamped alike are not 0 µs apart): 1 s, and no latency is a value."""
    packets = [(float(int(t)), data) for t, data in polls([0.005] * 600)]
    store = frame(tmp_path, packets)
    assert store.resolution == 1.0
    answers = [i for i in rows(store) if store.kind[i] == Kind.RESPONSE]
    assert len(answers) == 600
    told = [measure(store, i) for i in answers]
    assert all(m is None or m.bound for m in told)


def test_a_coarse_clock_moves_the_judged_wait_not_the_timeout_it_names() -> None:
    """Stamps of 1 s: the client's timeout stays the 3 s it waits; only waits past it by
    the resolution are judged overdue, and the timing line says so once (as a serial
    line's: `Pairer.judged`)."""
    line = LineSettings(baud=9600, mode="rtu")
    pipeline = NetPipeline(line, channels={}, stamps=Stamp.PRINT, resolution=1.0)
    assert pipeline.pairer.timeout == TCP_TIMEOUT
    assert pipeline.pairer.judged == TCP_TIMEOUT + 1.0
    # what `--stats` says of it (`Stats.timing_line`, given the session's pairer timeout)
    note = timing_note(pipeline.stamps, pipeline.store.resolution, pipeline.pairer.timeout)
    assert "only past 4 s (the 3 s response timeout plus the resolution)" in note
