"""Provides the sigrok session (.sr) reader: UART characters decoded from logic probes.

A `.sr` file is a ZIP archive: `version`, an INI `metadata` (`[device 1]` with
`samplerate`, `unitsize`, `capturefile`, `probeN = name` for 1-based probe N = bit N-1 of
each little-endian sample word) and the samples in `logic-1-1`, `logic-1-2`, ...

Probes are chosen with `ReadOptions.probes`: `probe3` or `#3` is probe number 3; any
other text is a probe name (exact, then ignoring case) and, failing that, a bare number.
sigrok often names probes "0", "1", ... after their bit, so a bare "1" that names probe2
picks probe2 and the capture says so in a warning. One probe gives channel 0 with no
direction; two give channel 0 for the first (the master's requests, Direction.MASTER)
and channel 1 for the second (the slaves' responses, Direction.SLAVE). With no probe
given, a capture with exactly one probe uses it; otherwise the reader lists the names.

The line format comes from the options (default 19200 8E1: the file has none); with no
baud rate given, `ReadOptions.estimator` (where set) measures it from the first
`ESTIMATE_SAMPLES` samples of the chosen probes. The decoder scans the level string for
falling edges (bytes.find, in C), samples each bit at its middle counted from that edge
(so it resyncs on every start bit), and checks the start bit, parity and stop bits.
Every character is its own chunk with exact times relative to the capture start:
`t_start` at the start bit's edge, `t_end` at the end of the last stop bit. A parity or
framing error gives an event chunk right after the character, which is still delivered.
"""

from __future__ import annotations

import configparser
import math
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from sniffer.errors import CaptureError
from sniffer.model import Chunk, Direction, Labels, LineSettings, SourceInfo, Stamp
from sniffer.sources.base import Capture, ReadOptions
from sniffer.sources.zipscan import Archive, ArchiveError, MemberTooLargeError

READ_BLOCK = 1 << 22  # sample bytes decoded per step
MIN_SAMPLES_PER_BIT = 3.0
# A character is held whole while it is decoded: 12 bits of this many samples at most
# (1 GHz sampling of a 300 baud line is 3.3 million samples per bit).
MAX_SAMPLES_PER_BIT = 4_000_000
MAX_SAMPLERATE = 1e10  # 10 GHz; the fastest logic analysers sample at a few GHz
LOWEST_BAUD = 300  # the slowest standard baud rate the line estimate considers
MAX_METADATA = 1 << 20  # bytes; sigrok writes a few hundred
ESTIMATE_SAMPLES = 1 << 22  # samples a line estimate looks at
_RATE = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([kKmMgG]?)(?:[hH][zZ])?\s*$")
_RATE_UNITS = {"": 1.0, "k": 1e3, "m": 1e6, "g": 1e9}


@dataclass(frozen=True, slots=True)
class SigrokMetadata:
    """What a session's metadata says about its logic data."""

    samplerate: float
    unitsize: int
    probes: dict[int, str]  # 1-based probe number -> name
    members: tuple[str, ...]  # logic data members in order


def _decimal(text: str) -> bool:
    return text.isascii() and text.isdigit()


def parse_samplerate(text: str) -> float | None:
    """`1 MHz`, `200 kHz`, `4000000`: samples per second, or None."""
    match = _RATE.match(text)
    if not match:
        return None
    rate = float(match[1]) * _RATE_UNITS[match[2].lower()]
    return rate if 0 < rate <= MAX_SAMPLERATE else None


def _read_metadata(path: Path, archive: Archive) -> SigrokMetadata:
    try:
        raw = archive.read("metadata", MAX_METADATA)
    except MemberTooLargeError as exc:
        raise CaptureError(
            f"{path}: {exc}; sigrok writes a metadata member of a few hundred bytes: "
            "this is not a sigrok session, or a damaged one (open it in PulseView)"
        ) from None
    text = raw.decode("utf-8", errors="replace")
    parser = configparser.ConfigParser(interpolation=None, strict=False)
    try:
        parser.read_string(text)
    except configparser.Error as exc:
        raise CaptureError(f"{path}: sigrok metadata cannot be parsed ({exc})") from None
    for section in parser.sections():
        if section.startswith("device") and parser.has_option(section, "capturefile"):
            device = parser[section]
            break
    else:
        raise CaptureError(f"{path}: sigrok metadata describes no device with logic data")
    rate = parse_samplerate(device.get("samplerate", ""))
    if rate is None:
        raise CaptureError(
            f"{path}: sigrok metadata has no usable samplerate ({device.get('samplerate')!r}); "
            f"expected a rate such as '1 MHz', above 0 and at most {MAX_SAMPLERATE / 1e9:g} GHz"
        )
    unitsize_text = device.get("unitsize", "1").strip()
    unitsize = int(unitsize_text) if _decimal(unitsize_text) else 0
    if not 1 <= unitsize <= 8:
        raise CaptureError(f"{path}: sigrok metadata has unitsize {unitsize_text!r}; expected 1-8")
    probes: dict[int, str] = {}
    for key, value in device.items():
        match = re.fullmatch(r"probe(\d{1,4})", key)
        if match and 1 <= int(match[1]) <= unitsize * 8:
            probes[int(match[1])] = value.strip()
    capturefile = device.get("capturefile", "").strip()
    members = []
    for name in archive.names():
        if name == capturefile:
            members.append((0, name))
        elif name.startswith(capturefile + "-") and _decimal(name[len(capturefile) + 1 :]):
            members.append((int(name[len(capturefile) + 1 :]), name))
    if not members:
        raise CaptureError(f"{path}: sigrok session has no logic data ({capturefile!r} chunks)")
    return SigrokMetadata(rate, unitsize, probes, tuple(name for _, name in sorted(members)))


def _probe_list(probes: dict[int, str]) -> str:
    return ", ".join(f"probe{number}={name!r}" for number, name in sorted(probes.items()))


def resolve_probe(token: str, probes: dict[int, str], path: Path) -> int:
    """The 1-based probe number `token` names: `probeN` or `#N` is number N; otherwise a
    probe name (exact, then ignoring case), then a bare number."""
    text = token.strip()
    numbered = re.fullmatch(r"(?:probe|#)(\d+)", text, re.IGNORECASE)
    if numbered and int(numbered[1]) in probes:
        return int(numbered[1])
    if not numbered:
        for number, name in sorted(probes.items()):
            if name == text:
                return number
        for number, name in sorted(probes.items()):
            if name.lower() == text.lower():
                return number
        if _decimal(text) and int(text) in probes:
            return int(text)
    raise CaptureError(
        f"{path}: no probe {token!r} in this capture; its probes are {_probe_list(probes)}"
    )


def ambiguity(token: str, number: int, probes: dict[int, str]) -> str:
    """A warning when a bare number picked a probe by name that is not that number."""
    text = token.strip()
    if _decimal(text) and int(text) != number and int(text) in probes:
        return (
            f"--probe {text} is the probe named {text!r} (probe{number}); "
            f"write probe{text} for probe number {text} ({probes[int(text)]!r})"
        )
    return ""


class UartDecoder:
    """Decodes UART characters from one probe's level string (1 = idle/mark)."""

    def __init__(
        self,
        samplerate: float,
        line: LineSettings,
        *,
        channel: int = 0,
        direction: Direction = Direction.UNKNOWN,
        label: str = "",
    ) -> None:
        self.rate = samplerate
        self.line = line
        self.channel = channel
        self.direction = direction
        self.label = label or f"channel {channel}"
        per_bit = samplerate / line.baud
        bits = line.char_bits
        self.char_samples = bits * per_bit
        self.need = math.ceil(self.char_samples)
        self.mids = [int((k + 0.5) * per_bit) for k in range(bits)]
        self.data_mids = self.mids[1 : 1 + line.bytesize]
        self.parity_mid = self.mids[1 + line.bytesize] if line.parity != "N" else None
        self.stop_mids = self.mids[bits - line.stopbits :]
        self.buf = b""
        self.base = 0  # absolute sample index of buf[0]
        self.pos = 0  # where the next edge search starts in buf
        self.samples = 0
        self.low_samples = 0
        self.first_level = self.last_level = 1
        self.characters = 0
        self.framing_errors = 0
        self.truncated = False

    def feed(self, levels: bytes, final: bool = False) -> list[Chunk]:
        """Chunks for every character complete in what has been fed; `final` flushes."""
        if levels:
            if not self.samples:
                self.first_level = levels[0]
            self.last_level = levels[-1]
        self.samples += len(levels)
        self.low_samples += levels.count(0)
        buf = self.buf[self.pos :] + levels
        base = self.base + self.pos
        out: list[Chunk] = []
        pos = 0
        find = buf.find
        size = len(buf)
        mids = self.mids
        last_mid = mids[-1]
        rate = self.rate
        while True:
            i = find(b"\x01\x00", pos)
            if i < 0:
                pos = max(size - 1, 0)  # keep the last sample: an edge may straddle
                break
            edge = i + 1
            if edge + self.need > size and not final:
                pos = i
                break
            if edge + last_mid >= size:
                self.truncated = True
                pos = size
                break
            if buf[edge + mids[0]]:  # start bit gone by mid-bit: a glitch
                pos = edge
                continue
            out.extend(self._character(buf, edge, (base + edge) / rate))
            pos = edge + last_mid
        self.buf = buf
        self.base = base
        self.pos = pos
        return out

    def _character(self, buf: bytes, edge: int, t_start: float) -> list[Chunk]:
        value = 0
        for bit, mid in enumerate(self.data_mids):
            if buf[edge + mid]:
                value |= 1 << bit
        t_end = t_start + self.char_samples / self.rate
        chunk = Chunk(
            data=bytes((value,)),
            t_end=t_end,
            t_start=t_start,
            channel=self.channel,
            direction=self.direction,
        )
        self.characters += 1
        events: list[str] = []
        if self.parity_mid is not None:
            parity = buf[edge + self.parity_mid]
            ones = value.bit_count() + parity
            ok = {
                "E": ones % 2 == 0,
                "O": ones % 2 == 1,
                "M": parity == 1,
                "S": parity == 0,
            }[self.line.parity]
            if not ok:
                events.append("parity error")
        if not all(buf[edge + mid] for mid in self.stop_mids):
            self.framing_errors += 1
            events.append("framing error")
        if not events:
            return [chunk]
        note = f"character 0x{value:02X}"
        return [chunk] + [
            Chunk(
                data=b"",
                t_end=t_end,
                t_start=t_start,
                channel=self.channel,
                direction=self.direction,
                event=event,
                note=note,
            )
            for event in events
        ]

    def warnings(self, inverted: bool) -> list[str]:
        """What looked wrong once everything was fed."""
        found = []
        if self.truncated:
            found.append(f"{self.label}: the capture ends inside a character; it is dropped")
        idle_low = self.first_level == 0 and self.last_level == 0
        if idle_low and self.low_samples > self.samples // 2:
            percent = 100 * self.low_samples // self.samples
            hint = "is --invert right?" if inverted else "an idle-low line? try --invert"
            found.append(f"{self.label}: the line is low {percent}% of the time; {hint}")
        elif self.characters >= 4 and self.framing_errors * 2 > self.characters:
            found.append(
                f"{self.label}: {self.framing_errors} of {self.characters} characters have "
                f"framing errors; check the baud rate and format ({self.line.describe()})"
            )
        return found


def _bit_table(bit: int, invert: bool) -> bytes:
    """A bytes.translate table turning a sample byte into its level at `bit` (0 or 1)."""
    return bytes(((b >> bit) & 1) ^ invert for b in range(256))


@dataclass(frozen=True, slots=True)
class _Probe:
    number: int  # 1-based
    decoder: UartDecoder
    table: bytes


def open_sigrok(path: Path, options: ReadOptions) -> Capture:
    """Open a sigrok session and set up UART decoding on the chosen probes."""
    try:
        with Archive(path) as archive:
            if "metadata" not in archive.names():
                raise CaptureError(
                    f"{path}: a ZIP archive without sigrok metadata; expected a sigrok "
                    "session (.sr) or a capture in another supported format"
                )
            meta = _read_metadata(path, archive)
            early = [archive.warning] if archive.warning else []
    except ArchiveError as exc:
        raise CaptureError(f"{path}: {exc}; expected a sigrok session (.sr)") from None
    numbers = _choose_probes(path, meta, options)
    line = options.line(None)
    notes: list[str] = []
    if options.baud is None and meta.samplerate < MIN_SAMPLES_PER_BIT * LOWEST_BAUD:
        raise CaptureError(
            f"{path}: {meta.samplerate:g} samples/s is too slow for any standard baud rate "
            f"({LOWEST_BAUD} baud needs {MIN_SAMPLES_PER_BIT * LOWEST_BAUD:g}); check the "
            "samplerate in the session's metadata, or give the line's --baud"
        )
    if options.baud is None and options.estimator is not None:  # measure it, say the choice
        levels = bit_levels(
            path, meta.unitsize, meta.members, numbers, options.invert, ESTIMATE_SAMPLES
        )
        guess = options.estimator(meta.samplerate, levels, options)
        if guess is not None:
            line = guess.line
            notes.append(f"{path}: {guess.note}")
    if meta.samplerate / line.baud < MIN_SAMPLES_PER_BIT:
        raise CaptureError(
            f"{path}: {meta.samplerate:g} samples/s is too slow for {line.baud} baud "
            f"(needs {MIN_SAMPLES_PER_BIT:g} samples per bit)"
        )
    if meta.samplerate / line.baud > MAX_SAMPLES_PER_BIT:
        raise CaptureError(
            f"{path}: {meta.samplerate:g} samples/s at {line.baud} baud is "
            f"{meta.samplerate / line.baud:,.0f} samples per bit, over the limit of "
            f"{MAX_SAMPLES_PER_BIT:,}; check --baud, or resample the capture to a lower rate "
            "(sigrok-cli or PulseView)"
        )
    for token, number in zip(options.probes, numbers, strict=False):
        if text := ambiguity(token, number, meta.probes):
            early.append(text)
    directions = [Direction.UNKNOWN] if len(numbers) == 1 else [Direction.MASTER, Direction.SLAVE]
    roles = {
        Direction.UNKNOWN: "",
        Direction.MASTER: " (requests)",
        Direction.SLAVE: " (responses)",
    }
    probes = []
    channels = {}
    for channel, (number, direction) in enumerate(zip(numbers, directions, strict=True)):
        label = f"probe {meta.probes[number]!r}{roles[direction]}"
        channels[channel] = label
        decoder = UartDecoder(
            meta.samplerate, line, channel=channel, direction=direction, label=label
        )
        probes.append(_Probe(number, decoder, _bit_table((number - 1) % 8, options.invert)))
    info = SourceInfo(
        path=str(path),
        format="sigrok",
        line=line,
        exact_timing=True,
        channels=channels,
        warnings=tuple(early),
        notes=tuple(notes),
        stamps=Stamp.EXACT,
        labels=Labels.CERTAIN if len(numbers) == 2 else Labels.NONE,
    )
    warnings: list[str] = list(early)
    chunks = _chunks(path, meta, probes, options.invert, warnings)
    return Capture(info=info, _chunks=chunks, warnings=warnings)


def _choose_probes(path: Path, meta: SigrokMetadata, options: ReadOptions) -> list[int]:
    if not options.probes:
        if len(meta.probes) == 1:
            return list(meta.probes)
        raise CaptureError(
            f"{path}: this capture has probes {_probe_list(meta.probes)}; pass --probe NAME "
            "(or two: requests, then responses)"
        )
    if len(options.probes) > 2:
        raise CaptureError(
            f"{path}: give one probe, or two (requests, then responses), not {len(options.probes)}"
        )
    numbers = [resolve_probe(token, meta.probes, path) for token in options.probes]
    if len(numbers) == 2 and numbers[0] == numbers[1]:
        raise CaptureError(f"{path}: the two probes given are the same probe")
    return numbers


def bit_levels(
    path: Path,
    unitsize: int,
    members: Sequence[str],
    numbers: Sequence[int],
    invert: bool,
    limit: int,
) -> list[bytes]:
    """The levels (0/1 bytes) of probes `numbers` over the first `limit` samples."""
    out = [bytearray() for _ in numbers]
    tables = [_bit_table((n - 1) % 8, invert) for n in numbers]
    taken = 0
    carry = b""
    try:
        with Archive(path) as archive:
            for name in members:
                for block in archive.blocks(name, READ_BLOCK):
                    data = carry + block
                    usable = len(data) - len(data) % unitsize
                    carry = data[usable:]
                    data = data[: min(usable, (limit - taken) * unitsize)]
                    taken += len(data) // unitsize
                    for k, n in enumerate(numbers):
                        byte = (n - 1) // 8
                        column = data if unitsize == 1 else data[byte::unitsize]
                        out[k] += column.translate(tables[k])
                    if taken >= limit:
                        return [bytes(b) for b in out]
    except ArchiveError:
        pass  # what was read is used; the full read reports the problem
    return [bytes(b) for b in out]


def _decode(probes: list[_Probe], unitsize: int, data: bytes, final: bool) -> list[Chunk]:
    batch: list[Chunk] = []
    for probe in probes:
        byte = (probe.number - 1) // 8
        column = data if unitsize == 1 else data[byte::unitsize]
        batch.extend(probe.decoder.feed(column.translate(probe.table), final))
    if len(probes) > 1:
        batch.sort(key=lambda chunk: (chunk.t_end, chunk.channel))
    return batch


def _chunks(
    path: Path, meta: SigrokMetadata, probes: list[_Probe], invert: bool, warnings: list[str]
) -> Iterator[Chunk]:
    carry = b""
    samples = 0
    try:
        archive = Archive(path)
    except ArchiveError as exc:
        warnings.append(f"{path}: {exc}")
        return
    with archive:
        for name in meta.members:
            try:
                for block in archive.blocks(name, READ_BLOCK):
                    data = carry + block
                    usable = len(data) - len(data) % meta.unitsize
                    carry = data[usable:]
                    samples += usable // meta.unitsize
                    yield from _decode(probes, meta.unitsize, data[:usable], False)
            except ArchiveError as exc:
                warnings.append(f"{exc}; decoding stopped after {samples} samples")
                break
    yield from _decode(probes, meta.unitsize, b"", True)
    for probe in probes:
        warnings.extend(probe.decoder.warnings(invert))
