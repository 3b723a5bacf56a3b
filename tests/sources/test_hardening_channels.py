"""Nothing dropped at 128 connections or interfaces (issue #30, item 4): a poller that
connects anew for each poll goes on past its 128th connection in the channels of closed
ones, every request answered and paired (tshark, a real peer, pairs as many); more
connections open at once than channels hold give one warning with a count, not one per
connection; 200 pcapng sections of one port joined by `cat` are read whole."""

from __future__ import annotations

import io
import shutil
import subprocess
from pathlib import Path

import pytest

from dissectors.checks import with_crc
from sniffer.model import LineSettings
from sniffer.session.session import Session, open_session
from sniffer.sources import open_capture
from sniffer.sources.linktypes import LINKTYPE_RTAC_SERIAL
from sniffer.sources.net.decoder import REUSED
from sniffer.sources.pcapng_writer import (
    EPB_FLAG_INBOUND,
    PcapngWriter,
    describe_interface,
    rtac_record,
)
from sniffer.vocab import Kind, Status
from tests.support.gateway import mbap_frame
from tests.support.netbuild import TCP_ACK, TCP_FIN, Conversation, pcap

T0 = 1_750_000_000.0
POLLS = 300
LINKTYPE_ETHERNET = 1


def _poll(
    conv: Conversation, tid: int, t: float, *, close: bool = True
) -> list[tuple[float, bytes]]:
    """One connection: handshake, a read of register `tid`, its answer, then FIN both ways."""
    request = mbap_frame(tid, bytes([1, 3]) + tid.to_bytes(2, "big") + b"\x00\x01")
    answer = mbap_frame(tid, bytes([1, 3, 2]) + (tid * 7 % 65536).to_bytes(2, "big"))
    packets = [*conv.handshake(), conv.client(request), conv.server(answer)]
    if close:
        packets += [conv.client(b"", TCP_FIN | TCP_ACK), conv.server(b"", TCP_FIN | TCP_ACK)]
        packets.append(conv.client(b"", TCP_ACK))
    return [(t + k * 0.001, p) for k, p in enumerate(packets)]


def _read(path: Path) -> tuple[Session, list[str]]:
    session, capture = open_session(path)
    session.ingest(capture.chunks())
    return session, capture.warnings + session.warnings


def test_a_poller_reconnecting_for_each_poll_is_read_past_128(tmp_path: Path) -> None:
    packets: list[tuple[float, bytes]] = []
    for k in range(POLLS):
        conv = Conversation(client_port=40000 + k)
        packets += _poll(conv, k + 1, T0 + k * 0.1)
    path = tmp_path / "reconnects.pcap"
    path.write_bytes(pcap(LINKTYPE_ETHERNET, packets))
    session, warnings = _read(path)
    store = session.store
    requests = [i for i in range(len(store)) if store.kind[i] == Kind.REQUEST]
    answers = [i for i in range(len(store)) if store.kind[i] == Kind.RESPONSE]
    assert len(requests) == len(answers) == POLLS  # none lost after the 128th
    assert all(store.status[i] == Status.OK for i in requests + answers)
    for i in requests:  # each paired with the answer to its own transaction
        j = store.partner[i]
        assert store.raw(i)[:2] == store.raw(j)[:2]
    assert not [w for w in warnings if "left out" in w], warnings
    notes = [store.notes.get(i, "") for i in range(len(store)) if store.kind[i] == Kind.EVENT]
    assert sum(REUSED in n for n in notes) == POLLS - 128
    # the reused channels name the client by its host: its ports varied
    peers = set(store.peers.values())
    assert "192.168.1.10:*" in peers and "192.168.1.20:502" in peers
    if shutil.which("tshark") is None:
        pytest.skip("tshark is not installed")
    done = subprocess.run(
        ["tshark", "-r", str(path), "-Y", "mbtcp && modbus.request_frame", "-T", "fields",
         "-e", "frame.number"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert len(done.stdout.split()) == POLLS  # tshark pairs as many answers


def test_too_many_connections_at_once_give_one_warning_with_a_count(tmp_path: Path) -> None:
    packets: list[tuple[float, bytes]] = []
    for k in range(200):  # all open at once: none closes
        conv = Conversation(client_port=40000 + k)
        packets += _poll(conv, k + 1, T0 + k * 0.01, close=False)
    path = tmp_path / "open.pcap"
    path.write_bytes(pcap(LINKTYPE_ETHERNET, sorted(packets, key=lambda p: p[0])))
    session, warnings = _read(path)
    left = [w for w in warnings if "left out" in w]
    assert len(left) == 1 and f"{path}: 72 connection(s) left out" in left[0], warnings
    assert "192.168.1.10:40128" in left[0]
    store = session.store
    assert sum(1 for i in range(len(store)) if store.kind[i] == Kind.REQUEST) == 128


def test_concatenated_pcapng_sections_are_read_past_128_interfaces(tmp_path: Path) -> None:
    """`cat` of 200 recordings of one port: each section describes the same interface,
    which goes on in one channel; every section's frames are read."""
    line = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
    frame = with_crc(bytes.fromhex("010300000001"))
    sections = []
    for k in range(200):
        out = io.BytesIO()
        writer = PcapngWriter(out)
        iface = writer.add_interface(
            LINKTYPE_RTAC_SERIAL, name="ttyUSB0", description=describe_interface(line)
        )
        t = T0 + k * 1.0
        writer.write_packet(iface, t, rtac_record(t - 0.005, frame), flags=EPB_FLAG_INBOUND)
        sections.append(out.getvalue())
    path = tmp_path / "cat.pcapng"
    path.write_bytes(b"".join(sections))
    capture = open_capture(path)
    data = [c for c in capture.chunks() if c.data]
    assert [c.data for c in data] == [frame] * 200
    assert {c.channel for c in data} == {0}
    assert capture.warnings == []
    assert capture.info.channels == {0: "ttyUSB0 (RTAC serial)"}
