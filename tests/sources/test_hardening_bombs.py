"""Sigrok sessions that would cost memory or time out of all proportion to their size are
refused in one line, or read in bounded memory (issue 30, items 8 and 9): a huge
metadata member, a member inflated whole while looking for its end, bzip2 members,
sample rates of a terahertz or a microhertz, and more samples per bit than a character
can be held in."""

from __future__ import annotations

import contextlib
import io
import struct
import tracemalloc
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path

import pytest

from sniffer.analysis.baud import estimate_line
from sniffer.cli import main
from sniffer.sources import CaptureError, ReadOptions, open_capture
from sniffer.sources.sigrok import MAX_METADATA, MAX_SAMPLES_PER_BIT
from sniffer.sources.zipscan import Archive

MIB = 1 << 20
_LOCAL = struct.Struct("<IHHHHHIIIHH")


def metadata(samplerate: str = "1 MHz", tail: str = "") -> bytes:
    return (
        "[global]\nsigrok version=0.5.1\n\n[device 1]\ncapturefile=logic-1\n"
        f"total probes=8\nsamplerate={samplerate}\nprobe1=RX\nunitsize=1\n{tail}"
    ).encode()


def uart(data: bytes, per_bit: int) -> bytes:
    """Levels (one sample byte each, probe 1) of `data` sent 8E1 with `per_bit` samples."""
    out = bytearray(b"\x01" * 40)
    for value in data:
        bits = [0] + [(value >> k) & 1 for k in range(8)] + [value.bit_count() % 2, 1]
        for bit in bits:
            out += bytes([bit]) * per_bit
        out += b"\x01" * 3
    return bytes(out + b"\x01" * 40)


def session(path: Path, rate: str = "1 MHz", logic: bytes = b"") -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("version", "2")
        archive.writestr("metadata", metadata(rate))
        archive.writestr("logic-1-1", logic or uart(b"\x01\x03", 10))
    return path


@contextlib.contextmanager
def peak_memory() -> Iterator[list[int]]:
    """The peak of Python's traced allocations inside the block, in found[0]."""
    found = [0]
    tracemalloc.start()
    try:
        yield found
        found[0] = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def one_line_error(path: Path, *args: str) -> str:
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(["replay", str(path), "--probe", "RX", *args])
    assert code == 2
    text = err.getvalue()
    assert "Traceback" not in text
    errors = [line for line in text.splitlines() if "error:" in line]
    assert len(errors) == 1
    assert str(path) in errors[0]
    return errors[0]


# ---------------------------------------------------------------- the metadata member


def test_metadata_over_the_limit_is_refused_in_bounded_memory(tmp_path: Path) -> None:
    # a comment line of 64 MiB deflates to 64 kB; it was read whole (1 GiB: MemoryError)
    path = tmp_path / "meta.sr"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        with archive.open("metadata", "w", force_zip64=True) as member:
            member.write(metadata(tail="#"))
            block = b"x" * MIB
            for _ in range(64):
                member.write(block)
        archive.writestr("logic-1-1", uart(b"\x01", 10))
    with peak_memory() as peak, pytest.raises(CaptureError) as caught:
        open_capture(path, ReadOptions(baud=9600, probes=("RX",)))
    message = str(caught.value)
    assert message.startswith(f"{path}: ZIP member 'metadata'")
    assert f"over {MAX_METADATA:,} bytes" in message
    assert "\n" not in message
    assert peak[0] < 8 * MIB


def test_metadata_at_its_usual_size_still_reads(tmp_path: Path) -> None:
    path = session(tmp_path / "ok.sr")
    capture = open_capture(path, ReadOptions(baud=100_000, probes=("RX",)))
    assert b"".join(chunk.data for chunk in capture.chunks()) == b"\x01\x03"


# ---------------------------------------------------------------- ZIP members


def local_member(name: str, body: bytes, *, method: int = 0, descriptor: bool = False) -> bytes:
    raw = name.encode()
    flags = 0x08 if descriptor else 0
    size = 0 if descriptor else len(body)
    header = _LOCAL.pack(0x04034B50, 20, flags, method, 0, 0, 0, size, size, len(raw), 0)
    return header + raw + body


def deflated(data_size: int, fill: bytes = b"\x01") -> bytes:
    inflater = zlib.compressobj(1, zlib.DEFLATED, -15)
    block = fill * MIB
    return b"".join(inflater.compress(block) for _ in range(data_size // MIB)) + inflater.flush()


def test_member_without_directory_is_found_and_read_in_bounded_memory(tmp_path: Path) -> None:
    # a session cut short (no central directory) whose logic member gives its size only
    # after its data: the walk inflated all 256 MiB at once to find the end (2.1 GiB for
    # the file); now it inflates a step at a time, and so does the read
    path = tmp_path / "cut.sr"
    path.write_bytes(
        local_member("version", b"2")
        + local_member("metadata", metadata())
        + local_member("logic-1-1", deflated(256 * MIB), method=8, descriptor=True)
    )
    with peak_memory() as peak:
        archive = Archive(path)
        with archive:
            assert "directory is missing" in archive.warning
            sizes = [len(block) for block in archive.blocks("logic-1-1", 4 * MIB)]
    assert sum(sizes) == 256 * MIB
    assert max(sizes) <= 4 * MIB
    assert peak[0] < 24 * MIB


def test_members_found_from_local_headers_come_in_blocks_of_the_size_asked(
    tmp_path: Path,
) -> None:
    body = bytes(range(256)) * 20_000  # 5 MB
    inflater = zlib.compressobj(6, zlib.DEFLATED, -15)
    packed = inflater.compress(body) + inflater.flush()
    path = tmp_path / "cut.zip"
    path.write_bytes(
        local_member("stored", body)
        + local_member("deflated", packed, method=8, descriptor=True)
        + b"PK\x07\x08"
        + bytes(12)
        + local_member("last", b"xyz")
    )
    with Archive(path) as archive:
        assert archive.names() == ["stored", "deflated", "last"]
        for name, expected in (("stored", body), ("deflated", body), ("last", b"xyz")):
            blocks = list(archive.blocks(name, MIB))
            assert b"".join(blocks) == expected
            assert max(len(block) for block in blocks) <= MIB


def test_cut_short_real_session_still_streams_every_character(tmp_path: Path) -> None:
    data = bytes(range(1, 200))
    logic = uart(data, 10)
    path = tmp_path / "short.sr"
    path.write_bytes(
        local_member("version", b"2")
        + local_member("metadata", metadata())
        + local_member("logic-1-1", zlib.compress(logic)[2:-4], method=8, descriptor=True)
        + b"PK\x07\x08"
        + bytes(12)
        + local_member("logic-1-2", b"\x01" * 100)
    )
    capture = open_capture(path, ReadOptions(baud=100_000, probes=("RX",)))
    assert b"".join(chunk.data for chunk in capture.chunks()) == data
    assert "directory is missing" in capture.warnings[0]


def test_bzip2_members_are_refused_not_inflated_whole(tmp_path: Path) -> None:
    # zipfile inflates bzip2 and LZMA without a bound per read: the 79 bytes of bzip2
    # below came out as 64 MiB at once. sigrok never writes them.
    path = tmp_path / "bzip2.sr"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("version", "2")
        archive.writestr("metadata", metadata())
        archive.writestr("logic-1-1", bytes(64 * MIB), compress_type=zipfile.ZIP_BZIP2)
    with peak_memory() as peak:
        capture = open_capture(path, ReadOptions(baud=100_000, probes=("RX",)))
        assert list(capture.chunks()) == []
    assert any("'logic-1-1'" in w and "method 12 (bzip2)" in w for w in capture.warnings)
    assert peak[0] < 8 * MIB


# ---------------------------------------------------------------- sample rates


def test_a_terahertz_samplerate_is_refused_in_one_line(tmp_path: Path) -> None:
    # 1 THz gave 52 million samples per bit at 19200 baud: 2 GiB and 94 s
    path = session(tmp_path / "thz.sr", rate="1000 GHz")
    line = one_line_error(path, "--baud", "19200")
    assert "no usable samplerate ('1000 GHz')" in line
    assert "at most 10 GHz" in line


def test_more_samples_per_bit_than_a_character_may_hold_is_refused(tmp_path: Path) -> None:
    path = session(tmp_path / "slowline.sr", rate="5 GHz")
    with pytest.raises(CaptureError) as caught:
        open_capture(path, ReadOptions(baud=300, probes=("RX",)))
    message = str(caught.value)
    assert message.startswith(f"{path}: 5e+09 samples/s at 300 baud")
    assert f"over the limit of {MAX_SAMPLES_PER_BIT:,}" in message
    assert "resample" in message


def test_a_microhertz_samplerate_without_baud_is_one_line(tmp_path: Path) -> None:
    # the estimator measured 0 baud and LineSettings(0) raised: a traceback (item 9)
    path = session(tmp_path / "tiny.sr", rate="0.000001", logic=uart(bytes(range(1, 60)), 52))
    line = one_line_error(path)
    assert "too slow for any standard baud rate" in line
    assert "--baud" in line


def test_pulses_seconds_long_at_a_real_samplerate_are_not_a_baud_rate(tmp_path: Path) -> None:
    # 1 kHz sampling, 3,000 samples a bit: the estimate was 0.33 baud, rounded to 0
    path = session(tmp_path / "slow.sr", rate="1 kHz", logic=uart(bytes(range(1, 60)), 3000))
    with pytest.raises(CaptureError) as caught:
        open_capture(path, ReadOptions(probes=("RX",), estimator=estimate_line))
    assert "too slow for 19200 baud" in str(caught.value)
