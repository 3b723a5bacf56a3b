"""Provides the sigrok decoding benchmark: UART characters from the bundled logic captures.

Run: python benchmarks/bench_sigrok.py. Prints samples per second per capture (65 M
samples in all), decoded with the line settings tests/captures/README.md gives.
"""

from __future__ import annotations

import os
import sys
import time
import zipfile
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from sniffer.sources import ReadOptions, open_capture

SIGROK = Path(__file__).resolve().parent.parent / "tests" / "captures" / "sigrok"
FLOW = ReadOptions(probes=("RXTX",), baud=9600, parity="N")
CAPTURES = [
    (
        "brainchild_io_16do/brainchild-io-16do.sr",
        ReadOptions(probes=("probe2", "probe1"), invert=True),
    ),
    ("flowmeter/flowmeter_graph_tool.sr", FLOW),
    ("flowmeter/flowmeter_target0_val0.sr", FLOW),
    ("flowmeter/flowmeter_target_0liter_per_min.sr", FLOW),
    ("flowmeter/flowmeter_target_15liter_per_min.sr", FLOW),
    ("flowmeter/flowmeter_target_20liter_per_min.sr", FLOW),
    ("wizmodbus/wizmodbus.sr", ReadOptions(probes=("RX", "TX"), baud=9600, parity="N")),
]


def samples(path: Path) -> int:
    with zipfile.ZipFile(path) as z:
        meta = z.read("metadata").decode()
        lines = meta.splitlines()
        unit = int(next(x.split("=")[1] for x in lines if x.startswith("unitsize")))
        return sum(i.file_size for i in z.infolist() if i.filename.startswith("logic-")) // unit


def main() -> None:
    total_samples = 0
    total_time = 0.0
    for name, options in CAPTURES:
        path = SIGROK / name
        n = samples(path)
        best = float("inf")
        chars = 0
        for _ in range(3):
            started = time.perf_counter()
            chars = sum(len(c.data) for c in open_capture(path, options).chunks())
            best = min(best, time.perf_counter() - started)
        total_samples += n
        total_time += best
        rate = n / best / 1e6
        size = f"{n / 1e6:5.1f} M samples {chars:5d} chars"
        print(f"{name:<46} {size} {best * 1e3:6.1f} ms {rate:4.0f} M/s")
    rate = total_samples / total_time / 1e6
    print(
        f"all: {total_samples / 1e6:.1f} M samples in {total_time:.2f} s ({rate:.0f} M samples/s)"
    )


if __name__ == "__main__":
    main()
