"""Fuzz: the Ethernet-family reader (sniffer/sources/net) through pcap and pcapng, over
Modbus TCP, Modbus over UDP, and RTU over TCP and over UDP, carried by Ethernet (with
VLAN tags), raw IP (101, 228, 229), Linux cooked (113, 276) and BSD loopback (0), over
IPv4 and IPv6. Conversations are built packet by packet (tests/support/netbuild) and then
damaged where TCP meets the wire: segments dropped, repeated, reordered, split into tiny
ones, overlapped with other bytes, SYN, FIN and RST in odd places, sequence jumps, IP
fragments; and sometimes the file's bytes too.

Invariants: only CaptureError escapes, no input hangs, every byte the reader gives lands
in exactly one row of its channel (harness.conserved; for TCP the reader's bytes are the
reassembled stream, so the invariant holds on what reassembly gives, not on the bytes on
the wire: a retransmission is dropped on purpose, and a hole is a gap event, not bytes).
Beyond that, a conversation whose segments were only repeated or reordered reassembles
to exactly the bytes each side sent.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, replace
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sniffer.model import Chunk
from sniffer.sources import CaptureError, ReadOptions, open_capture
from sniffer.sources.net.packets import (
    LINKTYPE_ETHERNET,
    LINKTYPE_IPV4,
    LINKTYPE_IPV6,
    LINKTYPE_LINUX_SLL,
    LINKTYPE_LINUX_SLL2,
    LINKTYPE_NULL,
    LINKTYPE_RAW,
)
from sniffer.sources.pcapng_writer import PcapngWriter
from sniffer.sources.synth import polling_frames
from tests.fuzz.harness import budget, bytes_by_channel, mutated, no_hang
from tests.fuzz.test_fuzz_sources import read_and_frame
from tests.support.gateway import mbap_frame
from tests.support.netbuild import (
    TCP_ACK,
    TCP_FIN,
    TCP_RST,
    TCP_SYN,
    ethernet,
    ipv4,
    ipv6,
    null_loopback,
    pcap,
    sll,
    sll2,
    tcp,
    udp,
)

pytestmark = [pytest.mark.fuzz, pytest.mark.slow]

T0 = 1_750_000_000.0
RTU = [f.raw for f in polling_frames(8, seed=3)]
LINKS = [
    LINKTYPE_ETHERNET,
    LINKTYPE_RAW,
    LINKTYPE_IPV4,
    LINKTYPE_IPV6,
    LINKTYPE_LINUX_SLL,
    LINKTYPE_LINUX_SLL2,
    LINKTYPE_NULL,
]
CLIENT, SERVER = ("192.168.1.10", "192.168.1.20")
CLIENT6, SERVER6 = ("fd00::10", "fd00::20")


@dataclass(frozen=True)
class Seg:
    """One packet of a conversation: who sends it, its TCP sequence number (ignored for
    UDP), flags and payload, and whether its IP packet is sent as a fragment."""

    client: bool
    seq: int
    flags: int
    payload: bytes
    fragment: bool = False


@dataclass(frozen=True)
class Conv:
    transport: str  # tcp, udp
    port: int  # the server's
    link: int
    v6: bool
    vlans: tuple[int, ...]
    segs: tuple[Seg, ...]


def messages(carrier: str, count: int) -> list[tuple[bool, bytes]]:
    """Requests and answers as each side sends them: MBAP (Modbus TCP) or RTU frames."""
    out: list[tuple[bool, bytes]] = []
    for k, frame in enumerate(RTU[:count]):
        client = k % 2 == 0
        out.append((client, mbap_frame(k // 2 + 1, frame[:-2]) if carrier == "mbap" else frame))
    return out


def build_segments(
    transport: str, msgs: list[tuple[bool, bytes]], handshake: bool, close: bool
) -> list[Seg]:
    if transport == "udp":
        return [Seg(c, 0, 0, m) for c, m in msgs]
    seq = {True: 1000, False: 5000}
    segs: list[Seg] = []

    def send(client: bool, payload: bytes, flags: int) -> None:
        segs.append(Seg(client, seq[client], flags, payload))
        seq[client] = (seq[client] + len(payload) + (1 if flags & (TCP_SYN | TCP_FIN) else 0)) % (
            1 << 32
        )

    if handshake:
        send(True, b"", TCP_SYN)
        send(False, b"", TCP_SYN | TCP_ACK)
        send(True, b"", TCP_ACK)
    for client, payload in msgs:
        send(client, payload, TCP_ACK)
    if close:
        send(True, b"", TCP_FIN | TCP_ACK)
        send(False, b"", TCP_FIN | TCP_ACK)
    return segs


def packet(conv: Conv, seg: Seg) -> bytes:
    src, dst = (CLIENT6, SERVER6) if conv.v6 else (CLIENT, SERVER)
    sport, dport = 40001, conv.port
    if not seg.client:
        src, dst, sport, dport = dst, src, dport, sport
    if conv.transport == "udp":
        body, proto = udp(sport, dport, seg.payload), 17
    else:
        body, proto = tcp(sport, dport, seg.seq, 0, seg.flags, seg.payload), 6
    if conv.v6:
        # a fragment header (44) with an offset makes a fragment, else no extension
        ext = bytes([proto, 0, 0, 8, 0, 0, 0, 1]) if seg.fragment else b""
        ip = ipv6(src, dst, proto, body, ext=ext, first=44)
    else:
        ip = ipv4(src, dst, proto, body, frag=0x2000 if seg.fragment else 0)
    if conv.link == LINKTYPE_ETHERNET:
        return ethernet(ip, v6=conv.v6, vlans=conv.vlans)
    if conv.link == LINKTYPE_LINUX_SLL:
        return sll(ip, v6=conv.v6)
    if conv.link == LINKTYPE_LINUX_SLL2:
        return sll2(ip, v6=conv.v6)
    if conv.link == LINKTYPE_NULL:
        return null_loopback(ip, v6=conv.v6)
    return ip  # raw IP (101, 228, 229)


def capture_file(conv: Conv, container: str) -> bytes:
    packets = [(T0 + k * 0.002, packet(conv, s)) for k, s in enumerate(conv.segs)]
    if container == "pcap":
        return pcap(conv.link, packets)
    out = io.BytesIO()
    writer = PcapngWriter(out, application="fuzz")
    iface = writer.add_interface(conv.link, name="eth0")
    for t, data in packets:
        writer.write_packet(iface, t, data)
    return out.getvalue()


@st.composite
def conversations(draw: st.DrawFn) -> Conv:
    transport = draw(st.sampled_from(["tcp", "udp"]))
    carrier = draw(st.sampled_from(["mbap", "rtu"]))
    port = draw(st.sampled_from([502, 503, 4001]))
    v6 = draw(st.booleans())
    link = draw(st.sampled_from(LINKS))
    if link == LINKTYPE_IPV4:
        v6 = False
    elif link == LINKTYPE_IPV6:
        v6 = True
    vlans = tuple(draw(st.lists(st.integers(1, 4094), max_size=2))) * (link == LINKTYPE_ETHERNET)
    msgs = messages(carrier, draw(st.integers(1, len(RTU))))
    segs = build_segments(transport, msgs, draw(st.booleans()), draw(st.booleans()))
    return Conv(transport, port, link, v6, vlans, tuple(segs))


@st.composite
def damaged(draw: st.DrawFn) -> Conv:
    """A conversation with its segments damaged as a network and a capture damage them."""
    conv = draw(conversations())
    segs = list(conv.segs)
    for _ in range(draw(st.integers(0, 8))):
        if not segs:
            break
        at = draw(st.integers(0, len(segs) - 1))
        seg = segs[at]
        op = draw(
            st.sampled_from(
                ["drop", "repeat", "swap", "split", "overlap", "flags", "jump", "fragment", "cut"]
            )
        )
        if op == "drop":
            del segs[at]
        elif op == "repeat":  # a retransmission, maybe much later
            segs.insert(draw(st.integers(at, len(segs))), seg)
        elif op == "swap" and at + 1 < len(segs):  # captured out of order
            segs[at], segs[at + 1] = segs[at + 1], seg
        elif op == "split" and len(seg.payload) > 1:  # tiny segments, maybe reversed
            size = draw(st.integers(1, 3))
            parts = [
                replace(seg, seq=(seg.seq + i) % (1 << 32), payload=seg.payload[i : i + size])
                for i in range(0, len(seg.payload), size)
            ]
            if draw(st.booleans()):
                parts.reverse()
            segs[at : at + 1] = parts
        elif op == "overlap" and seg.payload:  # the same sequence numbers, other bytes
            changed = bytes(b ^ 0x5A for b in seg.payload)
            start = draw(st.integers(0, len(seg.payload) - 1))
            segs.insert(
                at + 1,
                replace(seg, seq=(seg.seq + start) % (1 << 32), payload=changed[start:]),
            )
        elif op == "flags":  # SYN, FIN or RST where they do not belong (RST first too)
            flag = draw(st.sampled_from([TCP_SYN, TCP_FIN, TCP_RST, TCP_RST | TCP_ACK]))
            segs.insert(at, replace(seg, flags=flag, payload=seg.payload * draw(st.booleans())))
        elif op == "jump":
            shift = draw(st.sampled_from([1, -1, 1 << 16, 1 << 31, (1 << 32) - 1]))
            segs[at] = replace(seg, seq=(seg.seq + shift) % (1 << 32))
        elif op == "fragment":
            segs[at] = replace(seg, fragment=True)
        elif op == "cut":
            segs[at] = replace(seg, payload=seg.payload[: draw(st.integers(0, len(seg.payload)))])
    return replace(conv, segs=tuple(segs))


OPTIONS = st.sampled_from(
    [
        ReadOptions(),
        ReadOptions(port=502),
        ReadOptions(port=4001, carrier="rtu-over-tcp"),
        ReadOptions(carrier="modbus-tcp"),
        ReadOptions(carrier="rtu-over-udp"),
    ]
)


@budget(250)
@given(damaged(), st.sampled_from(["pcap", "pcapng"]), OPTIONS, st.data())
def test_damaged_network_captures_never_raise_and_conserve_bytes(
    tmp_path_factory: pytest.TempPathFactory,
    conv: Conv,
    container: str,
    options: ReadOptions,
    draw: st.DataObject,
) -> None:
    data = capture_file(conv, container)
    if draw.draw(st.integers(0, 3)) == 0:  # one time in four, the file's bytes too
        data = draw.draw(mutated([data]))
    path = tmp_path_factory.getbasetemp() / f"net.{container}"
    path.write_bytes(data)
    read_and_frame(path, options)


SEEDS = [
    capture_file(
        Conv(t, 502, link, v6, (7,) * (link == 1), tuple(build_segments(t, messages(c, 8), h, h))),
        container,
    )
    for t, c, link, v6, h, container in [
        ("tcp", "mbap", LINKTYPE_ETHERNET, False, True, "pcapng"),
        ("tcp", "rtu", LINKTYPE_RAW, True, False, "pcap"),
        ("udp", "mbap", LINKTYPE_LINUX_SLL, False, False, "pcapng"),
        ("udp", "rtu", LINKTYPE_IPV4, False, False, "pcap"),
    ]
]


@budget(200)
@given(mutated(SEEDS), OPTIONS)
def test_network_captures_with_damaged_bytes_never_raise(
    tmp_path_factory: pytest.TempPathFactory, data: bytes, options: ReadOptions
) -> None:
    path = tmp_path_factory.getbasetemp() / "net-bytes"
    path.write_bytes(data)
    read_and_frame(path, options)


@st.composite
def shuffled(draw: st.DrawFn) -> tuple[Conv, list[Seg]]:
    """A TCP conversation whose data segments are repeated and captured out of order
    (within the reorder window), nothing lost: the original and the capture's order. It
    opens with its handshake: a capture that starts inside a connection takes the first
    segment it sees as the start of the stream, and the bytes before it as already gone."""
    conv = draw(
        conversations().filter(lambda c: c.transport == "tcp" and c.segs[0].flags & TCP_SYN)
    )
    segs = list(conv.segs)
    for _ in range(draw(st.integers(0, 6))):
        at = draw(st.integers(0, len(segs) - 1))
        if draw(st.booleans()):
            segs.insert(draw(st.integers(at, len(segs))), segs[at])
        elif at + 1 < len(segs) and segs[at].payload and segs[at + 1].payload:
            segs[at], segs[at + 1] = segs[at + 1], segs[at]
    return conv, segs


def sent(conv: Conv) -> dict[bool, bytes]:
    return {
        side: b"".join(s.payload for s in conv.segs if s.client == side) for side in (True, False)
    }


@budget(150)
@given(shuffled(), st.sampled_from(["pcap", "pcapng"]))
def test_repeated_and_reordered_segments_reassemble_to_what_was_sent(
    tmp_path_factory: pytest.TempPathFactory, case: tuple[Conv, list[Seg]], container: str
) -> None:
    conv, segs = case
    path = tmp_path_factory.getbasetemp() / f"order.{container}"
    path.write_bytes(capture_file(replace(conv, segs=tuple(segs)), container))
    with no_hang():
        capture = open_capture(path, ReadOptions())
        chunks: list[Chunk] = list(capture.chunks())
    by_channel = bytes_by_channel(chunks)
    want = sent(conv)
    # channels 0 and 1: what the client sent and what the server sent
    assert by_channel.get(0, b"") == want[True]
    assert by_channel.get(1, b"") == want[False]
    assert not [c for c in chunks if c.event == "reassembly error"]


def test_seed_conversations_read_whole(tmp_path: Path) -> None:
    for k, data in enumerate(SEEDS):
        path = tmp_path / f"seed{k}"
        path.write_bytes(data)
        try:
            capture = open_capture(path, ReadOptions())
        except CaptureError as exc:
            raise AssertionError(f"seed {k}: {exc}") from None
        assert sum(len(c.data) for c in capture.chunks()) > 0, k
