"""Provides the doctor's test buses: RTU traffic with one known fault each, written as Saleae
Logic 1 CSV exports (one row per byte, exact times), so every timing the doctor judges is
in the file. `python -m tests.analysis.test_doctor_bus tests/captures/doctor` writes them all;
tests/captures/doctor/README.md says what each holds."""

from __future__ import annotations

import random
import struct
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from dissectors.checks import lrc, with_crc
from sniffer.model import LineSettings

LINE = LineSettings(baud=19200, bytesize=8, parity="E", stopbits=1, mode="rtu")
CHAR = LINE.char_time
TIMEOUT = 0.3  # the simulated master's response timeout
PERIOD = 0.5
CYCLES = 40


def read_req(unit: int, fc: int, address: int, count: int) -> bytes:
    return with_crc(struct.pack(">BBHH", unit, fc, address, count))


def read_ans(unit: int, fc: int, words: list[int]) -> bytes:
    data = b"".join(struct.pack(">H", w & 0xFFFF) for w in words)
    return with_crc(bytes([unit, fc, len(data)]) + data)


@dataclass
class Bus:
    """Bytes on one wire with their start times, in order."""

    rng: random.Random = field(default_factory=lambda: random.Random(5))
    bytes_at: list[tuple[float, int]] = field(default_factory=list)
    t: float = 0.1
    text: str = ""  # the export as a decoder wrote it, when not one row per byte sent

    def send(self, data: bytes, gap_after: int = -1, pause: float = 0.0) -> None:
        """Put `data` on the wire from now; `pause` seconds of silence after byte
        `gap_after` (a converter sending in chunks)."""
        for k, b in enumerate(data):
            self.bytes_at.append((self.t, b))
            self.t += CHAR
            if k == gap_after:
                self.t += pause

    def wait(self, seconds: float) -> None:
        self.t += seconds

    def poll(self, req: bytes, ans: bytes | None, latency: float) -> None:
        """A transaction: the request, then the answer after `latency` (None: the
        master waits out its timeout), then the master's own pause."""
        self.send(req)
        if ans is None:
            self.wait(TIMEOUT)
            return
        self.wait(latency * self.rng.uniform(0.95, 1.05))
        self.send(ans)
        self.wait(0.004)

    def csv(self) -> str:
        if self.text:
            return self.text
        lines = ["Time [s],Value,Parity Error,Framing Error"]
        lines += [f"{t:.9f},0x{b:02X},," for t, b in self.bytes_at]
        return "\n".join(lines) + "\n"


def _values(unit: int, cycle: int, count: int) -> list[int]:
    return [(unit * 100 + k + (cycle % 3 if k == 0 else 0)) for k in range(count)]


def healthy_cycle(bus: Bus, cycle: int, skip: tuple[int, ...] = ()) -> None:
    """The clean bus: units 1-3 polled once a cycle, each answering at its own pace."""
    if 1 not in skip:
        bus.poll(read_req(1, 3, 0, 10), read_ans(1, 3, _values(1, cycle, 10)), 0.008)
    if 2 not in skip:
        bus.poll(read_req(2, 4, 0, 4), read_ans(2, 4, _values(2, cycle, 4)), 0.012)
    if 3 not in skip:
        bus.poll(read_req(3, 3, 100, 2), read_ans(3, 3, _values(3, cycle, 2)), 0.005)


def _run(each: Callable[[Bus, int], None]) -> Bus:
    bus = Bus()
    for cycle in range(CYCLES):
        start = 0.1 + cycle * PERIOD
        bus.t = max(bus.t, start)
        each(bus, cycle)
    return bus


def clean() -> Bus:
    return _run(healthy_cycle)


def silent_unit() -> Bus:
    def each(bus: Bus, cycle: int) -> None:
        healthy_cycle(bus, cycle)
        bus.poll(read_req(7, 3, 0, 2), None, 0)

    return _run(each)


def intermittent_unit() -> Bus:
    def each(bus: Bus, cycle: int) -> None:
        healthy_cycle(bus, cycle, skip=(2,))
        missed = 20 <= cycle < 26 or cycle == 5
        bus.poll(read_req(2, 4, 0, 4), None if missed else read_ans(2, 4, [1, 2, 3, 4]), 0.012)

    return _run(each)


def slow_answers() -> Bus:
    def each(bus: Bus, cycle: int) -> None:
        healthy_cycle(bus, cycle, skip=(3,))
        latency = 0.080 if cycle % 4 == 1 else 0.005
        bus.poll(read_req(3, 3, 100, 2), read_ans(3, 3, [7, 8]), latency)

    return _run(each)


def address_conflict() -> Bus:
    """Two devices set to address 5: one answers in 4 ms, the other in about 30 ms; now
    one, now the other, sometimes both."""

    def each(bus: Bus, cycle: int) -> None:
        healthy_cycle(bus, cycle)
        req = read_req(5, 3, 0, 2)
        a, b = read_ans(5, 3, [11, 12]), read_ans(5, 3, [900, 901])
        bus.send(req)
        if cycle % 3 == 0:
            bus.wait(0.004)
            bus.send(a)
            bus.wait(0.025)
            bus.send(b)
        elif cycle % 3 == 1:
            bus.wait(0.004)
            bus.send(a)
        else:
            bus.wait(0.030)
            bus.send(b)
        bus.wait(0.004)

    return _run(each)


def two_masters() -> Bus:
    """A second master polls unit 3 on its own: every other cycle its request goes out
    while the first master still waits for unit 1's answer."""

    def each(bus: Bus, cycle: int) -> None:
        req1, ans1 = read_req(1, 3, 0, 10), read_ans(1, 3, _values(1, cycle, 10))
        req3, ans3 = read_req(3, 3, 100, 2), read_ans(3, 3, [5, 6])
        if cycle % 2 == 0:
            bus.send(req1)
            bus.wait(0.001)
            bus.send(req3)  # the second master, unaware of the open transaction
            bus.wait(0.003)
            bus.send(ans1)
            bus.wait(0.003)
            bus.send(ans3)
            bus.wait(0.004)
        else:
            bus.poll(req1, ans1, 0.008)
            bus.poll(req3, ans3, 0.005)
        bus.poll(read_req(2, 4, 0, 4), read_ans(2, 4, _values(2, cycle, 4)), 0.012)

    return _run(each)


def line_overload() -> Bus:
    """Four units, each read 60 registers at a time, polled back to back: the cycle
    takes all the time there is."""
    bus = Bus()
    for cycle in range(12):
        for unit in (1, 2, 3, 4):
            bus.poll(read_req(unit, 3, 0, 60), read_ans(unit, 3, _values(unit, cycle, 60)), 0.01)
    return bus


def errors_follow_station() -> Bus:
    """Unit 2's transmitter rings after it sends: garbage bytes after its answers, and
    some of its answers damaged."""

    def each(bus: Bus, cycle: int) -> None:
        healthy_cycle(bus, cycle, skip=(2,))
        ans = bytearray(read_ans(2, 4, _values(2, cycle, 4)))
        bus.send(read_req(2, 4, 0, 4))
        bus.wait(0.012)
        if cycle % 5 == 2:
            ans[4] ^= 0x21
        bus.send(bytes(ans))
        if cycle % 3 == 0:
            bus.wait(0.0002)
            bus.send(b"\xff\xf0\xfe")
        bus.wait(0.004)

    return _run(each)


def exception_poll() -> Bus:
    def each(bus: Bus, cycle: int) -> None:
        healthy_cycle(bus, cycle)
        bus.poll(read_req(3, 3, 0x0100, 2), with_crc(bytes([3, 0x83, 2])), 0.005)

    return _run(each)


def _even(b: int) -> int:
    return b | (bin(b).count("1") & 1) << 7


def wrong_line_settings() -> Bus:
    """A Modbus ASCII line at 7E1 (unit 1 polled), recorded by an analyser set to 8N1:
    each character's parity bit lands in bit 7."""
    bus = Bus()
    for cycle in range(20):
        body_req = struct.pack(">BBHH", 1, 3, 0, 2)
        body_ans = bytes([1, 3, 4]) + struct.pack(">HH", 10 + cycle, 20)
        for body, wait in ((body_req, 0.02), (body_ans, 0.2)):
            frame = b":" + (body + bytes([lrc(body)])).hex().upper().encode() + b"\r\n"
            bus.send(bytes(_even(c) for c in frame))
            bus.wait(wait)
    return bus


def _uart_bits(data: bytes) -> list[int]:
    """8E1 characters as line levels, one per bit: start 0, data LSB first, even parity,
    stop 1."""
    bits: list[int] = []
    for b in data:
        word = [(b >> k) & 1 for k in range(8)]
        bits += [0, *word, sum(word) & 1, 1]
    return bits


def wrong_baud() -> Bus:
    """The clean bus's traffic sent at 9600 8E1 and recorded by an analyser set to 19200
    8E1: a UART sampling at twice the speed, bit by bit (bytes, parity and framing errors
    as such an analyser reports them)."""
    sent = 9600
    levels: list[tuple[float, int]] = []  # (time, level) at each bit boundary
    bus = clean()
    # regroup the clean bus's bytes into frames by their start times, re-timed at 9600
    t_prev = None
    for t, b in bus.bytes_at[:1200]:
        start = t * (19200 / sent) if t_prev is None else max(t * 2, levels[-1][0] + 1 / sent)
        t_prev = t
        for k, level in enumerate(_uart_bits(bytes([b]))):
            levels.append((start + k / sent, level))
    out = Bus()
    bit = 1 / 19200
    rows: list[tuple[float, int, bool, bool]] = []
    k = 0
    n = len(levels)

    def level_at(when: float) -> int:
        nonlocal k
        while k + 1 < n and levels[k + 1][0] <= when:
            k += 1
        return levels[k][1] if levels[k][0] <= when else 1

    t = levels[0][0]
    end = levels[-1][0] + 1 / sent
    while t < end:
        if level_at(t) == 1:
            t += bit / 8  # idle: look for the next start bit
            continue
        samples = [level_at(t + (j + 0.5) * bit) for j in range(11)]
        word = samples[1:9]
        value = sum(v << j for j, v in enumerate(word))
        parity_bad = (sum(word) & 1) != samples[9]
        framing_bad = samples[10] != 1
        rows.append((t, value, parity_bad, framing_bad))
        t += 10.5 * bit
    lines = ["Time [s],Value,Parity Error,Framing Error"]
    for when, value, parity_bad, framing_bad in rows:
        p, f = ("Error" if parity_bad else ""), ("Error" if framing_bad else "")
        lines.append(f"{when:.9f},0x{value:02X},{p},{f}")
    out.text = "\n".join(lines) + "\n"
    return out


def timing_violation() -> Bus:
    """The master's converter pauses 2 ms inside every request (t1.5 at 19200 baud is
    0.86 ms), and unit 3 answers 0.5 ms after its request (t3.5 is 2 ms)."""

    def each(bus: Bus, cycle: int) -> None:
        bus.send(read_req(1, 3, 0, 10), gap_after=3, pause=0.002)
        bus.wait(0.008)
        bus.send(read_ans(1, 3, _values(1, cycle, 10)))
        bus.wait(0.004)
        bus.send(read_req(3, 3, 100, 2))
        bus.wait(0.0005)
        bus.send(read_ans(3, 3, [1, 2]))
        bus.wait(0.004)

    return _run(each)


def write_effect() -> Bus:
    """The master writes 500 to holding 5 of unit 1 at cycle 20; the poll of holding
    0-9 shows it from the next cycle on."""
    value = [100]

    def each(bus: Bus, cycle: int) -> None:
        words = [100 + k for k in range(10)]
        words[5] = value[0]
        bus.poll(read_req(1, 3, 0, 10), read_ans(1, 3, words), 0.008)
        healthy_cycle(bus, cycle, skip=(1,))
        if cycle == 20:
            write = with_crc(struct.pack(">BBHH", 1, 6, 5, 500))
            bus.poll(write, write, 0.01)
            value[0] = 500

    return _run(each)


# name -> (builder, the settings to read it with beyond 19200 8E1, expected findings)
BUSES: dict[str, tuple[Callable[[], Bus], tuple[str, ...]]] = {
    "clean": (clean, ()),
    "silent-unit": (silent_unit, ()),
    "intermittent-unit": (intermittent_unit, ()),
    "slow-answers": (slow_answers, ()),
    "address-conflict": (address_conflict, ()),
    "two-masters": (two_masters, ()),
    "line-overload": (line_overload, ()),
    "errors-follow-station": (errors_follow_station, ()),
    "exception-poll": (exception_poll, ()),
    "wrong-line-settings": (wrong_line_settings, ("--parity", "N")),
    "wrong-baud": (wrong_baud, ()),
    "timing-violation": (timing_violation, ()),
    "write-effect": (write_effect, ()),
}


def write_all(folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name, (build, _) in BUSES.items():
        (folder / f"{name}.csv").write_text(build().csv())


if __name__ == "__main__":
    write_all(Path(sys.argv[1]))
