"""Each finding of issue #30 as a fixed input, run through the same invariants as the fuzz
tests (only documented errors, no hang, every byte in one row) and the behaviour the fix
promised. Plain tests, not marked `fuzz`: they run with the suite, in a few seconds."""

from __future__ import annotations

import struct
import time
from pathlib import Path

from sniffer.sources import ReadOptions, open_capture
from sniffer.sources.linktypes import LINKTYPE_USER0
from sniffer.sources.reads import batching
from tests.fuzz.test_fuzz_sources import read_and_frame

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
