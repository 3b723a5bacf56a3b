"""Provides bus mixes the benchmarks were not tuned on: random polling buses, seeded.

A mix is a bus drawn at random: how many slaves and at which addresses, which function
codes (1, 2, 3, 4, 5, 6, 15, 16) in which proportions, 1-60 registers or 8-200 bits a
poll, fresh values in every answer, how often a slave answers with an exception or not
at all, stray bytes between frames, the line's baud rate and format, and how the reads
of a capture cut the bytes: 16 ms reads of a USB adapter (a frame split wherever a read
ends), reads of random sizes, or one frame per packet. The traffic is made here, not by
`sniffer.sources.synth.polling_frames` (the project's own stream, kept as the mix
"project"), so a figure taken over mixes says how modscope does on buses it has not seen.
"""

from __future__ import annotations

import random
from bisect import bisect_right
from dataclasses import dataclass
from pathlib import Path

from benchmarks.common import Unflushed, usb_reads
from dissectors.checks import with_crc
from sniffer.live.port import PortSpec
from sniffer.live.recorder import Recorder
from sniffer.model import Chunk, LineSettings
from sniffer.sources.linktypes import LINKTYPE_RTAC_SERIAL, RTAC_DATA_RX_START
from sniffer.sources.pcapng_writer import (
    EPB_FLAG_INBOUND,
    PcapngWriter,
    describe_interface,
    rtac_record,
)
from sniffer.sources.synth import polling_frames

START = 1768464000.0  # 2026-01-15 08:00:00 UTC, as the demo
CODES = (1, 2, 3, 4, 5, 6, 15, 16)
USB_LATENCY = 0.016  # an FTDI adapter's default latency timer
BAUDS = (9600, 19200, 38400, 57600, 115200)


@dataclass(frozen=True, slots=True)
class Mix:
    """One bus: its slaves, codes, faults and line, and how its capture was read."""

    name: str
    seed: int
    line: LineSettings
    units: tuple[int, ...]
    weights: tuple[float, ...]  # one per code of CODES
    exception_rate: float
    timeout_rate: float
    noise_rate: float  # stray bytes after this share of frames
    reads: str  # "usb": 16 ms reads; "random": reads of 1..read_max bytes
    read_max: int = 0
    project: bool = False  # the project's own stream (synth.polling_frames, whole frames)

    def describe(self) -> str:
        if self.project:
            return "the project's own stream (synth.polling_frames), 16 ms reads of whole frames"
        codes = ",".join(str(c) for c, w in zip(CODES, self.weights, strict=True) if w > 0)
        line = self.line
        reads = "16 ms reads" if self.reads == "usb" else f"reads of 1-{self.read_max} bytes"
        return (
            f"{len(self.units)} slaves, FC {codes}, exceptions {self.exception_rate:.1%}, "
            f"timeouts {self.timeout_rate:.1%}, noise {self.noise_rate:.1%}, "
            f"{line.baud} {line.bytesize}{line.parity}{line.stopbits}, {reads}"
        )


def project_mix() -> Mix:
    line = LineSettings(baud=115200, bytesize=8, parity="N", stopbits=1, mode="rtu")
    return Mix("project", 1, line, (), (), 0.02, 0.01, 0.0, "usb", project=True)


def issue_mix() -> Mix:
    """The bus of issue #29: 9 slaves, FC 1-6, 15, 16, about 3% exceptions and 1%
    timeouts, 115200 8E1, 16 ms reads."""
    line = LineSettings(baud=115200, bytesize=8, parity="E", stopbits=1, mode="rtu")
    return Mix(
        "issue29",
        29,
        line,
        (1, 2, 3, 5, 8, 10, 17, 21, 30),
        (0.08, 0.08, 0.35, 0.25, 0.06, 0.08, 0.04, 0.06),
        0.03,
        0.01,
        0.0,
        "usb",
    )


def random_mix(seed: int) -> Mix:
    """A bus drawn at random from `seed`."""
    rng = random.Random(seed)
    n_units = rng.choice((1, 2, 3, 5, 9, 16, 32))
    units = tuple(sorted(rng.sample(range(1, 248), n_units)))
    weights = [rng.random() ** 2 if rng.random() < 0.75 else 0.0 for _ in CODES]
    if not any(weights[:4]):
        weights[rng.randrange(4)] = 1.0  # a master reads something
    parity = rng.choice("NEO")
    line = LineSettings(
        baud=rng.choice(BAUDS),
        bytesize=8,
        parity=parity,
        stopbits=rng.choice((1, 2)) if parity == "N" else 1,
        mode="rtu",
    )
    reads = rng.choice(("usb", "usb", "random"))
    return Mix(
        f"mix{seed}",
        seed,
        line,
        units,
        tuple(weights),
        rng.choice((0.0, 0.01, 0.03, 0.06)),
        rng.choice((0.0, 0.005, 0.01, 0.03)),
        rng.choice((0.0, 0.0, 0.001, 0.01)),
        reads,
        rng.choice((8, 64, 256, 1024)) if reads == "random" else 0,
    )


def mixes(count: int, seed: int) -> list[Mix]:
    """The project's stream, the bus of issue #29, then random buses: `count` in all."""
    fixed = [project_mix(), issue_mix()]
    rng = random.Random(seed)
    drawn = [random_mix(rng.randrange(1 << 30)) for _ in range(max(0, count - len(fixed)))]
    return (fixed + drawn)[: max(count, 1)]


@dataclass(frozen=True, slots=True)
class Wire:
    """Bytes on the line from time `t` (a frame, or stray bytes when `frame` is False)."""

    raw: bytes
    t: float
    frame: bool = True


def _poll(rng: random.Random, unit: int, fc: int) -> tuple[int, int, int]:
    """A poll table entry: (code, address, quantity)."""
    addr = rng.randrange(0, 10000)
    if fc in (3, 4, 16):
        return fc, addr, rng.randint(1, 60)
    if fc in (1, 2, 15):
        return fc, addr, rng.randint(8, 200)
    return fc, addr, 1


def _exchange(rng: random.Random, unit: int, entry: tuple[int, int, int]) -> tuple[bytes, bytes]:
    """A request and its normal answer, with fresh values."""
    fc, addr, qty = entry
    head = bytes([unit, fc]) + addr.to_bytes(2, "big")
    if fc in (1, 2):
        data = bytearray(rng.randbytes((qty + 7) // 8))
        if qty % 8:
            data[-1] &= (1 << (qty % 8)) - 1
        return head + qty.to_bytes(2, "big"), bytes([unit, fc, len(data)]) + data
    if fc in (3, 4):
        return head + qty.to_bytes(2, "big"), bytes([unit, fc, 2 * qty]) + rng.randbytes(2 * qty)
    if fc == 5:
        req = head + rng.choice((b"\xff\x00", b"\x00\x00"))
        return req, req
    if fc == 6:
        req = head + rng.randbytes(2)
        return req, req
    count = head + qty.to_bytes(2, "big")
    nbytes = (qty + 7) // 8 if fc == 15 else 2 * qty
    return count + bytes([nbytes]) + rng.randbytes(nbytes), count


def mix_frames(mix: Mix, n: int) -> list[Wire]:
    """About `n` frames of the mix's bus (stray bytes besides), with wire times."""
    if mix.project:
        return [Wire(f.raw, f.t) for f in polling_frames(n, line=mix.line)]
    rng = random.Random(mix.seed)
    char = mix.line.char_time
    t35 = mix.line.t35
    tables = {
        u: [_poll(rng, u, rng.choices(CODES, mix.weights)[0]) for _ in range(rng.randint(1, 6))]
        for u in mix.units
    }
    delay = rng.uniform(0.001, 0.02)  # the slowest slave's answer time
    timeout = rng.choice((0.1, 0.2, 0.5))  # the master's response timeout
    out: list[Wire] = []
    t = 0.0
    frames = 0
    while frames < n:
        for unit in mix.units:
            for entry in tables[unit]:
                req, answer = _exchange(rng, unit, entry)
                req = with_crc(req)
                out.append(Wire(req, t))
                frames += 1
                t += len(req) * char
                fate = rng.random()
                if fate < mix.timeout_rate:
                    t += timeout
                else:
                    if fate < mix.timeout_rate + mix.exception_rate:
                        answer = bytes([unit, entry[0] | 0x80, rng.choice((1, 2, 3, 4, 6))])
                    answer = with_crc(answer)
                    t += t35 + rng.uniform(0.0, delay)
                    out.append(Wire(answer, t))
                    frames += 1
                    t += len(answer) * char
                if mix.noise_rate and rng.random() < mix.noise_rate:
                    t += t35
                    stray = rng.randbytes(rng.randint(1, 3))
                    out.append(Wire(stray, t, frame=False))
                    t += len(stray) * char
                t += t35 * rng.uniform(1.0, 3.0)  # the master's gap before its next poll
    # exactly n frames (a cycle of many slaves is long: a file of 10 frames takes
    # start-up off a rate, so it must hold 10)
    seen = 0
    for i, w in enumerate(out):
        seen += w.frame
        if seen == n:
            return out[: i + 1]
    return out


def _reads(mix: Mix, wire: list[Wire]) -> list[Chunk]:
    """The bytes as the capture's reads deliver them, each stamped at its end."""
    if mix.project:
        from sniffer.sources.synth import SynthFrame

        return usb_reads([SynthFrame(w.raw, "request", w.t) for w in wire])
    char = mix.line.char_time
    data = b"".join(w.raw for w in wire)
    starts: list[int] = []
    at = 0
    for w in wire:
        starts.append(at)
        at += len(w.raw)

    def end_time(offset: int) -> float:
        """When the byte at `offset` was all received."""
        k = bisect_right(starts, offset) - 1
        return wire[k].t + (offset - starts[k] + 1) * char

    cuts: list[tuple[int, float]] = []  # (end offset, time) of each read
    if mix.reads == "usb":
        period = USB_LATENCY
        deadline = period
        for w, o in zip(wire, starts, strict=True):
            finish = w.t + len(w.raw) * char
            while deadline < finish:
                done = max(0, min(len(w.raw), int((deadline - w.t) / char)))
                cut = o + done
                if not cuts or cut > cuts[-1][0]:
                    cuts.append((cut, deadline))
                deadline += period if done else max(1, int((w.t - deadline) / period)) * period
        if not cuts or cuts[-1][0] < len(data):
            cuts.append((len(data), deadline))
    else:
        rng = random.Random(mix.seed + 1)
        cut = 0
        last = 0.0
        while cut < len(data):
            cut = min(len(data), cut + rng.randint(1, mix.read_max))
            last = max(last, end_time(cut - 1) + rng.uniform(0.0, 0.001))
            cuts.append((cut, last))
    out: list[Chunk] = []
    prev = 0
    for cut, t in cuts:
        if cut > prev:
            out.append(Chunk(data[prev:cut], t_end=t))
            prev = cut
    return out


def write_reads(path: Path, mix: Mix, wire: list[Wire]) -> int:
    """The mix as `modscope record` writes its reads; returns how many reads."""
    stream = Unflushed(path)
    port = PortSpec("/dev/ttyUSB0", mix.line)
    recorder = Recorder(path, [port], stream=stream)  # type: ignore[arg-type]
    reads = _reads(mix, wire)
    for chunk in reads:
        recorder.write(Chunk(chunk.data, START + chunk.t_end))
    recorder.close(START + (reads[-1].t_end if reads else 0.0) + 0.1)
    stream.close()
    return len(reads)


def write_frames(path: Path, mix: Mix, wire: list[Wire]) -> None:
    """The same bytes one frame (or run of stray bytes) a packet: RTAC header time at the
    first byte, packet time at the last."""
    stream = Unflushed(path)
    writer = PcapngWriter(stream)  # type: ignore[arg-type]
    iface = writer.add_interface(
        LINKTYPE_RTAC_SERIAL, name="/dev/ttyUSB0", description=describe_interface(mix.line)
    )
    char = mix.line.char_time
    for w in wire:
        t0 = START + w.t
        packet = rtac_record(t0, w.raw, event=RTAC_DATA_RX_START)
        writer.write_packet(iface, t0 + len(w.raw) * char, packet, flags=EPB_FLAG_INBOUND)
    stream.close()


def write_mix(folder: Path, mix: Mix, n: int) -> tuple[Path, Path]:
    """`MIX-reads-N.pcapng` and `MIX-frames-N.pcapng` in `folder` (written unless there)."""
    folder.mkdir(parents=True, exist_ok=True)
    reads = folder / f"{mix.name}-reads-{n}.pcapng"
    one = folder / f"{mix.name}-frames-{n}.pcapng"
    if not (reads.exists() and one.exists()):
        wire = mix_frames(mix, n)
        write_reads(reads, mix, wire)
        write_frames(one, mix, wire)
    return reads, one
