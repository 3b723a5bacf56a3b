"""Provides synthetic Modbus traffic: a polling mix for benchmarks and a hostile stress stream.

Deterministic for a given seed. The polling mix is what a SCADA master does all day
(mostly FC 3/4 reads of a few to a few dozen registers, some coil and input reads,
writes now and then, an exception or a silent slave rarely); the stress stream then
delivers it the way a cheap USB adapter does, with stray bytes, trailing zeros from
transceiver turn-off and bit errors.
"""

from __future__ import annotations

import random
from collections.abc import Iterator
from dataclasses import dataclass

from dissectors.checks import with_crc
from sniffer.model import Chunk, LineSettings


@dataclass(frozen=True, slots=True)
class SynthFrame:
    raw: bytes
    role: str  # request | response | exception
    t: float  # start time on the wire


def _request(rng: random.Random, unit: int) -> tuple[bytes, bytes | None]:
    """One request and its normal answer (None for a broadcast)."""
    pick = rng.random()
    addr = rng.randrange(0, 2000)
    if pick < 0.70:
        fc = 3 if rng.random() < 0.7 else 4
        qty = rng.choice((2, 4, 8, 12, 16, 20, 25, 30, 40, 50, 60, 64))
        req = bytes([unit, fc]) + addr.to_bytes(2, "big") + qty.to_bytes(2, "big")
        data = bytes(rng.getrandbits(8) for _ in range(2 * qty))
        return req, bytes([unit, fc, 2 * qty]) + data
    if pick < 0.80:
        fc = rng.choice((1, 2))
        qty = rng.randrange(1, 64)
        req = bytes([unit, fc]) + addr.to_bytes(2, "big") + qty.to_bytes(2, "big")
        nbytes = (qty + 7) // 8
        bits = bytearray(rng.getrandbits(8) for _ in range(nbytes))
        if qty % 8:
            bits[-1] &= (1 << (qty % 8)) - 1
        return req, bytes([unit, fc, nbytes]) + bytes(bits)
    if pick < 0.90:
        value = rng.randrange(0, 65536)
        req = bytes([unit, 6]) + addr.to_bytes(2, "big") + value.to_bytes(2, "big")
        return req, req
    if pick < 0.95:
        qty = rng.randrange(1, 12)
        values = bytes(rng.getrandbits(8) for _ in range(2 * qty))
        head = bytes([unit, 16]) + addr.to_bytes(2, "big") + qty.to_bytes(2, "big")
        return head + bytes([2 * qty]) + values, head
    if pick < 0.98:
        value = rng.choice((0xFF00, 0x0000))
        req = bytes([unit, 5]) + addr.to_bytes(2, "big") + value.to_bytes(2, "big")
        return req, req
    qty = rng.randrange(1, 30)
    req = bytes([unit, 15]) + addr.to_bytes(2, "big") + qty.to_bytes(2, "big")
    nbytes = (qty + 7) // 8
    req += bytes([nbytes]) + bytes(rng.getrandbits(8) for _ in range(nbytes))
    return req, req[:6]


def polling_frames(
    n_frames: int,
    *,
    seed: int = 1,
    line: LineSettings | None = None,
    units: tuple[int, ...] = (1, 2, 3, 5, 7, 11, 17, 32),
) -> list[SynthFrame]:
    """About `n_frames` frames of a master polling `units`, with wire timing."""
    line = line or LineSettings(baud=115200, parity="N", stopbits=1, mode="rtu")
    rng = random.Random(seed)
    char = line.char_time
    t = 0.0
    frames: list[SynthFrame] = []
    while len(frames) < n_frames:
        unit = rng.choice(units)
        req, resp = _request(rng, unit)
        req = with_crc(req)
        frames.append(SynthFrame(req, "request", t))
        t += len(req) * char + line.t35 * rng.uniform(1.0, 1.3)
        fate = rng.random()
        if fate < 0.01:  # silent slave
            t += 0.05
            continue
        if fate < 0.03:
            code = rng.choice((1, 2, 3, 4, 6))
            answer = with_crc(bytes([unit, req[1] | 0x80, code]))
            role = "exception"
        else:
            answer = with_crc(resp) if resp is not None else b""
            role = "response"
        if answer:
            t += rng.uniform(0.5, 3.0) * char  # slaves answer inside t3.5
            frames.append(SynthFrame(answer, role, t))
            t += len(answer) * char
        t += line.t35 * rng.uniform(1.0, 2.0)
    return frames[:n_frames]


def clean_chunks(frames: list[SynthFrame], line: LineSettings) -> Iterator[Chunk]:
    """Each frame as its own chunk with exact times, as a logic analyser would see it."""
    char = line.char_time
    for f in frames:
        yield Chunk(f.raw, t_start=f.t, t_end=f.t + len(f.raw) * char)


@dataclass(frozen=True, slots=True)
class Stress:
    chunks: list[Chunk]
    intact: list[bytes]  # frames delivered unchanged, in order
    damaged: int  # frames with a flipped bit
    stray: int  # frames preceded by stray bytes
    zeros: int  # frames followed by 0x00 bytes


def stress_stream(
    frames: list[SynthFrame],
    *,
    seed: int = 2,
    burst: float = 0.016,
    stray_rate: float = 0.05,
    zero_rate: float = 0.05,
    flip_rate: float = 0.01,
) -> Stress:
    """The frames as a USB adapter with a 16 ms latency timer delivers them: bytes in
    bursts sharing one timestamp (no usable gaps), stray bytes before some frames, 0x00
    bytes after some (transceiver turn-off), single bit flips in some."""
    rng = random.Random(seed)
    stream = bytearray()
    times: list[float] = []
    intact: list[bytes] = []
    damaged = stray = zeros = 0
    for f in frames:
        if rng.random() < stray_rate:
            n = rng.randrange(1, 4)
            stream += bytes(rng.getrandbits(8) for _ in range(n))
            times += [f.t] * n
            stray += 1
        raw = bytearray(f.raw)
        if rng.random() < flip_rate:
            bit = rng.randrange(len(raw) * 8)
            raw[bit // 8] ^= 1 << (bit % 8)
            damaged += 1
        else:
            intact.append(f.raw)
        stream += raw
        times += [f.t] * len(raw)
        if rng.random() < zero_rate:
            n = rng.randrange(1, 3)
            stream += bytes(n)
            times += [f.t] * n
            zeros += 1
    chunks: list[Chunk] = []
    start = 0
    while start < len(stream):
        deadline = times[start] + burst
        stop = start
        while stop < len(stream) and times[stop] < deadline:
            stop += 1
        chunks.append(Chunk(bytes(stream[start:stop]), t_end=deadline))
        start = stop
    return Stress(chunks, intact, damaged, stray, zeros)
