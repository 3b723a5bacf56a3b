"""The compiled core (sniffer._core) and the pure-Python core give the same results.

Every store column of every row, the streams, the pairs, the statistics and every
warning are compared, with the compiled core and without it, on the demo capture and on
recordings of polling traffic with noise, damage, CRC errors, broadcasts, exceptions,
echoed answers (FC 5, 6, 8) and unknown codes, cut into reads at every position, one
frame per packet and many. Without the extension these tests skip, saying so, unless
MODSCOPE_REQUIRE_COMPILED=1 (check.sh sets it): then they fail.
"""

from __future__ import annotations

import math
import os
import random
import struct
import subprocess
import sys
from array import array
from fractions import Fraction
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dissectors.checks import crc16_py, with_crc
from sniffer import core
from sniffer.framing import serial as framing
from sniffer.model import Chunk
from sniffer.session import index
from sniffer.session.session import Session, open_session
from sniffer.sources import open_capture
from sniffer.sources.linktypes import LINKTYPE_RTAC_SERIAL, LINKTYPE_USER0
from sniffer.sources.reads import Reads, batching
from tests.support.core import KINDS, _compiled, _frame
from tests.support.reads import (
    COLUMNS,
    FRAMES,
    LINE,
    LINKTYPE_MIXES,
    PCAP_MAGIC,
    SHAPES,
    T0,
    _block,
    _capture,
    _opt,
    _opts,
    _recording,
    _shb,
    damage,
    hurt_file,
    packet,
    pcap_capture,
)

ROOT = Path(__file__).resolve().parent.parent.parent
DEMO = ROOT / "sniffer" / "demo" / "demo.pcapng"


@pytest.fixture
def compiled() -> ModuleType:
    return _compiled()


def _ingest(path: Path, fast: ModuleType | None, batched: bool = True) -> Session:
    saved = core.FAST, framing.FAST_MIN_BYTES
    core.FAST = fast
    framing.FAST_MIN_BYTES = 0  # the compiled path for every lone chunk too, however short
    try:
        session, capture = open_session(path, index=False)
        session.batch_reads = batched
        session.ingest(capture.chunks())
    finally:
        core.FAST, framing.FAST_MIN_BYTES = saved
    return session


def _assert_same(path: Path, fast: ModuleType, batched: bool = True) -> Session:
    pure, comp = _ingest(path, None, batched), _ingest(path, fast, batched)
    for name in COLUMNS:
        assert getattr(comp.store, name) == getattr(pure.store, name), name
    assert comp.store.streams == pure.store.streams
    assert comp.store.notes == pure.store.notes
    assert comp.store.resolution == pure.store.resolution
    assert comp.stats.table() == pure.stats.table()
    assert (comp.warnings, comp.notes) == (pure.warnings, pure.notes)
    return pure


def _chunks(path: Path, fast: ModuleType | None) -> tuple[list[Chunk], list[str]]:
    saved = core.FAST
    core.FAST = fast
    try:
        capture = open_capture(path)
        got: list[Chunk] = []
        with batching(True):
            for chunk in capture.chunks():
                got.extend(chunk.split() if isinstance(chunk, Reads) else [chunk])
    finally:
        core.FAST = saved
    return got, capture.warnings


def test_demo_capture_is_the_same_with_either_core(compiled: ModuleType) -> None:
    pure = _assert_same(DEMO, compiled)
    assert len(pure.store) > 100


def test_crc16_matches_the_table_of_the_pure_core(compiled: ModuleType) -> None:
    rng = random.Random(5)
    for n in range(0, 300, 7):
        data = bytes(rng.getrandbits(8) for _ in range(n))
        assert compiled.crc16(data) == crc16_py(data)
    assert compiled.crc16(with_crc(b"\x01\x03\x00\x00\x00\x02")) == 0


def test_frames_of_every_length_are_checked_alike_by_either_core(
    tmp_path: Path, compiled: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The compiled scan checks a frame's CRC four bytes a step, then the 0-3 left one by
    one: FC 15 requests of every length from 10 to 255 bytes, each whole and then with
    one byte changed, in reads of one frame (framed in the compiled scan) and in reads
    cut across frames, give the rows of the pure core, which checks a byte a step; and
    the compiled scan takes every whole one itself (a check it got wrong would send it
    to the slow path, which would hide the error in the rows)."""
    rng = random.Random(15)
    whole: list[tuple[bytes, float]] = []
    both: list[tuple[bytes, float]] = []
    t = T0
    for count in range(1, 247):
        data = bytes(rng.getrandbits(8) for _ in range(count))
        unit = 1 + count % 200  # never the unit of the request before, whose answer is due
        frame = with_crc(struct.pack(">BBHHB", unit, 15, 0, 8 * count, count) + data)
        hurt = bytearray(frame)
        hurt[rng.randrange(len(frame))] ^= 1 << rng.randrange(8)
        for sent, into in ((frame, (whole, both)), (bytes(hurt), (both,))):
            t += len(sent) * LINE.char_time
            for frames in into:
                frames.append((sent, t))
            t += LINE.t35 * 1.2
    for name, frames, cuts in (("whole", whole, [0]), ("both", both, [0]), ("cut", both, [61, 7])):
        path = tmp_path / f"{name}.pcapng"
        _recording(path, _cut(frames, cuts, 0.0))
        pure = _assert_same(path, compiled)
        requests = [
            i
            for i in range(len(pure.store))
            if pure.store.kind[i] == 1 and pure.store.fc[i] == 15 and not pure.store.flags[i] & 1
        ]
        assert len(requests) == len(whole)  # every whole frame, none changed, framed as good
    stops: list[bool] = []
    scan = framing.RtuFramer._fast_scan

    def watched(self: framing.RtuFramer, *args: Any) -> tuple[bool, int, int, int]:
        done = scan(self, *args)
        stops.append(done[0])  # whether the compiled scan left a frame to Python
        return done

    monkeypatch.setattr(framing.RtuFramer, "_fast_scan", watched)
    _ingest(tmp_path / "whole.pcapng", compiled)
    assert stops and not any(stops)


# -- traffic with everything the fast paths hand over to the slow path ---------------------


def _traffic(seed: int, n: int, mix: list[str]) -> list[tuple[bytes, float]]:
    """Frames with their end times on the wire: each frame separated by a little more
    than t3.5, sometimes by a long silence."""
    rng = random.Random(seed)
    char = LINE.char_time
    out: list[tuple[bytes, float]] = []
    t = T0
    for _ in range(n):
        for frame in _frame(rng, rng.choice(mix)):
            t += len(frame) * char
            out.append((frame, t))
            t += LINE.t35 * rng.uniform(1.05, 1.5) + (0.3 if rng.random() < 0.02 else 0.0)
    return out


def _cut(
    frames: list[tuple[bytes, float]], cuts: list[int], lag: float
) -> list[tuple[bytes, float]]:
    """The frames' bytes in reads of the sizes `cuts` gives in turn (0: one read per
    frame), each stamped when its last byte came, some later."""
    if not cuts or cuts == [0]:
        return frames
    stream = b"".join(f for f, _ in frames)
    ends: list[float] = []
    for f, t in frames:
        ends += [t - (len(f) - 1 - i) * LINE.char_time for i in range(len(f))]
    reads: list[tuple[bytes, float]] = []
    pos = k = 0
    while pos < len(stream):
        n = cuts[k % len(cuts)] or 1
        k += 1
        stop = min(len(stream), pos + n)
        reads.append((stream[pos:stop], ends[stop - 1] + (lag if k % 4 == 0 else 0.0)))
        pos = stop
    return reads


# a recording of random traffic (`_traffic`, cut into reads by `_cut`) in one of the
# SHAPES, and whether its reads are handed over in batches (`_random_recording`)
RANDOM_RECORDING = st.fixed_dictionaries(
    {
        "seed": st.integers(0, 10**6),
        "n": st.integers(1, 120),
        "mix": st.sampled_from(
            [["read"], KINDS, ["read", "echo", "exception", "broadcast", "write"]]
        ),
        "cuts": st.one_of(st.just([0]), st.lists(st.integers(1, 90), min_size=1, max_size=50)),
        "lag": st.sampled_from([0.0, 0.0, 0.004, 0.05]),
        "batched": st.booleans(),
        "shape": st.sampled_from(SHAPES),
    }
)


def _random_recording(path: Path, case: dict[str, Any]) -> bool:
    """The recording `case` (drawn from RANDOM_RECORDING) written to `path`; whether
    its reads are to be batched."""
    frames = _traffic(case["seed"], case["n"], case["mix"])
    _recording(path, _cut(frames, case["cuts"], case["lag"]), case["shape"])
    return bool(case["batched"])


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=RANDOM_RECORDING)
def test_random_traffic_is_the_same_with_either_core(
    tmp_path_factory: pytest.TempPathFactory, case: dict[str, Any]
) -> None:
    fast = _compiled()
    path = tmp_path_factory.mktemp("core") / "r.pcapng"
    _assert_same(path, fast, _random_recording(path, case))


def test_reads_split_at_every_position_are_the_same_with_either_core(
    tmp_path: Path, compiled: ModuleType
) -> None:
    frames = _traffic(3, 14, KINDS)
    stream = b"".join(f for f, _ in frames)
    t_end = frames[-1][1]
    for at in range(1, len(stream)):
        path = tmp_path / f"split{at}.pcapng"
        first = t_end - (len(stream) - at) * LINE.char_time
        _recording(path, [(stream[:at], first), (stream[at:], t_end)])
        _assert_same(path, compiled)
        path.unlink()


def test_large_polling_recording_is_the_same_with_either_core(
    tmp_path: Path, compiled: ModuleType
) -> None:
    frames = [(f, T0 + k * 0.004) for k, f in enumerate(FRAMES)]
    for shape in SHAPES:
        for cuts in ([0], [37, 90, 5, 64]):
            path = tmp_path / "poll.pcapng"
            _recording(path, _cut(frames, cuts, 0.0), shape)
            pure = _assert_same(path, compiled)
            assert len(pure.store) == len(FRAMES)


# -- the pcapng walk -------------------------------------------------------------------------


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    order=st.sampled_from(["<", ">"]),
    linktypes=st.sampled_from(LINKTYPE_MIXES),
    packets=st.lists(packet, max_size=40),
    second_section=st.integers(-1, 40),
    hurt=damage,
)
def test_the_bulk_walk_gives_the_same_chunks_and_warnings_with_either_core(
    tmp_path_factory: pytest.TempPathFactory,
    order: str,
    linktypes: list[int],
    packets: list[tuple[int, str, int | None, str, int, int, float, float]],
    second_section: int,
    hurt: tuple[object, ...] | None,
) -> None:
    fast = _compiled()
    data = hurt_file(_capture(order, linktypes, packets, second_section), hurt)
    path = tmp_path_factory.mktemp("walk") / "c.pcapng"
    path.write_bytes(data)
    assert _chunks(path, fast) == _chunks(path, None)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    order=st.sampled_from(["<", ">"]),
    layout=st.sampled_from(list(PCAP_MAGIC)),
    linktype=st.sampled_from([LINKTYPE_RTAC_SERIAL, LINKTYPE_USER0]),
    packets=st.lists(packet, max_size=40),
    hurt=damage,
)
def test_the_bulk_pcap_walk_gives_the_same_chunks_and_warnings_with_either_core(
    tmp_path_factory: pytest.TempPathFactory,
    order: str,
    layout: tuple[bool, bool],
    linktype: int,
    packets: list[tuple[int, str, int | None, str, int, int, float, float]],
    hurt: tuple[object, ...] | None,
) -> None:
    fast = _compiled()
    data = hurt_file(pcap_capture(order, *layout, linktype, packets), hurt)
    path = tmp_path_factory.mktemp("walkpcap") / "c.pcap"
    path.write_bytes(data)
    assert _chunks(path, fast) == _chunks(path, None)


def test_packet_times_halfway_between_two_doubles_round_half_to_even(
    tmp_path: Path, compiled: ModuleType
) -> None:
    """A timestamp of 2**-23 s ticks (if_tsresol 0x97) with 54 significant bits lies
    exactly halfway between two doubles: Python's int / int rounds it to the even one,
    and so must the compiled walk (exact_quotient), down or up as the even one lies."""
    tps = 1 << 23
    whole = 1_714_564_800  # 31 bits: a double keeps 22 bits of fraction, the ticks 23
    order = "<"
    resolution = _opt(order, 9, bytes([0x80 | 23]))
    idb = struct.pack(order + "HHI", LINKTYPE_USER0, 0, 0) + _opts(order, [resolution])
    out = bytearray(_shb(order) + _block(order, 1, idb))
    all_ticks = [(whole << 23) + odd for odd in range(1, 2000, 2)]
    for ticks in all_ticks:
        data = FRAMES[ticks % len(FRAMES)]
        head = (0, ticks >> 32, ticks & 0xFFFFFFFF, len(data), len(data))
        body = struct.pack(order + "IIIII", *head)
        out += _block(order, 6, body + data + b"\0" * (-len(data) % 4))
    path = tmp_path / "ties.pcapng"
    path.write_bytes(bytes(out))
    chunks, warnings = _chunks(path, compiled)
    assert not warnings
    assert [c.t_end for c in chunks] == [ticks / tps for ticks in all_ticks]
    # every one is a tie, and the even neighbour lies below for some, above for others
    down = up = 0
    for ticks, chunk in zip(all_ticks, chunks, strict=True):
        low = (ticks >> 1) / (tps >> 1)  # 53 bits over a power of two: exact
        high = math.nextafter(low, math.inf)
        assert Fraction(low) + Fraction(high) == 2 * Fraction(ticks, tps)  # exactly halfway
        down += chunk.t_end == low
        up += chunk.t_end == high
    assert down == up == len(all_ticks) // 2
    assert _chunks(path, None)[0] == chunks


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    resolution=st.sampled_from([3, 6, 9, 12, 0x80 | 10, 0x80 | 23, 0x80 | 30, 0x80 | 40]),
    seconds=st.lists(
        st.one_of(
            st.floats(1.0, 9e9),
            st.floats(1_600_000_000, 1_900_000_000),
            st.integers(1, 2**31).map(float),
        ),
        min_size=1,
        max_size=40,
    ),
    wobble=st.lists(st.integers(-3, 3), min_size=1, max_size=40),
)
def test_packet_times_of_any_resolution_are_those_of_python_int_division(
    tmp_path_factory: pytest.TempPathFactory,
    resolution: int,
    seconds: list[float],
    wobble: list[int],
) -> None:
    """The compiled walk's time of a packet is ticks / ticks-per-second rounded once, as
    Python divides two ints (exact_quotient), at every resolution an interface may state."""
    fast = _compiled()
    tps = 2 ** (resolution & 0x7F) if resolution & 0x80 else 10**resolution
    order = "<"
    idb = struct.pack(order + "HHI", LINKTYPE_USER0, 0, 0) + _opts(
        order, [_opt(order, 9, bytes([resolution]))]
    )
    out = bytearray(_shb(order) + _block(order, 1, idb))
    all_ticks = []
    for k, s in enumerate(seconds):
        ticks = min(2**64 - 1, max(0, int(s * tps) + wobble[k % len(wobble)]))
        all_ticks.append(ticks)
        data = FRAMES[k % len(FRAMES)]
        head = (0, ticks >> 32, ticks & 0xFFFFFFFF, len(data), len(data))
        body = struct.pack(order + "IIIII", *head)
        out += _block(order, 6, body + data + b"\0" * (-len(data) % 4))
    path = tmp_path_factory.mktemp("resolution") / "r.pcapng"
    path.write_bytes(bytes(out))
    chunks, warnings = _chunks(path, fast)
    assert (chunks, warnings) == _chunks(path, None)
    assert [c.t_end for c in chunks] == [t / tps for t in all_ticks]


# -- which core runs -------------------------------------------------------------------------


def _run(code: str, **env: str) -> str:
    environment = {**os.environ, "PYTHONPATH": str(ROOT), **env}
    return subprocess.run(
        [sys.executable, "-c", code],
        env=environment,
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    ).stdout.strip()


VERSION = "from sniffer.cli import main; main(['--version'])"


def test_modscope_pure_python_selects_the_pure_core() -> None:
    said = _run("from sniffer import core; print(core.FAST is None, core.describe())",
                MODSCOPE_PURE_PYTHON="1")  # fmt: skip
    assert said == "True pure-Python core: MODSCOPE_PURE_PYTHON=1"
    assert _run(VERSION, MODSCOPE_PURE_PYTHON="1").endswith(
        "(pure-Python core: MODSCOPE_PURE_PYTHON=1)"
    )


def test_version_says_the_compiled_core_runs(compiled: ModuleType) -> None:
    assert _run(VERSION, MODSCOPE_PURE_PYTHON="0").endswith("(compiled core)")
    said = _run("from sniffer import core; print(core.FAST is not None)", MODSCOPE_PURE_PYTHON="")
    assert said == "True"


@settings(max_examples=150, deadline=None)
@given(
    st.lists(st.one_of(st.just(-1), st.integers(0, 3_000_000)), max_size=300),
    st.integers(0, 2_000_000),
)
def test_partners_shift_alike_with_either_core(partners: list[int], base: int) -> None:
    fast = _compiled()
    column = memoryview(array("i", partners))
    saved = core.FAST
    try:
        for at_least, by in ((0, base), (base, -base)):
            core.FAST = None
            pure = index.shifted_partners(column, at_least, by)
            core.FAST = fast
            assert index.shifted_partners(column, at_least, by) == pure
            shifted = array("i")
            shifted.frombytes(pure)
            expected = [p + by if p >= at_least else -1 for p in partners]
            assert list(shifted) == expected
    finally:
        core.FAST = saved
    with pytest.raises(OverflowError):
        fast.shift_partners(memoryview(array("i", [2**31 - 5])), 0, 10)


_WIDE = {"B": 8, "H": 16, "I": 32, "Q": 64}


@settings(max_examples=150, deadline=None)
@given(st.sampled_from("BHIQi"), st.data())
def test_column_bounds_alike_with_either_core(code: str, data: st.DataObject) -> None:
    """The sidecar's checks take the least and greatest word of each block's columns:
    the compiled scan gives min and max of every word, at each width's extremes too."""
    fast = _compiled()
    words = (
        st.integers(-(2**31), 2**31 - 1) if code == "i" else st.integers(0, 2 ** _WIDE[code] - 1)
    )
    values = data.draw(st.lists(words, min_size=1, max_size=200))
    column = memoryview(array(code, values))
    saved = core.FAST
    try:
        core.FAST = None
        pure = index._bounds(column, code)
        core.FAST = fast
        assert index._bounds(column, code) == pure == (min(values), max(values))
    finally:
        core.FAST = saved
    assert fast.bounds(memoryview(array(code)), code) is None
    with pytest.raises(ValueError):
        fast.bounds(b"\0\0\0", "H")  # (not a whole number of words)
