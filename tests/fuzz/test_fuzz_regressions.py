"""Each finding of issue #30 as a fixed input, run through the same invariants as the fuzz
tests (only documented errors, no hang, every byte in one row) and the behaviour the fix
promised. Plain tests, not marked `fuzz`: they run with the suite, in a few seconds."""

from __future__ import annotations

import signal
import struct
import time
from pathlib import Path

import pytest

from sniffer.model import Chunk
from sniffer.sources import ReadOptions, open_capture
from sniffer.sources.linktypes import LINKTYPE_USER0
from sniffer.sources.logs.base import MAX_LINE
from sniffer.sources.reads import batching
from tests.fuzz.harness import CAPTURES, HangError, no_hang
from tests.fuzz.test_fuzz_sources import read_and_frame
from tests.support.gateway import mbap_frame, read_answer, read_request
from tests.support.netbuild import TCP_ACK, TCP_FIN, TCP_RST, Conversation, pcap

T0 = 1_750_000_000.0
LINKTYPE_ETHERNET = 1

REQUEST = bytes.fromhex("010300000001840a")


def _block(block_type: int, body: bytes) -> bytes:
    total = 12 + len(body)
    return struct.pack("<II", block_type, total) + body + struct.pack("<I", total)


SHB = _block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1))


def _idb(linktype: int = LINKTYPE_USER0, snaplen: int = 0) -> bytes:
    return _block(1, struct.pack("<HHI", linktype, 0, snaplen))


def _epb(interface: int, data: bytes) -> bytes:
    body = struct.pack("<IIIII", interface, 0, 0, len(data), len(data))
    return _block(6, body + data + b"\0" * (-len(data) % 4))


# -- item 7: 40,000 interface descriptions in 800 kB -------------------------------------


def test_40k_interface_descriptions_read_in_linear_time(tmp_path: Path) -> None:
    """40,000 interface descriptions (800 kB) then a packet: each description used to
    rebuild the compiled walk's table of all those before it (58 s on the issue's
    machine, 27 s of CPU here, #30.7); now 0.4 s of CPU. The bound is over ten times
    that, and far below the quadratic time."""
    path = tmp_path / "idbs.pcapng"
    path.write_bytes(SHB + _idb() * 40_000 + _epb(0, REQUEST))
    assert path.stat().st_size > 800_000
    start = time.process_time()
    with batching():
        capture = open_capture(path)
        data = b"".join(c.data for c in capture.chunks())
    took = time.process_time() - start
    assert data == REQUEST
    assert any("modscope reads 128 interfaces at most" in w for w in capture.warnings)
    assert took < 5.0, f"{took:.1f} s of CPU for 40,000 interface descriptions"


def test_40k_distinct_interfaces_then_packets_in_each_are_read(tmp_path: Path) -> None:
    """Distinct descriptions interleaved with packets: the first 128 interfaces' packets
    are read, the others skipped with one warning, whatever the walk (compiled or not)."""
    parts = [SHB]
    for k in range(2_000):
        parts += [_idb(snaplen=k + 1), _epb(k, REQUEST)]
    path = tmp_path / "many.pcapng"
    path.write_bytes(b"".join(parts))
    for batched in (True, False):
        with batching(batched):
            capture = open_capture(path)
            chunks = [c for c in capture.chunks() if c.data]
        assert len(chunks) == 128
        assert {c.channel for c in chunks} == set(range(128))
    read_and_frame(path, ReadOptions())


# -- network captures -----------------------------------------------------------------------


def _net_read(path: Path) -> list[Chunk]:
    read_and_frame(path, ReadOptions())  # the fuzz invariants
    return list(open_capture(path).chunks())


def test_a_reset_opening_a_tcp_direction_is_read(tmp_path: Path) -> None:
    """The first segment a side sends is an RST carrying bytes (a refused connection)."""
    conv = Conversation()
    request = mbap_frame(1, read_request(0))
    packets = [conv.server(b"", TCP_RST | TCP_ACK), conv.client(request), conv.client(request)]
    path = tmp_path / "rst.pcap"
    path.write_bytes(pcap(LINKTYPE_ETHERNET, [(T0 + k * 0.01, p) for k, p in enumerate(packets)]))
    chunks = _net_read(path)
    assert any(c.event == "connection" and "reset" in c.note for c in chunks)


def test_overlapping_segments_with_other_bytes_are_a_reassembly_error(tmp_path: Path) -> None:
    conv = Conversation()
    request = mbap_frame(1, read_request(0))
    first = conv.client(request)
    other = bytes(b ^ 0xFF for b in request[4:])
    again = conv.segment(True, other, seq=(conv.client_seq - len(other)) % (1 << 32))
    packets = [first, again, conv.server(mbap_frame(1, read_answer(7)))]
    path = tmp_path / "overlap.pcap"
    path.write_bytes(pcap(LINKTYPE_ETHERNET, [(T0 + k * 0.01, p) for k, p in enumerate(packets)]))
    chunks = _net_read(path)
    assert [c.event for c in chunks].count("reassembly error") == 1
    assert b"".join(c.data for c in chunks if c.channel == 0) == request  # the first kept


def test_20k_one_byte_segments_in_reverse_reassemble(tmp_path: Path) -> None:
    conv = Conversation()
    packets = conv.handshake()
    stream = b"".join(mbap_frame(k, read_request(k)) for k in range(1, 2_000))[:20_000]
    start = conv.client_seq
    tiny = [conv.segment(True, stream[i : i + 1], seq=start + i) for i in range(len(stream))]
    tiny.reverse()
    packets += tiny
    path = tmp_path / "tiny.pcap"
    path.write_bytes(pcap(LINKTYPE_ETHERNET, [(T0 + k * 1e-5, p) for k, p in enumerate(packets)]))
    start_cpu = time.process_time()
    chunks = _net_read(path)
    assert time.process_time() - start_cpu < 60.0  # 47 s before the heap; about 2 s now
    assert b"".join(c.data for c in chunks if c.channel == 0) == stream


def test_300_reconnecting_connections_are_read_whole(tmp_path: Path) -> None:
    packets: list[tuple[float, bytes]] = []
    for k in range(300):
        conv = Conversation(client_port=40000 + k)
        request = mbap_frame(k + 1, read_request(k))
        segs = [
            *conv.handshake(),
            conv.client(request),
            conv.server(mbap_frame(k + 1, read_answer(k))),
        ]
        segs += [conv.client(b"", TCP_FIN | TCP_ACK), conv.server(b"", TCP_FIN | TCP_ACK)]
        packets += [(T0 + k * 0.1 + j * 0.001, p) for j, p in enumerate(segs)]
    path = tmp_path / "polls.pcap"
    path.write_bytes(pcap(LINKTYPE_ETHERNET, packets))
    chunks = _net_read(path)
    capture = open_capture(path)
    list(capture.chunks())
    assert not any("left out" in w for w in capture.warnings), capture.warnings
    assert sum(len(c.data) for c in chunks if c.channel % 2 == 0) == 300 * 12


def test_200_concatenated_pcapng_sections_are_read_whole(tmp_path: Path) -> None:
    one = SHB + _idb() + _epb(0, REQUEST)
    path = tmp_path / "cat.pcapng"
    path.write_bytes(one * 200)
    read_and_frame(path, ReadOptions())
    capture = open_capture(path)
    chunks = [c for c in capture.chunks() if c.data]
    assert len(chunks) == 200 and {c.channel for c in chunks} == {0}


# -- text exports --------------------------------------------------------------------------


SALEAE = CAPTURES / "logs" / "saleae_logic2_table.csv"


def test_a_csv_field_past_131072_characters_is_no_traceback(tmp_path: Path) -> None:
    lines = SALEAE.read_bytes().split(b"\n")
    lines[3] = lines[3].replace(b'"data"', b'"' + b"d" * 131_073 + b'"')
    path = tmp_path / "huge.csv"
    path.write_bytes(b"\n".join(lines))
    read_and_frame(path, ReadOptions())


def test_a_stray_cr_in_a_saleae_csv_is_no_traceback(tmp_path: Path) -> None:
    lines = SALEAE.read_bytes().split(b"\n")
    lines[4] = lines[4][:10] + b"\r" + lines[4][10:]
    path = tmp_path / "cr.csv"
    path.write_bytes(b"\n".join(lines))
    read_and_frame(path, ReadOptions())


LONG_LINE_SEEDS = {
    "esphome.log": (
        CAPTURES / "logs" / "esphome_hex_ms.log",
        b"[12:00:00.000][D][uart_debug]: >>> ",
    ),
    "saleae.csv": (SALEAE, b'"Master","data",0.5,0.001,0x'),
    "socat.log": (CAPTURES / "hexdump" / "socat_modbus.log", b" 01 03 "),
    "text2pcap.txt": (CAPTURES / "hexdump" / "text2pcap_modbus.txt", b"000010 "),
}


@pytest.mark.parametrize("name", sorted(LONG_LINE_SEEDS))
def test_a_line_past_1_mib_is_skipped_and_told(tmp_path: Path, name: str) -> None:
    """#30.8: a line past `MAX_LINE` (1 MiB) was held whole (a 200 MB line took 620 MB);
    it is read on in pieces, skipped, and told once with its line, length and start."""
    seed, start = LONG_LINE_SEEDS[name]
    lines = seed.read_bytes().split(b"\n")
    line = start + b"0A " * (MAX_LINE // 3 + 1)
    lines.insert(6, line)
    path = tmp_path / name
    path.write_bytes(b"\n".join(lines))
    read_and_frame(path, ReadOptions())
    capture = open_capture(path)
    assert sum(len(c.data) for c in capture.chunks()) > 0
    told = [w for w in capture.warnings if "a line may hold" in w]
    assert told == [
        f"{path} line 7: a line of {len(line):,} bytes, more than the {MAX_LINE:,} a line "
        f"may hold; the line is skipped (it starts {line[:40].decode()!r})"
    ]


# -- MQTT messages -----------------------------------------------------------------------


def test_hostile_mqtt_messages_are_refused_and_counted() -> None:
    """Issue #30's MQTT inputs: a raw message on interface 300, an interface message
    nested 1,000 deep, `"baud": 1e999`, a 10 MB raw message, a read stamped in 2540 and
    one numbered 2**63. Each is refused and counted; the good reads around them are fed;
    no latency of 1.8e13 ms, no 9.2e18 lost reads (item 9)."""
    pytest.importorskip("paho.mqtt.client")
    from tests.fuzz.test_fuzz_mqtt import BASE, GOOD_RAW, Message, check_fed, feed, reader

    raw, interface = f"{BASE}/raw", f"{BASE}/interface"
    channel = bytearray(GOOD_RAW[1])
    channel[8:12] = struct.pack("<I", 300)
    future = bytearray(GOOD_RAW[2])
    ticks = 18_000_000_000 * 10**9
    future[12:20] = struct.pack("<II", ticks >> 32, ticks & 0xFFFFFFFF)
    numbered = bytearray(GOOD_RAW[2])
    at = bytes(numbered).rfind(struct.pack("<HH", 5, 8))
    numbered[at + 4 : at + 12] = struct.pack("<Q", 2**63)
    messages = [
        Message(raw, GOOD_RAW[0]),
        Message(raw, bytes(channel)),
        Message(raw, GOOD_RAW[1]),
        Message(interface, b'{"a":' * 1000 + b"1" + b"}" * 1000),
        Message(interface, b'{"line": {"baud": 1e999}, "session": "h"}'),
        Message(raw, b"\0" * (10 * 1024 * 1024)),
        Message(raw, bytes(future)),
        Message(raw, bytes(numbered)),
        Message(raw, GOOD_RAW[2]),
        Message(raw, GOOD_RAW[3]),
    ]
    r = reader()
    feed(r, messages)
    check_fed(r, messages)
    assert r.stats[0].reads == 4 and r.lost_messages == 0
    assert r.bad_messages == 6 and r.refused == 1
    assert set(r.bad_kinds) == {
        "channel",
        "interface nested too deep",
        "interface baud",
        "raw size",
        "time",
        "sequence",
    }


def test_a_retransmission_after_the_fin_is_no_reassembly_error(tmp_path: Path) -> None:
    """The FIN takes a sequence number but delivers no byte: a retransmission of the
    bytes before it was compared one byte off and reported as a reassembly error (found
    by test_fuzz_net's repeated-and-reordered property)."""
    conv = Conversation()
    packets = conv.handshake()
    second = mbap_frame(2, read_request(3))
    packets += [conv.client(mbap_frame(1, read_request(0)))]
    again = conv.segment(True, second)
    packets += [conv.client(second), conv.client(b"", TCP_FIN | TCP_ACK), again]
    path = tmp_path / "fin.pcap"
    path.write_bytes(pcap(LINKTYPE_ETHERNET, [(T0 + k * 0.01, p) for k, p in enumerate(packets)]))
    chunks = _net_read(path)
    assert not [c for c in chunks if c.event == "reassembly error"]
    assert (
        b"".join(c.data for c in chunks if c.channel == 0)
        == mbap_frame(1, read_request(0)) + second
    )


# -- the harness -------------------------------------------------------------------------


def test_the_hang_limit_is_cpu_time_and_leaves_the_test_timeout_armed() -> None:
    """`no_hang` stops an example that spins past its CPU time, whatever the load (a
    machine at load 17 stretched the wall-clock time of the slowest Saleae examples 13
    times), and no longer cancels the real-time timer pytest-timeout arms for the whole
    test (it set and then cleared `ITIMER_REAL` itself)."""
    arm = signal.getitimer(signal.ITIMER_REAL)[0] == 0  # (pytest-timeout may have armed it)
    if arm:
        signal.setitimer(signal.ITIMER_REAL, 600)
    try:
        with pytest.raises(HangError), no_hang(0.2):
            while True:
                pass
        with no_hang(0.2):
            time.sleep(0.3)  # waiting spends no CPU time: not a hang by this limit
        assert signal.getitimer(signal.ITIMER_REAL)[0] > 0
    finally:
        if arm:
            signal.setitimer(signal.ITIMER_REAL, 0)
