"""Provides synthetic Modbus traffic: a polling mix for benchmarks and a hostile stress stream.

Deterministic for a given seed. The polling mix is what a SCADA master does all day
(a fixed poll table per unit, mostly FC 3/4 reads of a few to a few dozen registers and
some coil and input reads, repeated every cycle while the values drift; writes now and
then, an exception or a silent slave rarely); the stress stream then
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


def _read(rng: random.Random, unit: int) -> tuple[bytes, bytearray]:
    """A read a master polls: the request, and the data of its answer (which drifts)."""
    addr = rng.randrange(0, 2000)
    if rng.random() < 0.85:
        fc = 3 if rng.random() < 0.7 else 4
        qty = rng.choice((2, 4, 8, 10, 12, 16, 20, 25, 30, 40, 50, 60))
        data = bytearray(rng.getrandbits(8) for _ in range(2 * qty))
    else:
        fc = rng.choice((1, 2))
        qty = rng.randrange(1, 64)
        data = bytearray(rng.getrandbits(8) for _ in range((qty + 7) // 8))
        if qty % 8:
            data[-1] &= (1 << (qty % 8)) - 1
    req = bytes([unit, fc]) + addr.to_bytes(2, "big") + qty.to_bytes(2, "big")
    return req, data


def _write(rng: random.Random, unit: int) -> tuple[bytes, bytes]:
    """A write now and then: the request and its normal answer."""
    pick = rng.random()
    addr = rng.randrange(0, 2000)
    if pick < 0.5:
        value = rng.randrange(0, 65536)
        req = bytes([unit, 6]) + addr.to_bytes(2, "big") + value.to_bytes(2, "big")
        return req, req
    if pick < 0.75:
        qty = rng.randrange(1, 12)
        values = bytes(rng.getrandbits(8) for _ in range(2 * qty))
        head = bytes([unit, 16]) + addr.to_bytes(2, "big") + qty.to_bytes(2, "big")
        return head + bytes([2 * qty]) + values, head
    if pick < 0.9:
        value = rng.choice((0xFF00, 0x0000))
        req = bytes([unit, 5]) + addr.to_bytes(2, "big") + value.to_bytes(2, "big")
        return req, req
    qty = rng.randrange(1, 30)
    req = bytes([unit, 15]) + addr.to_bytes(2, "big") + qty.to_bytes(2, "big")
    nbytes = (qty + 7) // 8
    req += bytes([nbytes]) + bytes(rng.getrandbits(8) for _ in range(nbytes))
    return req, req[:6]


def _drift(rng: random.Random, data: bytearray, fc: int) -> None:
    """Between two polls a few values change (measurements), most stay (setpoints)."""
    if fc in (3, 4):
        for k in range(0, len(data), 2):
            if rng.random() < 0.05:
                data[k + 1] = (data[k + 1] + rng.choice((1, 255))) & 0xFF
    elif rng.random() < 0.05:
        data[0] ^= 1 << rng.randrange(min(8, 1 + data[0].bit_length()))


def polling_frames(
    n_frames: int,
    *,
    seed: int = 1,
    line: LineSettings | None = None,
    units: tuple[int, ...] = (1, 2, 3, 4, 5, 6, 7, 8, 11, 12, 17, 21, 32, 33, 40, 41),
) -> list[SynthFrame]:
    """About `n_frames` frames of a master polling `units`, with wire timing.

    Like a SCADA master: each unit has a poll table of two to five reads, repeated
    every cycle with the same request bytes while the answers drift; a write now and
    then; an exception or a silent slave rarely.
    """
    line = line or LineSettings(baud=115200, parity="N", stopbits=1, mode="rtu")
    rng = random.Random(seed)
    char = line.char_time
    tables = {u: [_read(rng, u) for _ in range(rng.randrange(2, 6))] for u in units}
    t = 0.0
    frames: list[SynthFrame] = []

    def exchange(req: bytes, resp: bytes) -> None:
        nonlocal t
        req = with_crc(req)
        frames.append(SynthFrame(req, "request", t))
        t += len(req) * char + line.t35 * rng.uniform(1.0, 1.3)
        fate = rng.random()
        if fate < 0.01:  # silent slave
            t += 0.05
            return
        if fate < 0.03:
            code = rng.choice((1, 2, 3, 4, 6))
            answer = with_crc(bytes([req[0], req[1] | 0x80, code]))
            role = "exception"
        else:
            answer = with_crc(resp)
            role = "response"
        t += rng.uniform(0.5, 3.0) * char  # slaves answer inside t3.5
        frames.append(SynthFrame(answer, role, t))
        t += len(answer) * char + line.t35 * rng.uniform(1.0, 2.0)

    while len(frames) < n_frames:
        for unit in units:
            for req, data in tables[unit]:
                _drift(rng, data, req[1])
                exchange(req, bytes([unit, req[1], len(data)]) + bytes(data))
            if rng.random() < 0.1:
                exchange(*_write(rng, unit))
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
