"""Tests format recognition by content, unreadable files, and that no content escapes as
anything but CaptureError (hypothesis: random and mutated files)."""

from __future__ import annotations

import io
import os
import shutil
import tempfile
import zipfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dissectors.checks import ascii_frame, with_crc
from sniffer.model import LineSettings
from sniffer.sources import CaptureError, ReadOptions, open_capture
from sniffer.sources.pcapng_writer import (
    EPB_FLAG_INBOUND,
    LINKTYPE_RTAC_SERIAL,
    LINKTYPE_USER0,
    LINKTYPE_WIRESHARK_UPPER_PDU,
    PcapngWriter,
    rtac_record,
    upper_pdu_record,
)

CAPTURES = Path(__file__).parent.parent / "captures"
REQUEST = with_crc(bytes.fromhex("010300000002"))
T0 = 1_714_564_800.0


def pcapng_bytes() -> bytes:
    stream = io.BytesIO()
    writer = PcapngWriter(stream)
    raw = writer.add_interface(LINKTYPE_USER0, description="modscope 9600 8N1 rtu")
    rtac = writer.add_interface(LINKTYPE_RTAC_SERIAL)
    export = writer.add_interface(LINKTYPE_WIRESHARK_UPPER_PDU, tsresol_ns=False)
    writer.write_packet(raw, T0, REQUEST, flags=EPB_FLAG_INBOUND, comment="c")
    writer.write_packet(rtac, T0 + 0.1, rtac_record(T0 + 0.09, REQUEST))
    writer.write_packet(export, T0 + 0.2, upper_pdu_record(REQUEST))
    return stream.getvalue()


def pcap_bytes() -> bytes:
    header = bytes.fromhex("d4c3b2a1020004000000000000000000ffff000093000000")
    record = bytes.fromhex("00e0316600000000") + len(REQUEST).to_bytes(4, "little") * 2
    return header + record + REQUEST


def sigrok_bytes() -> bytes:
    levels = [1] * 20
    for value in REQUEST[:3]:
        bits = [0] + [(value >> k) & 1 for k in range(8)] + [bin(value).count("1") % 2, 1]
        for bit in bits:
            levels += [bit] * 10
    levels += [1] * 20
    stream = io.BytesIO()
    with zipfile.ZipFile(stream, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("version", "2")
        archive.writestr(
            "metadata",
            "[device 1]\ncapturefile=logic-1\nsamplerate=192 kHz\nprobe1=RX\nunitsize=1\n",
        )
        archive.writestr("logic-1-1", bytes(levels[:200]))
        archive.writestr("logic-1-2", bytes(levels[200:]))
    return stream.getvalue()


SEEDS = {
    "pcapng": pcapng_bytes(),
    "pcap": pcap_bytes(),
    "sigrok": sigrok_bytes(),
    "socat": (CAPTURES / "hexdump" / "socat_modbus.log").read_bytes(),
    "hexdump": (CAPTURES / "hexdump" / "text2pcap_modbus.txt").read_bytes(),
    "raw": REQUEST * 3,
}


@pytest.mark.parametrize("kind", sorted(SEEDS))
def test_format_is_recognised_by_content_not_name(tmp_path: Path, kind: str) -> None:
    path = tmp_path / "capture.pcapng.txt.sr"  # the name says everything and nothing
    path.write_bytes(SEEDS[kind])
    capture = open_capture(path)
    assert capture.info.format == kind
    chunks = list(capture.chunks())
    assert capture.warnings == []
    assert REQUEST[:3] in b"".join(c.data for c in chunks)


def test_modbus_ascii_text_is_raw(tmp_path: Path) -> None:
    path = tmp_path / "ascii.txt"
    text = ascii_frame(bytes.fromhex("010300000002")) * 3
    path.write_bytes(text)
    capture = open_capture(path, ReadOptions(mode="ascii"))
    assert capture.info.format == "raw"
    assert b"".join(c.data for c in capture.chunks()) == text


def test_raw_bytes_are_spaced_one_character_apart(tmp_path: Path) -> None:
    path = tmp_path / "raw.bin"
    path.write_bytes(REQUEST)
    capture = open_capture(path, ReadOptions(baud=9600, parity="N"))
    (chunk,) = list(capture.chunks())
    assert chunk.t_start == 0.0
    assert chunk.t_end == pytest.approx(len(REQUEST) * LineSettings(9600, parity="N").char_time)


def test_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(CaptureError, match="no such file"):
        open_capture(tmp_path / "missing.pcapng")
    with pytest.raises(CaptureError, match="is a folder"):
        open_capture(tmp_path)
    empty = tmp_path / "empty.pcapng"
    empty.write_bytes(b"")
    with pytest.raises(CaptureError, match=r"empty\.pcapng: the file is empty; expected a capture"):
        open_capture(empty)
    with pytest.raises(CaptureError, match="baud rate must be positive"):
        open_capture(empty, ReadOptions(baud=0))


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their permissions")
def test_permission_denied(tmp_path: Path) -> None:
    path = tmp_path / "secret.pcapng"
    path.write_bytes(SEEDS["pcapng"])
    path.chmod(0)
    with pytest.raises(CaptureError, match=r"secret\.pcapng: cannot be read"):
        open_capture(path)


def test_unreadable_file_by_os_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "secret.pcapng"
    path.write_bytes(SEEDS["pcapng"])

    def deny(self: Path, *args: object, **kwargs: object) -> io.BufferedReader:
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "open", deny)
    with pytest.raises(CaptureError, match=r"secret.pcapng: cannot be read \(Permission denied\)"):
        open_capture(path)


def _consume(data: bytes, options: ReadOptions | None = None) -> None:
    """Open and read `data` as a capture; only CaptureError may come out."""
    folder = tempfile.mkdtemp()
    try:
        path = Path(folder) / "fuzz"
        path.write_bytes(data)
        try:
            capture = open_capture(path, options)
        except CaptureError:
            return
        for chunk in capture.chunks():
            assert chunk.t_start is None or chunk.t_start <= chunk.t_end + 1e-9
        assert all(isinstance(w, str) for w in capture.warnings)
    finally:
        shutil.rmtree(folder)


FUZZ = settings(
    max_examples=int(os.environ.get("MODSCOPE_FUZZ_EXAMPLES", "300")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)


@FUZZ
@given(st.binary(max_size=2048))
def test_random_bytes_never_escape(data: bytes) -> None:
    _consume(data)


@st.composite
def mutated(draw: st.DrawFn) -> tuple[str, bytes]:
    kind = draw(st.sampled_from(sorted(SEEDS)))
    data = bytearray(SEEDS[kind])
    for _ in range(draw(st.integers(1, 6))):
        action = draw(st.sampled_from(["flip", "cut", "insert", "delete", "zero"]))
        if not data:
            break
        at = draw(st.integers(0, len(data) - 1))
        if action == "flip":
            data[at] ^= 1 << draw(st.integers(0, 7))
        elif action == "cut":
            del data[at:]
        elif action == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=16))
        elif action == "delete":
            del data[at : at + draw(st.integers(1, 16))]
        else:
            data[at : at + 4] = b"\0\0\0\0"
    return kind, bytes(data)


@FUZZ
@given(mutated())
def test_mutated_captures_never_escape(case: tuple[str, bytes]) -> None:
    kind, data = case
    options = ReadOptions(probes=("RX",)) if kind == "sigrok" else None
    _consume(data, options)


@FUZZ
@given(st.lists(st.sampled_from(sorted(SEEDS)), min_size=2, max_size=3), st.data())
def test_spliced_captures_never_escape(kinds: list[str], data: st.DataObject) -> None:
    parts: list[bytes] = []
    for kind in kinds:
        seed = SEEDS[kind]
        start = data.draw(st.integers(0, len(seed)))
        parts.append(seed[start:] if len(parts) else seed[:start])
    _consume(b"".join(parts))
