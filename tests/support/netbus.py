"""A network capture of random traffic for tests: Modbus TCP clients polling servers
(answers in and out of order, exceptions, timeouts, late answers, answers so late they
are orphans, transaction ids reused, requests split over segments, bytes no frame
claims, pauses) and an RTU-over-TCP device on port 4001, interleaved in time and written
as a pcap of Ethernet frames (tests/support/netbuild)."""

from __future__ import annotations

import random

from dissectors.checks import with_crc
from sniffer.framing.tcp import LATE_WAITS, TCP_TIMEOUT
from tests.support.gateway import mbap_frame
from tests.support.netbuild import TCP_FIN, Conversation, pcap

T0 = 1_750_000_000.0
# what a Modbus TCP client does next (`steps`); the RTU-over-TCP device takes the same
# steps, those that have no meaning there taken as polls
STEPS = (
    "poll",
    "poll",
    "write",
    "exception",
    "timeout",
    "late",
    "too_late",
    "pipelined",
    "reused",
    "orphan",
    "split",
    "garbage",
    "pause",
)
RTU_PORT = 4001


def _read(unit: int, count: int) -> tuple[bytes, bytes]:
    request = bytes([unit, 3, 0, 10]) + count.to_bytes(2, "big")
    values = b"".join((1000 + k).to_bytes(2, "big") for k in range(count))
    return request, bytes([unit, 3, 2 * count]) + values


def network_bus(steps: list[tuple[int, str]], seed: int = 0) -> bytes:
    """A pcap of `steps`: (connection, step) with connection 0 or 1 a Modbus TCP client
    (of two servers) and 2 the RTU-over-TCP device, each step 50 ms after the last."""
    rng = random.Random(seed)
    # (time, connection, from the client, payload): sent in time order below, so that
    # each direction's sequence numbers follow its times
    sends: list[tuple[float, int, bool, bytes]] = []
    tids = [rng.randrange(65536), rng.randrange(65536)]
    t = T0 + 0.1
    for conn, step in steps:
        t += 0.05
        if step == "pause":
            t += 5.0
            continue
        unit = 1 + conn
        request, answer = _read(unit, rng.randint(1, 20))
        if step == "write":
            request = bytes([unit, 16, 0, 1, 0, 2, 4, 0, 1, 0, 2])
            answer = request[:6]
        elif step == "exception":
            answer = bytes([unit, 0x83, 2])
        delay = rng.uniform(0.0005, 0.02)
        if conn == 2:  # RTU over TCP: one request at a time
            answer_at = {"timeout": None, "late": TCP_TIMEOUT + 0.5}.get(step, delay)
            sends.append((t, conn, True, with_crc(request)))
            if answer_at is not None:
                sends.append((t + answer_at, conn, False, with_crc(answer)))
            continue
        tid = tids[conn] = (tids[conn] + 1) % 65536
        if step == "garbage":
            sends.append((t, conn, True, bytes([0xFF, 0x00, 0x12, 0x34, 0x00])))
            continue
        if step == "orphan":
            sends.append((t, conn, False, mbap_frame((tid + 7) % 65536, answer)))
            continue
        if step in ("pipelined", "reused"):  # two requests in flight, answered in turn
            second = tid if step == "reused" else (tid + 1) % 65536
            tids[conn] = second
            sends += [
                (t, conn, True, mbap_frame(tid, request)),
                (t + 0.001, conn, True, mbap_frame(second, request)),
                (t + delay + 0.002, conn, False, mbap_frame(second, answer)),
                (t + delay + 0.003, conn, False, mbap_frame(tid, answer)),
            ]
            continue
        frame = mbap_frame(tid, request)
        if step == "split":
            sends += [(t, conn, True, frame[:5]), (t + 0.001, conn, True, frame[5:])]
        else:
            sends.append((t, conn, True, frame))
        answer_at = {
            "timeout": None,
            "late": TCP_TIMEOUT + 0.5,
            "too_late": (LATE_WAITS + 1) * TCP_TIMEOUT,
        }.get(step, delay)
        if answer_at is not None:
            sends.append((t + answer_at, conn, False, mbap_frame(tid, answer)))
    conversations = [
        Conversation(client_port=50211),
        Conversation(client_port=50300, server_ip="192.168.1.30"),
        Conversation(client_port=50400, server_ip="192.168.1.40", server_port=RTU_PORT),
    ]
    packets: list[tuple[float, bytes]] = []
    for k, conv in enumerate(conversations):
        packets += [(T0 + k * 0.01 + j * 0.001, p) for j, p in enumerate(conv.handshake())]
    for when, conn, from_client, payload in sorted(sends, key=lambda s: s[0]):
        packets.append((when, conversations[conn].send(from_client, payload)))
    end = max([T0 + 1.0, *(p[0] for p in packets)]) + 0.5
    for k, conv in enumerate(conversations):
        packets.append((end + k * 0.001, conv.client(b"", TCP_FIN)))
    return pcap(1, packets)
