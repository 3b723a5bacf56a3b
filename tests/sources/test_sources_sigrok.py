"""Tests the sigrok reader: real Modbus captures frame cleanly, synthetic UART decodes exactly."""

from __future__ import annotations

import itertools
import struct
import zipfile
from collections.abc import Sequence
from pathlib import Path

import pytest

from dissectors.checks import crc16, with_crc
from sniffer.model import Chunk, Direction, LineSettings
from sniffer.sources import CaptureError, ReadOptions, open_capture
from sniffer.sources.base import LineGuess
from sniffer.sources.sigrok import UartDecoder, parse_samplerate

SIGROK = Path(__file__).parent.parent / "captures" / "sigrok"
BRAINCHILD = SIGROK / "brainchild_io_16do" / "brainchild-io-16do.sr"
WIZMODBUS = SIGROK / "wizmodbus" / "wizmodbus.sr"
FLOWMETER = SIGROK / "flowmeter"
BRAINCHILD_OPTIONS = ReadOptions(probes=("1", "0"), invert=True, baud=19200)  # requests on "1"
FLOWMETER_OPTIONS = ReadOptions(probes=("RXTX",), baud=9600, parity="N")
WIZMODBUS_OPTIONS = ReadOptions(probes=("RX", "TX"), baud=9600, parity="N")

# Frames per channel, split at silences of at least 3.5 character times. Counted by
# printing every frame and reading them: brainchild polls FC 1, 2, 3, 4, 5, 6, 15, 16 and
# the capture ends after the second FC 15 exchange; flowmeter alternates request and
# response on one wire; wizmodbus reads pairs of registers 1000, 1002, ...
REAL_CAPTURES = [
    (BRAINCHILD, BRAINCHILD_OPTIONS, {0: 15, 1: 15}),
    (FLOWMETER / "flowmeter_graph_tool.sr", FLOWMETER_OPTIONS, {0: 18}),
    (FLOWMETER / "flowmeter_target0_val0.sr", FLOWMETER_OPTIONS, {0: 74}),
    (FLOWMETER / "flowmeter_target_0liter_per_min.sr", FLOWMETER_OPTIONS, {0: 112}),
    (FLOWMETER / "flowmeter_target_15liter_per_min.sr", FLOWMETER_OPTIONS, {0: 132}),
    (FLOWMETER / "flowmeter_target_20liter_per_min.sr", FLOWMETER_OPTIONS, {0: 66}),
    (WIZMODBUS, WIZMODBUS_OPTIONS, {0: 44, 1: 44}),
]


def split_frames(chunks: list[Chunk], line: LineSettings) -> dict[int, list[bytes]]:
    """Bytes of each channel cut at silences of at least 3.5 character times."""
    frames: dict[int, list[bytes]] = {}
    ends: dict[int, float] = {}
    for chunk in chunks:
        if chunk.event:
            continue
        assert chunk.t_start is not None
        channel = frames.setdefault(chunk.channel, [])
        if not channel or chunk.t_start - ends[chunk.channel] >= line.t35:
            channel.append(b"")
        channel[-1] += chunk.data
        ends[chunk.channel] = chunk.t_end
    return frames


@pytest.mark.parametrize(
    ("path", "options", "counts"), REAL_CAPTURES, ids=[p.name for p, _, _ in REAL_CAPTURES]
)
def test_real_captures_give_only_valid_frames(
    path: Path, options: ReadOptions, counts: dict[int, int]
) -> None:
    capture = open_capture(path, options)
    assert capture.info.format == "sigrok"
    assert capture.info.exact_timing
    chunks = list(capture.chunks())
    # brainchild's probes are named "0" and "1": the reader notes how it took "1"
    assert [w for w in capture.warnings if "--probe 1 is the probe named" not in w] == []
    assert all(not c.event for c in chunks)
    assert all(len(c.data) == 1 for c in chunks)
    assert capture.info.line is not None
    frames = split_frames(chunks, capture.info.line)
    assert {channel: len(found) for channel, found in frames.items()} == counts
    for found in frames.values():
        assert all(crc16(frame) == 0 for frame in found), [f.hex() for f in found]
    times = [c.t_end for c in chunks]
    assert times == sorted(times)


def test_brainchild_directions_and_first_exchange() -> None:
    capture = open_capture(BRAINCHILD, BRAINCHILD_OPTIONS)
    assert capture.info.channels == {0: "probe '1' (requests)", 1: "probe '0' (responses)"}
    assert capture.info.line == LineSettings(19200, 8, "E", 1, "auto")
    chunks = list(capture.chunks())
    assert {c.direction for c in chunks if c.channel == 0} == {Direction.MASTER}
    assert {c.direction for c in chunks if c.channel == 1} == {Direction.SLAVE}
    frames = split_frames(chunks, LineSettings(19200, 8, "E", 1))
    assert frames[0][0] == bytes.fromhex("01010003000 10dca".replace(" ", ""))
    assert frames[1][0] == bytes.fromhex("0101010190 48".replace(" ", ""))
    first = chunks[0]
    assert first.t_start is not None
    assert first.t_end - first.t_start == pytest.approx(11 / 19200)
    assert first.t_start == pytest.approx(0.031127, abs=2e-6)


def test_wizmodbus_slave_answers_inside_t35() -> None:
    capture = open_capture(WIZMODBUS, WIZMODBUS_OPTIONS)
    chunks = list(capture.chunks())
    line = LineSettings(9600, 8, "N", 1)
    gaps = []
    for before, after in itertools.pairwise(chunks):
        if before.channel == 0 and after.channel == 1:
            assert after.t_start is not None
            gaps.append((after.t_start - before.t_end) / line.char_time)
    assert len(gaps) == 44
    assert all(2.5 < gap < 3.2 for gap in gaps)


def test_probe_by_number_matches_probe_by_name() -> None:
    path = FLOWMETER / "flowmeter_graph_tool.sr"
    by_name = [c.data for c in open_capture(path, FLOWMETER_OPTIONS).chunks()]
    for token in ("probe3", "#3", "2"):  # "2": no probe is named so, so it is number 2
        numbered = ReadOptions(probes=(token,), baud=9600, parity="N")
        chunks = [c.data for c in open_capture(path, numbered).chunks()]
        assert (chunks == by_name) == (token != "2")
    # a bare "3" is the probe named "3" (probe4), and the reader says so
    capture = open_capture(path, ReadOptions(probes=("3",), baud=9600, parity="N"))
    assert capture.info.warnings == (
        "--probe 3 is the probe named '3' (probe4); write probe3 for probe number 3 ('RXTX')",
    )
    lower = ReadOptions(probes=("rxtx",), baud=9600, parity="N")
    assert [c.data for c in open_capture(path, lower).chunks()] == by_name


def test_missing_probe_lists_the_names() -> None:
    with pytest.raises(CaptureError, match=r"--probe.*") as info:
        open_capture(FLOWMETER / "flowmeter_graph_tool.sr")
    assert "'RXTX'" in str(info.value)
    assert "flowmeter_graph_tool.sr" in str(info.value)
    with pytest.raises(CaptureError, match="no probe 'CLK'"):
        open_capture(WIZMODBUS, ReadOptions(probes=("CLK",)))
    with pytest.raises(CaptureError, match="one probe, or two"):
        open_capture(WIZMODBUS, ReadOptions(probes=("RX", "TX", "DE")))


def test_idle_low_capture_without_invert_warns() -> None:
    capture = open_capture(BRAINCHILD, ReadOptions(probes=("1", "0")))
    list(capture.chunks())
    assert any("--invert" in warning for warning in capture.warnings)


# ---------------------------------------------------------------- synthetic sessions


def uart_levels(
    data: bytes,
    line: LineSettings,
    samples_per_bit: int,
    *,
    idle: int = 40,
    bad_parity: frozenset[int] = frozenset(),
    bad_stop: frozenset[int] = frozenset(),
) -> list[int]:
    """Levels (1 = mark) of `data` sent with `line`, `idle` samples of mark around it."""
    levels = [1] * idle
    for index, value in enumerate(data):
        bits = [0] + [(value >> k) & 1 for k in range(line.bytesize)]
        if line.parity != "N":
            ones = bin(value).count("1")
            parity = {"E": ones % 2, "O": 1 - ones % 2, "M": 1, "S": 0}[line.parity]
            bits.append(parity ^ (index in bad_parity))
        bits += [0 if index in bad_stop else 1] * line.stopbits
        for bit in bits:
            levels += [bit] * samples_per_bit
        levels += [1] * 3
    return levels + [1] * idle


def write_session(
    path: Path,
    columns: dict[int, list[int]],
    *,
    samplerate: str = "1 MHz",
    unitsize: int = 1,
    names: dict[int, str] | None = None,
    member_size: int = 1000,
    pad: int = 1,
) -> None:
    """A sigrok v2 session: `columns` maps 1-based probe number to its levels (shorter
    columns are padded with `pad`)."""
    length = max(len(levels) for levels in columns.values())
    words = []
    for i in range(length):
        word = 0
        for number, levels in columns.items():
            level = levels[i] if i < len(levels) else pad
            word |= level << (number - 1)
        words.append(word)
    raw = b"".join(struct.pack("<Q", word)[:unitsize] for word in words)
    names = names or {number: f"D{number - 1}" for number in columns}
    probe_lines = "".join(f"probe{number}={name}\n" for number, name in sorted(names.items()))
    metadata = (
        "[global]\nsigrok version=0.5.1\n\n[device 1]\ncapturefile=logic-1\n"
        f"total probes={unitsize * 8}\nsamplerate={samplerate}\n{probe_lines}unitsize={unitsize}\n"
    )
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("version", "2")
        archive.writestr("metadata", metadata)
        step = member_size * unitsize
        for k, start in enumerate(range(0, len(raw), step), start=1):
            archive.writestr(f"logic-1-{k}", raw[start : start + step])


def test_synthetic_exact_times_and_straddling_members(tmp_path: Path) -> None:
    line = LineSettings(9600, 8, "E", 1)
    frame = with_crc(bytes.fromhex("0103000a0001"))
    levels = uart_levels(frame, line, 10, idle=57)
    path = tmp_path / "one.sr"
    write_session(path, {1: levels}, samplerate="96 kHz", names={1: "A"}, member_size=333)
    capture = open_capture(path, ReadOptions(baud=9600))
    chunks = list(capture.chunks())
    assert capture.warnings == []
    assert capture.info.channels == {0: "probe 'A'"}
    assert b"".join(c.data for c in chunks) == frame
    per_char = (11 * 10 + 3) / 96000
    starts = [c.t_start for c in chunks]
    assert starts == pytest.approx([(57 + k * (11 * 10 + 3)) / 96000 for k in range(len(frame))])
    for chunk in chunks:
        assert chunk.t_start is not None
        assert chunk.t_end == pytest.approx(chunk.t_start + 11 * 10 / 96000)
        assert chunk.direction == Direction.UNKNOWN
    assert chunks[1].t_start is not None and chunks[0].t_start is not None
    assert chunks[1].t_start - chunks[0].t_start == pytest.approx(per_char)


def test_a_line_without_baud_is_measured_by_the_estimator_given(tmp_path: Path) -> None:
    # choosing a format means framing the characters, which is above the readers: the
    # reader hands the chosen probes' levels to the estimator in its options (a session
    # passes sniffer.analysis.baud.estimate_line), and without one keeps the defaults
    line = LineSettings(9600, 8, "N", 1)
    frame = with_crc(bytes.fromhex("0103000a0001"))
    levels = uart_levels(frame, line, 10, idle=57)
    path = tmp_path / "one.sr"
    write_session(path, {1: [1] * len(levels), 2: levels}, samplerate="96 kHz")
    asked: list[tuple[float, list[bytes], ReadOptions]] = []

    def estimator(
        samplerate: float, levels: Sequence[bytes], options: ReadOptions
    ) -> LineGuess | None:
        asked.append((samplerate, list(levels), options))
        return LineGuess(line, "measured at 9600 8N1")

    options = ReadOptions(probes=("2",), estimator=estimator)
    capture = open_capture(path, options)
    assert asked == [(96000.0, [bytes(levels)], options)]
    assert capture.info.line == line
    assert capture.info.notes == (f"{path}: measured at 9600 8N1",)
    assert b"".join(c.data for c in capture.chunks()) == frame

    asked.clear()
    given = open_capture(path, ReadOptions(probes=("2",), baud=9600, estimator=estimator))
    assert asked == [] and given.info.notes == ()
    defaults = open_capture(path, ReadOptions(probes=("2",)))
    assert defaults.info.line == LineSettings() and defaults.info.notes == ()
    assert b"".join(c.data for c in defaults.chunks()) != frame  # read at 19200 8E1


def test_synthetic_parity_and_framing_errors_are_events(tmp_path: Path) -> None:
    line = LineSettings(19200, 8, "O", 1)
    data = b"\x11\x22\x33\x44"
    levels = uart_levels(data, line, 8, bad_parity=frozenset({1}), bad_stop=frozenset({2}))
    path = tmp_path / "errors.sr"
    write_session(path, {2: levels}, samplerate="153.6 kHz", names={2: "B"})
    capture = open_capture(path, ReadOptions(parity="O"))
    chunks = list(capture.chunks())
    assert [(c.data, c.event) for c in chunks] == [
        (b"\x11", ""),
        (b"\x22", ""),
        (b"", "parity error"),
        (b"\x33", ""),
        (b"", "framing error"),
        (b"\x44", ""),
    ]
    assert chunks[2].note == "character 0x22"
    assert chunks[2].t_end == chunks[1].t_end


def test_synthetic_glitch_is_not_a_character(tmp_path: Path) -> None:
    line = LineSettings(19200, 8, "N", 2)
    levels = [1] * 50 + [0, 0] + [1] * 50 + uart_levels(b"\xa5", line, 10)
    path = tmp_path / "glitch.sr"
    write_session(path, {1: levels}, samplerate="192 kHz", names={1: "RX"})
    chunks = list(open_capture(path, ReadOptions(parity="N", stopbits=2)).chunks())
    assert [c.data for c in chunks] == [b"\xa5"]


def test_synthetic_two_probes_wide_samples_inverted(tmp_path: Path) -> None:
    line = LineSettings(19200, 7, "E", 1)
    request = b"\x3a\x30\x31"
    response = b"\x0d\x0a"
    master = uart_levels(request, line, 10, idle=20)
    slave = [1] * len(master) + uart_levels(response, line, 10, idle=20)
    inverted = {11: [1 - v for v in master], 14: [1 - v for v in slave]}
    path = tmp_path / "wide.sr"
    write_session(
        path,
        inverted,
        samplerate="192 kHz",
        unitsize=2,
        names={11: "REQ", 14: "RSP", 1: "unused"},
        member_size=77,
        pad=0,
    )
    options = ReadOptions(probes=("REQ", "14"), bytesize=7, invert=True)
    capture = open_capture(path, options)
    chunks = list(capture.chunks())
    assert capture.warnings == []
    assert [c.channel for c in chunks] == [0, 0, 0, 1, 1]
    assert b"".join(c.data for c in chunks if c.channel == 0) == request
    assert b"".join(c.data for c in chunks if c.channel == 1) == response
    assert [c.direction for c in chunks] == [Direction.MASTER] * 3 + [Direction.SLAVE] * 2


def test_single_probe_is_chosen_without_option(tmp_path: Path) -> None:
    path = tmp_path / "single.sr"
    write_session(path, {3: uart_levels(b"\x01", LineSettings(), 10)}, samplerate="192kHz")
    chunks = list(open_capture(path).chunks())
    assert [c.data for c in chunks] == [b"\x01"]


def test_capture_ending_inside_a_character_warns(tmp_path: Path) -> None:
    levels = uart_levels(b"\x01\x02", LineSettings(), 10, idle=10)[: -(10 + 3 + 60)]
    path = tmp_path / "cut.sr"
    write_session(path, {1: levels}, samplerate="192 kHz", names={1: "RX"})
    capture = open_capture(path)
    assert [c.data for c in capture.chunks()] == [b"\x01"]
    assert any("ends inside a character" in w for w in capture.warnings)


def test_too_slow_samplerate(tmp_path: Path) -> None:
    path = tmp_path / "slow.sr"
    write_session(path, {1: [1, 0, 1]}, samplerate="20 kHz", names={1: "RX"})
    with pytest.raises(CaptureError, match="too slow for 19200 baud"):
        open_capture(path)


def test_zip_without_metadata(tmp_path: Path) -> None:
    path = tmp_path / "other.zip"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("readme.txt", "hello")
    with pytest.raises(CaptureError, match="without sigrok metadata") as info:
        open_capture(path)
    assert "other.zip" in str(info.value)


def test_corrupt_member_keeps_what_came_before(tmp_path: Path) -> None:
    line = LineSettings()
    data = bytes(range(40))
    path = tmp_path / "corrupt.sr"
    write_session(path, {1: uart_levels(data, line, 10)}, samplerate="192 kHz", names={1: "RX"})
    raw = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as archive:
        third = archive.getinfo("logic-1-3")
        offset = third.header_offset
    start = offset + 30 + len("logic-1-3")
    raw[start : start + 8] = b"\xff" * 8  # ruin the deflate stream
    path.write_bytes(bytes(raw))
    capture = open_capture(path)
    got = b"".join(c.data for c in capture.chunks())
    assert 0 < len(got) < len(data)
    assert got == data[: len(got)]
    assert any(f"'logic-1-3' at byte offset {offset}" in w for w in capture.warnings)


def test_session_cut_short_is_read_from_local_headers(tmp_path: Path) -> None:
    line = LineSettings()
    data = bytes(range(60))
    path = tmp_path / "short.sr"
    write_session(path, {1: uart_levels(data, line, 10)}, samplerate="192 kHz", names={1: "RX"})
    raw = path.read_bytes()
    with zipfile.ZipFile(path) as archive:
        fifth = archive.getinfo("logic-1-5").header_offset
    path.write_bytes(raw[: fifth + 50])
    capture = open_capture(path)
    got = b"".join(c.data for c in capture.chunks())
    assert 0 < len(got) < len(data)
    assert got == data[: len(got)]
    assert "ZIP directory is missing" in capture.warnings[0]
    assert any(f"'logic-1-5' at byte offset {fifth}" in w for w in capture.warnings)


@pytest.mark.parametrize(
    ("text", "rate"),
    [("1 MHz", 1e6), ("4 MHz", 4e6), ("200 kHz", 2e5), ("1.5 GHz", 1.5e9), ("9600", 9600.0)],
)
def test_parse_samplerate(text: str, rate: float) -> None:
    assert parse_samplerate(text) == rate


def test_decoder_resyncs_on_every_start_bit() -> None:
    """A transmitter 3% fast still decodes: each character is timed from its own edge."""
    line = LineSettings(9600, 8, "N", 1)
    levels: list[int] = [1] * 30
    for value in b"\x55\xaa\x00\xff":
        bits = [0] + [(value >> k) & 1 for k in range(8)] + [1]
        for k, bit in enumerate(bits):
            levels += [bit] * (10 if k % 3 else 9)  # 9.67 samples per bit, not 10
    levels += [1] * 30
    decoder = UartDecoder(96000, line)
    chunks = decoder.feed(bytes(levels), final=True)
    assert b"".join(c.data for c in chunks) == b"\x55\xaa\x00\xff"
