"""A UART model for tests: Modbus traffic put on a wire at its true line settings, and
read back by a receiver at any other setting, as a real UART would read it.

The sender turns each character into bits (start 0, data LSB first, parity, stop 1s) at
the true baud rate; the line idles high between frames. The receiver hunts for a falling
edge, checks the start bit half a bit later, samples each data bit in its middle, then
the parity bit and the first stop bit at its own baud rate and format: a low stop bit is
a framing error, a wrong parity bit a parity error, and the byte is delivered anyway
(pyserial's raw mode does not drop or mark it). Hunting resumes from the middle of the
stop bit, so at the wrong speed start bits are found inside characters, as on a real
line.

Two receiver behaviours differ after a framing error. A plain receiver hunts for the
next falling edge. A 16550-family receiver (the PC's UART and many adapters) takes the
low level it found where the stop bit should be for the next start bit and reads the
next character from there ("resynchronises"): at 8N1 on an 8E1 line a parity bit of 0
starts a new character in the middle of the real one, and the bytes come out garbled,
where a plain receiver reads them cleanly. And drivers differ in what they count: most
report framing and parity errors, some (CP210x adapters) report none at all although
their ioctl answers, and a pseudo-terminal has no counters.
"""

from __future__ import annotations

import bisect
import os
from dataclasses import dataclass, field
from typing import Any

import serial

from dissectors.checks import lrc, with_crc
from sniffer.live.scan import Sample
from sniffer.model import Chunk, LineSettings
from tests.support.virtual_bus import Tripwire


def character_bits(byte: int, line: LineSettings) -> list[int]:
    """The levels of one character on the wire, one per bit time."""
    data = [(byte >> i) & 1 for i in range(line.bytesize)]
    bits = [0, *data]
    if line.parity != "N":
        ones = sum(data)
        bits.append(ones & 1 if line.parity == "E" else 1 - (ones & 1))
    return bits + [1] * line.stopbits


def modbus_cycle(
    line: LineSettings, ascii_mode: bool = False
) -> tuple[list[tuple[float, bytes]], float]:
    """One poll cycle at `line`: three units read (FC 3), each answering after a few
    character times; returns (offset, frame) pairs and the cycle's period."""
    out: list[tuple[float, bytes]] = []
    t = 0.0
    gap = max(5 * line.char_time, 0.002)
    for unit in (1, 2, 3):
        request = bytes([unit, 3, 0, 0, 0, 4])
        answer = bytes([unit, 3, 8, *[unit * 16 + k for k in range(8)]])
        for body in (request, answer):
            if ascii_mode:
                frame = b":" + (body + bytes([lrc(body)])).hex().upper().encode() + b"\r\n"
            else:
                frame = with_crc(body)
            out.append((t, frame))
            t += len(frame) * line.char_time + gap
    return out, t + 4 * gap


@dataclass
class Wire:
    """A line carrying `cycle` (offsets in seconds, frames) every `period` seconds."""

    line: LineSettings
    cycle: list[tuple[float, bytes]]
    period: float = 0.1
    edges: list[float] = field(default_factory=list)  # times of every level change
    falling: list[float] = field(default_factory=list)  # times of changes to low
    rendered_until: float = 0.0

    def render(self, until: float) -> None:
        """Draw the waveform up to `until` seconds."""
        bit = 1 / self.line.baud
        while self.rendered_until < until:
            base = self.rendered_until
            for offset, frame in self.cycle:
                t = base + offset
                level = 1
                for byte in frame:
                    for b in character_bits(byte, self.line):
                        if b != level:
                            self.edges.append(t)
                            if b == 0:
                                self.falling.append(t)
                            level = b
                        t += bit
                if level != 1:  # a stop bit always ends high; kept for safety
                    self.edges.append(t)
            self.rendered_until = base + self.period

    def level(self, t: float) -> int:
        """1 on an idle line; edges alternate starting from high."""
        return 1 if bisect.bisect_right(self.edges, t) % 2 == 0 else 0

    def receive(
        self, line: LineSettings, t0: float, t1: float, resync: bool = False
    ) -> tuple[list[tuple[float, int]], int, int]:
        """Bytes (with the time of their stop bit) a receiver at `line` reads in [t0, t1),
        and its framing and parity error counts; `resync` for a 16550-family receiver."""
        self.render(t1 + 0.05)
        bit = 1 / line.baud
        got: list[tuple[float, int]] = []
        framing = parity = 0
        t = t0
        forced: float | None = None  # a start bit a 16550 took from a missing stop bit
        while True:
            if forced is not None:
                start, forced = forced, None
                if start >= t1:
                    break
            else:
                k = bisect.bisect_left(self.falling, t)
                if k == len(self.falling):
                    break
                start = self.falling[k]
                if start >= t1:
                    break
                if self.level(start + bit / 2) != 0:  # a glitch, not a start bit
                    t = start + bit / 2
                    continue
            value = 0
            ones = 0
            for i in range(line.bytesize):
                b = self.level(start + (1.5 + i) * bit)
                value |= b << i
                ones += b
            at = start + (1.5 + line.bytesize) * bit
            if line.parity != "N":
                p = self.level(at)
                want = ones & 1 if line.parity == "E" else 1 - (ones & 1)
                parity += p != want
                at += bit
            if self.level(at) == 0:
                framing += 1
                if resync:
                    forced = at - bit / 2
            got.append((at + bit / 2, value))
            t = at
        return got, framing, parity


@dataclass
class GarbledLine:
    """`listen(line, seconds)` for `sniffer.live.scan.scan`: what a receiver at `line` reads
    from the wire in the next `seconds` of (simulated) time, as read-sized chunks."""

    wire: Wire
    now: float = 0.003  # not on a character boundary
    heard: list[LineSettings] = field(default_factory=list)
    counters: str = "counting"  # "counting", "zero" (CP210x) or "none" (a pty)
    resync: bool = False  # a 16550-family receiver

    def __call__(self, line: LineSettings, seconds: float) -> Sample:
        self.heard.append(line)
        got, framing, parity = self.wire.receive(
            line, self.now, self.now + seconds, resync=self.resync
        )
        self.now += seconds
        chunks: list[Chunk] = []
        block = bytearray()
        block_end = 0.0
        for t, value in got:  # reads of 4 ms, like a USB adapter's bursts
            if block and t > block_end:
                chunks.append(Chunk(bytes(block), block_end))
                block = bytearray()
            if not block:
                block_end = t + 0.004
            block.append(value)
        if block:
            chunks.append(Chunk(bytes(block), block_end))
        if self.counters == "none":
            return Sample(tuple(chunks), seconds)
        if self.counters == "zero":
            return Sample(tuple(chunks), seconds, 0, 0)
        return Sample(tuple(chunks), seconds, framing, parity)


class GarblingPort(Tripwire):
    """A serial port double on a wire: when it opens, it holds what a UART at its own
    settings would read from the wire in the next `window` seconds. Everything that
    could drive the line raises (see Tripwire)."""

    def __init__(self, wire: Wire, window: float, start: float, resync: bool = False) -> None:
        self.wire = wire
        self.window = window
        self.start = start
        self.resync = resync
        self.framing = 0
        self.parity_count = 0
        super().__init__()

    def open(self) -> None:
        super().open()
        line = LineSettings(
            int(self.baudrate), int(self.bytesize), str(self.parity), int(self.stopbits)
        )
        got, self.framing, self.parity_count = self.wire.receive(
            line, self.start, self.start + self.window, resync=self.resync
        )
        data = bytes(v for _t, v in got)
        if data:
            os.write(self.feed_fd, data)


class GarblingPorts:
    """A port factory for `PortListener`: each open is a fresh stretch of the wire."""

    def __init__(self, wire: Wire, window: float = 0.3, resync: bool = False) -> None:
        self.wire = wire
        self.window = window
        self.resync = resync
        self.ports: list[GarblingPort] = []
        self.asked: set[int] = set()

    def __call__(self, name: str) -> serial.Serial:
        start = 0.003 + len(self.ports) * self.window
        port = GarblingPort(self.wire, self.window, start, self.resync)
        self.ports.append(port)
        return port

    def counters(self, port: Any) -> tuple[int, int] | None:
        """Driver counters as the double counted them: zero before, its own after."""
        if not isinstance(port, GarblingPort):
            return None
        if id(port) not in self.asked:
            self.asked.add(id(port))
            return (0, 0)
        return (port.framing, port.parity_count)

    def violations(self) -> list[str]:
        return [v for p in self.ports for v in p.violations]
