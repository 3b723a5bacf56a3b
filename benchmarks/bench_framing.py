"""Provides the framing benchmark: index a 1M-frame stream, against pymodbus's RTU framer,
and the compiled core against the pure-Python one.

Run: python benchmarks/bench_framing.py [--frames N] [--only pymodbus|cores] [--dir DIR]

pymodbus: modscope frames a stream whose direction it must infer; pymodbus is told each
frame's direction and gets each frame as its own read (its framer takes one frame per
call), which only helps it.

cores: CPU time per frame in this process (`time.process_time`, median of --runs) of
reading a capture file (the chunks `Session.ingest` takes, batched) and of reading,
framing and pairing it, with the compiled core (`sniffer.core`) and with the pure-Python
one, on three file shapes of the same N frames: `modscope record`'s 16 ms reads and one
frame per packet (link type 250, written by bench_scale into DIR and kept), and one frame
per packet of link type 147 (as bench_tui writes).

passes: CPU time per frame in this process of the session's passes over the indexed rows,
with the compiled core and the pure-Python one, on the 16 ms reads and the one-frame-per-
packet files: the whole `Session.ingest` (reading, framing, pairing, annotation with
SunSpec's tracker, statistics) and the `--stats` table (its quantiles); then the other
passes of `replay --stats` over the same rows: the poll cycle (`PollCycles.add` and its
table) and the statistics in their bounded form (`Stats.bound`: `Tallies`, as a windowed
`replay --stats` and a live capture count them).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.common import LINE, file_reads, peak_rss_mb, timed, usb_reads, workload
from sniffer import core
from sniffer.analysis.pollcycle import cycle_table, poll_cycles
from sniffer.analysis.stats import Stats
from sniffer.framing.pipeline import Pipeline
from sniffer.framing.store import FrameStore
from sniffer.session.session import open_session
from sniffer.sources import open_capture
from sniffer.sources.reads import batching
from sniffer.vocab import Flag, Kind

HERE = Path(__file__).resolve().parent


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


def shapes(folder: Path, n: int) -> dict[str, Path]:
    """The capture files of the comparison, written by child processes unless there."""
    from benchmarks.bench_scale import make_files

    reads, one = make_files(folder, n)
    user0 = folder / f"user0-frames-{n}.pcapng"
    if not user0.exists():
        subprocess.run(
            [sys.executable, str(HERE / "bench_tui.py"), "--make", str(user0), "--frames", str(n)],
            check=True,
        )
    return {
        "16 ms reads (250)": reads,
        "one frame per packet (250)": one,
        "one frame per packet (147)": user0,
    }


def _reading(path: Path) -> float:
    capture = open_capture(path)
    t = time.process_time()
    with batching(True):
        for _chunk in capture.chunks():
            pass
    return time.process_time() - t


def _indexing(path: Path) -> tuple[float, int]:
    session, capture = open_session(path, index=False)
    pipeline = session.pipeline
    t = time.process_time()
    with batching(True):
        for chunk in capture.chunks():
            pipeline.feed(chunk)
    pipeline.finish()
    return time.process_time() - t, len(session.store)


def _session_passes(path: Path) -> tuple[float, float, float, float, int]:
    session, capture = open_session(path, index=False)
    t = time.process_time()
    session.ingest(capture.chunks())
    ingest = time.process_time() - t
    t = time.process_time()
    session.stats.table()
    table = time.process_time() - t
    t = time.process_time()
    cycle_table(poll_cycles(session.store))
    poll = time.process_time() - t
    t = time.process_time()
    bounded = Stats(session.store)
    bounded.bound()
    bounded.update()
    bounded.table()
    return ingest, table, poll, time.process_time() - t, len(session.store)


def compare_passes(folder: Path, n: int, runs: int) -> None:
    """The session's passes over the rows, per frame: compiled and pure."""
    files = shapes(folder, n)
    compiled = core.FAST
    print(f"\npasses: CPU time per frame in this process, median of {runs} ({core.describe()})")
    if compiled is None:
        print("  the compiled core is not built here: nothing to compare")
        return
    print(
        f"  {'file':<28} {'core':<10} {'whole ingest':>14} {'stats table':>13} "
        f"{'poll cycle':>13} {'bounded stats':>14}"
    )
    for name, path in list(files.items())[:2]:
        for label, module in (("pure", None), ("compiled", compiled)):
            core.FAST = module
            try:
                measured = [_session_passes(path) for _ in range(runs)]
            finally:
                core.FAST = compiled
            rows = measured[0][4]
            ingest, table, poll, bounded = (
                statistics.median(m[k] for m in measured) for k in range(4)
            )
            print(
                f"  {name:<28} {label:<10} {ingest / rows * 1e6:11.2f} us "
                f"{table / rows * 1e6:10.3f} us {poll / rows * 1e6:10.3f} us "
                f"{bounded / rows * 1e6:11.3f} us"
            )


def compare_cores(folder: Path, n: int, runs: int) -> None:
    """Reading, and reading with framing and pairing, per frame: compiled and pure."""
    files = shapes(folder, n)
    compiled = core.FAST
    print(f"\ncores: CPU time per frame in this process, median of {runs} ({core.describe()})")
    if compiled is None:
        print("  the compiled core is not built here: nothing to compare")
        return
    print(f"  {'file':<28} {'core':<10} {'reading':>12} {'read+frame+pair':>18}")
    for name, path in files.items():
        for label, module in (("pure", None), ("compiled", compiled)):
            core.FAST = module
            try:
                read = statistics.median(_reading(path) for _ in range(runs))
                measured = [_indexing(path) for _ in range(runs)]
            finally:
                core.FAST = compiled
            rows = measured[0][1]
            index = statistics.median(m[0] for m in measured)
            print(
                f"  {name:<28} {label:<10} {read / rows * 1e6:9.2f} us "
                f"{index / rows * 1e6:15.2f} us"
            )


def pymodbus_comparison(frames_wanted: int) -> None:
    frames = workload(frames_wanted)
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


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--frames", type=int, default=1_000_000, help="frames in the stream")
    parser.add_argument(
        "--only", choices=("pymodbus", "cores", "passes"), help="run one comparison"
    )
    parser.add_argument(
        "--dir", type=Path, default=Path("/tmp/modscope-bench"), help="capture files (kept)"
    )
    parser.add_argument("--runs", type=int, default=3, help="runs of each core (median)")
    args = parser.parse_args()
    if args.only in (None, "pymodbus"):
        pymodbus_comparison(args.frames)
    if args.only in (None, "cores"):
        compare_cores(args.dir, args.frames, args.runs)
    if args.only in (None, "passes"):
        compare_passes(args.dir, args.frames, args.runs)


if __name__ == "__main__":
    main()
