"""Provides the benchmark workload: the 1M-frame polling stream, generated once per run."""

from __future__ import annotations

import argparse
import gc
import resource
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

from sniffer.model import Chunk, LineSettings
from sniffer.sources.synth import SynthFrame, polling_frames

LINE = LineSettings(baud=115200, bytesize=8, parity="N", stopbits=1, mode="rtu")
T = TypeVar("T")


def arguments(description: str, frames: int = 1_000_000) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--frames", type=int, default=frames, help="frames in the stream")
    return parser.parse_args()


def workload(n: int) -> list[SynthFrame]:
    t = time.perf_counter()
    frames = polling_frames(n, line=LINE)
    # the workload is a million long-lived objects that neither side made: keep the
    # garbage collector from walking them again and again while either side is timed
    gc.collect()
    gc.freeze()
    size = sum(len(f.raw) for f in frames)
    print(
        f"workload: {len(frames):,} frames, {size / 1e6:.1f} MB, "
        f"{size / len(frames):.2f} bytes per frame ({time.perf_counter() - t:.1f} s to generate)"
    )
    return frames


def file_reads(frames: list[SynthFrame], block: int = 1 << 16) -> list[Chunk]:
    """The stream as a replay reads a file of it: 64 KiB blocks."""
    data = b"".join(f.raw for f in frames)
    char = LINE.char_time
    return [
        Chunk(data[i : i + block], t_end=(i + len(data[i : i + block])) * char)
        for i in range(0, len(data), block)
    ]


def usb_reads(frames: list[SynthFrame], latency: float = 0.016) -> list[Chunk]:
    """The stream as a USB adapter delivers it live: one read per 16 ms of traffic."""
    out: list[Chunk] = []
    buf = bytearray()
    deadline = frames[0].t + latency if frames else 0.0
    for f in frames:
        if f.t >= deadline and buf:
            out.append(Chunk(bytes(buf), t_end=deadline))
            buf.clear()
            while deadline <= f.t:
                deadline += latency
        buf += f.raw
    if buf:
        out.append(Chunk(bytes(buf), t_end=deadline))
    return out


def timed(label: str, n: int, fn: Callable[[], T]) -> tuple[T, float]:
    t = time.perf_counter()
    result = fn()
    elapsed = time.perf_counter() - t
    print(f"{label:<52} {elapsed:7.2f} s  {n / elapsed:>12,.0f} frames/s")
    return result, elapsed


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def chunks_of(items: list[T], size: int) -> Iterator[list[T]]:
    for i in range(0, len(items), size):
        yield items[i : i + size]


class Unflushed:
    """A file the pcapng writer may flush after every block without a system call each."""

    def __init__(self, path: Path) -> None:
        self.handle = path.open("wb", buffering=1 << 20)

    def write(self, data: bytes) -> int:
        return self.handle.write(data)

    def flush(self) -> None:
        pass

    def tell(self) -> int:
        return self.handle.tell()

    def close(self) -> None:
        self.handle.close()
