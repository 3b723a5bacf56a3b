"""Fuzz: the sidecar index (sniffer/session/index.py) damaged beside a good capture:
bytes flipped, set, inserted or deleted anywhere (header, a later block, the tail), the
file cut short or grown. `replay --format jsonl` must list every row, the same rows and
the same exit status as with no sidecar at all, whatever the sidecar holds.

The sidecar's bytes are packed against the capture (format 3): the capture's own bytes
changed under a good sidecar, its size, time and head kept (so that the sidecar still
seems to fit), must list either the rows the sidecar was written from or, where a
block's bytes no longer check, the changed capture's own rows, never a mix of both.
"""

from __future__ import annotations

import io
import os
from collections.abc import Iterator
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from sniffer.cli import main
from sniffer.session import index
from sniffer.sources.linktypes import LINKTYPE_RTAC_SERIAL
from sniffer.sources.pcapng_writer import EPB_FLAG_INBOUND, PcapngWriter, rtac_record
from sniffer.sources.synth import polling_frames
from tests.fuzz.harness import budget, mutated, no_hang
from tests.support.index import LINE, T0

pytestmark = [pytest.mark.fuzz, pytest.mark.slow]

BLOCK = 64  # rows a sidecar block here, so that a small capture has many blocks


def _capture(path: Path) -> None:
    frames = polling_frames(400, line=LINE, seed=11)
    with path.open("wb") as out:
        writer = PcapngWriter(out)
        iface = writer.add_interface(LINKTYPE_RTAC_SERIAL, name="ttyUSB0")
        for k, f in enumerate(frames):
            raw = bytearray(f.raw)
            if k % 97 == 5:
                raw[-1] ^= 0xFF  # a CRC error now and then
            t = T0 + f.t + 0.001
            writer.write_packet(
                iface, t, rtac_record(t - 0.0005, bytes(raw)), flags=EPB_FLAG_INBOUND
            )


def _replay(capture: Path) -> tuple[int, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err), no_hang():
        code = main(["replay", str(capture), "--format", "jsonl"])
    assert "Traceback" not in err.getvalue()
    return code, out.getvalue()


class Bench:
    """A capture, its listing without a sidecar, and its good sidecar."""

    def __init__(self, folder: Path) -> None:
        self.capture = folder / "bus.pcapng"
        _capture(self.capture)
        self.sidecar = Path(str(self.capture) + index.SUFFIX)
        self.plain = _replay(self.capture)  # writes the sidecar
        assert self.sidecar.exists(), "no sidecar written"
        self.good = self.sidecar.read_bytes()
        assert _replay(self.capture) == self.plain  # read from the sidecar


@pytest.fixture(scope="module")
def bench(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Bench]:
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(index, "MIN_SIZE", 0)
        mp.setattr(index, "pays", lambda capture, mode: True)  # (serial pcapng too)
        mp.setattr(index, "BLOCK", BLOCK)
        folder = tmp_path_factory.mktemp("sidecar")
        mp.setenv("XDG_CACHE_HOME", str(folder / "cache"))
        mp.delenv("MODSCOPE_NO_INDEX", raising=False)
        yield Bench(folder)


def _later_block_flip(good: bytes) -> bytes:
    """The good sidecar with one byte flipped three quarters of the way in (a block past
    the first ones: issue #30's finding)."""
    data = bytearray(good)
    data[len(data) * 3 // 4] ^= 0x01
    return bytes(data)


def test_the_sidecar_spans_many_blocks(bench: Bench) -> None:
    rows = bench.plain[1].count("\n")
    assert rows > 4 * BLOCK, rows


def _check(bench: Bench, damaged: bytes) -> None:
    bench.sidecar.write_bytes(damaged)
    assert _replay(bench.capture) == bench.plain
    # the sidecar was rebuilt or left alone, never kept damaged and trusted: read again
    assert _replay(bench.capture) == bench.plain


def test_a_flipped_byte_in_a_later_block_lists_every_row(bench: Bench) -> None:
    _check(bench, _later_block_flip(bench.good))


@pytest.mark.parametrize("size", [0, 1, 16, 100, -4, -1])
def test_a_cut_sidecar_lists_every_row(bench: Bench, size: int) -> None:
    _check(bench, bench.good[:size])


def test_a_grown_sidecar_lists_every_row(bench: Bench) -> None:
    _check(bench, bench.good + bench.good[-4096:])


def test_damaged_sidecars_list_every_row_as_without_one(bench: Bench) -> None:
    # given() inside, with the module fixture: one bench for every example
    seeds = [bench.good]

    @budget(40)
    @given(mutated(seeds))
    @example(_later_block_flip(bench.good))
    def run(damaged: bytes) -> None:
        _check(bench, damaged)

    run()


class Loose(Bench):
    """A bench whose sidecar trusts all but the capture's first 256 bytes (`HEAD`), so
    that changes to the capture's bytes reach the sidecar's reading."""

    def __init__(self, folder: Path) -> None:
        super().__init__(folder)
        self.bytes = self.capture.read_bytes()
        self.stat = self.capture.stat()


@pytest.fixture(scope="module")
def loose(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Loose]:
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(index, "MIN_SIZE", 0)
        mp.setattr(index, "pays", lambda capture, mode: True)  # (serial pcapng too)
        mp.setattr(index, "BLOCK", BLOCK)
        mp.setattr(index, "HEAD", 256)
        folder = tmp_path_factory.mktemp("loose")
        mp.setenv("XDG_CACHE_HOME", str(folder / "cache"))
        mp.delenv("MODSCOPE_NO_INDEX", raising=False)
        yield Loose(folder)


def _changed(bench: Loose, changes: list[tuple[int, int]]) -> tuple[int, str]:
    """The capture with bytes past its head changed, its size and time kept, beside its
    good sidecar: listed with the sidecar (what `replay` says), then restored."""
    data = bytearray(bench.bytes)
    for at, mask in changes:
        data[256 + at % (len(data) - 256)] ^= mask
    try:
        bench.capture.write_bytes(bytes(data))
        os.utime(bench.capture, ns=(bench.stat.st_atime_ns, bench.stat.st_mtime_ns))
        bench.sidecar.write_bytes(bench.good)
        listed = _replay(bench.capture)
        os.environ["MODSCOPE_NO_INDEX"] = "1"
        try:
            own = _replay(bench.capture)
        finally:
            del os.environ["MODSCOPE_NO_INDEX"]
    finally:
        bench.capture.write_bytes(bench.bytes)
        os.utime(bench.capture, ns=(bench.stat.st_atime_ns, bench.stat.st_mtime_ns))
        bench.sidecar.write_bytes(bench.good)
    assert listed in (bench.plain, own)
    return listed


def test_a_capture_changed_under_its_sidecar_lists_its_rows_or_the_sidecars(
    loose: Loose,
) -> None:
    # every byte of the bus from the middle on: the sidecar's regions changed
    middle = (len(loose.bytes) - 256) // 2
    changes = [(middle + k, 0x55) for k in range(len(loose.bytes) // 4)]
    assert _changed(loose, changes) != loose.plain  # (the changed capture's own rows)

    @budget(20)
    @given(st.lists(st.tuples(st.integers(0, 1 << 20), st.integers(1, 255)), min_size=1))
    def run(changes: list[tuple[int, int]]) -> None:
        _changed(loose, changes)

    run()
