"""The line-settings scan: a UART double serves the same Modbus traffic garbled as a real
receiver would read it at each wrong setting; the scan must find the true one, say when
it cannot, and never drive the line."""

from __future__ import annotations

import contextlib
import os
import random
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.analysis.baud import estimate_baud, estimate_line, wrong_speed
from sniffer.analysis.linescore import (
    BAUDS,
    ENOUGH_BYTES,
    Sample,
    Trial,
    candidates,
    decide,
    format_of,
    parse_format,
    score,
)
from sniffer.framing.pipeline import frame_capture
from sniffer.framing.store import FrameStore
from sniffer.live.scan import FORMATS, PortListener, live_command, no_line_settings, scan
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import open_session
from sniffer.sources import ReadOptions, open_capture
from sniffer.vocab import BAD_CHECK, Flag, Kind
from tests.support.scan_ports import NoControlPorts, PickyPorts
from tests.support.uart_double import GarbledLine, GarblingPorts, Wire, character_bits, modbus_cycle

REQUEST = with_crc(bytes.fromhex("010300000004"))
ANSWER = with_crc(bytes.fromhex("0103080001000200030004"))


def garbled(
    line: LineSettings,
    ascii_mode: bool = False,
    counters: str = "counting",
    resync: bool = False,
) -> GarbledLine:
    cycle, period = modbus_cycle(line, ascii_mode)
    return GarbledLine(Wire(line, cycle, period), counters=counters, resync=resync)


# -- the double itself ------------------------------------------------------------------


def test_character_bits_8e1_and_7o1() -> None:
    assert character_bits(0x01, LineSettings(9600, 8, "E", 1)) == [0, 1, 0, 0, 0, 0, 0, 0, 0, 1, 1]
    assert character_bits(0x3A, LineSettings(9600, 7, "O", 1)) == [0, 0, 1, 0, 1, 1, 1, 0, 1, 1]


def test_double_reads_cleanly_at_the_true_setting_and_garbles_elsewhere() -> None:
    line = LineSettings(19200, 8, "E", 1)
    wire = Wire(line, [(0.0, REQUEST), (0.01, ANSWER)], period=0.05)
    got, framing, parity = wire.receive(line, 0.0, 0.05)
    assert bytes(v for _t, v in got) == REQUEST + ANSWER
    assert (framing, parity) == (0, 0)
    wrong, framing, parity = wire.receive(LineSettings(9600, 8, "E", 1), 0.0, 0.05)
    assert bytes(v for _t, v in wrong) != REQUEST + ANSWER
    assert framing + parity > 0
    odd, _framing, parity = wire.receive(LineSettings(19200, 8, "O", 1), 0.0, 0.05)
    assert bytes(v for _t, v in odd) == REQUEST + ANSWER  # data intact, every parity wrong
    assert parity == len(REQUEST + ANSWER)


# -- scoring and deciding ---------------------------------------------------------------


def test_score_counts_valid_frames_pairs_and_noise() -> None:
    line = LineSettings(19200, 8, "E", 1)
    chunks = (Chunk(REQUEST, 0.001), Chunk(ANSWER, 0.010), Chunk(b"\x55\xaa\x13", 0.05))
    trial = score(line, Sample(chunks, 0.1, 0, 0))
    assert (trial.frames, trial.pairs, trial.bad_frames) == (2, 1, 0)
    assert trial.noise == 3 and trial.bytes == len(REQUEST + ANSWER) + 3
    assert trial.valid


@pytest.mark.parametrize(
    ("baud", "fmt", "ascii_mode"),
    [
        (9600, "8E1", False),
        (19200, "8O1", False),
        (1200, "8E1", False),
        (115200, "8N1", False),
        (921600, "8E1", False),
        (4800, "7E1", True),
        (38400, "7O1", True),
        (9600, "8N1", True),  # ASCII sent with 8 data bits
    ],
)
def test_scan_finds_the_true_setting(baud: int, fmt: str, ascii_mode: bool) -> None:
    bytesize, parity, stopbits = parse_format(fmt)
    line = LineSettings(baud, bytesize, parity, stopbits)
    result = scan(garbled(line, ascii_mode))
    assert result.winner is not None, result.verdict
    assert (result.winner.line.baud, result.winner.line.bytesize) == (baud, bytesize)
    assert result.winner.line.parity == parity
    assert result.winner.mode == ("ascii" if ascii_mode else "rtu")
    assert result.trials[0] is result.winner
    assert result.winner.pairs > 0
    # every wrong baud rate read bytes but no run of valid frames
    assert all(not t.valid for t in result.trials if t.line.baud != baud)


def test_two_stop_bits_read_as_one_and_the_scan_says_so() -> None:
    result = scan(garbled(LineSettings(19200, 8, "N", 2)))
    assert result.winner is not None and result.winner.settings() == "19200 8N1"
    assert result.alike == ("8N1", "8N2") and result.confidence == "medium"
    assert result.verdict.startswith("19200 8N1 or 8N2 (RTU): ")
    assert "only the first stop bit" in result.reason
    assert any("logic analyser" in r for r in result.raise_it)


def test_without_driver_counters_the_format_is_a_stated_guess() -> None:
    # a plain receiver reads 8E1 traffic at 8N1 cleanly; with no counters nothing here
    # tells the four formats apart, and the verdict says so instead of picking one
    result = scan(garbled(LineSettings(9600, 8, "E", 1), counters="none"))
    assert result.winner is not None and result.winner.line.baud == 9600
    assert result.counters == "none" and not result.counted_errors
    assert result.alike == ("8N1", "8E1", "8O1", "8N2") and result.confidence == "low"
    assert "keeps no framing or parity error counters" in result.reason
    assert "nothing here tells them apart" in result.reason


def test_second_round_only_at_bauds_that_read_frames() -> None:
    listen = garbled(LineSettings(9600, 8, "E", 1))
    scan(listen)
    formats = {(line.baud, f"{line.bytesize}{line.parity}{line.stopbits}") for line in listen.heard}
    assert {f for b, f in formats if b != 9600} == {"8N1", "8E1", "7E1"}
    assert {f for b, f in formats if b == 9600} == {"8N1", "8E1", "8O1", "8N2", "7E1"}


def test_a_silent_line_is_too_quiet_and_listened_to_longer() -> None:
    heard: list[float] = []
    bauds: list[int] = []

    def silent(line: LineSettings, seconds: float) -> Sample:
        heard.append(seconds)
        bauds.append(line.baud)
        return Sample((), seconds, 0, 0)

    result = scan(silent, bauds=(1200, 9600, 19200), formats=("8N1",), dwell=0.5, max_dwell=3)
    assert result.winner is None and result.quiet
    assert result.verdict.startswith("too quiet to decide: no byte arrived in 6.0 s")
    # each setting listened to for longer and longer, up to max_dwell; two silent
    # settings are enough: a wrong setting would still have heard bytes
    assert heard == [0.5, 1.0, 1.5] * 2
    assert bauds == [19200] * 3 + [9600] * 3  # fastest first
    assert len(result.trials) == 2
    assert len(result.trials) == 2


def test_a_few_bytes_are_too_quiet_not_a_verdict() -> None:
    def sparse(line: LineSettings, seconds: float) -> Sample:
        return Sample((Chunk(b"\x01\x03", 0.0),), seconds, 0, 0)

    result = scan(sparse, bauds=(9600,), formats=("8N1",), dwell=0.1, max_dwell=0.2)
    assert result.quiet and result.winner is None


def test_a_garbling_setting_that_heard_a_busier_stretch_does_not_win() -> None:
    """Found running the scan through a port double: 8N1 read 13 frames in 1.8 s with a
    line error on most bytes, 8E1 17 frames in 4 s with almost none; 8E1 is the line's."""

    def trial(fmt: str, seconds: float, size: int, frames: int, errors: int) -> Trial:
        bytesize, parity, stopbits = parse_format(fmt)
        line = LineSettings(19200, bytesize, parity, stopbits)
        return Trial(line, seconds, size, frames, 0, 0, frames // 2, errors, 0, "rtu")

    result = decide(
        [
            trial("8N1", 1.8, 250, 13, 158),
            trial("8E1", 4.0, 424, 17, 4),
            trial("8O1", 4.0, 394, 19, 394),
        ]
    )
    assert result.winner is not None and result.winner.settings() == "19200 8E1"


def test_noise_without_frames_is_no_setting() -> None:
    def hiss(line: LineSettings, seconds: float) -> Sample:
        return Sample((Chunk(bytes(range(256)) * 2, 0.0),), seconds, 40, 10)

    result = decide([score(line, hiss(line, 0.5)) for line in candidates((9600,), ("8N1",))])
    assert result.winner is None and not result.quiet
    assert "no setting gave valid Modbus frames" in result.verdict


def test_live_command_is_exact() -> None:
    result = scan(garbled(LineSettings(4800, 7, "E", 1), ascii_mode=True))
    assert result.winner is not None
    assert live_command("/dev/ttyUSB0", result.winner) == (
        "modscope live /dev/ttyUSB0 --baud 4800 --parity E --bytesize 7 --mode ascii"
    )
    table = result.table()
    assert table.splitlines()[1].split()[1:3] == ["4800", "7E1"]


@pytest.mark.slow
@settings(max_examples=15, deadline=None)
@given(
    baud=st.sampled_from(BAUDS),
    fmt=st.sampled_from(["8N1", "8E1", "8O1"]),
    start=st.floats(min_value=0.0, max_value=0.05),
)
def test_scan_never_names_a_wrong_baud(baud: int, fmt: str, start: float) -> None:
    bytesize, parity, stopbits = parse_format(fmt)
    listen = garbled(LineSettings(baud, bytesize, parity, stopbits))
    listen.now = start
    result = scan(listen, dwell=0.4)
    assert result.winner is not None and result.winner.line.baud == baud


# -- through a port: passive ------------------------------------------------------------


def test_port_listener_scans_through_a_passive_port_double() -> None:
    line = LineSettings(19200, 8, "E", 1)
    cycle, period = modbus_cycle(line)
    ports = GarblingPorts(Wire(line, cycle, period), window=0.3)
    listener = PortListener("/dev/ttyDOUBLE0", factory=ports, counters=ports.counters)
    result = scan(listener, bauds=(9600, 19200, 38400), dwell=0.02, max_dwell=0.05)
    assert result.winner is not None and result.winner.settings() == "19200 8E1"
    assert result.winner.parity_errors == 0
    odd = next(t for t in result.trials if t.settings() == "19200 8O1")
    assert odd.parity_errors is not None and odd.parity_errors > 0
    # passive: every port configured before it opened, RTS/DTR off, nothing written
    assert ports.violations() == []
    for port in ports.ports:
        assert port.calls[0] == "open" and port.calls[-1] == "close"
        assert set(port.calls) <= {"open", "close", "low_latency=True"}
        assert (port.rts, port.dtr) == (False, False)
    assert len(ports.ports) >= len(result.trials)  # a quiet setting is reopened to listen longer


# -- offline: the baud rate and format of a logic capture -------------------------------

SIGROK = Path(__file__).parent.parent / "captures" / "sigrok"


@pytest.mark.parametrize(
    ("path", "probes", "invert", "setting", "frames"),
    [
        # settings and frame counts as tests/captures/README.md gives them
        (SIGROK / "brainchild_io_16do/brainchild-io-16do.sr", ("1", "0"), True, "19200 8E1", 30),
        (SIGROK / "flowmeter/flowmeter_graph_tool.sr", ("RXTX",), False, "9600 8N1", 18),
        (SIGROK / "flowmeter/flowmeter_target0_val0.sr", ("RXTX",), False, "9600 8N1", 74),
        (SIGROK / "wizmodbus/wizmodbus.sr", ("RX", "TX"), False, "9600 8N1", 88),
    ],
    ids=lambda v: v.name if isinstance(v, Path) else None,
)
def test_sigrok_without_line_flags_measures_the_line(
    path: Path, probes: tuple[str, ...], invert: bool, setting: str, frames: int
) -> None:
    # the session gives the reader the estimator (readers stand below the framing it needs)
    _session, capture = open_session(path, ReadOptions(probes=probes, invert=invert), index=False)
    line = capture.info.line
    assert line is not None and f"{line.baud} {format_of(line)}" == setting
    notes = [w for w in capture.info.notes if "no --baud given" in w]
    assert len(notes) == 1 and f"chose {setting}" in notes[0] and str(path) in notes[0]
    store = frame_capture(capture.chunks(), line, exact_timing=True)
    valid = sum(
        1
        for i in range(len(store))
        if store.kind[i] not in (Kind.NOISE, Kind.EVENT) and not store.flags[i] & Flag.CHECK_BAD
    )
    assert valid == frames


def test_sigrok_flags_given_are_kept() -> None:
    path = SIGROK / "wizmodbus/wizmodbus.sr"
    capture = open_capture(path, ReadOptions(probes=("RX", "TX"), baud=9600, parity="N"))
    assert not [w for w in capture.info.notes if "no --baud given" in w]
    # the line is 8N1: told it is odd parity, the estimate keeps that and shows the cost
    options = ReadOptions(probes=("RX", "TX"), parity="O", estimator=estimate_line)
    capture = open_capture(path, options)
    assert capture.info.line is not None
    assert (capture.info.line.baud, capture.info.line.parity) == (9600, "O")
    (note,) = [w for w in capture.info.notes if "no --baud given" in w]
    assert " 0 line errors" not in note and "line errors" in note


def _levels(line: LineSettings, data: bytes, per_bit: int, gap_bits: int) -> bytes:
    out = bytearray(b"\x01" * per_bit * 20)
    for byte in data:
        for b in character_bits(byte, line):
            out += bytes([b]) * per_bit
        out += b"\x01" * per_bit * gap_bits
    return bytes(out + b"\x01" * per_bit * 20)


@settings(max_examples=40, deadline=None)
@given(
    baud=st.sampled_from([1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200]),
    data=st.binary(min_size=12, max_size=40),
    gap=st.integers(min_value=0, max_value=3),
)
def test_estimate_baud_finds_the_rate_of_any_bytes(baud: int, data: bytes, gap: int) -> None:
    line = LineSettings(baud, 8, "E", 1)
    samplerate = baud * 8.0  # 8 samples per bit
    levels = _levels(line, data, 8, gap)
    guess = estimate_baud(samplerate, [levels])
    if guess is None:  # only when the bytes hold no lone bit at all
        assert all(b in (0x00, 0xFF) for b in data)
        return
    assert guess.baud == baud and guess.common
    assert guess.bit_samples == pytest.approx(8.0, rel=0.02)


def test_estimate_line_picks_parity_from_the_characters() -> None:
    for fmt in ("8E1", "8O1", "8N1", "7E1"):
        bytesize, parity, stopbits = parse_format(fmt)
        line = LineSettings(9600, bytesize, parity, stopbits)
        body = bytes.fromhex("010300000004")
        frame = with_crc(body) if bytesize == 8 else b":010300000004F8\r\n"
        levels = _levels(line, frame * 3, 10, 0)
        guess = estimate_line(96000.0, [levels], ReadOptions())
        assert guess is not None, fmt
        assert format_of(guess.line) == fmt, guess.note


def test_wrong_speed_is_said_and_scan_suggested() -> None:
    line = LineSettings(19200, 8, "E", 1)
    wire = Wire(line, *modbus_cycle(line))
    right, _f, _p = wire.receive(line, 0.003, 0.5)
    wrong, _f, _p = wire.receive(LineSettings(9600, 8, "E", 1), 0.003, 0.5)
    good = frame_capture([Chunk(bytes(v for _t, v in right), 0.5)], line)
    bad = frame_capture([Chunk(bytes(v for _t, v in wrong), 0.5)], line)
    assert wrong_speed(good) is None
    warning = wrong_speed(bad)
    assert warning is not None and "wrong speed" in warning and "modscope scan" in warning


def wrong_speed_row_by_row(store: FrameStore, min_bytes: int = 64) -> str | None:
    """wrong_speed's definition: every row but events looked at in order, stopping at
    the first frame with a good check."""
    total = noise = errors = 0
    for i in range(len(store)):
        if store.kind[i] == Kind.EVENT:
            continue
        total += store.length[i]
        if store.kind[i] == Kind.NOISE:
            noise += store.length[i]
        elif not store.flags[i] & BAD_CHECK:
            return None
        if store.flags[i] & Flag.LINE_ERROR:
            errors += 1
    if total < min_bytes or noise < total // 2:
        return None
    lead = f"{total} bytes and no valid Modbus frame"
    if errors:
        lead += f" ({errors} rows with framing or parity errors)"
    return (
        f"{lead}: were these bytes read at the wrong speed or format? "
        "On the line itself, `modscope scan PORT` finds its settings"
    )


def noisy_store(rng: random.Random, rows: int, valid_at: int | None) -> FrameStore:
    """Noise, events and frames with bad checks (some with line errors), and one valid
    frame at row `valid_at`."""
    store = FrameStore()
    stream = store.stream(0)
    frame = with_crc(bytes.fromhex("010300000001"))
    for i in range(rows):
        offset = len(stream)
        roll = rng.random()
        if i == valid_at:
            stream += frame
            store.add_row(0, offset, len(frame), i, i, int(Kind.REQUEST), 0)
        elif roll < 0.05:
            store.add_event(float(i), "gap")
        elif roll < 0.85:
            stream += rng.randbytes(rng.randrange(1, 6))
            flags = int(Flag.LINE_ERROR) if rng.random() < 0.3 else 0
            store.add_row(0, offset, len(stream) - offset, i, i, int(Kind.NOISE), flags)
        else:
            stream += frame
            bad = rng.choice((Flag.CHECK_BAD, Flag.NON_HEX, Flag.ENVELOPE_BAD))
            flags = int(bad | (Flag.LINE_ERROR if rng.random() < 0.3 else 0))
            kind = rng.choice((Kind.REQUEST, Kind.RESPONSE, Kind.UNKNOWN))
            store.add_row(0, offset, len(frame), i, i, int(kind), flags)
    return store


@pytest.mark.parametrize("seed", range(20))
def test_wrong_speed_as_row_by_row_also_when_the_first_valid_frame_comes_late(seed: int) -> None:
    rng = random.Random(seed)
    rows = rng.choice((0, 3, 40, 900))
    valid_at = rng.choice((None, None, rows - 1, rows // 2, 0)) if rows else None
    store = noisy_store(rng, rows, valid_at)
    for min_bytes in (0, 64, 10_000):
        found = wrong_speed(store, min_bytes)
        assert found == wrong_speed_row_by_row(store, min_bytes)
        if valid_at is not None:
            assert found is None  # one valid frame, however late, says the speed is right


def test_wrong_speed_counts_rows_with_line_errors() -> None:
    store = noisy_store(random.Random(1), 500, None)
    warning = wrong_speed(store)
    assert warning is not None and "rows with framing or parity errors" in warning


# -- live --baud auto: the scan, then the capture at the winner ------------------------


def _fast_scan(monkeypatch: pytest.MonkeyPatch, ports: GarblingPorts | None = None) -> None:
    import sniffer.live.port
    import sniffer.live.scan

    monkeypatch.setattr(sniffer.live.scan, "BAUDS", (9600, 19200, 38400))
    monkeypatch.setattr(sniffer.live.scan, "DWELL", 0.02)
    monkeypatch.setattr(sniffer.live.scan, "MAX_DWELL", 0.05)
    if ports is not None:
        monkeypatch.setattr(sniffer.live.port, "new_port", ports)
        monkeypatch.setattr(sniffer.live.scan, "driver_counters", ports.counters)


def test_live_baud_auto_scans_then_listens_at_the_winner(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from sniffer.cli import main

    line = LineSettings(19200, 8, "E", 1)
    cycle, period = modbus_cycle(line)
    ports = GarblingPorts(Wire(line, cycle, period), window=0.3)
    _fast_scan(monkeypatch, ports)
    code = main(["live", "/dev/ttyDOUBLE0", "--baud", "auto", "--format", "text", "-c", "6"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "--baud auto:" in err and "chose 19200 8E1 (RTU)" in err
    assert "listening on /dev/ttyDOUBLE0 (19200 8E1" in err
    rows = out.splitlines()
    assert len(rows) == 6
    # the capture after the scan reads the wire's frames cleanly (it opens mid-cycle, so
    # the first bytes may be the tail of a frame, shown as noise)
    frames = [r for r in rows if "03  Read Holding Registers" in r]
    assert len(frames) >= 4
    assert all(" ok " in r for r in frames)
    assert any("4 values" in r for r in frames)  # answers decoded: right baud, right format
    # passive throughout: the scan's opens and the capture's open
    assert ports.violations() == []
    assert len(ports.ports) >= 4  # a few scan settings, then the live port
    live_port = ports.ports[-1]
    assert (live_port.baudrate, live_port.parity, live_port.bytesize) == (19200, "E", 8)
    for port in ports.ports:
        assert port.calls[0] == "open"
        assert set(port.calls) <= {"open", "close", "low_latency=True"}
        assert (port.rts, port.dtr) == (False, False)


def test_live_baud_auto_keeps_the_format_flags_given(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from sniffer.cli import main

    line = LineSettings(9600, 8, "N", 1)
    cycle, period = modbus_cycle(line)
    ports = GarblingPorts(Wire(line, cycle, period), window=0.3)
    _fast_scan(monkeypatch, ports)
    args = ["live", "/dev/ttyDOUBLE0", "-b", "auto", "-P", "N", "--format", "text", "-c", "2"]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "chose 9600 8N1" in err
    tried = {(p.baudrate, p.parity) for p in ports.ports}
    assert {parity for _baud, parity in tried} == {"N"}  # only formats with parity N


def test_live_baud_auto_on_a_silent_line_says_so_and_exits_2(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from sniffer.cli import main

    line = LineSettings(19200, 8, "E", 1)
    ports = GarblingPorts(Wire(line, [], 0.1), window=0.3)  # a wire nobody talks on
    _fast_scan(monkeypatch, ports)
    code = main(["live", "/dev/ttyDOUBLE0", "--baud", "auto", "--format", "text"])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    last = err.strip().splitlines()[-1]
    assert "--baud auto on /dev/ttyDOUBLE0: too quiet to decide" in last
    assert "`modscope scan /dev/ttyDOUBLE0`" in last
    # two silent settings (each reopened to listen longer) end the scan; no capture opens
    assert {(p.baudrate, p.bytesize, p.parity) for p in ports.ports} == {
        (38400, 8, "N"),
        (38400, 8, "E"),
    }
    assert ports.violations() == []
    assert all((p.rts, p.dtr) == (False, False) for p in ports.ports)


def test_baud_takes_a_number_or_auto(capsys: pytest.CaptureFixture[str]) -> None:
    from sniffer.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["live", "/dev/ttyDOUBLE0", "--baud", "fast"])
    assert stop.value.code == 2
    assert "'fast' is not a baud rate; give a number (19200) or auto" in capsys.readouterr().err


# -- receivers: what each reads, and what the scan may conclude from it ----------------

TRUTHS = ("8N1", "8E1", "8O1", "8N2")


@pytest.mark.parametrize("truth", TRUTHS)
@pytest.mark.parametrize("resync", [False, True], ids=["plain", "16550"])
@pytest.mark.parametrize("counters", ["counting", "zero", "none"])
def test_the_verdict_never_leaves_out_the_true_format(
    truth: str, resync: bool, counters: str
) -> None:
    """Whatever the receiver and its driver, the line's own format is among the formats
    named, and the confidence is high only when it is the only one."""
    bytesize, parity, stopbits = parse_format(truth)
    line = LineSettings(19200, bytesize, parity, stopbits)
    result = scan(garbled(line, counters=counters, resync=resync), bauds=(9600, 19200, 38400))
    assert result.winner is not None and result.winner.line.baud == 19200, result.verdict
    assert truth in result.alike, (result.alike, result.reason)
    assert format_of(result.winner.line) == result.alike[0]
    assert (result.confidence == "high") == (result.alike == (truth,)), result.reason
    assert result.reason and (result.confidence == "high" or result.raise_it)


@pytest.mark.parametrize(
    ("truth", "resync", "counters", "alike", "confidence"),
    [
        # a counting driver tells parity apart; no receiver tells one stop bit from two
        ("8E1", False, "counting", ("8E1",), "high"),
        ("8O1", True, "counting", ("8O1",), "high"),
        ("8N1", False, "counting", ("8N1", "8N2"), "medium"),
        ("8N2", True, "counting", ("8N1", "8N2"), "medium"),
        # a 16550 garbles parity traffic read without parity: the data rule 8N1/8N2 out,
        # and without counters even and odd stay alike
        ("8E1", True, "zero", ("8E1", "8O1"), "medium"),
        ("8E1", True, "none", ("8E1", "8O1"), "medium"),
        # CP210x (a 16550 whose driver counts nothing): every format reads 8N1 traffic
        ("8N1", True, "zero", ("8N1", "8E1", "8O1", "8N2"), "low"),
        ("8N2", True, "zero", ("8N1", "8E1", "8O1", "8N2"), "low"),
        # a plain receiver garbles back-to-back 8N1 read with parity: the data decides
        ("8N1", False, "none", ("8N1", "8N2"), "medium"),
    ],
)
def test_what_each_receiver_lets_the_scan_say(
    truth: str, resync: bool, counters: str, alike: tuple[str, ...], confidence: str
) -> None:
    bytesize, parity, stopbits = parse_format(truth)
    line = LineSettings(19200, bytesize, parity, stopbits)
    result = scan(garbled(line, counters=counters, resync=resync), bauds=(9600, 19200, 38400))
    assert (result.alike, result.confidence) == (alike, confidence), result.reason


def test_a_16550_on_an_8e1_line_is_found_by_the_first_round_at_8e1() -> None:
    """At 8N1 a 16550 takes each low parity bit for a start bit: not one valid frame. A
    first round read at 8N1 alone never tried 8E1 at the right speed."""
    line = LineSettings(19200, 8, "E", 1)
    listen = garbled(line, resync=True)
    result = scan(listen, bauds=(9600, 19200, 38400))
    at_8n1 = next(t for t in result.trials if t.settings() == "19200 8N1")
    assert at_8n1.frames == 0 and at_8n1.bytes > ENOUGH_BYTES
    assert result.winner is not None and result.winner.settings() == "19200 8E1"
    assert result.confidence == "high"
    assert "8N1 and 8N2 garble the frames" in result.reason
    first = [format_of(x) for x in listen.heard[:2]]
    assert first == ["8N1", "8E1"]


def test_cp210x_zero_counters_never_name_8e1_on_an_8n1_line() -> None:
    """The driver answers the counter ioctl with zeros at every setting, wrong baud rates
    included: its zeros prove nothing, and the verdict says so."""
    for truth in (LineSettings(19200, 8, "N", 1), LineSettings(19200, 8, "N", 2)):
        result = scan(garbled(truth, counters="zero", resync=True), bauds=(9600, 19200, 38400))
        assert result.counters == "silent" and not result.counted_errors
        assert result.winner is not None and result.winner.settings() == "19200 8N1"
        assert result.confidence == "low"
        assert result.verdict.startswith("19200 8N1, 8E1, 8O1 or 8N2 (RTU): ")
        assert "line errors" not in result.verdict  # zeros that prove nothing are not shown
        assert "does not count them (CP210x adapters do not)" in result.reason
        assert any("FTDI" in r for r in result.raise_it)
        assert "-" in result.table().splitlines()[1].split()  # the errors column


def test_valid_frames_outweigh_error_counters_that_never_count() -> None:
    """Synthesised trials at one speed: 8E1 reads every frame, 8N1 garbles them; the
    driver reported zero errors at both. The data decides, the zeros do not."""

    def trial(fmt: str, frames: int, valid_bytes: int, noise: int) -> Trial:
        bytesize, parity, stopbits = parse_format(fmt)
        line = LineSettings(19200, bytesize, parity, stopbits)
        return Trial(line, 1.0, 400, frames, 1, noise, frames // 2, 0, 0, "rtu", valid_bytes)

    result = decide([trial("8N1", 3, 30, 300), trial("8E1", 30, 390, 0), trial("8O1", 30, 390, 0)])
    assert result.winner is not None and result.winner.settings() == "19200 8E1"
    assert result.counters == "silent"
    assert result.alike == ("8E1", "8O1") and result.confidence == "medium"
    assert [format_of(t.line) for t in result.trials] == ["8E1", "8O1", "8N1"]


def test_few_frames_or_no_answers_are_not_high_confidence() -> None:
    line = LineSettings(9600, 8, "E", 1)
    trials = [
        Trial(line, 2.0, 40, 4, 0, 0, 0, 0, 0, "rtu", 40),
        Trial(LineSettings(9600, 8, "O", 1), 2.0, 40, 4, 0, 0, 0, 0, 40, "rtu", 40),
        Trial(LineSettings(9600, 8, "N", 1), 2.0, 40, 0, 0, 40, 0, 20, 0, "rtu", 0),
    ]
    result = decide(trials)
    assert result.alike == ("8E1",) and result.confidence == "medium"
    assert "only 4 valid frames and no answered request" in result.reason
    assert any("listen longer" in r for r in result.raise_it)


# -- settings the port refuses, ports with no settings ----------------------------------


def test_a_refused_setting_is_skipped_with_a_note() -> None:
    line = LineSettings(19200, 8, "N", 1)
    ports = PickyPorts(Wire(line, *modbus_cycle(line)), refuse={"8E1"})
    listener = PortListener("/dev/ttyDOUBLE0", factory=ports, counters=ports.counters)
    result = scan(listener, bauds=(9600, 19200, 38400), dwell=0.02, max_dwell=0.05)
    assert result.winner is not None and result.winner.settings() == "19200 8N1"
    assert [r.settings() for r in result.refused] == ["38400 8E1", "19200 8E1", "9600 8E1"]
    assert {r.reason for r in result.refused} == {"Invalid argument"}
    assert "8E1" not in {format_of(t.line) for t in result.trials}
    assert result.refused_text() == (
        "skipped 3 settings the port refused (38400 8E1, 19200 8E1, 9600 8E1): Invalid argument"
    )
    assert ports.violations() == []
    assert all((p.rts, p.dtr) == (False, False) for p in ports.ports)


def test_scan_command_skips_refused_settings_instead_of_stopping(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from sniffer.cli import main

    line = LineSettings(19200, 8, "N", 1)
    ports = PickyPorts(Wire(line, *modbus_cycle(line)), refuse={"8E1", "8O1"})
    _fast_scan(monkeypatch, ports)
    argv = ["scan", "/dev/ttyDOUBLE0", "-b", "9600,19200", "--dwell", "0.02"]
    code = main([*argv, "--max-dwell", "0.05"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "skipped 3 settings the port refused (19200 8E1, 19200 8O1, 9600 8E1): " in out
    assert "winner: 19200 8N1 or 8N2 (RTU): " in out
    assert "confidence: medium: 8N1 or 8N2: a receiver checks only the first stop bit" in out
    assert "  modscope live /dev/ttyDOUBLE0 --baud 19200 --parity N\n" in out


def test_a_pseudo_terminal_has_no_line_settings_to_find(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import sniffer.live.port
    from sniffer.cli import main

    opened: list[str] = []
    monkeypatch.setattr(sniffer.live.port, "new_port", lambda name: opened.append(name))
    master, slave = os.openpty()
    try:
        name = os.ttyname(slave)
        link = tmp_path / "ttyV0"  # as socat's link= makes it
        link.symlink_to(name)
        for port in (name, str(link)):
            code = main(["scan", port])
            out, err = capsys.readouterr()
            assert (code, err) == (1, "")
            assert out.startswith(f"no line settings to find: {port}")
            assert "is a pseudo-terminal: bytes pass through it unchanged" in out
            assert out.count("\n") == 1
    finally:
        os.close(master)
        os.close(slave)
    assert opened == []  # said before anything was opened


@pytest.mark.parametrize("url", ["socket://127.0.0.1:4001", "spy://socket://127.0.0.1:4001"])
def test_a_socket_url_has_no_line_settings_to_find(
    url: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import sniffer.live.port
    from sniffer.cli import main

    opened: list[str] = []
    monkeypatch.setattr(sniffer.live.port, "new_port", lambda name: opened.append(name))
    code = main(["scan", url])
    out, err = capsys.readouterr()
    assert (code, err, opened) == (1, "", [])
    assert out == (
        "no line settings to find: socket://127.0.0.1:4001 is a raw TCP connection: the "
        "bytes were read off the line by the server's UART, at the settings set on the "
        "server, and arrive the same at any setting here\n"
    )


def test_an_rfc2217_server_without_control_has_no_line_settings_to_find(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import sniffer.live.port
    from sniffer.cli import main

    ports = NoControlPorts()
    monkeypatch.setattr(sniffer.live.port, "new_port", ports)
    url = "rfc2217://127.0.0.1:2217"
    code = main(["scan", url, "-b", "9600,19200"])
    out, err = capsys.readouterr()
    assert (code, err) == (1, "")
    assert out.startswith(f"no line settings to find: {url}: the server takes no line settings")
    assert len(ports.ports) == 1  # found out at the first setting, not 12 times
    code = main(["live", url, "--baud", "auto", "--format", "text"])
    err = capsys.readouterr().err
    assert code == 2 and "--baud auto on rfc2217://127.0.0.1:2217: no line settings" in err


def test_live_baud_auto_on_a_pseudo_terminal_listens_as_it_is(
    capsys: pytest.CaptureFixture[str],
) -> None:
    import threading

    from sniffer.cli import main
    from tests.support.virtual_bus import open_pty

    master, slave, name = open_pty()
    stop = threading.Event()

    def talk() -> None:
        while not stop.wait(0.05):
            with contextlib.suppress(OSError):
                os.write(master, REQUEST)
                time.sleep(0.01)
                os.write(master, ANSWER)

    threading.Thread(target=talk, daemon=True).start()
    try:
        code = main(["live", name, "--baud", "auto", "--format", "text", "-c", "2"])
    finally:
        stop.set()
        time.sleep(0.1)
        os.close(master)
        os.close(slave)
    out, err = capsys.readouterr()
    assert code == 0, err
    assert f"--baud auto: no line settings to find: {name} is a pseudo-terminal" in err
    assert "listening at 19200 8N1, which changes nothing here" in err
    assert len(out.splitlines()) == 2 and "Read Holding Registers" in out


def test_a_port_that_refuses_every_setting_says_so() -> None:
    line = LineSettings(19200, 8, "N", 1)
    ports = PickyPorts(Wire(line, *modbus_cycle(line)), refuse=set(FORMATS))
    listener = PortListener("/dev/ttyDOUBLE0", factory=ports, counters=ports.counters)
    result = scan(listener, bauds=(9600, 19200), dwell=0.02, max_dwell=0.05)
    assert result.winner is None and not result.quiet
    # the first round only (8N1, 8E1, 7E1 at each speed): nothing read, no second round
    assert result.verdict == "the port refused all 6 settings tried; none could be listened to"
    assert len(result.refused) == 6 and result.trials == ()


def test_which_ports_have_line_settings(tmp_path: Path) -> None:
    assert no_line_settings("loop://") is not None
    assert no_line_settings("rfc2217://127.0.0.1:2217") is None  # found out when it opens
    assert no_line_settings(str(tmp_path / "ttyNOPE")) is None  # said when it opens
    assert no_line_settings("/dev/null") is None  # a character device, not a pty
