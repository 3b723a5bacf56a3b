"""Provides the framing benchmark: index a 1M-frame stream, against pymodbus's RTU framer.

Run: python benchmarks/bench_framing.py [--frames N]. modscope frames a stream whose
direction it must infer; pymodbus is told each frame's direction and gets each frame
as its own read (its framer takes one frame per call), which only helps it.
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.common import LINE, arguments, file_reads, peak_rss_mb, timed, usb_reads, workload
from sniffer.pipeline import Pipeline
from sniffer.store import FrameStore
from sniffer.vocab import Flag, Kind


def index(chunks: list) -> FrameStore:  # type: ignore[type-arg]
    pipeline = Pipeline(LINE)
    for chunk in chunks:
        pipeline.feed(chunk)
    pipeline.finish()
    return pipeline.store


def pymodbus_frames(frames: list) -> int:  # type: ignore[type-arg]
    from pymodbus.framer import FramerRTU
    from pymodbus.pdu import DecodePDU

    to_server = FramerRTU(DecodePDU(True))
    to_client = FramerRTU(DecodePDU(False))
    n = 0
    for f in frames:
        framer = to_server if f.role == "request" else to_client
        _, pdu = framer.handleFrame(f.raw, 0, 0)
        n += pdu is not None
    return n


def main() -> None:
    args = arguments(__doc__ or "")
    frames = workload(args.frames)
    n = len(frames)
    reads = file_reads(frames)
    size = sum(len(c.data) for c in reads)
    store, t_file = timed("modscope index, 64 KiB file reads", n, lambda: index(reads))
    rows = len(store)
    good = sum(
        1
        for i in range(rows)
        if store.kind[i] != Kind.NOISE and not store.flags[i] & Flag.CHECK_BAD
    )
    paired = sum(1 for i in range(rows) if store.partner[i] >= 0)
    rate = size / t_file / 1e6
    print(f"  rows {rows:,}, good frames {good:,} of {n:,}, paired {paired:,}; {rate:.1f} MB/s")
    usb = usb_reads(frames)
    _, t_usb = timed(f"modscope index, 16 ms USB reads ({len(usb):,} reads)", n, lambda: index(usb))
    decoded, t_pm = timed(
        "pymodbus FramerRTU, one frame per call, told direction", n, lambda: pymodbus_frames(frames)
    )
    print(f"  pymodbus decoded {decoded:,} of {n:,}")
    print(
        f"ratio modscope/pymodbus: file reads {t_pm / t_file:.1f}x, USB reads {t_pm / t_usb:.1f}x"
    )
    print(f"store: {store.memory_bytes() / n:.1f} bytes per frame; peak RSS {peak_rss_mb():.0f} MB")


if __name__ == "__main__":
    main()
