"""Tests reading Modbus over Ethernet: link layers, IP, TCP reassembly, carriers, framing
and pairing of Modbus TCP, RTU over TCP/UDP; pymodbus over loopback against tshark."""

from __future__ import annotations

import asyncio
import random
import shutil
import signal
import struct
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.framing.store import FrameStore
from sniffer.framing.tcp import CUT_SHORT, ENVELOPE_BAD, MBAP, TID_REUSED, NetPipeline
from sniffer.model import Chunk, Direction, Labels, Stamp
from sniffer.sources import Capture, ReadOptions, open_capture
from sniffer.sources.net import parse_label
from sniffer.sources.net.packets import Segment, Skip, decode
from sniffer.sources.pcapng_writer import PcapngWriter
from sniffer.vocab import Kind, Status
from tests.support.netbuild import (
    TCP_ACK,
    TCP_FIN,
    TCP_RST,
    TCP_SYN,
    Conversation,
    ethernet,
    ipv4,
    ipv6,
    null_loopback,
    pcap,
    tcp,
    udp,
)

T0 = 1_714_564_800.0
REQ1 = bytes.fromhex("0001 0000 0006 01 03 0000 0002")
RESP1 = bytes.fromhex("0001 0000 0007 01 03 04 0001 0002")
REQ2 = bytes.fromhex("0002 0000 0006 01 04 0010 0001")
RESP2 = bytes.fromhex("0002 0000 0005 01 04 02 1234")
RTU_REQ = with_crc(bytes.fromhex("11 03 006B 0003"))
RTU_RESP = with_crc(bytes.fromhex("11 03 06 022B 0000 0064"))


def write(tmp_path: Path, packets: list[bytes], linktype: int = 1, name: str = "c.pcap") -> Path:
    path = tmp_path / name
    path.write_bytes(pcap(linktype, [(T0 + k * 0.01, p) for k, p in enumerate(packets)]))
    return path


def read(path: Path, options: ReadOptions | None = None) -> tuple[Capture, list[Chunk]]:
    capture = open_capture(path, options or ReadOptions())
    return capture, list(capture.chunks())


def frame(path: Path, options: ReadOptions | None = None) -> tuple[Capture, FrameStore]:
    capture = open_capture(path, options or ReadOptions())
    pipeline = NetPipeline(
        capture.info.line or ReadOptions().line(), channels=capture.info.channels
    )
    pipeline.feed_all(capture.chunks())
    pipeline.finish()
    return capture, pipeline.store


def frames(store: FrameStore) -> list[tuple[int, bytes]]:
    """(channel, raw) of every frame row, in store order."""
    return [
        (store.channel[i], store.raw(i))
        for i in range(len(store))
        if store.kind[i] not in (Kind.NOISE, Kind.EVENT)
    ]


def data_by_channel(chunks: list[Chunk]) -> dict[int, bytes]:
    out: dict[int, bytes] = {}
    for c in chunks:
        out[c.channel] = out.get(c.channel, b"") + c.data
    return out


# ---------------------------------------------------------------- link layers and IP


LINKS = [
    ("ethernet", 1, {}),
    ("vlan", 1, {"vlans": (100, 200)}),
    ("sll", 113, {"link": "sll"}),
    ("sll2", 276, {"link": "sll2"}),
    ("raw", 101, {"link": "raw"}),
    ("raw-ipv4", 228, {"link": "raw"}),
    ("null", 0, {"link": "null"}),
    ("ipv6", 1, {"v6": True, "client_ip": "2001:db8::10", "server_ip": "2001:db8::20"}),
    ("raw-ipv6", 229, {"link": "raw", "v6": True, "client_ip": "fe80::1", "server_ip": "fe80::2"}),
    ("sll-ipv6", 113, {"link": "sll", "v6": True, "client_ip": "::1", "server_ip": "::1"}),
]


@pytest.mark.parametrize(("name", "linktype", "kw"), LINKS, ids=[x[0] for x in LINKS])
def test_every_link_type_gives_the_same_streams(
    tmp_path: Path, name: str, linktype: int, kw: dict[str, object]
) -> None:
    conv = Conversation(**kw)  # type: ignore[arg-type]
    packets = [*conv.handshake(), conv.client(REQ1), conv.server(RESP1)]
    capture, chunks = read(write(tmp_path, packets, linktype))
    assert data_by_channel(chunks) == {0: REQ1, 1: RESP1}
    assert capture.info.stamps == Stamp.FRAME_END
    assert capture.info.labels == Labels.CERTAIN
    assert capture.info.resolution == 1e-6
    client = parse_label(capture.info.channels[0])
    server = parse_label(capture.info.channels[1])
    assert client is not None and server is not None
    assert client.role == Direction.MASTER and server.role == Direction.SLAVE
    assert client.carrier == "modbus-tcp"
    host = f"[{conv.client_ip}]" if conv.v6 else conv.client_ip
    assert client.sender == f"{host}:{conv.client_port}"
    assert server.receiver == client.sender
    assert {c.direction for c in chunks if c.channel == 0} == {Direction.MASTER}
    assert {c.direction for c in chunks if c.channel == 1} == {Direction.SLAVE}
    assert capture.warnings == []


def test_loopback_108_is_network_order_and_null_may_be_big_endian() -> None:
    seg = tcp(50000, 502, 1, 0, TCP_ACK, REQ1)
    packet = ipv4("127.0.0.1", "127.0.0.1", 6, seg)
    loop = struct.pack("!I", 2) + packet
    found = decode(108, loop)
    assert isinstance(found, Segment) and found.payload == REQ1
    found = decode(0, null_loopback(packet, big_endian=True))
    assert isinstance(found, Segment) and found.payload == REQ1


def test_ipv6_extension_headers_are_skipped() -> None:
    seg = tcp(50000, 502, 1, 0, TCP_ACK, REQ1)
    hop = bytes([60, 0]) + b"\0" * 6  # hop-by-hop, next: destination options
    dest = bytes([44, 1]) + b"\0" * 14  # destination options (16 bytes), next: fragment
    frag = bytes([6, 0, 0, 0]) + b"\0\0\0\1"  # an atomic fragment header (offset 0, no more)
    packet = ipv6("2001:db8::1", "2001:db8::2", 6, seg, ext=hop + dest + frag, first=0)
    found = decode(1, ethernet(packet, v6=True))
    assert isinstance(found, Segment)
    assert found.payload == REQ1 and found.src == "[2001:db8::1]:50000"


def test_fragments_and_other_protocols_are_skipped_with_a_reason() -> None:
    seg = tcp(50000, 502, 1, 0, TCP_ACK, REQ1)
    frag = decode(1, ethernet(ipv4("10.0.0.1", "10.0.0.2", 6, seg, frag=0x2000)))
    assert isinstance(frag, Skip) and frag.reason == "fragment"
    icmp = decode(1, ethernet(ipv4("10.0.0.1", "10.0.0.2", 1, b"\x08\0\0\0\0\0\0\0")))
    assert isinstance(icmp, Skip) and icmp.reason == "not TCP or UDP"
    arp = decode(1, b"\xff" * 12 + b"\x08\x06" + b"\0" * 28)
    assert isinstance(arp, Skip) and arp.reason == "not IP"


def test_ethernet_padding_is_not_payload() -> None:
    """A short segment is padded to 60 bytes on the wire; the IP length excludes it."""
    found = decode(1, ethernet(ipv4("10.0.0.1", "10.0.0.2", 6, tcp(1, 502, 0, 0, TCP_ACK))))
    assert isinstance(found, Segment) and found.payload == b""


@settings(max_examples=300)
@given(st.sampled_from([0, 1, 101, 108, 113, 228, 229, 276]), st.binary(max_size=120))
def test_any_bytes_decode_without_raising(linktype: int, data: bytes) -> None:
    assert isinstance(decode(linktype, data), Segment | Skip)


# ---------------------------------------------------------------- TCP reassembly


def test_split_and_coalesced_segments_frame_the_same(tmp_path: Path) -> None:
    conv = Conversation()
    packets = [
        *conv.handshake(),
        conv.client(REQ1[:3]),  # a header split across three segments
        conv.client(REQ1[3:7]),
        conv.client(REQ1[7:] + REQ2),  # the tail of one request and the whole next one
        conv.server(RESP1 + RESP2),  # two answers in one segment
    ]
    _, store = frame(write(tmp_path, packets))
    assert frames(store) == [(0, REQ1), (0, REQ2), (1, RESP1), (1, RESP2)]
    assert [store.status[i] for i in range(len(store)) if store.flags[i] & MBAP] == [Status.OK] * 4


def test_retransmissions_are_dropped(tmp_path: Path) -> None:
    conv = Conversation()
    hs = conv.handshake()
    first = conv.segment(True, REQ1)
    packets = [*hs, first, first]
    conv.client_seq += len(REQ1)
    packets += [
        conv.segment(True, REQ1[6:] + REQ2, seq=conv.client_seq - 6),  # overlaps the end
        conv.server(RESP1),
        conv.server(RESP2),
    ]
    _, chunks = read(write(tmp_path, packets))
    assert data_by_channel(chunks)[0] == REQ1 + REQ2
    _, store = frame(write(tmp_path, packets, name="again.pcap"))
    assert frames(store) == [(0, REQ1), (0, REQ2), (1, RESP1), (1, RESP2)]


def test_out_of_order_segments_are_put_in_order(tmp_path: Path) -> None:
    conv = Conversation()
    hs = conv.handshake()
    a = conv.client(REQ1[:5])
    b = conv.client(REQ1[5:])
    c = conv.client(REQ2)
    _, chunks = read(write(tmp_path, [*hs, c, b, a, conv.server(RESP1), conv.server(RESP2)]))
    assert data_by_channel(chunks)[0] == REQ1 + REQ2
    assert not [c for c in chunks if c.event == "gap"]
    times = [c.t_end for c in chunks if c.channel == 0]
    assert times == sorted(times)  # bytes leave when the hole is filled


def test_a_gap_is_reported_and_never_guessed_over(tmp_path: Path) -> None:
    conv = Conversation()
    hs = conv.handshake()
    conv.client(REQ1[:8])  # never captured
    tail = conv.client(REQ1[8:])
    after = conv.client(REQ2)
    ack = conv.segment(False, b"")  # the server acknowledges everything: the bytes arrived
    packets = [*hs, tail, after, ack, conv.server(RESP1), conv.server(RESP2)]
    capture, chunks = read(write(tmp_path, packets))
    gaps = [c for c in chunks if c.event == "gap"]
    assert len(gaps) == 1 and gaps[0].channel == 0
    assert gaps[0].note.startswith("8 bytes missing from the capture")
    assert any("1 gap(s) in TCP streams, 8 bytes" in w for w in capture.warnings)
    _, store = frame(write(tmp_path, packets, name="gap.pcap"))
    rows = [(store.channel[i], store.kind[i], store.raw(i)) for i in range(len(store))]
    # the tail of the lost request is shown as noise, not glued to anything
    assert (0, Kind.NOISE, REQ1[8:]) in rows
    assert (0, Kind.REQUEST, REQ2) in rows
    answered = [i for i in range(len(store)) if store.raw(i) == RESP1]
    assert store.status[answered[0]] == Status.ORPHAN  # its request was never seen
    assert frames(store)[-1] == (1, RESP2)


def test_a_gap_inside_a_frame_cuts_it_short(tmp_path: Path) -> None:
    conv = Conversation()
    hs = conv.handshake()
    head = conv.client(REQ1[:9])
    conv.client(REQ1[9:])  # lost
    after = conv.client(REQ2)
    packets = [*hs, head, after, conv.segment(False, b""), conv.server(RESP2)]
    _, store = frame(write(tmp_path, packets))
    cut = [i for i in range(len(store)) if store.flags[i] & CUT_SHORT]
    assert [store.raw(i) for i in cut] == [REQ1[:9]]
    assert (0, REQ2) in frames(store)


def test_hole_never_filled_is_a_gap_at_the_end(tmp_path: Path) -> None:
    conv = Conversation()
    hs = conv.handshake()
    conv.client(REQ1)
    late = conv.client(REQ2)
    _, chunks = read(write(tmp_path, [*hs, late]))
    assert [c.event for c in chunks if c.channel == 0 and c.event != "connection"] == ["gap", ""]
    assert data_by_channel(chunks)[0] == REQ2


def test_snap_length_cut_is_a_gap(tmp_path: Path) -> None:
    conv = Conversation()
    packets = [*conv.handshake(), conv.client(REQ1), conv.client(REQ2)]
    path = tmp_path / "snap.pcap"
    path.write_bytes(pcap(1, [(T0 + k, p) for k, p in enumerate(packets)], snaplen=60))
    _, chunks = read(path)
    assert [c.note for c in chunks if c.event == "gap"] == [
        "6 bytes cut off by the capture's snap length"
    ] * 2


def test_syn_fin_rst_are_noted(tmp_path: Path) -> None:
    conv = Conversation()
    packets = [
        *conv.handshake(),
        conv.client(REQ1),
        conv.server(RESP1),
        conv.client(b"", TCP_FIN | TCP_ACK),
        conv.server(b"", TCP_RST),
    ]
    _, chunks = read(write(tmp_path, packets))
    notes = [(c.channel, c.note) for c in chunks if c.event == "connection"]
    assert notes == [
        (0, "opened (SYN)"),
        (1, "accepted (SYN ACK)"),
        (0, "closed by the sender (FIN)"),
        (1, "reset (RST)"),
    ]


def test_sequence_numbers_wrap(tmp_path: Path) -> None:
    conv = Conversation(client_seq=(1 << 32) - 7)
    packets = [*conv.handshake(), conv.client(REQ1), conv.client(REQ2), conv.server(RESP1)]
    _, chunks = read(write(tmp_path, packets))
    assert data_by_channel(chunks) == {0: REQ1 + REQ2, 1: RESP1}


@settings(max_examples=60, deadline=None)
@given(st.data())
def test_any_segmentation_order_and_duplication_gives_the_stream(data: st.DataObject) -> None:
    stream = data.draw(st.binary(min_size=1, max_size=400))
    cuts = sorted(data.draw(st.sets(st.integers(1, len(stream)), max_size=12)) | {len(stream)})
    conv = Conversation(client_seq=data.draw(st.integers(0, (1 << 32) - 1)))
    syn = conv.client(b"", TCP_SYN)  # without it, the first segment seen starts the stream
    base = conv.client_seq
    pieces = []
    start = 0
    for end in cuts:
        pieces.append(conv.segment(True, stream[start:end], seq=(base + start) % (1 << 32)))
        start = end
    order = data.draw(st.permutations(pieces))
    dupes = data.draw(st.lists(st.sampled_from(pieces), max_size=4))
    from sniffer.sources.net.decoder import NetDecoder

    channels: dict[int, str] = {}
    warnings: list[str] = []
    decoder = NetDecoder(channels, warnings, carrier="tcp")
    out: list[Chunk] = []
    for k, packet in enumerate([syn, *order, *dupes]):
        out += decoder.packet(1, T0 + k * 0.001, packet)
    out += decoder.finish()
    assert b"".join(c.data for c in out) == stream
    assert not [c for c in out if c.event == "gap"]


# ---------------------------------------------------------------- connections and carriers


def test_several_connections_get_their_own_channels_and_pairing(tmp_path: Path) -> None:
    a = Conversation(client_port=40001)
    b = Conversation(client_port=40002, client_ip="192.168.1.11")
    same_tid = bytes.fromhex("0001 0000 0006 02 03 0000 0001")
    same_tid_answer = bytes.fromhex("0001 0000 0005 02 03 02 00FF")
    packets = [
        *a.handshake(),
        *b.handshake(),
        a.client(REQ1),
        b.client(same_tid),  # the same transaction id on another connection
        b.server(same_tid_answer),
        a.server(RESP1),
    ]
    capture, store = frame(write(tmp_path, packets))
    assert frames(store) == [(0, REQ1), (2, same_tid), (3, same_tid_answer), (1, RESP1)]
    rows = {store.raw(i): i for i in range(len(store)) if store.flags[i] & MBAP}
    assert store.partner[rows[REQ1]] == rows[RESP1]
    assert store.partner[rows[same_tid]] == rows[same_tid_answer]
    labels = [parse_label(capture.info.channels[ch]) for ch in range(4)]
    assert [x.sender.split(":")[1] for x in labels if x] == ["40001", "502", "40002", "502"]


def test_many_transactions_in_flight_duplicates_and_unknown_ids(tmp_path: Path) -> None:
    conv = Conversation()
    reqs = [bytes([0, k]) + REQ1[2:] for k in range(1, 6)]
    resps = [bytes([0, k]) + RESP1[2:] for k in range(1, 6)]
    stray = bytes([0, 99]) + RESP1[2:]
    packets = [*conv.handshake(), *(conv.client(r) for r in reqs)]
    packets += [conv.client(reqs[2])]  # id 3 again while the first is in flight
    packets += [conv.server(resps[k]) for k in (4, 2, 0, 3, 1)]  # answered out of order
    packets += [conv.server(stray), conv.server(resps[2])]
    _, store = frame(write(tmp_path, packets))
    mb = [i for i in range(len(store)) if store.flags[i] & MBAP]
    requests = [i for i in mb if store.kind[i] == Kind.REQUEST]
    for i in requests:
        j = store.partner[i]
        assert j >= 0 and store.raw(j)[:2] == store.raw(i)[:2]
    assert [bool(store.flags[i] & TID_REUSED) for i in requests] == [False] * 5 + [True]
    orphans = [store.raw(i) for i in mb if store.status[i] == Status.ORPHAN]
    assert orphans == [stray]


def test_mbap_errors_are_problems_not_exceptions(tmp_path: Path) -> None:
    conv = Conversation()
    bad_protocol = REQ1[:2] + b"\x00\x07" + REQ1[4:]
    packets = [*conv.handshake(), conv.client(REQ1), conv.client(bad_protocol + REQ2)]
    _, store = frame(write(tmp_path, packets))
    rows = [(store.kind[i], store.raw(i)) for i in range(len(store)) if store.kind[i] != Kind.EVENT]
    assert rows == [(Kind.REQUEST, REQ1), (Kind.NOISE, bad_protocol), (Kind.REQUEST, REQ2)]


def test_a_frame_whose_length_runs_past_the_end_is_cut_short(tmp_path: Path) -> None:
    conv = Conversation()
    wrong = REQ1[:5] + b"\x09" + REQ1[6:]  # announces 3 more bytes than were sent
    _, store = frame(write(tmp_path, [*conv.handshake(), conv.client(REQ1), conv.client(wrong)]))
    last = len(store) - 1
    assert store.raw(last) == wrong and store.flags[last] & CUT_SHORT
    assert not store.flags[last] & ENVELOPE_BAD


def test_rtu_over_tcp_goes_to_the_rtu_framer(tmp_path: Path) -> None:
    conv = Conversation(server_port=4001)
    packets = [
        *conv.handshake(),
        conv.client(RTU_REQ[:3]),
        conv.client(RTU_REQ[3:]),
        conv.server(RTU_RESP),
        conv.client(RTU_REQ),
        conv.server(RTU_RESP),
    ]
    capture, store = frame(write(tmp_path, packets))
    assert parse_label(capture.info.channels[0]).carrier == "rtu-over-tcp"  # type: ignore[union-attr]
    assert frames(store) == [(0, RTU_REQ), (1, RTU_RESP), (0, RTU_REQ), (1, RTU_RESP)]
    assert [store.status[i] for i in range(len(store)) if store.kind[i] in (1, 2)] == [
        Status.OK
    ] * 4
    assert not any(store.flags[i] & MBAP for i in range(len(store)))


def test_carrier_option_overrides_detection(tmp_path: Path) -> None:
    conv = Conversation(server_port=502)
    packets = [*conv.handshake(), conv.client(RTU_REQ), conv.server(RTU_RESP)]
    path = write(tmp_path, packets)
    detected, _ = read(path)
    assert parse_label(detected.info.channels[0]).carrier == "rtu-over-tcp"  # type: ignore[union-attr]
    forced, _ = read(path, ReadOptions(carrier="tcp"))
    assert parse_label(forced.info.channels[0]).carrier == "modbus-tcp"  # type: ignore[union-attr]


def test_port_option_picks_the_server_and_leaves_other_traffic_out(tmp_path: Path) -> None:
    modbus = Conversation(client_port=3000, server_port=8899)
    other = Conversation(client_port=3001, server_port=22)
    packets = [
        modbus.client(RTU_REQ),  # no handshake: the port alone says who serves
        other.client(b"SSH-2.0-x\r\n"),
        modbus.server(RTU_RESP),
    ]
    capture, chunks = read(write(tmp_path, packets), ReadOptions(port=8899))
    assert data_by_channel(chunks) == {0: RTU_REQ, 1: RTU_RESP}
    label = parse_label(capture.info.channels[1])
    assert label is not None and label.sender.endswith(":8899") and label.role == Direction.SLAVE


def test_non_modbus_connections_are_left_out_with_a_warning(tmp_path: Path) -> None:
    web = Conversation(server_port=80)
    packets = [
        *web.handshake(),
        web.client(b"GET / HTTP/1.1\r\n\r\n"),
        web.server(b"HTTP/1.1 200 OK\r\n"),
    ]
    capture, chunks = read(write(tmp_path, packets))
    assert chunks == []
    assert any("carry neither Modbus TCP nor RTU" in w and ":80" in w for w in capture.warnings)


def test_udp_modbus_and_rtu_over_udp(tmp_path: Path) -> None:
    def dgram(src: str, dst: str, sport: int, dport: int, payload: bytes) -> bytes:
        return ethernet(ipv4(src, dst, 17, udp(sport, dport, payload)))

    packets = [
        dgram("10.0.0.1", "10.0.0.2", 40000, 502, REQ1),
        dgram("10.0.0.2", "10.0.0.1", 502, 40000, RESP1),
        dgram("10.0.0.1", "10.0.0.3", 40001, 4001, RTU_REQ),
        dgram("10.0.0.3", "10.0.0.1", 4001, 40001, RTU_RESP),
        dgram("10.0.0.1", "10.0.0.3", 40001, 4001, RTU_REQ),
        dgram("10.0.0.3", "10.0.0.1", 4001, 40001, RTU_RESP),
    ]
    capture, store = frame(write(tmp_path, packets))
    carriers = {ch: parse_label(text).carrier for ch, text in capture.info.channels.items()}  # type: ignore[union-attr]
    assert carriers == {0: "modbus-udp", 1: "modbus-udp", 2: "rtu-over-udp", 3: "rtu-over-udp"}
    assert frames(store) == [
        (0, REQ1),
        (1, RESP1),
        (2, RTU_REQ),
        (3, RTU_RESP),
        (2, RTU_REQ),
        (3, RTU_RESP),
    ]
    assert all(store.status[i] == Status.OK for i in range(len(store)))


def test_pcapng_with_nanosecond_interfaces(tmp_path: Path) -> None:
    conv = Conversation()
    path = tmp_path / "c.pcapng"
    with path.open("wb") as handle:
        writer = PcapngWriter(handle)
        iface = writer.add_interface(1, name="eth0")
        for k, packet in enumerate([*conv.handshake(), conv.client(REQ1), conv.server(RESP1)]):
            writer.write_packet(iface, T0 + k * 0.000_001_5, packet)
    capture, chunks = read(path)
    assert data_by_channel(chunks) == {0: REQ1, 1: RESP1}
    assert capture.info.resolution == 1e-9
    assert chunks[-1].t_end == pytest.approx(T0 + 4 * 0.000_001_5, abs=1e-9)


def test_random_packet_soup_never_raises(tmp_path: Path) -> None:
    rng = random.Random(7)
    conv = Conversation()
    good = [*conv.handshake(), conv.client(REQ1), conv.server(RESP1)]
    soup = []
    for _ in range(300):
        packet = bytearray(rng.choice(good))
        for _ in range(rng.randrange(4)):
            packet[rng.randrange(len(packet))] = rng.randrange(256)
        soup.append(bytes(packet[: rng.randrange(len(packet) + 1)]))
    _, store = frame(write(tmp_path, soup))
    total = sum(len(s) for s in store.streams.values())
    covered = sum(store.length[i] for i in range(len(store)))
    assert covered == total  # every reassembled byte is in a frame or a noise row


# ---------------------------------------------------------------- real peers over loopback


class _TcpPeer:
    """pymodbus's TCP server on loopback in a thread, with dumpcap capturing its port."""

    def __init__(self, capture: Path, rtu: bool = False) -> None:
        import socket

        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            self.port: int = probe.getsockname()[1]
        self.capture = capture
        self.rtu = rtu
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._server: Any = None
        self._dumpcap: subprocess.Popen[str] | None = None

    def __enter__(self) -> _TcpPeer:
        threading.Thread(target=self._run, daemon=True).start()
        assert self._ready.wait(5), "the pymodbus TCP server did not start"
        self._dumpcap = subprocess.Popen(
            ["dumpcap", "-i", "lo", "-f", f"tcp port {self.port}", "-w", str(self.capture)],
            stderr=subprocess.PIPE,
            text=True,
        )
        assert self._dumpcap.stderr is not None
        for line in self._dumpcap.stderr:
            if "Capturing on" in line:
                break
        time.sleep(1.0)  # dumpcap says it captures a little before it does
        return self

    def _run(self) -> None:
        from pymodbus import FramerType
        from pymodbus.server import ModbusTcpServer
        from pymodbus.simulator import DataType, SimData, SimDevice

        def device(unit: int) -> Any:
            bits = [SimData(0, values=[k % 3 == 0 for k in range(32)], datatype=DataType.BITS)]
            words = [SimData(0, values=list(range(unit, unit + 32)), datatype=DataType.REGISTERS)]
            return SimDevice(id=unit, simdata=(bits, bits, words, words))

        async def serve() -> None:
            self._server = ModbusTcpServer(
                [device(1), device(7)],
                framer=FramerType.RTU if self.rtu else FramerType.SOCKET,
                address=("127.0.0.1", self.port),
            )
            await self._server.serve_forever(background=True)
            self._ready.set()
            await self._server.serving

        asyncio.set_event_loop(self._loop)
        self._loop.run_until_complete(serve())

    def client(self) -> Any:
        from pymodbus import FramerType
        from pymodbus.client import ModbusTcpClient

        framer = FramerType.RTU if self.rtu else FramerType.SOCKET
        client: Any = ModbusTcpClient(
            "127.0.0.1", port=self.port, framer=framer, timeout=2, retries=0
        )
        assert client.connect()
        return client

    def __exit__(self, *exc: object) -> None:
        time.sleep(0.3)
        if self._dumpcap is not None:
            self._dumpcap.send_signal(signal.SIGINT)
            self._dumpcap.wait(10)
        if self._server is not None:
            future = asyncio.run_coroutine_threadsafe(self._server.shutdown(), self._loop)
            future.result(5)


def _exchange(clients: list[Any]) -> int:
    """Requests of several kinds from each client in turn; returns how many were sent."""
    sent = 0
    for round_ in range(3):
        for k, c in enumerate(clients):
            unit = 7 if k % 2 else 1
            c.read_holding_registers(round_, count=4, device_id=unit)
            c.read_input_registers(2, count=3, device_id=unit)
            c.read_coils(0, count=10, device_id=unit)
            c.write_register(3, 70 + round_, device_id=unit)
            c.write_registers(4, [1, 2, round_], device_id=unit)
            c.read_holding_registers(100, count=5, device_id=unit)  # an exception answer
            sent += 6
    for c in clients:
        c.close()
    return sent


def _tshark(path: Path, port: int, proto: str) -> list[tuple[int, int]]:
    unit = "mbtcp.unit_id" if proto == "mbtcp" else "mbrtu.unit_id"
    decode_as = f"tcp.port=={port},{proto}"
    fields = ["-T", "fields", "-e", unit, "-e", "modbus.func_code"]
    result = subprocess.run(
        ["tshark", "-r", str(path), "-d", decode_as, "-Y", proto, *fields],
        capture_output=True,
        text=True,
        check=True,
    )
    rows = []
    for line in result.stdout.splitlines():
        unit, fc = line.split("\t")
        rows.append((int(unit), int(fc)))
    return rows


needs_tools = pytest.mark.skipif(
    not (shutil.which("dumpcap") and shutil.which("tshark")), reason="needs dumpcap and tshark"
)


@pytest.mark.peer
@pytest.mark.slow
@needs_tools
def test_pymodbus_tcp_over_loopback_matches_tshark(tmp_path: Path) -> None:
    pytest.importorskip("pymodbus")
    path = tmp_path / "lo.pcapng"
    with _TcpPeer(path) as peer:
        sent = _exchange([peer.client(), peer.client()])
    capture, store = frame(path)
    rows = [i for i in range(len(store)) if store.flags[i] & MBAP and store.kind[i] != Kind.NOISE]
    ours = [(store.unit[i], store.fc[i] & 0x7F) for i in rows]
    assert ours == _tshark(path, peer.port, "mbtcp")
    assert len(ours) == 2 * sent
    requests = [i for i in rows if store.kind[i] == Kind.REQUEST]
    assert len(requests) == sent
    statuses = [store.status[i] for i in requests]
    assert statuses.count(Status.EXCEPTION) == sent // 6
    assert statuses.count(Status.OK) == sent - sent // 6
    assert {store.channel[i] for i in rows} == {0, 1, 2, 3}  # two connections, two directions
    assert capture.warnings == []


@pytest.mark.peer
@pytest.mark.slow
@needs_tools
def test_pymodbus_rtu_over_tcp_over_loopback(tmp_path: Path) -> None:
    pytest.importorskip("pymodbus")
    path = tmp_path / "rtu.pcapng"
    with _TcpPeer(path, rtu=True) as peer:
        sent = _exchange([peer.client()])
    capture, store = frame(path)
    assert parse_label(capture.info.channels[0]).carrier == "rtu-over-tcp"  # type: ignore[union-attr]
    rows = [
        i
        for i in range(len(store))
        if store.kind[i] in (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION)
    ]
    assert len(rows) == 2 * sent
    assert not any(store.kind[i] == Kind.NOISE for i in range(len(store)))
    ours = [(store.unit[i], store.fc[i] & 0x7F) for i in rows]
    theirs = _tshark(path, peer.port, "mbrtu")
    assert ours == theirs
