"""Provides the dissection benchmark: take every frame of the polling stream apart,
against pymodbus decoding the same frames in the same run.

Run: python benchmarks/bench_dissect.py [--frames N] [--runs R] [--detail]. modscope
dissects only the rows somebody looks at, so this is the worst case (everything
dissected, each response with its request); pymodbus decodes the PDU of each frame with
the decoder for its direction. The two take turns R times on the same frames, and the
best run of each side gives the ratio, so a busy machine slows both alike. `--detail`
adds per-frame times for an FC 3 request and a 10-register response.
"""

from __future__ import annotations

import argparse
import os
import sys
import timeit
from collections.abc import Callable

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.common import peak_rss_mb, timed, workload
from dissectors.dissect import Role, dissect
from sniffer.sources.synth import SynthFrame


def modscope_all(frames: list[SynthFrame]) -> int:
    fields = 0
    request = b""
    for f in frames:
        body = f.raw[:-2]
        if f.role == "request":
            request = body
            d = dissect(body, Role.REQUEST)
        else:
            d = dissect(body, Role.RESPONSE, request=request)
        fields += len(d.fields)
    return fields


def pymodbus_all(frames: list[SynthFrame]) -> int:
    from pymodbus.pdu import DecodePDU

    server, client = DecodePDU(True), DecodePDU(False)
    decoded = 0
    for f in frames:
        decoder = server if f.role == "request" else client
        decoded += decoder.decode(f.raw[1:-2]) is not None
    return decoded


def detail() -> None:
    """Per-frame times, best of 7, for the commonest frames: an FC 3 request (first seen,
    and seen before) and its answer of 10 registers."""
    from pymodbus.pdu import DecodePDU

    server, client = DecodePDU(True), DecodePDU(False)
    request = bytes.fromhex("11 03 006B 000A")
    response = bytes.fromhex("11 03 14") + bytes(range(20))
    fresh = [bytes([0x11, 3, i >> 8, i & 0xFF, 0, 10]) for i in range(20_000)]

    def first_seen() -> None:
        for body in fresh:
            dissect(body, Role.REQUEST)

    def pymodbus_requests() -> None:
        for body in fresh:
            server.decode(body[1:])

    def per_frame(fn: Callable[[], object], number: int) -> float:
        return min(timeit.repeat(fn, number=number, repeat=7)) / number * 1e6

    cases = [
        (
            "FC 3 request, first seen",
            per_frame(first_seen, 1) / len(fresh),
            per_frame(pymodbus_requests, 1) / len(fresh),
        ),
        (
            "FC 3 request, seen before",
            per_frame(lambda: dissect(request, Role.REQUEST), 20_000),
            per_frame(lambda: server.decode(request[1:]), 20_000),
        ),
        (
            "FC 3 response, 10 registers, with request",
            per_frame(lambda: dissect(response, Role.RESPONSE, request=request), 20_000),
            per_frame(lambda: client.decode(response[1:]), 20_000),
        ),
    ]
    for label, ours, theirs in cases:
        print(f"  {label:<42} modscope {ours:6.2f} us   pymodbus {theirs:6.2f} us")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__ or "")
    parser.add_argument("--frames", type=int, default=200_000, help="frames in the stream")
    parser.add_argument("--runs", type=int, default=3, help="turns each side takes")
    parser.add_argument("--detail", action="store_true", help="per-frame times of FC 3 frames")
    args = parser.parse_args()
    frames = workload(args.frames)
    n = len(frames)
    ours: list[float] = []
    theirs: list[float] = []
    decoded = 0
    for run in range(1, max(1, args.runs) + 1):
        _, t_ours = timed(
            f"run {run}: modscope dissect() every frame", n, lambda: modscope_all(frames)
        )
        decoded, t_pm = timed(
            f"run {run}: pymodbus DecodePDU.decode, told direction", n, lambda: pymodbus_all(frames)
        )
        ours.append(t_ours)
        theirs.append(t_pm)
    print(f"  pymodbus decoded {decoded:,} of {n:,}")
    best_ours, best_pm = min(ours), min(theirs)
    print(
        f"best: modscope {n / best_ours:,.0f} frames/s, pymodbus {n / best_pm:,.0f} frames/s; "
        f"runs' ratios {', '.join(f'{pm / us:.2f}' for us, pm in zip(ours, theirs, strict=True))}"
    )
    print(f"ratio modscope/pymodbus: {best_pm / best_ours:.2f}x; peak RSS {peak_rss_mb():.0f} MB")
    if args.detail:
        detail()


if __name__ == "__main__":
    main()
