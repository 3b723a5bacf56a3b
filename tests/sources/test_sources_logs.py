"""Tests the log readers (ESPHome, pymodbus, libmodbus, serial monitors) and the Saleae CSV
reader: bytes, directions and times from fixtures modelled on each tool's output; the same
frames as the same bytes given raw; recognition from content; bad lines as warnings."""

from __future__ import annotations

import itertools
import json
from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.cli import main
from sniffer.model import Chunk, Direction, Labels, LineSettings, SourceInfo, Stamp
from sniffer.session.session import Session
from sniffer.sources import ReadOptions, detect, open_capture
from sniffer.sources.logs import (
    LOG_FORMATS,
    PARSERS,
    LogRecord,
    parse_stamp,
    record_chunks,
    sniff_log,
)
from sniffer.sources.saleae import parse_value, sniff_saleae

LOGS = Path(__file__).parent.parent / "captures" / "logs"
CAPTURES = Path(__file__).parent.parent / "captures"

READ = with_crc(bytes.fromhex("010300000002"))
READ_ANSWER = with_crc(bytes.fromhex("010304000a000d"))
WRITE = with_crc(bytes.fromhex("0106000100ab"))  # FC 6: the answer echoes it
MULTI = with_crc(bytes.fromhex("11100001000204000a0102"))
MULTI_ANSWER = with_crc(bytes.fromhex("111000010002"))
INPUTS = with_crc(bytes.fromhex("02040000000a"))
INPUTS_ANSWER = with_crc(bytes.fromhex("02041400010002000300040005000600070008000900" + "0a"))

M, S, U = Direction.MASTER, Direction.SLAVE, Direction.UNKNOWN
EXCHANGE = [(READ, M), (READ_ANSWER, S), (WRITE, M), (WRITE, S)]
ASCII_READ = b":010300000002FA\r\n"  # Modbus ASCII: the same read, LRC 0xFA
ASCII_ANSWER = b":010304000A000DE1\r\n"
GARBLED_ANSWER = b"\x81" + READ_ANSWER[1:]  # one bit flipped on the wire: the CRC fails
ECHO_10 = with_crc(bytes.fromhex("0a0607d00004"))  # FC 6 to unit 10, answered by its echo


def read(
    name: str, options: ReadOptions | None = None
) -> tuple[list[tuple[bytes, Direction]], list[float], SourceInfo, list[str]]:
    capture = open_capture(LOGS / name, options)
    chunks = [c for c in capture.chunks() if not c.event]
    return (
        [(c.data, c.direction) for c in chunks],
        [c.t_end for c in chunks],
        capture.info,
        capture.warnings,
    )


# ---------------------------------------------------------------- what each reader gives

# file, format, records (bytes, direction), stamps, resolution, labels
CASES = [
    (
        "esphome_hex_ms.log",
        "esphome",
        [*EXCHANGE, (MULTI, M), (MULTI_ANSWER, S), (INPUTS, M)],
        Stamp.PRINT,
        1e-3,
        Labels.HINT,
    ),
    ("esphome_hex_seconds.log", "esphome", EXCHANGE, Stamp.PRINT, 1.0, Labels.HINT),
    (
        "esphome_rx_only.log",
        "esphome",
        [(d, U) for d, _ in EXCHANGE],
        Stamp.NONE,
        0.0,
        Labels.NONE,
    ),
    ("esphome_decimal.log", "esphome", EXCHANGE[:2], Stamp.PRINT, 1.0, Labels.HINT),
    ("esphome_string.log", "esphome", EXCHANGE, Stamp.PRINT, 1.0, Labels.HINT),
    (
        "pymodbus_3x.log",
        "pymodbus",
        [
            (READ, M),
            (READ_ANSWER[:4], S),  # pymodbus logs every read: the answer came in two
            (READ_ANSWER[4:], S),
            (WRITE, M),
            (WRITE, S),
            (MULTI, M),
            (MULTI_ANSWER, S),
            (INPUTS, M),
        ],
        Stamp.PRINT,
        1e-3,
        Labels.HINT,
    ),
    ("pymodbus_2x_ha.log", "pymodbus", EXCHANGE, Stamp.PRINT, 1.0, Labels.HINT),
    ("pymodbus_notime.log", "pymodbus", EXCHANGE, Stamp.NONE, 0.0, Labels.HINT),
    (
        "libmodbus_client.log",
        "libmodbus",
        [*EXCHANGE, (MULTI, M), (MULTI, M), (MULTI_ANSWER, S)],
        Stamp.NONE,
        0.0,
        Labels.HINT,
    ),
    ("libmodbus_server.log", "libmodbus", EXCHANGE, Stamp.NONE, 0.0, Labels.HINT),
    (
        "tio_hex.log",
        "monitor",
        [(d, U) for d, _ in [*EXCHANGE, (MULTI, M), (MULTI_ANSWER, S)]],
        Stamp.PRINT,
        1e-3,
        Labels.NONE,
    ),
    (
        "tio_iso.log",
        "monitor",
        [(READ + READ_ANSWER[:4], U), (READ_ANSWER[4:], U), (WRITE, U), (WRITE, U)],
        Stamp.PRINT,
        1e-3,
        Labels.NONE,
    ),
    (
        "generic_txrx.log",
        "monitor",
        [*EXCHANGE, (MULTI, M), (MULTI_ANSWER, S)],
        Stamp.PRINT,
        1e-3,
        Labels.HINT,
    ),
    ("arrows_notime.log", "monitor", EXCHANGE, Stamp.NONE, 0.0, Labels.HINT),
    (
        "evcc_rtu.log",
        "evcc",
        [*EXCHANGE, (INPUTS, M), (INPUTS, M), (INPUTS_ANSWER, S)],
        Stamp.PRINT,
        1.0,
        Labels.HINT,
    ),
    (
        "evcc_ascii.log",
        "evcc",
        [(ASCII_READ, M), (ASCII_ANSWER, S)] * 2,
        Stamp.PRINT,
        1.0,
        Labels.HINT,
    ),
    (
        "modbustools_client.log",
        "modbustools",
        [*EXCHANGE, (MULTI, M), (MULTI_ANSWER, S), (READ, M), (GARBLED_ANSWER, S)],
        Stamp.PRINT,
        1e-3,
        Labels.HINT,
    ),
    (
        "modbustools_ascii_notime.log",
        "modbustools",
        [(ASCII_READ, M), (ASCII_ANSWER, S), (ASCII_READ, M), (ASCII_ANSWER[:-4] + b"E2\r\n", S)],
        Stamp.NONE,
        0.0,
        Labels.HINT,
    ),
    (
        "cas_newest_first.log",  # read from its last line up
        "cas",
        [
            (READ, M),
            (READ_ANSWER, S),
            (INPUTS, M),
            (WRITE, M),
            (WRITE, S),
            (MULTI, M),
            (MULTI_ANSWER, S),
        ],
        Stamp.PRINT,
        1.0,
        Labels.HINT,
    ),
    ("cas_one_second.log", "cas", [(ECHO_10, M), (ECHO_10, S)], Stamp.PRINT, 1.0, Labels.HINT),
    (
        "pymodbus_sync_37.log",
        "pymodbus",
        [(READ, M), (READ_ANSWER, S), (INPUTS, M), (INPUTS, M), (INPUTS_ANSWER, S)],
        Stamp.PRINT,
        1e-3,
        Labels.HINT,
    ),
    (
        "pymodbus_sync_38.log",  # answers only, and the write heard back as local echo
        "pymodbus",
        [(READ_ANSWER, S), (WRITE, M), (WRITE, S), (INPUTS_ANSWER[:9], S), (INPUTS_ANSWER[9:], S)],
        Stamp.PRINT,
        1e-3,
        Labels.HINT,
    ),
    (
        "sscom_gbk.log",
        "monitor",
        [*EXCHANGE, (MULTI, M), (MULTI_ANSWER, S)],
        Stamp.PRINT,
        1e-3,
        Labels.HINT,
    ),
    (
        "serial_port_monitor.txt",
        "monitor",
        [
            (READ, M),
            (READ_ANSWER, S),
            (MULTI, M),
            (MULTI_ANSWER, S),
            (INPUTS, M),
            (INPUTS_ANSWER, S),
        ],
        Stamp.PRINT,
        1.0,
        Labels.HINT,
    ),
]


@pytest.mark.parametrize(
    ("name", "kind", "expected", "stamps", "resolution", "labels"),
    CASES,
    ids=[c[0] for c in CASES],
)
def test_reader_gives_the_logged_bytes_directions_and_time_meaning(
    name: str,
    kind: str,
    expected: list[tuple[bytes, Direction]],
    stamps: Stamp,
    resolution: float,
    labels: Labels,
) -> None:
    capture = open_capture(LOGS / name)
    chunks = [c for c in capture.chunks() if not c.event]
    assert capture.info.format == kind
    assert [(c.data, c.direction) for c in chunks] == expected
    assert {c.channel for c in chunks} == {0}
    assert capture.info.stamps == stamps
    assert capture.info.resolution == pytest.approx(resolution)
    assert capture.info.labels == labels
    times = [c.t_end for c in chunks]
    assert times == sorted(times)
    if stamps == Stamp.NONE:  # synthetic: strictly increasing, one character time a byte
        assert all(b > a for a, b in itertools.pairwise(times))


def test_esphome_millisecond_times_are_the_printed_times() -> None:
    _, times, _, _ = read("esphome_hex_ms.log")
    base = 12 * 3600 + 34 * 60 + 56
    assert times[:4] == pytest.approx([base + 0.120, base + 0.151, base + 0.320, base + 0.352])


def test_time_of_day_going_past_midnight_moves_on_a_day() -> None:
    _, times, _, _ = read("esphome_hex_seconds.log")
    assert times == [86399.0, 86399.0, 86400.0, 86400.0]


def test_pymodbus_times_are_the_logging_records_times() -> None:
    _, times, _, _ = read("pymodbus_3x.log")
    first = parse_stamp("2024-05-01 12:00:00,103")
    assert first is not None and first.dated
    assert times[0] == pytest.approx(first.seconds)
    assert times[1] - times[0] == pytest.approx(0.015, abs=1e-6)


def test_libmodbus_opening_line_gives_the_line_settings() -> None:
    _, _, info, _ = read("libmodbus_client.log")
    assert info.line == LineSettings(baud=9600, bytesize=8, parity="N", stopbits=2)
    _, _, info, _ = read("libmodbus_client.log", ReadOptions(baud=19200))
    assert info.line is not None and info.line.baud == 19200


def test_serial_port_monitor_blocks_join_their_hex_lines() -> None:
    records, times, _, _ = read("serial_port_monitor.txt")
    assert records[-1] == (INPUTS_ANSWER, S)  # 25 bytes over two lines, ASCII column left out
    assert times[0] == times[1]  # one-second print times: same second


# ---------------------------------------------------------------- bad lines


@pytest.mark.parametrize(
    ("name", "line", "records"),
    [
        ("esphome_hex_ms.log", 11, 7),
        ("pymodbus_3x.log", 12, 8),
        ("generic_txrx.log", 8, 6),
    ],
)
def test_a_bad_line_is_a_warning_naming_file_and_line(name: str, line: int, records: int) -> None:
    found, _, _, warnings = read(name)
    assert len(found) == records
    assert len(warnings) == 1
    assert str(LOGS / name) in warnings[0]
    assert f"line {line}:" in warnings[0]


def test_pymodbus_repeating_marker_is_reported(tmp_path: Path) -> None:
    path = tmp_path / "repeat.log"
    path.write_text(
        "2024-05-01 12:00:00,103 DEBUG transaction:180 send: 0x1 0x3 0x0 0x0 0x0 0x2 0xc4 0xb\n"
        "2024-05-01 12:00:00,203 DEBUG transaction:180 Repeating....\n"
    )
    capture = open_capture(path)
    assert [c.data for c in capture.chunks()] == [READ]
    assert any("line 2:" in w and "Repeating" in w for w in capture.warnings)


def test_modbus_tcp_in_a_pymodbus_log_is_framed_as_modbus_tcp(tmp_path: Path) -> None:
    path = tmp_path / "tcp.log"
    path.write_text(
        "DEBUG:pymodbus.logging:SEND: 0x0 0x7 0x0 0x0 0x0 0x6 0x1 0x1 0x0 0x1 0x0 0x8\n"
    )
    capture = open_capture(path)
    chunks = list(capture.chunks())
    assert capture.info.network
    assert capture.info.channels[0].endswith("modbus-tcp")
    assert [(c.channel, c.direction) for c in chunks] == [(0, M)]
    assert not capture.warnings


def test_a_log_with_no_bytes_says_so(tmp_path: Path) -> None:
    path = tmp_path / "empty.log"
    path.write_text("[12:00:00][D][uart_debug:158]: <<< \n")
    capture = open_capture(path)
    assert list(capture.chunks()) == []
    assert any("no bytes" in w for w in capture.warnings)


lines_strategy = st.lists(
    st.one_of(
        st.text(max_size=60),
        st.builds(
            lambda prefix, body: prefix + body,
            st.sampled_from(
                [
                    "[12:00:00][D][uart_debug:158]: >>> ",
                    "[12:00:00.1][D][uart_debug:158]: <<< ",
                    "2024-05-01 12:00:00,1 DEBUG x:1 send: ",
                    "recv: ",
                    "[12:00:00.123] TX: ",
                    "[01/05/2024 12:00:00] Read data (COM1)",
                    "[sdm   ] TRACE 2024/07/29 11:25:25 modbus: send ",
                    "[sdm   ] TRACE 2024/07/29 11:25:25 modbus: recv ",
                    "Jul 29 x: [a] TRACE 2024/07/29 23:59:59 modbus: ",
                    "14.05.2025 09:57:07.113 'Device' Tx: ",
                    "'Device' Rx: ",
                    "14.05.2025 09:57:07.113 'PORT' Error: ",
                    "[11:20:03] => Poll: ",
                    "[11:20:03] <= Response: ",
                    "[23:59:59] ",
                    "2025-03-02 08:00:00,042 DEBUG base:76 Processing: ",
                    "sync recv skipping (local_echo): ",
                    "Connecting to [192.168.1.20]:502",
                    "",
                ]
            ),
            st.text(alphabet='0123456789abcdefABCDEFx:, "\\<>[]-', max_size=40),
        ),
    ),
    max_size=20,
)


@pytest.mark.parametrize("kind", LOG_FORMATS)
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lines=lines_strategy)
def test_parsers_never_raise_and_keep_time_in_order(kind: str, lines: list[str]) -> None:
    parsed = PARSERS[kind](lines, "f.log")
    warnings: list[str] = []
    chunks = list(record_chunks(parsed.records, LineSettings(), "f.log", warnings))
    times = [c.t_end for c in chunks]
    assert times == sorted(times)
    assert all(bool(c.data) != bool(c.event) for c in chunks)  # bytes, or an event
    assert all(w.startswith("f.log") for w in [*parsed.warnings, *warnings])


def test_times_that_go_back_keep_file_order_with_one_warning() -> None:
    stamps = [parse_stamp(t) for t in ("2024-05-01 12:00:01", "2024-05-01 12:00:00")]
    records = [LogRecord(READ, 1, stamps[0], M), LogRecord(READ_ANSWER, 2, stamps[1], S)]
    warnings: list[str] = []
    chunks = list(record_chunks(records, LineSettings(), "f.log", warnings))
    assert [c.data for c in chunks] == [READ, READ_ANSWER]
    assert chunks[1].t_end == chunks[0].t_end
    assert len(warnings) == 1 and "line 2:" in warnings[0]


@pytest.mark.parametrize(
    ("text", "seconds", "resolution", "dated"),
    [
        ("[12:34:56]", 45296.0, 1.0, False),
        ("[12:34:56.789]x", 45296.789, 1e-3, False),
        ("12:00:00,5 TX", 43200.5, 0.1, False),
        ("[2024-05-01T00:00:01.250]", None, 1e-3, True),
        ("2024-05-01 00:00:01,250 DEBUG", None, 1e-3, True),
        ("[01/05/2024 00:00:01] Read", None, 1.0, True),
        ("[05/13/2024 00:00:01] Read", None, 1.0, True),
    ],
)
def test_stamp_forms(text: str, seconds: float | None, resolution: float, dated: bool) -> None:
    stamp = parse_stamp(text)
    assert stamp is not None
    assert stamp.resolution == pytest.approx(resolution)
    assert stamp.dated == dated
    if seconds is not None:
        assert stamp.seconds == pytest.approx(seconds)


def test_dated_stamps_agree_across_forms() -> None:
    a = parse_stamp("2024-05-01 00:00:01,250")
    b = parse_stamp("[01/05/2024 00:00:01.250]")
    c = parse_stamp("[2024-05-01T00:00:01.250]")
    assert a is not None and b is not None and c is not None
    assert a.seconds == pytest.approx(b.seconds) == pytest.approx(c.seconds)


@pytest.mark.parametrize("text", ["[25:00:00]", "12:61:00", "[12:00:00", "hello"])
def test_not_a_stamp(text: str) -> None:
    assert parse_stamp(text) is None


# ---------------------------------------------------------------- Saleae


def test_saleae_logic1_bytes_start_times_and_errors() -> None:
    capture = open_capture(LOGS / "saleae_logic1.csv", ReadOptions(baud=9600, parity="N"))
    chunks = list(capture.chunks())
    info = capture.info
    assert (info.format, info.stamps, info.labels, info.exact_timing) == (
        "saleae",
        Stamp.EXACT,
        Labels.NONE,
        True,
    )
    data = [c for c in chunks if not c.event]
    assert b"".join(c.data for c in data) == READ + READ_ANSWER + WRITE + WRITE + b"\x00\xff"
    assert all(len(c.data) == 1 and c.t_start is not None for c in data)
    assert data[0].t_start == pytest.approx(0.1)
    assert data[0].t_end == pytest.approx(0.1 + 10 / 9600)  # no duration: one character
    events = [(c.event, c.t_end) for c in chunks if c.event]
    assert [e for e, _ in events] == ["framing error", "parity error"]
    # each event follows the byte it marks
    marked = [chunks[i - 1].data for i, c in enumerate(chunks) if c.event]
    assert marked == [b"\x00", b"\xff"]


def test_saleae_logic2_table_analysers_are_channels_with_their_direction() -> None:
    capture = open_capture(LOGS / "saleae_logic2_table.csv")
    chunks = list(capture.chunks())
    assert capture.info.labels == Labels.CERTAIN
    assert capture.info.channels == {
        0: "analyser 'Master' (requests)",
        1: "analyser 'Slave' (responses)",
    }
    by_channel = {
        ch: b"".join(c.data for c in chunks if c.channel == ch and not c.event) for ch in (0, 1)
    }
    assert by_channel == {0: READ + WRITE, 1: READ_ANSWER + WRITE + b"\x00"}
    assert {c.direction for c in chunks if c.channel == 0} == {M}
    assert {c.direction for c in chunks if c.channel == 1} == {S}
    first = chunks[0]
    assert first.t_start == pytest.approx(0.1)
    assert first.t_end == pytest.approx(0.1 + 9.5 / 9600, abs=1e-9)  # start + duration
    assert [c.event for c in chunks if c.event] == ["framing error"]


def test_saleae_bad_row_is_a_warning(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(
        "Time [s],Value,Parity Error,Framing Error\n0.1,0x01,,\nabc,0x02,,\n0.2,0x1FF,,\n"
    )
    capture = open_capture(path)
    assert [c.data for c in capture.chunks()] == [b"\x01"]
    assert len(capture.warnings) == 2
    assert f"{path} line 3:" in capture.warnings[0]
    assert f"{path} line 4:" in capture.warnings[1]


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("0x1B", 0x1B),
        ("0b00000110", 6),
        ("200", 200),
        ("A", 65),
        ("7", 55),  # ASCII radix: one character is that character
        ("' '", 32),
        ("\\r", 13),
        ("COMMA", 44),
        ("\\x01", 1),
        ("0x100", None),
        ("", None),
        ("xyz", None),
    ],
)
def test_saleae_values(text: str, value: int | None) -> None:
    assert parse_value(text) == value


# ---------------------------------------------------------------- same frames as raw bytes

LINE = ["--baud", "9600", "--parity", "N"]


def jsonl_frames(
    path: Path, capsys: pytest.CaptureFixture[str], *options: str, warned: bool = False
) -> list[tuple[str, bool, str]]:
    """(raw hex, check ok, kind) of every row `modscope replay --format jsonl` lists; the
    exit status is 1 where the file has lines it had to skip, else 0."""
    code = main(["replay", str(path), "--format", "jsonl", "--mode", "rtu", *LINE, *options])
    out = capsys.readouterr().out
    assert code == (1 if warned else 0)
    rows = [json.loads(line) for line in out.splitlines() if line.strip()]
    return [(r["raw"], r["check_ok"], r["kind"]) for r in rows if r.get("kind") != "event"]


def session_frames(chunks: list[Chunk], exact: bool) -> list[tuple[bytes, bool, str]]:
    session = Session(LineSettings(baud=9600, parity="N", mode="rtu"), exact_timing=exact)
    session.ingest(chunks)
    views = [session.store.view(i) for i in range(len(session.store))]
    # kinds by name: `Kind` moves to sniffer.vocab in the architecture refactor
    return [(v.raw, v.check_ok, v.kind.name) for v in views if v.kind.name != "EVENT"]


def raw_file_frames(data: bytes, tmp_path: Path) -> list[tuple[bytes, bool, str]]:
    path = tmp_path / "same.bin"
    path.write_bytes(data)
    capture = open_capture(path, ReadOptions(baud=9600, parity="N", mode="rtu"))
    return session_frames(list(capture.chunks()), exact=False)


EXPECTED = {c[0]: c[2] for c in CASES}
# Modbus ASCII logs: framed as ASCII in tests/sources/test_sources_field_logs.py
ASCII_LOGS = {"evcc_ascii.log", "modbustools_ascii_notime.log"}
FRAME_CASES = [c[0] for c in CASES if c[0] not in ASCII_LOGS] + [
    "rvs_dn_example2_text2pcap.txt",
    "saleae_logic1.csv",
    "saleae_logic2_table.csv",
]


@pytest.mark.parametrize("name", FRAME_CASES)
def test_log_timing_finds_the_frames_of_the_same_bytes_given_raw(name: str, tmp_path: Path) -> None:
    """The reader's times (print times, synthetic times, exact byte times) and its cuts into
    lines change no frame: the chunks with their directions taken away are framed as the
    same bytes in a raw file are. (Direction labels are the pairing core's matter: below.)"""
    capture = open_capture(LOGS / name, ReadOptions(baud=9600, parity="N", mode="rtu"))
    chunks = list(capture.chunks())
    unlabelled = [replace(c, direction=U, channel=0) for c in chunks]
    data = b"".join(c.data for c in chunks)
    from_log = session_frames(unlabelled, capture.info.exact_timing)
    from_raw = raw_file_frames(data, tmp_path)
    if capture.info.stamps == Stamp.EXACT:
        # exact times show the silence between glitch bytes that a raw file cannot:
        # the same frames, and the same bytes left over as noise
        assert [f for f in from_log if f[1]] == [f for f in from_raw if f[1]]
        noise = [b"".join(f[0] for f in frames if not f[1]) for frames in (from_log, from_raw)]
        assert noise[0] == noise[1]
    else:
        assert from_log == from_raw
    whole = {data for data, _ in EXPECTED.get(name, []) if with_crc(data[:-2]) == data}
    assert whole <= {raw for raw, ok, _ in from_log if ok}


@pytest.mark.parametrize(
    "name",
    FRAME_CASES,
)
def test_replay_lists_the_frames_of_the_same_bytes_given_raw(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capture = open_capture(LOGS / name)
    raw = tmp_path / "same.bin"
    raw.write_bytes(b"".join(c.data for c in capture.chunks()))
    from_log = jsonl_frames(LOGS / name, capsys, warned=bool(capture.warnings))
    from_raw = jsonl_frames(raw, capsys)
    if capture.info.channels.keys() != {0}:  # one stream per analyser or direction
        assert sorted(f for f in from_log if f[1]) == sorted(f for f in from_raw if f[1])
    elif capture.info.stamps == Stamp.EXACT:  # glitch bytes apart in time: see above
        assert [f for f in from_log if f[1]] == [f for f in from_raw if f[1]]
    else:
        assert from_log == from_raw


def test_rvs_dn_example_2_dump_labels_and_frames(capsys: pytest.CaptureFixture[str]) -> None:
    path = LOGS / "rvs_dn_example2_text2pcap.txt"
    capture = open_capture(path)
    chunks = list(capture.chunks())
    request = bytes.fromhex("600300280003")  # unit 96, FC 3, registers 0x28-0x2A
    answer = bytes.fromhex("600308000000100000")  # as the manual prints it
    assert [(c.data, c.direction) for c in chunks] == [
        (with_crc(request), M),
        (with_crc(answer), S),
    ]
    assert capture.info.labels == Labels.HINT
    assert capture.info.stamps == Stamp.PRINT
    assert capture.info.resolution == pytest.approx(1e-6)
    frames = jsonl_frames(path, capsys)
    assert [(raw, ok) for raw, ok, _ in frames] == [
        (with_crc(request).hex(), True),
        (with_crc(answer).hex(), True),
    ]
    assert frames[0][2] == "request"  # the answer's kind: see the replay test above


# ---------------------------------------------------------------- recognition


@pytest.mark.parametrize(("name", "kind"), [(c[0], c[1]) for c in CASES])
def test_recognised_from_content(name: str, kind: str) -> None:
    head = (LOGS / name).read_bytes()[: detect.HEAD_SIZE]
    assert detect.sniff(head) == kind


@pytest.mark.parametrize("name", ["saleae_logic1.csv", "saleae_logic2_table.csv"])
def test_saleae_recognised_from_its_header(name: str) -> None:
    head = (LOGS / name).read_bytes()
    assert sniff_saleae(head)
    assert detect.sniff(head) == detect.SALEAE


def test_rvs_dn_dump_is_still_a_hexdump() -> None:
    head = (LOGS / "rvs_dn_example2_text2pcap.txt").read_bytes()
    assert detect.sniff(head) == detect.HEXDUMP


# the doctor's buses are Saleae exports by design (tests/captures/doctor/README.md)
DOCTOR = CAPTURES / "doctor"
EXISTING = sorted(
    p
    for p in CAPTURES.rglob("*")
    if p.is_file() and LOGS not in p.parents and DOCTOR not in p.parents
)


@pytest.mark.parametrize("path", sorted(DOCTOR.glob("*.csv")), ids=lambda p: p.name)
def test_the_doctors_buses_are_read_as_the_saleae_exports_they_are(path: Path) -> None:
    head = path.read_bytes()[: detect.HEAD_SIZE]
    assert sniff_log(head) is None
    assert detect.sniff(head) == detect.SALEAE


@pytest.mark.parametrize("path", EXISTING, ids=[p.name for p in EXISTING])
def test_existing_captures_are_not_taken_for_logs(path: Path) -> None:
    head = path.read_bytes()[: detect.HEAD_SIZE]
    assert sniff_log(head) is None
    assert not sniff_saleae(head)
    assert detect.sniff(head) not in (*LOG_FORMATS, detect.SALEAE)


@pytest.mark.parametrize(
    "text",
    [
        "just a note\n12:00:00 started\n",
        "Time [s],Channel 0\n0.0,1\n",  # a digital export, not the serial analyser
        "> 2024/05/01 12:00:00.000001  length=8 from=0 to=7\n 01 03\n--\n",
        "one line 01 02 03\n",
    ],
)
def test_other_text_is_not_a_log(text: str) -> None:
    head = text.encode()
    assert sniff_log(head) is None
    assert not sniff_saleae(head)


@settings(max_examples=200, deadline=None)
@given(head=st.binary(max_size=400))
def test_recognition_never_raises(head: bytes) -> None:
    sniff_log(head)
    sniff_saleae(head)
