"""TCP reassembly of untrusted captures (issue #30, items 7 and 9): 20,000 one-byte
segments in reverse or shuffled order come out whole and in order at a cost of a few
sequence comparisons each (the reassembler once compared every waiting segment for each
one: 47 s for 20,000); a retransmission whose bytes differ from those delivered is
reported as a reassembly error, the first bytes kept, as Wireshark does."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

import sniffer.sources.net.tcp as tcp
from sniffer.model import Chunk
from sniffer.sources import ReadOptions, open_capture
from tests.support.gateway import mbap_frame
from tests.support.netbuild import Conversation, pcap

N = 20_000
REQUEST = mbap_frame(1, bytes([1, 3, 0, 1, 0, 1]))


def _read(tmp_path: Path, packets: list[bytes]) -> tuple[list[Chunk], list[str]]:
    path = tmp_path / "c.pcap"
    path.write_bytes(pcap(1, [(1_750_000_000.0 + k * 1e-6, p) for k, p in enumerate(packets)]))
    capture = open_capture(path, ReadOptions())
    chunks = list(capture.chunks())
    return chunks, capture.warnings


@pytest.mark.parametrize("order", ["reverse", "shuffled"])
def test_tiny_out_of_order_segments_cost_a_few_comparisons_each(
    tmp_path: Path, order: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    conv = Conversation()
    packets = conv.handshake()
    stream = (REQUEST * (N // len(REQUEST) + 1))[:N]
    base = conv.client_seq
    segments = [conv.segment(True, stream[i : i + 1], seq=base + i) for i in range(N)]
    if order == "reverse":
        segments.reverse()
    else:
        random.Random(7).shuffle(segments)
    calls = 0
    real = tcp.seq_diff

    def counted(a: int, b: int) -> int:
        nonlocal calls
        calls += 1
        return real(a, b)

    monkeypatch.setattr(tcp, "seq_diff", counted)
    chunks, warnings = _read(tmp_path, packets + segments)
    assert b"".join(c.data for c in chunks) == stream  # whole, in order
    assert not [c for c in chunks if c.event == tcp.GAP] and warnings == []
    assert calls <= 10 * N, calls  # a few per segment, not one per segment waiting


def test_a_retransmission_with_other_bytes_is_a_reassembly_error(tmp_path: Path) -> None:
    conv = Conversation()
    packets = conv.handshake()
    base = conv.client_seq
    forged = bytearray(REQUEST)
    forged[9] ^= 0xFF  # the register address, changed in the copy sent again
    packets += [
        conv.segment(True, REQUEST, seq=base),
        conv.segment(True, REQUEST, seq=base),  # the same again: a plain retransmission
        conv.segment(True, bytes(forged), seq=base),  # other bytes at the same place
    ]
    chunks, warnings = _read(tmp_path, packets)
    assert b"".join(c.data for c in chunks) == REQUEST  # the first bytes kept
    errors = [c for c in chunks if c.event == tcp.REASSEMBLY]
    assert len(errors) == 1 and "1 byte(s) different" in errors[0].note
    assert any("reassembly error" in w for w in warnings), warnings
