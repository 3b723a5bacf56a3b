"""The compiled export's keys (sniffer/_core.c: ex_packet_key): rows whose Modbus/TCP
packet differs only in the bytes spliced in are made from one template in C, not
described again in Python. FC 15 requests and FC 1/2 answers carry fresh bits in every
frame; of their last data byte only whether a padding bit (past the quantity) is set
changes what the packet says, so frames with other values and the same padding share a
template, and each core writes the same bytes as the pure-Python export of an uncached
describer, on hand-made frames and on the benchmark's random bus mixes."""

from __future__ import annotations

import io
import random
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.mixes import mix_frames, random_mix, write_reads
from dissectors.checks import with_crc
from sniffer.framing.store import FrameStore
from sniffer.meaning.annotate import Annotator
from sniffer.meaning.describe import Describer
from sniffer.outputs.export import PcapExporter
from sniffer.session.session import Session, replay_file
from sniffer.vocab import Flag, Kind
from tests.support.core import _compiled, running
from tests.support.describe import LINE, session

STYLES = ("modbus-tcp", "rtu")


@contextmanager
def counted() -> Iterator[list[int]]:
    """The rows the export hands to Python (`PcapExporter._rows`), counted."""
    seen = [0]
    plain = PcapExporter._rows

    def counting(self: PcapExporter, rows: Iterable[int]) -> int:
        part = list(rows)
        seen[0] += len(part)
        return plain(self, part)

    PcapExporter._rows = counting  # type: ignore[method-assign]
    try:
        yield seen
    finally:
        PcapExporter._rows = plain  # type: ignore[method-assign]


def export_of(s: Session, style: str, compiled: bool, shared_size: int | None = None) -> bytes:
    """The export of every row of `s`, with the compiled core or the pure-Python one."""
    out = io.BytesIO()
    size = {} if shared_size is None else {"shared_size": shared_size}
    with running(_compiled() if compiled else None):
        describer = Describer(s.store, s.annotator, **size)
        PcapExporter(out, describer, s.line, style=style).write(range(len(s.store)))
    return out.getvalue()


def _fc15(rng: random.Random, quantity: int, padded: bool) -> tuple[bytes, bytes]:
    """An FC 15 request of unit 7 writing `quantity` coils with fresh values (padding
    bits set or clear), and its answer."""
    need = (quantity + 7) // 8
    data = bytearray(rng.randbytes(need))
    used = quantity % 8
    if used:
        pad = 0xFF << used & 0xFF
        data[-1] = data[-1] & ~pad & 0xFF
        if padded:
            data[-1] |= rng.choice([b for b in range(1, 256) if not b & ~pad])
    head = bytes([7, 15, 0, 16]) + quantity.to_bytes(2, "big")
    return with_crc(head + bytes([need]) + bytes(data)), with_crc(head)


def _bits_read(rng: random.Random, fc: int, quantity: int, padded: bool) -> tuple[bytes, bytes]:
    """An FC 1 or 2 read of unit 9 and its answer of fresh bits (padding set or clear)."""
    need = (quantity + 7) // 8
    data = bytearray(rng.randbytes(need))
    used = quantity % 8
    if used:
        pad = 0xFF << used & 0xFF
        data[-1] = data[-1] & ~pad & 0xFF
        if padded:
            data[-1] |= rng.choice([b for b in range(1, 256) if not b & ~pad])
    request = with_crc(bytes([9, fc, 0, 32]) + quantity.to_bytes(2, "big"))
    return request, with_crc(bytes([9, fc, need]) + bytes(data))


def _exchanges(pairs: list[tuple[bytes, bytes]]) -> list[tuple[bytes, bytes | None, float]]:
    return [(q, a, 0.01) for q, a in pairs]


def test_fc15_requests_of_other_values_and_the_same_padding_share_a_template() -> None:
    rng = random.Random(15)
    pairs = [_fc15(rng, 10, padded=k % 3 == 0) for k in range(90)]
    assert len({q for q, _ in pairs}) > 80  # fresh values: (nearly) every request differs
    s = session(_exchanges(pairs), bound=False)
    assert len(s.store) == 180
    plain = export_of(s, "modbus-tcp", False, 0)
    with counted() as seen:
        made = export_of(s, "modbus-tcp", True)
    assert made == plain
    # one request of each padding (clear, set) and one answer go to Python; the rest
    # are made from their templates (before: every request, its last byte in the key)
    assert seen[0] <= 4, seen[0]
    # (a packet's comment names each problem once)
    assert made.count(b"padding bits after 10 values are not zero") == 30


@pytest.mark.parametrize("fc", [1, 2])
def test_bit_reads_of_other_values_and_the_same_padding_share_a_template(fc: int) -> None:
    rng = random.Random(fc)
    pairs = [_bits_read(rng, fc, 13, padded=k % 4 == 0) for k in range(80)]
    assert len({a for _, a in pairs}) > 70
    s = session(_exchanges(pairs), bound=False)
    plain = export_of(s, "modbus-tcp", False, 0)
    with counted() as seen:
        made = export_of(s, "modbus-tcp", True)
    assert made == plain
    assert seen[0] <= 4, seen[0]
    assert made.count(b"padding bits after 13 values are not zero") == 20


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    quantities=st.lists(st.integers(0, 40), min_size=1, max_size=4),
    padded=st.floats(0.0, 1.0),
)
def test_writes_and_bit_reads_export_alike_with_either_core(
    seed: int, quantities: list[int], padded: float
) -> None:
    """Any quantities (multiples of 8 among them: no padding), padding bits set at any
    rate: the compiled export is the uncached pure-Python one, byte for byte."""
    rng = random.Random(seed)
    pairs: list[tuple[bytes, bytes]] = []
    for _ in range(60):
        quantity = rng.choice(quantities)
        pad = rng.random() < padded
        what = rng.choice((15, 1, 2))
        if what == 15:
            pairs.append(_fc15(rng, quantity, pad))
        else:
            pairs.append(_bits_read(rng, what, quantity, pad))
    s = session(_exchanges(pairs), bound=False)
    for style in STYLES:
        assert export_of(s, style, True) == export_of(s, style, False, 0)


def _mix_session(folder: Path, seed: int, frames: int) -> Session:
    mix = random_mix(seed)
    path = folder / f"{mix.name}.pcapng"
    write_reads(path, mix, mix_frames(mix, frames))
    return replay_file(path)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10**9), frames=st.integers(50, 800))
def test_random_mixes_export_the_same_with_either_core(
    tmp_path_factory: pytest.TempPathFactory, seed: int, frames: int
) -> None:
    """The benchmark's bus mixes (benchmarks/mixes.py: random slaves and codes, fresh
    values, exceptions, timeouts, stray bytes, any line): the compiled export writes
    what the pure-Python export of an uncached describer writes."""
    s = _mix_session(tmp_path_factory.mktemp("mix"), seed, frames)
    assert isinstance(s.store, FrameStore)
    for style in STYLES:
        assert export_of(s, style, True) == export_of(s, style, False, 0)


def test_a_mix_with_fresh_writes_leaves_few_rows_to_python(tmp_path: Path) -> None:
    """mix742668188 of the benchmark (FC 15 writes with fresh values every poll): nearly
    every row is made in C (before the padding key, one in seven went to Python)."""
    s = _mix_session(tmp_path, 742668188, 6000)
    rows = len(s.store)
    fifteen = sum(1 for i in range(rows) if s.store.fc[i] == 15 and s.store.kind[i] == 1)
    assert fifteen > rows // 20
    with counted() as seen:
        made = export_of(s, "modbus-tcp", True)
    assert made == export_of(s, "modbus-tcp", False, 0)
    assert seen[0] < rows // 50, (seen[0], rows)


def _noise_store(rows: int) -> tuple[FrameStore, Annotator]:
    """Stray bytes of 1-3 bytes, every one other bytes, some with a flag, between reads."""
    rng = random.Random(3)
    store = FrameStore()
    stream = store.stream(0)
    t = 1_700_000_000.0
    for k in range(rows):
        t += 0.01
        raw = (
            with_crc(bytes([7, 3, 0, 0, 0, 1])) if k % 5 == 0 else rng.randbytes(rng.randint(1, 3))
        )
        kind = Kind.REQUEST if k % 5 == 0 else Kind.NOISE
        flags = int(Flag.LINE_ERROR) if kind == Kind.NOISE and k % 7 == 0 else 0
        offset = len(stream)
        stream.extend(raw)
        store.add_row(0, offset, len(raw), t, t + len(raw) * LINE.char_time, int(kind), flags)
    store.sync()
    annotator = Annotator({})
    annotator.update(store)
    return store, annotator


@pytest.mark.parametrize("style", STYLES)
def test_noise_of_other_bytes_and_the_same_length_shares_a_template(style: str) -> None:
    store, annotator = _noise_store(400)
    out: dict[bool, bytes] = {}
    for compiled in (False, True):
        buf = io.BytesIO()
        with running(_compiled() if compiled else None), counted() as seen:
            describer = Describer(store, annotator, **({} if compiled else {"shared_size": 0}))
            PcapExporter(buf, describer, LINE, style=style).write(range(len(store)))
        out[compiled] = buf.getvalue()
    assert out[True] == out[False]
    # the compiled export describes one noise row of each length and flags (and the
    # request): 3 lengths, with and without the flag
    assert seen[0] <= 7, seen[0]
    assert out[True].count(b"noise: 2 bytes no frame claims") > 50
