"""Tests the readers of the logs people post from the field: evcc traces, ModbusTools logs,
CAS Modbus Scanner logs (newest line first), libmodbus/mbpoll and pymodbus logs of Modbus
TCP, pymodbus synchronous clients, and Saleae Logic 1 exports in the ASCII and ASCII & Hex
radices. Each fixture in tests/captures/logs/ was written for these tests from the tool's
source (the lines each prints); the tests check bytes, directions, events, times, order,
frames and pairs, and that unreadable lines are warnings naming file and line."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from dissectors.checks import with_crc
from sniffer.framing.pairing import measure
from sniffer.framing.store import FrameStore
from sniffer.model import Chunk, Direction, Labels, LineSettings, Stamp
from sniffer.session.session import Session, replay_file
from sniffer.sources import ReadOptions, detect, open_capture
from sniffer.sources.logs import parse_stamp, sniff_log
from sniffer.sources.logs.evcc import go_unquote
from sniffer.sources.logs.modbustools import frame_bytes
from sniffer.vocab import Kind, Status

LOGS = Path(__file__).parent.parent / "captures" / "logs"
M, S, U = Direction.MASTER, Direction.SLAVE, Direction.UNKNOWN

READ = with_crc(bytes.fromhex("010300000002"))
READ_ANSWER = with_crc(bytes.fromhex("010304000a000d"))
WRITE = with_crc(bytes.fromhex("0106000100ab"))
INPUTS = with_crc(bytes.fromhex("02040000000a"))
ASCII_READ = b":010300000002FA\r\n"
ASCII_ANSWER = b":010304000A000DE1\r\n"

# Modbus TCP: the same read and write behind an MBAP header, and an exception
TCP_READ = bytes.fromhex("000100000006 0103 00000002")
TCP_READ_ANSWER = bytes.fromhex("000100000007 0103 04000a000d")
TCP_WRITE = bytes.fromhex("000200000006 0106 000100ab")
TCP_BAD_READ = bytes.fromhex("000300000006 0103 7ff00004")
TCP_EXCEPTION = bytes.fromhex("000300000003 0183 02")


def chunks_of(name: str) -> list[Chunk]:
    return list(open_capture(LOGS / name).chunks())


def data_of(name: str) -> list[tuple[int, Direction, bytes]]:
    return [(c.channel, c.direction, c.data) for c in chunks_of(name) if not c.event]


def events_of(name: str) -> list[tuple[str, str]]:
    return [(c.event, c.note) for c in chunks_of(name) if c.event]


def rows(session: Session) -> list[tuple[bytes, Kind, Status]]:
    store = session.store
    return [
        (store.raw(i), Kind(store.kind[i]), Status(store.status[i]))
        for i in range(len(store))
        if store.kind[i] != Kind.EVENT
    ]


# ---------------------------------------------------------------- evcc


def only_second_bounds(store: FrameStore) -> bool:
    """Whether every latency `measure` gives is a bound in whole seconds (or none)."""
    found = [measure(store, i) for i in range(len(store))]
    return all(m is None or (m.bound and m.seconds >= 1 and m.seconds % 1 == 0) for m in found)


def test_evcc_trace_bytes_times_and_events() -> None:
    capture = open_capture(LOGS / "evcc_rtu.log")
    chunks = list(capture.chunks())
    info = capture.info
    assert (info.format, info.stamps, info.resolution, info.labels) == (
        "evcc",
        Stamp.PRINT,
        1.0,
        Labels.HINT,
    )
    assert not info.network and set(info.channels) == {0}
    base = parse_stamp("2024/07/29 11:25:24")
    assert base is not None and base.dated
    frames = [c for c in chunks if not c.event]
    # whole seconds, as Go's log.Ltime prints them
    assert [c.t_end - base.seconds for c in frames] == [0, 0, 1, 1, 1, 2, 2]
    # the library's other lines are events, in their place; other areas' lines are not
    assert [(c.event, c.note) for c in chunks if c.event] == [
        ("error", "sdm: modbus: read error: serial: timeout")
    ]
    assert chunks[5].event and chunks[4].data == INPUTS and chunks[6].data == INPUTS
    assert capture.warnings == [
        f"{LOGS / 'evcc_rtu.log'} line 11: cannot read '01 03 00 00 zz' as the bytes of a "
        "frame; the line is skipped (a cut or edited line?)"
    ]


def test_evcc_rtu_frames_pair_and_the_silent_read_times_out() -> None:
    session = replay_file(LOGS / "evcc_rtu.log", ReadOptions(baud=9600, parity="N"))
    assert [(k, s) for _, k, s in rows(session)] == [
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
        (Kind.REQUEST, Status.TIMEOUT),
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
    ]
    # one-second print times give no latency value: at most a bound in whole seconds
    assert only_second_bounds(session.store)
    # the response timeout is the master's (0.2 s and 256 characters at 9600 baud), and
    # the wait judged by the clock that plus the one second the prints may be off, once
    assert session.pipeline.pairer.timeout == pytest.approx(0.2 + 256 * 10 / 9600)  # 8N1: 10 bits
    assert session.pipeline.pairer.judged == pytest.approx(session.pipeline.pairer.timeout + 1)
    assert "only past 1.47 s (the 467 ms response timeout plus the resolution)" in (
        session.stats.timing_line()
    )


def test_an_early_event_keeps_its_place_while_the_mode_is_being_told(tmp_path: Path) -> None:
    # fewer bytes than the RTU/ASCII detection needs come before the event: it waits
    # with them instead of going first
    path = tmp_path / "evcc.log"
    path.write_text(
        f"[sdm   ] TRACE 2024/07/29 11:25:24 modbus: send {READ.hex(' ')}\n"
        "[sdm   ] TRACE 2024/07/29 11:25:25 modbus: read error: serial: timeout\n"
        f"[sdm   ] TRACE 2024/07/29 11:25:25 modbus: send {READ.hex(' ')}\n"
        f"[sdm   ] TRACE 2024/07/29 11:25:25 modbus: recv {READ_ANSWER.hex(' ')}\n"
    )
    store = replay_file(path).store
    assert [Kind(k) for k in store.kind] == [
        Kind.REQUEST,
        Kind.EVENT,
        Kind.REQUEST,
        Kind.RESPONSE,
    ]
    assert [Status(s) for s in store.status if s != Status.NONE] == [
        Status.TIMEOUT,
        Status.OK,
        Status.OK,
    ]
    assert list(store.t_end) == sorted(store.t_end)


def test_evcc_ascii_frames_quoted_or_as_characters() -> None:
    assert data_of("evcc_ascii.log") == [
        (0, M, ASCII_READ),
        (0, S, ASCII_ANSWER),
        (0, M, ASCII_READ),
        (0, S, ASCII_ANSWER),
    ]
    capture = open_capture(LOGS / "evcc_ascii.log")
    list(capture.chunks())
    assert len(capture.warnings) == 1 and " line 5: " in capture.warnings[0]
    session = replay_file(LOGS / "evcc_ascii.log", ReadOptions(bytesize=7, parity="E"))
    assert session.mode == "ascii"
    assert [(k, s) for _, k, s in rows(session)] == [
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
    ] * 2


@pytest.mark.parametrize(
    ("text", "data"),
    [
        ('":0103\\r\\n"', b":0103\r\n"),
        ('"\\x01\\x03\\x00"', b"\x01\x03\x00"),
        ('"a\\"b\\\\"', b'a"b\\'),
        ('"\\u00e9"', "é".encode()),
        ('"é"', "é".encode()),
        ('"\\101"', b"A"),
        ('"\\t\\v\\f\\a\\b"', b"\t\v\f\a\b"),
        ('"cut', None),
        ('"bad \\q"', None),
        ('"a"b"', None),
        ('"\\x0"', None),
        ('"\\777"', None),
    ],
)
def test_go_quoted_strings(text: str, data: bytes | None) -> None:
    assert go_unquote(text) == data


def test_evcc_modbus_tcp_areas_are_connections_framed_as_modbus_tcp() -> None:
    capture = open_capture(LOGS / "evcc_tcp.log")
    chunks = list(capture.chunks())
    info = capture.info
    assert info.network and info.labels == Labels.CERTAIN
    assert info.channels == {
        0: "tcp evcc > sma modbus-tcp",
        1: "tcp sma > evcc modbus-tcp (server)",
        2: "tcp evcc > fronius modbus-tcp",
        3: "tcp fronius > evcc modbus-tcp (server)",
    }
    assert [(c.channel, c.direction) for c in chunks if not c.event] == [
        (0, M),
        (1, S),
        (2, M),
        (3, S),
    ] * 2 + [(0, M)]
    assert [(c.channel, c.event) for c in chunks if c.event] == [(0, "error")]
    session = replay_file(LOGS / "evcc_tcp.log")
    store = session.store
    found = rows(session)
    # a request and its answer printed in one second keep the file's order, and pair
    assert [(k, s) for _, k, s in found] == [
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
        (Kind.REQUEST, Status.EXCEPTION),
        (Kind.EXCEPTION, Status.EXCEPTION),
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
        (Kind.REQUEST, Status.TIMEOUT),
    ]
    assert {store.peers[c] for c in (0, 2)} == {"evcc"}
    assert (store.servers[0], store.servers[2]) == ("sma", "fronius")
    assert only_second_bounds(store)


# ---------------------------------------------------------------- ModbusTools


def test_modbustools_client_log_bytes_events_and_times() -> None:
    capture = open_capture(LOGS / "modbustools_client.log")
    chunks = list(capture.chunks())
    info = capture.info
    assert (info.format, info.stamps, info.resolution, info.labels) == (
        "modbustools",
        Stamp.PRINT,
        1e-3,
        Labels.HINT,
    )
    first = parse_stamp("14.05.2025 09:57:07.113")
    assert first is not None and first.dated
    frames = [c for c in chunks if not c.event]
    assert frames[0].t_end == pytest.approx(first.seconds)
    assert frames[1].t_end - frames[0].t_end == pytest.approx(0.026)
    # Error and Info lines are events, not bytes, in their place
    assert [(k, c.event, c.note) for k, c in enumerate(chunks) if c.event] == [
        (0, "info", "PORT1: Start polling"),
        (9, "error", "PORT1: RTU. Wrong CRC"),
        (10, "info", "PORT1: Finish polling"),
    ]
    assert chunks[8].data == b"\x81" + READ_ANSWER[1:]  # the answer the error is about
    assert not capture.warnings


def test_modbustools_client_frames_and_the_answer_that_failed_its_crc() -> None:
    session = replay_file(LOGS / "modbustools_client.log", ReadOptions(baud=9600, parity="N"))
    store = session.store
    kinds = [Kind(k) for k in store.kind]
    assert kinds.count(Kind.EVENT) == 3
    found = rows(session)
    assert found[:4] == [
        (READ, Kind.REQUEST, Status.OK),
        (READ_ANSWER, Kind.RESPONSE, Status.OK),
        (WRITE, Kind.REQUEST, Status.OK),
        (WRITE, Kind.RESPONSE, Status.OK),
    ]
    # the read whose answer failed its CRC is not answered; the bad bytes are kept
    assert found[6][:2] == (READ, Kind.REQUEST) and found[6][2] != Status.OK
    assert found[7] == (b"\x81" + READ_ANSWER[1:], Kind.NOISE, Status.NONE)


def test_modbustools_ascii_without_time() -> None:
    capture = open_capture(LOGS / "modbustools_ascii_notime.log")
    chunks = list(capture.chunks())
    assert capture.info.stamps == Stamp.NONE
    times = [c.t_end for c in chunks]
    assert times == sorted(times)
    assert [c.data for c in chunks if not c.event][:2] == [ASCII_READ, ASCII_ANSWER]
    assert [c.event for c in chunks if c.event] == ["info", "error"]
    session = replay_file(
        LOGS / "modbustools_ascii_notime.log", ReadOptions(bytesize=7, parity="E")
    )
    assert session.mode == "ascii"
    found = rows(session)
    assert [(k, s) for _, k, s in found[:2]] == [
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
    ]
    assert found[3][0].endswith(b"E2\r\n")  # the answer with the wrong LRC stays


@pytest.mark.parametrize(
    ("text", "data"),
    [
        ("01 03 00 00 00 0A C5 CD ", bytes.fromhex("01030000000AC5CD")),
        (": 01 03 00 00 00 02 FA CR LF ", b":010300000002FA\r\n"),
        (": 0 CR ", b":0\r"),  # an odd digit before CR, as ModbusLib writes it
        ("", None),
        ("01 ä", None),
    ],
)
def test_modbustools_byte_texts(text: str, data: bytes | None) -> None:
    assert frame_bytes(text) == data


def test_modbustools_server_over_tcp() -> None:
    capture = open_capture(LOGS / "modbustools_server_tcp.log")
    chunks = list(capture.chunks())
    info = capture.info
    # the server's Rx are the requests (channel 0), its Tx the answers
    assert info.network and info.resolution == 1.0  # a custom time format, whole seconds
    assert info.channels[0] == "tcp 192.168.1.10:50211 > ModbusTools modbus-tcp"
    assert [(c.channel, c.direction, c.data) for c in chunks if not c.event][:2] == [
        (0, M, TCP_READ),
        (1, S, TCP_READ_ANSWER),
    ]
    assert [c.note for c in chunks if c.event][-1] == "TCP502: Close Connection: 192.168.1.10:50211"
    session = replay_file(LOGS / "modbustools_server_tcp.log")
    assert [(k, s) for _, k, s in rows(session)] == [
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
        (Kind.REQUEST, Status.EXCEPTION),
        (Kind.EXCEPTION, Status.EXCEPTION),
    ]


def test_modbustools_time_it_cannot_read_is_one_warning(tmp_path: Path) -> None:
    path = tmp_path / "tools.log"
    path.write_text(
        f"Mi 10:02 'Dev' Tx: {READ.hex(' ')}\nMi 10:03 'Dev' Rx: {READ_ANSWER.hex(' ')}\n"
    )
    capture = open_capture(path)
    assert [c.data for c in capture.chunks()] == [READ, READ_ANSWER]
    assert capture.info.stamps == Stamp.NONE
    assert len(capture.warnings) == 1 and f"{path} line 1:" in capture.warnings[0]


# ---------------------------------------------------------------- CAS Modbus Scanner


def test_cas_newest_first_is_read_in_time_order_with_one_note() -> None:
    capture = open_capture(LOGS / "cas_newest_first.log")
    chunks = list(capture.chunks())
    info = capture.info
    assert (info.stamps, info.resolution, info.labels) == (Stamp.PRINT, 1.0, Labels.HINT)
    times = [c.t_end for c in chunks]
    assert times == sorted(times)
    assert times[0] == 10 * 3600 + 14 * 60 + 59  # no date: seconds since midnight
    assert [c.event or c.direction.name for c in chunks] == [
        "MASTER",
        "SLAVE",
        "MASTER",
        "error",  # the timeout notice, after the poll it is about
        "MASTER",
        "SLAVE",
        "MASTER",
        "SLAVE",
        "info",
    ]
    assert len(info.notes) == 1 and "newest line first" in info.notes[0]
    assert not capture.warnings  # no time going back: the order was turned round
    session = replay_file(LOGS / "cas_newest_first.log", ReadOptions(baud=9600, parity="N"))
    assert [(k, s) for _, k, s in rows(session)] == [
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
        (Kind.REQUEST, Status.TIMEOUT),
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
    ]


def test_cas_lines_of_one_second_go_by_poll_and_response(tmp_path: Path) -> None:
    capture = open_capture(LOGS / "cas_one_second.log")
    chunks = list(capture.chunks())
    assert [c.event or c.direction.name for c in chunks] == ["MASTER", "SLAVE", "info"]
    assert len(capture.info.notes) == 1
    assert capture.warnings == [
        f"{LOGS / 'cas_one_second.log'} line 4: cannot read '01 03 04 00 0A 00 0D 1B G4' as "
        "hex bytes; the line is skipped (a cut or edited line?)"
    ]
    # a copy already in time order stays as it is, and says nothing
    path = tmp_path / "cas.log"
    path.write_text(
        f"[10:00:00] => Poll: {READ.hex(' ')}\n[10:00:00] <= Response: {READ_ANSWER.hex(' ')}\n"
        f"[10:00:01] => Poll: {WRITE.hex(' ')}\n"
    )
    capture = open_capture(path)
    assert [c.data for c in capture.chunks()] == [READ, READ_ANSWER, WRITE]
    assert capture.info.notes == ()


def test_cas_newest_first_across_midnight(tmp_path: Path) -> None:
    path = tmp_path / "cas.log"
    path.write_text(
        f"[00:00:01] <= Response: {READ_ANSWER.hex(' ')}\n[00:00:00] => Poll: {READ.hex(' ')}\n"
        f"[23:59:59] <= Response: {WRITE.hex(' ')}\n[23:59:59] => Poll: {WRITE.hex(' ')}\n"
    )
    chunks = list(open_capture(path).chunks())
    assert [c.data for c in chunks] == [WRITE, WRITE, READ, READ_ANSWER]
    assert [c.t_end for c in chunks] == [86399.0, 86399.0, 86400.0, 86401.0]


# ---------------------------------------------------------------- libmodbus, mbpoll


def test_mbpoll_modbus_tcp_is_framed_as_modbus_tcp() -> None:
    capture = open_capture(LOGS / "mbpoll_tcp.log")
    chunks = list(capture.chunks())
    info = capture.info
    assert (info.format, info.stamps, info.network) == ("libmodbus", Stamp.NONE, True)
    assert info.channels == {
        0: "tcp mbpoll > 192.168.1.20:502 modbus-tcp",
        1: "tcp 192.168.1.20:502 > mbpoll modbus-tcp (server)",
    }
    # `[1]: 10`, mbpoll's values, are no bytes
    assert [(c.channel, c.data[:2]) for c in chunks if not c.event] == [
        (0, b"\x00\x01"),
        (1, b"\x00\x01"),
        (0, b"\x00\x02"),
        (0, b"\x00\x03"),
        (1, b"\x00\x03"),
    ]
    assert [(c.event, c.note) for c in chunks if c.event] == [
        ("error", "ERROR Connection timed out: select"),
        ("error", "Read output (holding) register failed: Connection timed out"),
    ]
    session = replay_file(LOGS / "mbpoll_tcp.log")
    assert [(r, k, s) for r, k, s in rows(session)] == [
        (TCP_READ, Kind.REQUEST, Status.OK),
        (TCP_READ_ANSWER, Kind.RESPONSE, Status.OK),
        # no time: nothing tells how long it waited (the ERROR line is an event)
        (b"\x00\x02" + TCP_READ[2:], Kind.REQUEST, Status.OPEN),
        (b"\x00\x03" + TCP_READ[2:], Kind.REQUEST, Status.OK),
        (b"\x00\x03" + TCP_READ_ANSWER[2:], Kind.RESPONSE, Status.OK),
    ]
    assert session.store.peers[0] == "mbpoll"


def test_libmodbus_server_over_tcp_receives_the_requests() -> None:
    capture = open_capture(LOGS / "libmodbus_tcp_server.log")
    chunks = list(capture.chunks())
    assert capture.info.channels[0] == "tcp 192.168.1.10 > libmodbus modbus-tcp"
    assert [(c.channel, c.direction, c.data) for c in chunks if not c.event] == [
        (0, M, TCP_READ),
        (1, S, TCP_READ_ANSWER),
        (0, M, TCP_WRITE),
        (1, S, TCP_WRITE),
    ]
    assert [c.event for c in chunks if c.event] == ["error"]
    session = replay_file(LOGS / "libmodbus_tcp_server.log")
    assert [s for _, _, s in rows(session)] == [Status.OK] * 4


# ---------------------------------------------------------------- pymodbus


def test_pymodbus_synchronous_3x_log_and_its_failed_transaction() -> None:
    chunks = chunks_of("pymodbus_sync_37.log")
    # `Processing:` repeats what RECV showed: read once
    assert [c.data for c in chunks if not c.event] == [
        READ,
        READ_ANSWER,
        INPUTS,
        INPUTS,
        with_crc(bytes.fromhex("020414" + "".join(f"00{k:02x}" for k in range(1, 11)))),
    ]
    events = [(c.event, c.note) for c in chunks if c.event]
    assert events == [
        (
            "error",
            "Transaction failed. (Modbus Error: [Invalid Message] No response received, "
            "expected at least 4 bytes (0 received))",
        )
    ]


def test_pymodbus_38_synchronous_log_gives_answers_and_says_the_requests_are_missing() -> None:
    capture = open_capture(LOGS / "pymodbus_sync_38.log")
    chunks = list(capture.chunks())
    # the buffer held after `Frame - not ready` is not read twice
    answer = b"".join(c.data for c in chunks[3:5])
    assert answer == with_crc(bytes.fromhex("020414" + "".join(f"00{k:02x}" for k in range(1, 11))))
    assert [c.direction for c in chunks if not c.event] == [S, M, S, S, S]
    assert chunks[-1].event == "error"
    (note,) = capture.info.notes
    assert "not what it sent" in note and "local echo" in note
    session = replay_file(LOGS / "pymodbus_sync_38.log", ReadOptions(baud=9600, parity="N"))
    found = rows(session)
    assert (READ_ANSWER, Kind.RESPONSE, Status.ORPHAN) in found
    assert (WRITE, Kind.REQUEST, Status.OK) in found


def test_pymodbus_38_processing_line_it_cannot_read_is_a_warning(tmp_path: Path) -> None:
    path = tmp_path / "sync.log"
    path.write_text(
        "2025-03-02 08:00:00,042 DEBUG base:76 Processing: 0x1 0x3 0x4 0x0 0xzz\n"
        "2025-03-02 08:00:00,242 DEBUG base:76 Processing: "
        + " ".join(hex(b) for b in READ_ANSWER)
        + "\n"
    )
    capture = open_capture(path)
    assert [c.data for c in capture.chunks()] == [READ_ANSWER]
    assert len(capture.warnings) == 1 and f"{path} line 1:" in capture.warnings[0]


def test_pymodbus_modbus_tcp_answers_split_over_reads_are_joined() -> None:
    capture = open_capture(LOGS / "pymodbus_tcp.log")
    chunks = list(capture.chunks())
    assert capture.info.channels[0] == "tcp pymodbus > 192.168.1.20:502 modbus-tcp"
    assert capture.info.resolution == pytest.approx(1e-3)
    assert [c.channel for c in chunks] == [0, 1, 0, 1, 1, 0, 1]
    session = replay_file(LOGS / "pymodbus_tcp.log")
    assert rows(session) == [
        (TCP_READ, Kind.REQUEST, Status.OK),
        (TCP_READ_ANSWER, Kind.RESPONSE, Status.OK),
        (TCP_WRITE, Kind.REQUEST, Status.OK),
        (TCP_WRITE, Kind.RESPONSE, Status.OK),
        (TCP_BAD_READ, Kind.REQUEST, Status.EXCEPTION),
        (TCP_EXCEPTION, Kind.EXCEPTION, Status.EXCEPTION),
    ]
    latencies = [measure(session.store, i) for i in (1, 3, 5)]
    assert all(x is not None and x.seconds > 0 for x in latencies)


def test_a_pymodbus_servers_serial_log_is_told_by_what_it_decoded(tmp_path: Path) -> None:
    path = tmp_path / "server.log"
    path.write_text(
        "2025-03-02 08:10:00,005 DEBUG transport:308 recv: "
        + " ".join(hex(b) for b in READ)
        + " extra data: \n2025-03-02 08:10:00,005 DEBUG decoders:86 decoded PDU function_code"
        "(3 sub -1) -> ReadHoldingRegistersRequest(dev_id=1, transaction_id=0) \n"
        "2025-03-02 08:10:00,030 DEBUG transport:357 send: "
        + " ".join(hex(b) for b in READ_ANSWER)
        + "\n"
    )
    capture = open_capture(path)
    assert [(c.direction, c.data) for c in capture.chunks()] == [(M, READ), (S, READ_ANSWER)]
    assert "server" in capture.info.channels[0]
    session = replay_file(path, ReadOptions(baud=9600, parity="N"))
    assert [(k, s) for _, k, s in rows(session)] == [
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
    ]
    assert not [w for w in session.warnings if w.startswith("direction labels")]


def test_a_servers_log_of_modbus_tcp_is_read_the_other_way_round(tmp_path: Path) -> None:
    # a pymodbus server logs what it received (requests) as recv
    path = tmp_path / "server.log"
    path.write_text(
        "2025-03-02 08:10:00,005 DEBUG transport:308 recv: "
        + " ".join(hex(b) for b in TCP_READ)
        + " extra data: \n2025-03-02 08:10:00,006 DEBUG transport:357 send: "
        + " ".join(hex(b) for b in TCP_READ_ANSWER)
        + "\n"
    )
    capture = open_capture(path)
    chunks = list(capture.chunks())
    assert [(c.channel, c.direction) for c in chunks] == [(0, M), (1, S)]
    assert len(capture.info.notes) == 1 and "server's log" in capture.info.notes[0]
    session = replay_file(path)
    assert [(k, s) for _, k, s in rows(session)] == [
        (Kind.REQUEST, Status.OK),
        (Kind.RESPONSE, Status.OK),
    ]


# ---------------------------------------------------------------- Saleae Logic 1


def test_saleae_ascii_radix_quoted_decimals_are_values() -> None:
    capture = open_capture(LOGS / "saleae_logic1_ascii.csv", ReadOptions(baud=9600, parity="N"))
    chunks = list(capture.chunks())
    data = b"".join(c.data for c in chunks)
    assert data == READ + READ_ANSWER + WRITE + WRITE + b"\x00"  # '1' is 0x01, not '1'
    assert [c.event for c in chunks if c.event] == ["framing error"]
    assert not capture.warnings


def test_saleae_ascii_and_hex_radix_modbus_ascii() -> None:
    capture = open_capture(LOGS / "saleae_logic1_ascii_hex.csv", ReadOptions(bytesize=7))
    chunks = list(capture.chunks())
    assert b"".join(c.data for c in chunks) == ASCII_READ + ASCII_ANSWER + b'",' + ASCII_READ
    assert [c.event for c in chunks if c.event] == ["parity error"]
    assert not capture.warnings
    assert capture.info.stamps == Stamp.EXACT
    line = LineSettings(baud=9600, bytesize=7, parity="E", mode="ascii")
    session = Session(line, exact_timing=True)
    session.ingest(open_capture(LOGS / "saleae_logic1_ascii_hex.csv").chunks())
    found = rows(session)
    assert [(r, k) for r, k, _ in found if k != Kind.NOISE] == [
        (ASCII_READ, Kind.REQUEST),
        (ASCII_ANSWER, Kind.RESPONSE),
        (ASCII_READ, Kind.REQUEST),
    ]


HEADER = "Time [s],Value,Parity Error,Framing Error\n"


def test_saleae_stray_cr_and_quotes_do_not_stop_the_file(tmp_path: Path) -> None:
    path = tmp_path / "stray.csv"
    path.write_bytes(
        (
            HEADER + '0.1,"\t(0x22),,\n0.2,\r\t(0x0D),,\n0.3,0x01\r,,\n0.4,ab\rcd,,\n'
            "0.5,\"'1'\t(0x01)\",,\n0.6,0x02,,\n"
        ).encode()
    )
    capture = open_capture(path)
    assert b"".join(c.data for c in capture.chunks()) == b'"\r\x01\x01\x02'
    assert capture.warnings == [
        f"{path} line 5: cannot read the value 'ab\\rcd' as a byte; the row is skipped"
    ]


def test_saleae_line_over_the_csv_field_limit_is_one_warning(tmp_path: Path) -> None:
    for header, row in (
        (HEADER, "0.2," + "x" * 200_000 + ",,"),
        ("name,type,start_time,duration,data\n", 'a,data,0.2,0.001,"' + "x" * 200_000 + '"'),
    ):
        path = tmp_path / "long.csv"
        first = "0.1,0x01,," if header == HEADER else "a,data,0.1,0.001,0x01"
        last = "0.3,0x02,," if header == HEADER else "a,data,0.3,0.001,0x02"
        path.write_text(header + f"{first}\n{row}\n{last}\n")
        capture = open_capture(path)
        assert b"".join(c.data for c in capture.chunks()) == b"\x01\x02"
        assert len(capture.warnings) == 1 and f"{path} line 3:" in capture.warnings[0]


def test_saleae_lines_ending_in_cr_alone(tmp_path: Path) -> None:
    path = tmp_path / "mac.csv"
    path.write_bytes(b"Time [s],Value,Parity Error,Framing Error\r0.1,0x01,,\r0.2,0x03,,\r")
    assert b"".join(c.data for c in open_capture(path).chunks()) == b"\x01\x03"


# ---------------------------------------------------------------- recognition

FIELD_LOGS = {
    "evcc_rtu.log": "evcc",
    "evcc_tcp.log": "evcc",
    "evcc_ascii.log": "evcc",
    "modbustools_client.log": "modbustools",
    "modbustools_ascii_notime.log": "modbustools",
    "modbustools_server_tcp.log": "modbustools",
    "cas_newest_first.log": "cas",
    "cas_one_second.log": "cas",
    "mbpoll_tcp.log": "libmodbus",
    "libmodbus_tcp_server.log": "libmodbus",
    "pymodbus_sync_37.log": "pymodbus",
    "pymodbus_sync_38.log": "pymodbus",
    "pymodbus_tcp.log": "pymodbus",
    "saleae_logic1_ascii.csv": "saleae",
    "saleae_logic1_ascii_hex.csv": "saleae",
}


@pytest.mark.parametrize(("name", "kind"), sorted(FIELD_LOGS.items()))
def test_recognised_from_content_whatever_the_name(name: str, kind: str, tmp_path: Path) -> None:
    misleading = tmp_path / "capture.pcapng"
    shutil.copy(LOGS / name, misleading)
    assert detect.sniff(misleading.read_bytes()[: detect.HEAD_SIZE]) == kind
    assert open_capture(misleading).info.format == kind


@pytest.mark.parametrize(
    "text",
    [
        "[main  ] INFO 2024/07/29 11:25:20 evcc 0.128.3\n[site  ] DEBUG 2024/07/29 pv 1W\n",
        "14.05.2025 09:57:07.001 'PORT1' Info: Start polling\n",
        "[10:15:03] Read task has completed successfully\n",
        "[1]: \t10\n[2]: \t13\n",
    ],
)
def test_their_other_lines_alone_are_not_a_log(text: str) -> None:
    assert sniff_log(text.encode()) is None


@pytest.mark.parametrize("event_at", [1, 2])
def test_an_event_beside_an_answer_with_a_wrong_crc_changes_nothing(
    tmp_path: Path, event_at: int
) -> None:
    """An error line after the garbled answer (which the framer holds undecided until the
    capture ends: its CRC is wrong) is stored after it; one between the request and the
    answer leaves the request's unit known, so the answer is still a response with a bad
    check, not noise (both were so before: the event's row was stored first, and it
    completed the request's row before the framer counted its unit)."""
    bad = READ_ANSWER[:-1] + b"\xf5"
    lines = [
        f"14.05.2025 09:57:08.614 'Device' Tx: {READ.hex(' ')}\n",
        f"14.05.2025 09:57:08.640 'Device' Rx: {bad.hex(' ')}\n",
    ]
    options = ReadOptions(baud=9600, parity="N", mode="rtu")
    path = tmp_path / "tools.log"
    path.write_text("".join(lines))
    without = replay_file(path, options)
    lines.insert(event_at, "14.05.2025 09:57:08.630 'PORT1' Error: RTU. Wrong CRC\n")
    path.write_text("".join(lines))
    with_event = replay_file(path, options)
    assert rows(without) == [
        (READ, Kind.REQUEST, Status.BAD_ANSWER),
        (bad, Kind.RESPONSE, Status.BAD_ANSWER),
    ]
    assert rows(with_event) == rows(without)
    assert Kind(with_event.store.kind[event_at]) == Kind.EVENT  # where the log has it
