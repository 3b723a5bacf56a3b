"""Provides the fixtures of the session tests: `capture`, a recording with sidecars allowed."""

from __future__ import annotations

from pathlib import Path

import pytest

from sniffer.session import index
from sniffer.sources.linktypes import LINKTYPE_RTAC_SERIAL
from sniffer.sources.pcapng_writer import (
    EPB_FLAG_INBOUND,
    PcapngWriter,
    describe_interface,
    rtac_record,
)
from sniffer.sources.synth import polling_frames
from tests.support.index import LINE, T0


@pytest.fixture
def capture(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A recording of 3000 frames in 16 ms reads, with a CRC error and stray bytes, and
    sidecars allowed for it (MIN_SIZE 0, the cache folder in tmp_path), in blocks of 500
    rows."""
    monkeypatch.setattr(index, "MIN_SIZE", 0)
    monkeypatch.setattr(index, "pays", lambda capture, mode: True)  # (serial pcapng too)
    monkeypatch.setattr(index, "BLOCK", 500)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv("MODSCOPE_NO_INDEX", raising=False)
    frames = polling_frames(3000, line=LINE, seed=3)
    path = tmp_path / "bus.pcapng"
    with path.open("wb") as out:
        writer = PcapngWriter(out)
        iface = writer.add_interface(
            LINKTYPE_RTAC_SERIAL, name="ttyUSB0", description=describe_interface(LINE)
        )
        buf, t_read = bytearray(), 0.016
        for k, f in enumerate(frames):
            if f.t >= t_read and buf:
                t = T0 + t_read
                data = bytes(buf)
                packet = rtac_record(t - len(data) * LINE.char_time, data)
                writer.write_packet(iface, t, packet, flags=EPB_FLAG_INBOUND)
                buf.clear()
                while t_read <= f.t:
                    t_read += 0.016
            raw = bytearray(f.raw)
            if k == 100:
                raw[-1] ^= 0xFF  # a CRC error
            if k == 200:
                buf += b"\x00\xff"  # stray bytes
            buf += raw
        t = T0 + t_read
        writer.write_packet(iface, t, rtac_record(t - 0.001, bytes(buf)), flags=EPB_FLAG_INBOUND)
    return path
