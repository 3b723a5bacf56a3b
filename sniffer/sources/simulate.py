"""Provides the demo bus: a master polling the seed devices, recorded as a USB adapter sees it.

`python -m sniffer.sources.simulate sniffer/demo/demo.pcapng` writes the bundled demo capture. The
traffic is deterministic: a SCADA master polls a VED903B exciter (unit 1), a DCRL power
factor controller (unit 2) and an RVS-DN soft starter (unit 3) with plausible values
that drift over time, plus one address nobody answers (unit 4). A few faults are mixed
in on purpose: exceptions, timeouts, a slow answer, a write during the starter's quiet
time, a CRC error, noise and a transceiver's trailing zero byte.
"""

from __future__ import annotations

import argparse
import math
import random
import struct
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from dissectors.checks import with_crc
from sniffer.model import LineSettings, Stamp
from sniffer.sources.linktypes import LINKTYPE_RTAC_SERIAL, describe_interface
from sniffer.sources.pcapng_writer import PcapngWriter, rtac_record

LINE = LineSettings(baud=19200, bytesize=8, parity="E", stopbits=1, mode="rtu")
START = 1768464000.0  # 2026-01-15 08:00:00 UTC
READ_LATE = 0.002  # the latest a simulated host read returns after its last byte


@dataclass(frozen=True, slots=True)
class Step:
    """One poll: the request, and the answer (None: no answer) after `delay` seconds."""

    request: bytes
    answer: bytes | None
    delay: float = 0.012
    corrupt: bool = False  # flip a bit in the answer
    noise_before: bytes = b""
    zeros_after: int = 0


def _u16s(values: list[int]) -> bytes:
    return b"".join(struct.pack(">H", v & 0xFFFF) for v in values)


def _read(unit: int, fc: int, address: int, words: list[int]) -> tuple[bytes, bytes]:
    req = struct.pack(">BBHH", unit, fc, address, len(words))
    data = _u16s(words)
    return with_crc(req), with_crc(bytes([unit, fc, len(data)]) + data)


def _f32_cdab(value: float) -> list[int]:
    hi, lo = struct.unpack(">HH", struct.pack(">f", value))
    return [lo, hi]  # the VED903B stores the low word first


def _u32(value: int) -> list[int]:
    return [(value >> 16) & 0xFFFF, value & 0xFFFF]


def _ved903b(t: float) -> list[Step]:
    """Exciter protection setpoints (%R201.. floats) read as a block."""
    values = [95.0 + math.sin(t / 9), 10.0, 5.0, 140.0 + 5 * math.sin(t / 7), 160.0, 0.9]
    words: list[int] = []
    for v in values:
        words += _f32_cdab(v)
    req, resp = _read(1, 3, 3200, words)
    return [Step(req, resp, delay=0.008)]


def _dcrl(t: float, cycle: int) -> list[Step]:
    """Measures (input registers 02h..0Fh, 1-based), and now and then a setup parameter."""
    cos_phi = 95 + round(2 * math.sin(t / 11))
    sign_and_flags = 1 << 30 if cycle % 17 == 5 else 0  # capacitive now and then
    words = (
        _u32(cos_phi | sign_and_flags)
        + _u32(400 + round(3 * math.sin(t / 5)))
        + _u32(12345 + round(800 * math.sin(t / 3)))
        + _u32((-3) & 0xFFFFFFFF)
        + _u32(92)
        + [0, 0]
        + _u32(28)
    )
    req, resp = _read(2, 4, 0x0001, words)
    steps = [Step(req, resp, delay=0.025)]
    if cycle % 40 == 3:
        select = with_crc(struct.pack(">BBHH", 2, 6, 0x5001, 1))
        steps.append(Step(select, select, delay=0.02))
        req, resp = _read(2, 4, 0x5003, _u32(250))
        steps.append(Step(req, resp, delay=0.02))
    return steps


def _rvs_dn(t: float, cycle: int) -> list[Step]:
    running = (1 << 9) | ((1 << 10) if cycle % 30 > 20 else 0)
    current = 98 + round(4 * math.sin(t / 4))
    req, resp = _read(3, 4, 0, [running, current, 415 + round(5 * math.sin(t / 6)), 1])
    delay = 0.006 if cycle % 50 != 7 else 0.055  # one slow answer now and then
    steps = [Step(req, resp, delay=delay)]
    if cycle % 10 == 0:
        req, resp = _read(3, 3, 0x0B, [115, 4, 300])
        steps.append(Step(req, resp, delay=0.009))
    if cycle % 25 == 12:
        coils = with_crc(struct.pack(">BBHH", 3, 1, 0, 8))
        steps.append(Step(coils, with_crc(bytes([3, 1, 1, 0b00000100])), delay=0.007))
    if cycle == 60:
        write = with_crc(struct.pack(">BBHH", 3, 6, 0x0D, 300))
        steps.append(Step(write, write, delay=0.03))
        # the master ignores the 1 s quiet time the manual asks for after a write
        req, resp = _read(3, 3, 0x0B, [115, 4, 300])
        steps.append(Step(req, resp, delay=0.01))
    if cycle == 90:  # a write outside the documented range, refused with exception 03
        write = with_crc(struct.pack(">BBHH", 3, 6, 0x0D, 700))
        steps.append(Step(write, with_crc(bytes([3, 0x86, 3])), delay=0.01))
    if cycle % 45 == 30:  # a read of a reserved address
        req = with_crc(struct.pack(">BBHH", 3, 4, 0x0008, 2))
        steps.append(Step(req, with_crc(bytes([3, 0x84, 2])), delay=0.006))
    return steps


def traffic(
    cycles: int = 240, period: float = 0.25, seed: int = 7
) -> Iterator[tuple[float, bytes]]:
    """(time, bytes on the wire) in time order: the whole demo bus."""
    rng = random.Random(seed)
    char = LINE.char_time
    t = START
    for cycle in range(cycles):
        rel = cycle * period
        steps = _ved903b(rel) + _dcrl(rel, cycle) + _rvs_dn(rel, cycle)
        if cycle % 20 == 9:  # a slave that is not there
            steps.append(Step(with_crc(struct.pack(">BBHH", 4, 3, 0, 2)), None))
        if cycle == 150:
            steps[0] = Step(steps[0].request, steps[0].answer, steps[0].delay, corrupt=True)
        if cycle == 170:
            steps[1] = Step(steps[1].request, steps[1].answer, 0.02, noise_before=b"\xff\xfe\x7f")
        if cycle == 200:
            steps[2] = Step(steps[2].request, steps[2].answer, 0.01, zeros_after=1)
        t = START + rel
        for step in steps:
            if step.noise_before:
                yield t, step.noise_before
                t += len(step.noise_before) * char + 0.004
            yield t, step.request
            t += len(step.request) * char
            if step.answer is None:
                t += 0.3  # the master's response timeout
                continue
            t += step.delay * rng.uniform(0.9, 1.1)
            answer = bytearray(step.answer)
            if step.corrupt:
                answer[len(answer) // 2] ^= 0x10
            answer += bytes(step.zeros_after)
            yield t, bytes(answer)
            t += len(answer) * char + 0.004 + rng.uniform(0, 0.002)


def write_demo(path: Path, cycles: int = 240) -> int:
    """Record the demo bus as a USB adapter delivers it; returns the number of reads."""
    rng = random.Random(11)
    char = LINE.char_time
    reads = 0
    with path.open("wb") as handle:
        writer = PcapngWriter(handle, application="modscope demo simulator")
        # the reads below are stamped at most READ_LATE after their last byte: the
        # capture says so, as a recorder that knows its adapter would
        iface = writer.add_interface(
            LINKTYPE_RTAC_SERIAL,
            name="demo",
            description=describe_interface(LINE, timing=(Stamp.READ_END, READ_LATE)),
        )
        for t, data in traffic(cycles):
            # the adapter hands bytes over in reads of up to 16 ms worth; a frame may be
            # split in two reads
            cut = len(data) if len(data) < 12 or rng.random() < 0.8 else rng.randrange(4, len(data))
            for part, start in ((data[:cut], 0), (data[cut:], cut)):
                if not part:
                    continue
                # a host read is stamped when it returns: after its last byte, plus
                # the adapter's latency
                when = t + (start + len(part)) * char + rng.uniform(0.0005, READ_LATE)
                # the record's time is its first byte's, as modscope's recorder writes it:
                # estimated from the read's end and the baud rate
                writer.write_packet(iface, when, rtac_record(when - len(part) * char, part))
                reads += 1
    return reads


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Write the modscope demo capture.")
    parser.add_argument("output", type=Path, help="pcapng file to write")
    parser.add_argument("--cycles", type=int, default=240, help="polling cycles (0.25 s each)")
    args = parser.parse_args(argv)
    reads = write_demo(args.output, args.cycles)
    sys.stdout.write(f"wrote {args.output}: {reads} reads\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
