"""Device maps the draft has never seen, a master polling them, and the draft's score.

Three devices, written for these tests after the kinds of map their manuals publish: an
energy meter (three-phase, f32 high word first, u32 energy counters, an s32 reactive
power, a mirror of scaled u16s, a status bit field, a model string), a photovoltaic
inverter laid out the SunSpec way (marker and identity strings, u16 values each followed
by its scale factor register, an acc32 energy counter, a 32-bit event bit field, vendor
f32 values low word first) and an air-to-water heat pump (s16 temperatures in tenths of
a degree, one below zero all the time, one crossing it, enums and a small bit field,
counters and f32 values low word first, an s32, setpoints the master writes, a firmware
string, a sensor that reads "not available").

`bus_chunks()` simulates a master polling all three over time with values that move the
way such values do (mains voltage and frequency wander, load follows a profile, counters
grow, modes change), as byte-literal RTU frames; `score()` compares a draft's guesses with
the maps.
"""

from __future__ import annotations

import math
import random
import struct
from collections.abc import Callable
from dataclasses import dataclass, field

from dissectors.checks import with_crc
from sniffer.analysis.draft import Guess
from sniffer.model import Chunk

HOLDING, INPUT = "holding_registers", "input_registers"
Signal = Callable[[int, random.Random], float | str]
"""A value at poll cycle k (the generator is the value's own, seeded)."""


@dataclass(frozen=True)
class Value:
    """One entry of a device map: where it is, what type, order and scale, and how it
    moves (`signal(k, rng)` in engineering units; a string for str)."""

    table: str
    address: int
    type: str
    signal: Signal
    word_order: str = ""
    scale: float = 1
    length: int = 0  # registers of a str

    @property
    def size(self) -> int:
        if self.type == "str":
            return self.length
        return 2 if self.type in ("u32", "s32", "f32") else 1

    def words(self, value: float | str) -> list[int]:
        if self.type == "str":
            data = str(value).encode("ascii").ljust(2 * self.length, b"\0")
            return [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]
        assert isinstance(value, (int, float))
        if self.type == "f32":
            hi, lo = struct.unpack(">HH", struct.pack(">f", value))
        else:
            raw = round(value / self.scale)
            bits = 32 if self.size == 2 else 16
            raw &= (1 << bits) - 1
            if self.size == 1:
                return [raw]
            hi, lo = raw >> 16, raw & 0xFFFF
        return [hi, lo] if self.word_order == "ABCD" else [lo, hi]


@dataclass(frozen=True)
class Poll:
    """A read the master sends every `every` cycles (from cycle `first`)."""

    table: str
    start: int
    count: int
    every: int = 1
    first: int = 0


@dataclass(frozen=True)
class Write:
    """A setpoint the master writes (FC 6) at the cycles given."""

    address: int
    at: dict[int, int]  # cycle -> raw value


@dataclass
class Device:
    name: str
    unit: int
    values: list[Value]
    polls: list[Poll]
    writes: list[Write] = field(default_factory=list)

    def at(self, table: str, address: int) -> Value | None:
        for v in self.values:
            if v.table == table and v.address <= address < v.address + v.size:
                return v
        return None


# -- signals -------------------------------------------------------------------------------


def shared(signal: Signal) -> Signal:
    """One physical value several registers show: computed once per cycle."""
    seen: dict[int, float | str] = {}

    def at(k: int, rng: random.Random) -> float | str:
        if k not in seen:
            seen[k] = signal(k, rng)
        return seen[k]

    return at


def const(value: float | str) -> Signal:
    return lambda _k, _rng: value


def wander(mean: float, swing: float, period: float, noise: float, phase: float = 0) -> Signal:
    return lambda k, rng: mean + swing * math.sin(k / period + phase) + rng.gauss(0, noise)


def load(base: float, swing: float, period: float, noise: float, floor: float = 0) -> Signal:
    return lambda k, rng: max(floor, base + swing * math.sin(k / period) + rng.gauss(0, noise))


def counter(start: int, rate: Callable[[int], float]) -> Signal:
    """A counter that adds rate(k) per cycle (whole units, the fraction carried)."""
    state = {"k": -1, "total": float(start)}

    def signal(k: int, _rng: random.Random) -> float:
        while state["k"] < k:
            state["k"] += 1
            state["total"] += rate(int(state["k"]))
        return math.floor(state["total"])

    return signal


def steps(schedule: list[tuple[int, float]]) -> Signal:
    """A value that takes schedule[i][1] from cycle schedule[i][0] on."""

    def signal(k: int, _rng: random.Random) -> float:
        value = schedule[0][1]
        for start, v in schedule:
            if k >= start:
                value = v
        return value

    return signal


def cycle_of(values: list[float], hold: int) -> Signal:
    """Each of `values` in turn, held for `hold` cycles."""
    return lambda k, _rng: values[(k // hold) % len(values)]


# -- the maps ------------------------------------------------------------------------------


def energy_meter() -> Device:
    h, i = HOLDING, INPUT
    v1, v2, v3 = wander(230, 2, 40, 0.3), wander(231, 2, 37, 0.3, 1), wander(229.5, 2, 43, 0.3, 2)
    i1, i2, i3 = load(8, 6, 25, 0.2, 0.3), load(3, 2, 19, 0.1, 0.1), load(12, 4, 31, 0.2, 0.5)
    freq = wander(50, 0.05, 15, 0.01)
    pf = wander(0.92, 0.04, 22, 0.004)
    v1, i1, freq, pf = shared(v1), shared(i1), shared(freq), shared(pf)
    power = load(5200, 2600, 25, 80, 300)
    values = [
        Value(i, 0, "f32", v1, "ABCD"),
        Value(i, 2, "f32", v2, "ABCD"),
        Value(i, 4, "f32", v3, "ABCD"),
        Value(i, 6, "f32", i1, "ABCD"),
        Value(i, 8, "f32", i2, "ABCD"),
        Value(i, 10, "f32", i3, "ABCD"),
        Value(i, 12, "f32", power, "ABCD"),
        Value(i, 14, "f32", pf, "ABCD"),
        Value(i, 16, "f32", freq, "ABCD"),
        Value(i, 18, "u32", counter(1_234_567, lambda k: 2.9), "ABCD"),  # import Wh
        Value(i, 20, "u32", const(45_678), "ABCD"),  # export Wh: no export today
        Value(i, 22, "s32", wander(0, 800, 30, 40), "ABCD"),  # reactive power, var
        Value(i, 24, "u16", steps([(0, 1), (150, 2)])),  # tariff (enum)
        # holding: the same measures as scaled integers, then setup and identity
        Value(h, 100, "u16", v1, scale=0.1),
        Value(h, 101, "u16", i1, scale=0.01),
        Value(h, 102, "u16", freq, scale=0.01),
        Value(h, 103, "s16", pf, scale=0.001),
        Value(h, 110, "u16", const(1)),  # its own address
        Value(h, 111, "u16", const(3)),  # baud rate code (enum)
        Value(h, 112, "u16", cycle_of([1, 5, 37, 33, 1, 1], 9)),  # status bits 0, 2, 5
        Value(h, 120, "str", const("EM3P-230/80 v2"), length=8),
        Value(h, 128, "u32", const(2_319_004), "ABCD"),  # serial number
    ]
    polls = [
        Poll(i, 0, 25),
        Poll(h, 100, 4),
        Poll(h, 110, 3, every=10, first=2),
        Poll(h, 120, 10, every=30, first=4),
    ]
    return Device("energy meter", 1, values, polls)


def inverter() -> Device:
    h = HOLDING
    sun = wander(0, 1, 60, 0)  # a cloud pattern: -1..1

    def current(k: int, rng: random.Random) -> float:
        return max(0.2, 9 + 4 * float(sun(k, rng)) + rng.gauss(0, 0.05))

    ac_current = shared(current)

    def times(factor: float, plus: float = 0) -> Signal:
        return lambda k, rng: factor * float(ac_current(k, rng)) + plus

    values = [
        Value(h, 40000, "str", const("SunS"), length=2),
        Value(h, 40002, "u16", const(1)),  # model id
        Value(h, 40003, "u16", const(65)),  # model length
        Value(h, 40004, "str", const("Solarix GmbH"), length=16),
        Value(h, 40020, "str", const("SX-8.0-3M"), length=16),
        Value(h, 40036, "str", const(""), length=8),  # options: empty
        Value(h, 40044, "str", const("1.4.2"), length=8),
        Value(h, 40052, "str", const("SX80A2231004417"), length=16),
        Value(h, 40068, "u16", const(2)),  # device address
        Value(h, 40069, "u16", const(103)),  # model id
        Value(h, 40070, "u16", const(50)),  # model length
        Value(h, 40071, "u16", times(3), scale=0.01),
        Value(h, 40072, "u16", ac_current, scale=0.01),
        Value(h, 40073, "u16", times(1, 0.1), scale=0.01),
        Value(h, 40074, "u16", times(1, -0.1), scale=0.01),
        Value(h, 40075, "s16", const(-2)),  # A_SF
        Value(h, 40076, "u16", wander(400, 3, 40, 0.3), scale=0.1),
        Value(h, 40077, "u16", wander(401, 3, 41, 0.3), scale=0.1),
        Value(h, 40078, "u16", wander(399, 3, 39, 0.3), scale=0.1),
        Value(h, 40079, "u16", wander(230, 2, 40, 0.2), scale=0.1),
        Value(h, 40080, "u16", wander(231, 2, 41, 0.2), scale=0.1),
        Value(h, 40081, "u16", wander(230, 2, 39, 0.2), scale=0.1),
        Value(h, 40082, "s16", const(-1)),  # V_SF
        Value(h, 40083, "s16", times(690)),  # W
        Value(h, 40084, "s16", const(0)),  # W_SF
        Value(h, 40085, "u16", wander(50, 0.04, 15, 0.01), scale=0.01),
        Value(h, 40086, "s16", const(-2)),  # Hz_SF
        *[Value(h, a, "u16", const(0)) for a in range(40087, 40093)],  # VA, VAr, PF: unused
        Value(h, 40093, "u32", counter(18_456_000, lambda k: 3.6), "ABCD"),  # WH
        Value(h, 40095, "s16", const(0)),  # WH_SF
        Value(h, 40096, "u16", times(1.45), scale=0.01),
        Value(h, 40097, "s16", const(-2)),  # DCA_SF
        Value(h, 40098, "u16", wander(610, 12, 50, 0.5), scale=0.1),
        Value(h, 40099, "s16", const(-1)),  # DCV_SF
        Value(h, 40100, "s16", times(720)),  # DCW
        Value(h, 40101, "s16", const(0)),  # DCW_SF
        Value(h, 40102, "s16", wander(41, 4, 80, 0.1), scale=0.1),  # cabinet temperature
        Value(h, 40103, "s16", wander(48, 5, 80, 0.1), scale=0.1),  # heat sink
        Value(h, 40104, "s16", const(-1)),  # Tmp_SF
        Value(h, 40105, "u16", steps([(0, 2), (6, 4), (140, 5), (170, 4)])),  # St (enum)
        Value(h, 40106, "u16", const(0)),  # vendor state
        Value(h, 40107, "u32", steps([(0, 0), (90, 0x0004), (200, 0x0404)]), "ABCD"),  # Evt1
        # vendor block: f32, low word first
        Value(h, 41000, "f32", lambda k, rng: 2.5 + 0.012 * k, "CDAB"),  # yield today, kWh
        Value(h, 41002, "f32", wander(97.1, 0.5, 30, 0.05), "CDAB"),  # efficiency, %
        Value(h, 41004, "f32", wander(1350, 80, 50, 5), "CDAB"),  # insulation, kOhm
    ]
    polls = [
        Poll(h, 40069, 40),
        Poll(h, 41000, 6),
        Poll(h, 40000, 69, every=15, first=1),
    ]
    return Device("inverter", 2, values, polls)


def heat_pump() -> Device:
    h = HOLDING

    def running(k: int) -> bool:
        return (k // 40) % 3 != 0  # the compressor runs two periods of every three

    def mode(k: int, _rng: random.Random) -> float:
        return 0 if not running(k) else (2 if (k // 40) % 6 == 4 else 1)

    def status(k: int, rng: random.Random) -> float:
        if not running(k):
            return 2 if k % 40 < 4 else 0  # the pump runs on a while
        return 7 if mode(k, rng) == 2 else 3

    def power(k: int, rng: random.Random) -> float:
        return 0.0 if not running(k) else 1.6 + 0.6 * math.sin(k / 17) + rng.gauss(0, 0.02)

    kw = shared(power)

    def heat(k: int, rng: random.Random) -> float:
        return 3.4 * float(kw(k, rng))

    def rpm(k: int, rng: random.Random) -> float:
        return 0 if not running(k) else 3000 + 1500 * math.sin(k / 17) + rng.gauss(0, 20)

    def outdoor(k: int, rng: random.Random) -> float:
        return -6.5 + 9.5 * k / 300 + rng.gauss(0, 0.05)

    def cop(k: int, rng: random.Random) -> float:
        return 3.2 + 0.6 * math.sin(k / 23) + rng.gauss(0, 0.03)

    def flow(k: int, rng: random.Random) -> float:
        return 0 if not running(k) else 18 + rng.gauss(0, 0.3)

    values = [
        Value(h, 0, "s16", outdoor, scale=0.1),
        Value(h, 1, "s16", wander(38, 5, 30, 0.1), scale=0.1),  # flow
        Value(h, 2, "s16", wander(33, 4, 30, 0.1), scale=0.1),  # return
        Value(h, 3, "s16", wander(48, 3, 90, 0.05), scale=0.1),  # hot water tank
        Value(h, 4, "s16", wander(-7, 4, 25, 0.1), scale=0.1),  # evaporator
        Value(h, 5, "u16", mode),  # operating mode (enum)
        Value(h, 6, "u16", status),  # compressor, pump, hot water valve (bits)
        Value(h, 7, "u16", rpm),  # compressor speed
        Value(h, 8, "u32", counter(71_234, lambda k: k % 40 == 1), "CDAB"),  # starts
        Value(h, 10, "u32", counter(8_765_432, lambda k: 0.55 * running(k)), "CDAB"),  # Wh
        Value(h, 12, "f32", cop, "CDAB"),
        Value(h, 14, "f32", kw, "CDAB"),  # electrical power
        Value(h, 16, "f32", heat, "CDAB"),  # heat output
        Value(h, 18, "u16", flow, scale=0.1),  # water flow, l/min
        Value(h, 19, "s16", steps([(0, 40.0), (120, 42.0)]), scale=0.1),  # flow setpoint
        Value(h, 20, "u16", steps([(0, 1), (200, 2)])),  # mode setpoint (enum)
        Value(h, 21, "s32", wander(5000, 30000, 45, 200), "CDAB"),  # buffer energy, Wh
        Value(h, 30, "str", const("AW-HP12 fw2.03"), length=8),
        Value(h, 38, "s16", const(-32768)),  # second outdoor sensor: not fitted
    ]
    polls = [Poll(h, 0, 23), Poll(h, 30, 9, every=20, first=3)]
    writes = [Write(19, {120: 420}), Write(20, {200: 2})]
    return Device("heat pump", 3, values, polls, writes)


def battery() -> Device:
    """A lithium battery's BMS (unit 4), written after the draft's rules were fixed and
    never used to tune them: the score on it is the held-out one."""
    i = INPUT

    def current(k: int, rng: random.Random) -> float:
        return 30 * math.sin(k / 35) + 20 + rng.gauss(0, 0.5)  # charging > 0

    amps = shared(current)

    def volts(k: int, rng: random.Random) -> float:
        return 53.2 + 0.02 * float(amps(k, rng)) + rng.gauss(0, 0.01)

    def watts(k: int, rng: random.Random) -> float:
        return 53.2 * float(amps(k, rng)) * 15  # a rack of fifteen

    def state(k: int, rng: random.Random) -> float:
        a = float(amps(k, rng))
        return 0 if abs(a) < 3 else (1 if a > 0 else 2)

    def soc(k: int, _rng: random.Random) -> float:
        return 45 + k // 9

    values = [
        Value(i, 0, "u16", volts, scale=0.01),
        Value(i, 1, "s16", amps, scale=0.1),
        Value(i, 2, "u16", soc),
        Value(i, 3, "u16", const(97)),  # state of health
        Value(i, 4, "s16", wander(26, 3, 60, 0.1), scale=0.1),  # pack temperature
        Value(i, 5, "s16", wander(21, 2, 70, 0.2)),  # coldest cell, whole degrees
        Value(i, 6, "u32", const(412), "ABCD"),  # cycles
        Value(i, 8, "u16", steps([(0, 0), (50, 1), (60, 3), (75, 2), (90, 0)])),  # alarm bits
        Value(i, 9, "u16", state),  # idle, charging, discharging (enum)
        Value(i, 10, "f32", wander(3.38, 0.05, 35, 0.003), "CDAB"),  # highest cell, V
        Value(i, 12, "f32", wander(3.35, 0.05, 35, 0.003), "CDAB"),  # lowest cell, V
        Value(i, 14, "s32", watts, "CDAB"),
        Value(i, 16, "str", const("BMS-LFP48-100"), length=8),
        Value(i, 24, "u32", counter(5_123_456, lambda k: 2.2), "CDAB"),  # charged, Wh
        Value(i, 26, "u16", lambda k, rng: 450 + k, scale=0.1),  # remaining capacity, Ah
        Value(i, 27, "u16", const(16)),  # cells
    ]
    return Device("battery", 4, values, [Poll(i, 0, 16), Poll(i, 16, 12, every=5, first=1)])


def drive() -> Device:
    """A variable-frequency drive (unit 5) the master starts, sets and stops, written
    after the battery's score was taken and the rules last changed: held out too."""
    h = HOLDING
    reference = steps([(0, 0), (3, 30.0), (100, 45.0), (220, 50.0), (260, 0.0)])

    def hz(k: int, rng: random.Random) -> float:
        target = float(reference(k, rng))
        before = float(reference(max(k - 6, 0), rng))
        ramp = min(1.0, (k % 1000) / 6) if target != before else 1.0
        return max(0.0, before + (target - before) * ramp + rng.gauss(0, 0.02))

    freq = shared(hz)

    def amps(k: int, rng: random.Random) -> float:
        return (
            0.0
            if float(freq(k, rng)) < 0.5
            else 4 + 0.14 * float(freq(k, rng)) + rng.gauss(0, 0.05)
        )

    current = shared(amps)

    def torque(k: int, rng: random.Random) -> float:
        braking = 260 <= k < 266
        return -35.0 if braking else 10 * float(current(k, rng)) + rng.gauss(0, 1)

    def rpm(k: int, rng: random.Random) -> float:
        direction = -1 if 150 <= k < 190 else 1  # the line runs backwards a while
        return direction * 29.6 * float(freq(k, rng))

    def status(k: int, rng: random.Random) -> float:
        return 0x0231 if float(freq(k, rng)) < 0.5 else (0x0237 if k % 50 else 0x0233)

    values = [
        Value(h, 0, "u16", steps([(0, 0x047E), (3, 0x047F), (260, 0x047E)])),  # control word
        Value(h, 1, "u16", reference, scale=0.01),  # speed reference, Hz
        Value(h, 2, "u16", status),  # status word (bits)
        Value(h, 3, "u16", freq, scale=0.01),  # output frequency
        Value(h, 4, "u16", current, scale=0.1),  # motor current
        Value(h, 5, "s16", torque, scale=0.1),  # torque, %
        Value(h, 6, "u16", wander(550, 6, 40, 0.5)),  # DC bus, V
        Value(h, 7, "s16", lambda k, rng: 0.15 * float(torque(k, rng)), scale=0.01),  # kW
        Value(h, 8, "u16", wander(45, 6, 120, 0.2)),  # heat sink, whole degrees
        Value(h, 9, "u32", counter(123_456, lambda k: 0.02), "ABCD"),  # kWh
        Value(h, 11, "u16", steps([(0, 0), (180, 2310), (182, 0)])),  # last fault code
        Value(h, 12, "u16", steps([(0, 1), (3, 5), (260, 1), (280, 4)])),  # digital inputs
        Value(h, 13, "s16", rpm),  # motor speed, rpm
        Value(h, 14, "f32", freq, "ABCD"),
        Value(h, 16, "f32", current, "ABCD"),
        Value(h, 18, "str", const("VFD-7K5"), length=6),
    ]
    polls = [Poll(h, 0, 18), Poll(h, 18, 6, every=30, first=2)]
    writes = [Write(0, {3: 0x047F, 260: 0x047E}), Write(1, {3: 3000, 100: 4500, 220: 5000, 260: 0})]
    return Device("drive", 5, values, polls, writes)


DEVICES: tuple[Callable[[], Device], ...] = (energy_meter, inverter, heat_pump)
HELD_OUT: tuple[Callable[[], Device], ...] = (battery, drive)


# -- the master ----------------------------------------------------------------------------


def _rtu_read(unit: int, fc: int, start: int, words: list[int]) -> tuple[bytes, bytes]:
    request = with_crc(struct.pack(">BBHH", unit, fc, start, len(words)))
    data = b"".join(struct.pack(">H", w) for w in words)
    return request, with_crc(bytes([unit, fc, len(data)]) + data)


def bus_chunks(
    cycles: int = 300,
    period: float = 2.0,
    seed: int = 7,
    makers: tuple[Callable[[], Device], ...] = DEVICES + HELD_OUT,
) -> list[Chunk]:
    """A master polling the devices (units 1-4) every `period` seconds, as the bytes a
    receiver reads: each request, then its answer 15 ms or so later."""
    devices = [make() for make in makers]
    rngs = {
        (d.unit, v.table, v.address): random.Random(seed * 1000 + d.unit * 100_000 + v.address)
        for d in devices
        for v in d.values
    }
    chunks: list[Chunk] = []
    t = 1_700_000_000.0
    for k in range(cycles):
        at = t + k * period
        for d in devices:
            now = {
                (v.table, v.address): v.words(v.signal(k, rngs[(d.unit, v.table, v.address)]))
                for v in d.values
            }
            written = {w.address: w.at[k] for w in d.writes if k in w.at}
            for address, raw in written.items():
                request = with_crc(struct.pack(">BBHH", d.unit, 6, address, raw & 0xFFFF))
                chunks.append(Chunk(request, at + 0.001))
                chunks.append(Chunk(request, at + 0.012))  # FC 6 echoes the request
                at += 0.03
            for poll in d.polls:
                if k < poll.first or (k - poll.first) % poll.every:
                    continue
                words = [
                    _word(d, now, poll.table, a) for a in range(poll.start, poll.start + poll.count)
                ]
                fc = 3 if poll.table == HOLDING else 4
                request, answer = _rtu_read(d.unit, fc, poll.start, words)
                chunks.append(Chunk(request, at + 0.001))
                chunks.append(Chunk(answer, at + 0.016 + 0.0005 * len(words)))
                at += 0.05 + 0.0006 * len(words)
    return chunks


def _word(d: Device, now: dict[tuple[str, int], list[int]], table: str, address: int) -> int:
    value = d.at(table, address)
    if value is None:
        raise AssertionError(f"{d.name}: the master reads {table} {address}, which the map lacks")
    return now[(table, value.address)][address - value.address]


# -- the score -----------------------------------------------------------------------------


@dataclass
class Score:
    """Right / proposed / total for types, word orders and scales, and the false ones."""

    types: list[int] = field(default_factory=lambda: [0, 0, 0])
    orders: list[int] = field(default_factory=lambda: [0, 0, 0])
    scales: list[int] = field(default_factory=lambda: [0, 0, 0])
    false: list[str] = field(default_factory=list)  # every wrong proposal, said
    false_floats: int = 0  # f32 proposed where there is no f32

    def add(self, other: Score) -> None:
        for mine, theirs in (
            (self.types, other.types),
            (self.orders, other.orders),
            (self.scales, other.scales),
        ):
            for n in range(3):
                mine[n] += theirs[n]
        self.false += other.false
        self.false_floats += other.false_floats

    def line(self) -> str:
        def part(name: str, counts: list[int]) -> str:
            return f"{name} {counts[0]}/{counts[1]}/{counts[2]}"

        return (
            f"{part('types', self.types)}, {part('word orders', self.orders)}, "
            f"{part('scales', self.scales)} (right/proposed/total); "
            f"{len(self.false)} false proposals, {self.false_floats} false float pairs"
        )


def score(device: Device, found: list[Guess]) -> Score:
    """Compare a draft's guesses with the device's map. A guess counts for the value
    that starts at its address; a type, order or scale proposed at an address where no
    value starts (inside one, or across two) is a false proposal."""
    s = Score()
    starts = {(v.table, v.address): v for v in device.values}
    by_start = {(g.table, g.address): g for g in found}
    for v in device.values:
        s.types[2] += 1
        s.orders[2] += v.size == 2
        s.scales[2] += v.scale != 1
        g = by_start.get((v.table, v.address))
        if g is None:
            continue
        where = f"{device.name} {v.table.split('_')[0]} {v.address}"
        if g.type:
            s.types[1] += 1
            if g.type == v.type:
                s.types[0] += 1
            else:
                s.false.append(f"{where}: type {g.type}, is {v.type}")
                s.false_floats += g.type == "f32"
        if g.word_order:
            s.orders[1] += 1
            if v.size == 2 and g.word_order == v.word_order:
                s.orders[0] += 1
            else:
                s.false.append(f"{where}: word order {g.word_order}, is {v.word_order or 'none'}")
        if g.scale is not None:
            s.scales[1] += 1
            if math.isclose(g.scale, v.scale):
                s.scales[0] += 1
            else:
                s.false.append(f"{where}: scale {g.scale:g}, is {v.scale:g}")
    for g in found:
        if g.table not in (HOLDING, INPUT):
            continue  # single bits are not scored
        if (g.table, g.address) in starts or not (g.type or g.word_order or g.scale):
            continue
        inside = device.at(g.table, g.address)
        what = f"{inside.type} at {inside.address}" if inside is not None else "nothing"
        s.false.append(
            f"{device.name} {g.table.split('_')[0]} {g.address}: {g.claims()} inside {what}"
        )
        s.types[1] += bool(g.type)
        s.orders[1] += bool(g.word_order)
        s.scales[1] += g.scale is not None
        s.false_floats += g.type == "f32"
    return s
