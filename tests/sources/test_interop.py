"""Captures others make: the same bytes in every form give the same frames, pairs and status.

The reference is the traffic with exact timing and no direction labels. Each other form
adds what real loggers add: direction labels (EPB flags, text2pcap `O`/`I`, socat `>`/`<`),
stamps at a frame's start or end or when a line was printed, host reads of 16 ms, or no
time at all. Labels are hints and stamps only move times: frames, kinds, pairs and
status must not change, and no latency shown may be one the timing cannot measure.
"""

from __future__ import annotations

import io
import json
import random
import tempfile
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import lrc, with_crc
from sniffer.framing.pairing import measure
from sniffer.framing.store import FrameStore
from sniffer.model import Chunk, Direction, Labels, LineSettings, Stamp
from sniffer.outputs.listing import Lister
from sniffer.session.session import Session, replay_file
from sniffer.sources import ReadOptions
from sniffer.sources.linktypes import (
    EPB_FLAG_INBOUND,
    EPB_FLAG_OUTBOUND,
    LINKTYPE_USER0,
)
from sniffer.sources.pcapng_writer import PcapngWriter
from sniffer.vocab import Kind, Status

ECHOED = (5, 6, 8)  # the function codes whose answer repeats the request
# forms whose clock cannot order a write, its retry and its echoed answer: see the property
NO_TIME = (
    "no time",
    "evcc trace, 1 s",
    "CAS Modbus Scanner, newest first, 1 s",
    "ModbusTools, no time",
    "libmodbus, no time",
)
LINE = LineSettings(baud=9600, parity="N", mode="rtu")
CHAR = LINE.char_time


@dataclass(frozen=True)
class Frame:
    data: bytes
    start: float  # when its first bit left, exactly
    master: bool

    @property
    def end(self) -> float:
        return self.start + len(self.data) * CHAR


def _read_holding(unit: int, address: int, count: int) -> tuple[bytes, bytes]:
    request = with_crc(bytes([unit, 3]) + address.to_bytes(2, "big") + count.to_bytes(2, "big"))
    values = b"".join((address + k).to_bytes(2, "big") for k in range(count))
    return request, with_crc(bytes([unit, 3, 2 * count]) + values)


def _exchange(rng: random.Random, unit: int) -> tuple[bytes, bytes | None]:
    """One transaction of a polling master: a request and the answer it gets (or none)."""
    choice = rng.randrange(6)
    if choice == 0:
        return _read_holding(unit, rng.randrange(100), rng.randrange(1, 43))
    if choice == 1:  # read input registers
        count = rng.randrange(1, 10)
        request = with_crc(bytes([unit, 4, 0, 10, 0, count]))
        return request, with_crc(bytes([unit, 4, 2 * count]) + bytes(2 * count))
    if choice == 2:  # write single register: the answer echoes it
        request = with_crc(bytes([unit, 6, 0, rng.randrange(50), 1, rng.randrange(256)]))
        return request, request
    if choice == 3:  # write multiple registers
        request = with_crc(bytes([unit, 16, 0, 5, 0, 2, 4, 0, 1, 0, 2]))
        return request, with_crc(bytes([unit, 16, 0, 5, 0, 2]))
    if choice == 4:  # an exception
        request = with_crc(bytes([unit, 3, 0x7F, 0xF0, 0, 4]))
        return request, with_crc(bytes([unit, 0x83, 2]))
    return with_crc(bytes([unit, 5, 0, 3, 0xFF, 0])), with_crc(bytes([unit, 5, 0, 3, 0xFF, 0]))


def polling(seed: int, transactions: int = 30) -> list[Frame]:
    """A master polling units 1-4: answers after 2-40 ms, a silent unit now and then
    (the request then repeats), a broadcast."""
    rng = random.Random(seed)
    frames: list[Frame] = []
    t = 0.0
    for n in range(transactions):
        unit = rng.randrange(1, 5)
        request, answer = _exchange(rng, unit)
        if n == transactions // 2:
            request, answer = with_crc(bytes([0, 6, 0, 1, 0, 9])), None  # a broadcast
        frames.append(Frame(request, t, True))
        t = frames[-1].end
        if answer is not None and rng.random() < 0.1:
            # the slave stays silent; past the response timeout the master asks again
            t += 0.6  # the default timeout at 9600 baud is 0.47 s
            frames.append(Frame(request, t, True))
            t = frames[-1].end
        if answer is None:
            t += 0.05
            continue
        t += rng.uniform(0.002, 0.04)
        frames.append(Frame(answer, t, False))
        t = frames[-1].end + rng.uniform(0.01, 0.08)
    return frames


# -- the forms ---------------------------------------------------------------------------


def exact_chunks(frames: list[Frame]) -> list[Chunk]:
    return [Chunk(f.data, f.end, f.start) for f in frames]


def labelled(frames: list[Frame], stamp: str, wrong: frozenset[int] = frozenset()) -> list[Chunk]:
    """Chunks as a logger writes them: its sends and receives labelled, one stamp a line."""
    out = []
    for k, f in enumerate(frames):
        master = f.master != (k in wrong)
        t = {"end": f.end, "start": f.start}[stamp]
        out.append(Chunk(f.data, t, direction=Direction.MASTER if master else Direction.SLAVE))
    return out


def usb_reads(frames: list[Frame], period: float = 0.016) -> list[Chunk]:
    """What a host reading a USB adapter every `period` seconds gets: whatever arrived."""
    data = bytearray()
    chunks = []
    next_read = period
    for f in frames:
        for k, byte in enumerate(f.data):
            arrived = f.start + (k + 1) * CHAR
            while arrived > next_read:
                if data:
                    chunks.append(Chunk(bytes(data), next_read))
                    data.clear()
                next_read += period
            data.append(byte)
    if data:
        chunks.append(Chunk(bytes(data), next_read))
    return chunks


def session_of(
    chunks: list[Chunk],
    *,
    labels: Labels = Labels.NONE,
    stamps: Stamp = Stamp.READ_END,
    resolution: float = 0.0,
    line: LineSettings = LINE,
) -> Session:
    session = Session(line, labels=labels, stamps=stamps, resolution=resolution)
    session.ingest(chunks)
    return session


def outcome(store: FrameStore) -> list[tuple[bytes, int, int, int]]:
    """What must not change: each row's bytes, kind, status, and partner."""
    return [
        (store.raw(i), store.kind[i], store.status[i], store.partner[i]) for i in range(len(store))
    ]


def shown_latencies(session: Session) -> list[float]:
    """Every latency a view would print, in ms (bounds included)."""
    out = []
    for i in range(len(session.store)):
        d = session.describer.detail(i)
        for value in (d.latency_ms, d.latency_max_ms):
            if value is not None:
                out.append(value)
    return out


# -- the forms of the logs people post -----------------------------------------------------

T0 = 1_722_250_000.0  # a whole second; the log clocks below cut times down to their unit


def _local(t: float, form: str) -> str:
    """`t` as a program prints local time; `MS` in `form` stands for the milliseconds."""
    moment = datetime.fromtimestamp(T0 + t)
    return moment.strftime(form).replace("MS", f"{moment.microsecond // 1000:03d}")


def evcc_log(frames: list[Frame]) -> str:
    """evcc's trace: a send printed before the write, a recv after the read; whole seconds."""
    lines = []
    for f in frames:
        stamp = _local(f.start if f.master else f.end, "%Y/%m/%d %H:%M:%S")
        word = "send" if f.master else "recv"
        lines.append(f"[sdm   ] TRACE {stamp} modbus: {word} {f.data.hex(' ')}")
    return "\n".join(lines) + "\n"


def modbustools_log(frames: list[Frame], stamped: bool) -> str:
    """ModbusTools' client log: Tx when written, Rx when read; milliseconds, or no time."""
    lines = []
    for f in frames:
        stamp = _local(f.start if f.master else f.end, "%d.%m.%Y %H:%M:%S.MS ")
        flag = "Tx" if f.master else "Rx"
        lines.append(f"{stamp if stamped else ''}'Device' {flag}: {f.data.hex(' ').upper()} ")
    return "\n".join(lines) + "\n"


def cas_log(frames: list[Frame]) -> str:
    """CAS Modbus Scanner's log window: whole seconds, the newest line first."""
    lines = []
    for f in frames:
        stamp = _local(f.start if f.master else f.end, "[%H:%M:%S]")
        word = "=> Poll" if f.master else "<= Response"
        lines.append(f"{stamp} {word}: {f.data.hex(' ').upper()}")
    return "\n".join(reversed(lines)) + "\n"


def libmodbus_log(frames: list[Frame]) -> str:
    """libmodbus debug output of a client: no time at all."""
    lines = []
    for f in frames:
        if f.master:
            lines += ["".join(f"[{b:02X}]" for b in f.data), "Waiting for a confirmation..."]
        else:
            lines.append("".join(f"<{b:02X}>" for b in f.data))
    return "\n".join(lines) + "\n"


def pymodbus_sync_log(frames: list[Frame]) -> str:
    """A pymodbus 3.0-3.7 synchronous client: SEND, RECV and Processing, milliseconds."""
    lines = []
    for f in frames:
        stamp = _local(f.end, "%Y-%m-%d %H:%M:%S,MS")
        data = " ".join(hex(b) for b in f.data)
        if f.master:
            lines.append(f"{stamp} DEBUG transaction:293 SEND: {data}")
        else:
            lines.append(f"{stamp} DEBUG transaction:324 RECV: {data}")
            lines.append(f"{stamp} DEBUG base:92 Processing: {data}")
    return "\n".join(lines) + "\n"


def saleae_ascii_hex(frames: list[Frame]) -> str:
    """Saleae Logic 1's Async Serial export in the ASCII & Hex radix: each byte's start."""

    def ascii_form(v: int) -> str:
        names = {9: "\\t", 10: "\\n", 13: "\\r", 32: "' '", 44: "COMMA"}
        return names.get(v) or (chr(v) if 0x21 <= v <= 0x7E else f"'{v}'")

    rows = ["Time [s],Value,Parity Error,Framing Error"]
    for f in frames:
        for k, v in enumerate(f.data):
            rows.append(f"{f.start + k * CHAR:.15f},{ascii_form(v)}\t(0x{v:02X}),,")
    return "\n".join(rows) + "\n"


def log_forms(frames: list[Frame]) -> dict[str, str]:
    return {
        "evcc trace, 1 s": evcc_log(frames),
        "ModbusTools, 1 ms": modbustools_log(frames, stamped=True),
        "ModbusTools, no time": modbustools_log(frames, stamped=False),
        "CAS Modbus Scanner, newest first, 1 s": cas_log(frames),
        "libmodbus, no time": libmodbus_log(frames),
        "pymodbus synchronous, 1 ms": pymodbus_sync_log(frames),
        "Saleae ASCII & Hex, exact": saleae_ascii_hex(frames),
    }


# -- the property --------------------------------------------------------------------------


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_every_form_of_the_same_bytes_gives_the_same_frames(seed: int) -> None:
    frames = polling(seed)
    reference = session_of(exact_chunks(frames), stamps=Stamp.EXACT)
    want = outcome(reference.store)
    assert [row[0] for row in want] == [f.data for f in frames]  # every frame, nothing else
    # the reference itself is right: who sent each frame follows from content and order
    assert [row[1] == Kind.REQUEST for row in want] == [f.master for f in frames]
    forms = {
        "labels, end stamps": session_of(
            labelled(frames, "end"), labels=Labels.HINT, stamps=Stamp.FRAME_END
        ),
        "labels, start stamps": session_of(
            labelled(frames, "start"), labels=Labels.HINT, stamps=Stamp.FRAME_START
        ),
        "no labels, end stamps": session_of(
            [Chunk(c.data, c.t_end) for c in labelled(frames, "end")], stamps=Stamp.FRAME_END
        ),
        "16 ms reads": session_of(usb_reads(frames)),
        "no time": session_of(
            [Chunk(f.data, k * 1.0) for k, f in enumerate(frames)], stamps=Stamp.NONE
        ),
    }
    with tempfile.TemporaryDirectory() as folder:
        for name, text in log_forms(frames).items():
            path = Path(folder) / "log"
            path.write_text(text)
            forms[name] = replay_file(path, line_options())
            # print times may come sooner than the line speed allows: said once; a coarse
            # clock may leave a retried write's label against the order (below); no other
            said = ("timestamps", "direction labels") if name in NO_TIME else ("timestamps",)
            assert all(w.startswith(said) for w in forms[name].warnings), name
    for name, session in forms.items():
        got = outcome(session.store)
        if name in NO_TIME:
            # Without time, a write repeated after a timeout and its echoed answer are the
            # same bytes in the same order: only the frames, and the kinds of every other
            # code, can match. A clock of whole seconds (evcc, CAS) is no better inside a
            # second: the labels those logs carry could tell them apart, but a label is a
            # hint, and the pairing goes by content and order.
            assert [r[0] for r in got] == [r[0] for r in want], name
            plain = [k for k, r in enumerate(want) if r[0][1] & 0x7F not in ECHOED]
            assert [got[k][1] for k in plain] == [want[k][1] for k in plain], name
            if name != "no time":  # with labels, every other transaction pairs the same
                assert [got[k][1:] for k in plain] == [want[k][1:] for k in plain], name
            assert all(x > 0 for x in shown_latencies(session)), name
            continue
        assert got == want, name
        assert all(x > 0 for x in shown_latencies(session)), name


# -- the same transactions over Modbus TCP, as logs print them ----------------------------


def as_modbus_tcp(frames: list[Frame]) -> list[Frame]:
    """The polling of `frames` by a Modbus TCP client: a new transaction id for each
    request (a retry too), its answer with the same id; the RTU check left off."""
    out = []
    tid = 0
    for f in frames:
        if f.master:
            tid += 1
        pdu = f.data[:-2]
        header = tid.to_bytes(2, "big") + b"\0\0" + len(pdu).to_bytes(2, "big")
        out.append(Frame(header + pdu, f.start, f.master))
    return out


def tcp_log_forms(frames: list[Frame]) -> dict[str, str]:
    stamp_ms = "%Y-%m-%d %H:%M:%S,MS"
    return {
        "evcc trace, 1 s": evcc_log(frames),
        "mbpoll -v, no time": "Connecting to [192.168.1.20]:502\n" + libmodbus_log(frames),
        "pymodbus, 1 ms": "".join(
            f"{_local(f.start if f.master else f.end, stamp_ms)} DEBUG transport:357 "
            + ("send: " if f.master else "recv: ")
            + " ".join(hex(b) for b in f.data)
            + ("" if f.master else " extra data: ")
            + "\n"
            for f in frames
        ),
        "ModbusTools, 1 ms": modbustools_log(frames, stamped=True),
    }


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_every_modbus_tcp_log_of_the_same_transactions_gives_the_same_pairs(seed: int) -> None:
    frames = as_modbus_tcp(polling(seed))
    channels = {0: "tcp client > server modbus-tcp", 1: "tcp server > client modbus-tcp (server)"}
    reference = Session(LINE, labels=Labels.CERTAIN, stamps=Stamp.EXACT, network=channels)
    reference.ingest(
        [
            Chunk(
                f.data,
                f.end,
                f.start,
                0 if f.master else 1,
                Direction.MASTER if f.master else Direction.SLAVE,
            )
            for f in frames
        ]
    )
    want = outcome(reference.store)
    assert sorted(row[0] for row in want) == sorted(f.data for f in frames)
    with tempfile.TemporaryDirectory() as folder:
        for name, text in tcp_log_forms(frames).items():
            path = Path(folder) / "log"
            path.write_text(text)
            session = replay_file(path)
            assert session.store.servers, name  # framed as Modbus TCP
            got = outcome(session.store)
            # the same frames, kinds and pairs; a request nobody answered times out only
            # where the clock can show a wait of 3 s
            assert [r[:2] + r[3:] for r in got] == [r[:2] + r[3:] for r in want], name
            answered = [k for k, r in enumerate(want) if r[3] >= 0]
            assert [got[k][2] for k in answered] == [want[k][2] for k in answered], name
            assert all(x > 0 for x in shown_latencies(session)), name


def test_labels_against_the_content_are_reported_once_and_change_nothing() -> None:
    frames = polling(7)
    reference = outcome(session_of(exact_chunks(frames), stamps=Stamp.EXACT).store)
    wrong = frozenset({1, 4, 9})
    session = session_of(labelled(frames, "end", wrong), labels=Labels.HINT, stamps=Stamp.FRAME_END)
    assert outcome(session.store) == reference
    notes = [w for w in session.warnings if w.startswith("direction labels")]
    assert len(notes) == 1 and "3 frame(s)" in notes[0]


# -- what real sites showed ---------------------------------------------------------------


def _pcapng_147(frames: list[Frame], path: Path) -> None:
    """What a logger that records its own sends writes: EPB flags, frame-end times."""
    with path.open("wb") as handle:
        writer = PcapngWriter(handle)
        iface = writer.add_interface(LINKTYPE_USER0, name="COM3")
        for f in frames:
            flags = EPB_FLAG_OUTBOUND if f.master else EPB_FLAG_INBOUND
            writer.write_packet(iface, f.end, f.data, flags=flags)


def test_inbound_answers_in_a_147_capture_are_answers(tmp_path: Path) -> None:
    # A Solax inverter polling an Eastron meter, logged with direction flags: every
    # answer has the length its request predicts and a valid CRC, whatever its flag.
    frames = []
    t = 1_700_000_000.0
    for address in (0, 6, 12, 70, 342):
        request, answer = _read_holding(1, address, 2)
        frames += [Frame(request, t, True), Frame(answer, t + 0.03, False)]
        t += 1.0
    path = tmp_path / "solax.pcapng"
    _pcapng_147(frames, path)
    session = replay_file(path, line_options())
    store = session.store
    kinds = [Kind(k) for k in store.kind]
    assert kinds == [Kind.REQUEST, Kind.RESPONSE] * 5
    assert all(s == Status.OK for s in store.status)
    (unit,) = session.stats.units.values()
    assert unit.requests == 5 and unit.responses == 5 and len(unit.latencies) == 5
    rows = _jsonl(session)
    assert [r["direction"] for r in rows] == ["M>S", "S>M"] * 5
    assert all(r["transaction"]["status"] == "ok" for r in rows)
    assert not [w for w in session.warnings if "direction" in w]


def line_options() -> ReadOptions:
    return ReadOptions(baud=9600, parity="N", mode="rtu")


def _jsonl(session: Session) -> list[dict[str, Any]]:
    out = io.StringIO()
    Lister(out, "jsonl", session.describer).write(range(len(session.store)))
    return [json.loads(line) for line in out.getvalue().splitlines()]


def test_print_times_before_a_long_answer_ends_never_reorder_or_go_negative() -> None:
    # A Fronius inverter's monitor stamps an 89-byte answer (93 ms at 9600) 3-7 ms after
    # its request: before the answer could have been on the wire. Order is the file's;
    # the latency is unknown, and the stamps are reported once.
    chunks = []
    t = 100.0
    for k in range(6):
        request, answer = _read_holding(240, 40000 + k, 42)
        assert len(answer) == 89
        chunks.append(Chunk(request, t, direction=Direction.MASTER))
        chunks.append(Chunk(answer, t + 0.003 + k * 0.0008, direction=Direction.SLAVE))
        t += 0.5
    session = session_of(chunks, labels=Labels.HINT, stamps=Stamp.PRINT, resolution=1e-3)
    store = session.store
    assert [Kind(k) for k in store.kind] == [Kind.REQUEST, Kind.RESPONSE] * 6
    assert all(s == Status.OK for s in store.status)
    assert all(measure(store, i) is None for i in range(len(store)))
    assert shown_latencies(session) == []
    (unit,) = session.stats.units.values()
    assert unit.latencies.tolist() == [] and unit.unmeasured == 6
    notes = [w for w in session.warnings if w.startswith("timestamps")]
    assert len(notes) == 1 and "6 read(s) or line(s)" in notes[0]
    assert "6 latency(ies) the stamps cannot give" in session.stats.timing_line()


def test_request_and_answer_in_one_16ms_read_show_a_bound_not_zero() -> None:
    frames = polling(3, transactions=60)
    session = session_of(usb_reads(frames))
    store = session.store
    # the reads, 16 ms apart and later when the line pauses, give the resolution: at
    # least the read interval, with room for reads that came late
    assert 0.016 <= store.resolution < 0.1
    bounds = [measure(store, i) for i in range(len(store))]
    assert any(b is not None and b.bound for b in bounds)
    assert all(b is None or b.seconds > 0 for b in bounds)
    stats = session.stats
    assert all(min(u.latencies, default=1) > 0 for u in stats.units.values())
    assert "faster than that" in stats.timing_line()
    text = io.StringIO()
    Lister(text, "text", session.describer).write(range(len(store)))
    assert f"<{store.resolution * 1000:.0f}ms" in text.getvalue().replace(" ", "")
    assert " 0.0ms" not in text.getvalue() and "-0.0" not in text.getvalue()


def test_a_file_without_time_says_its_timing_is_synthetic(tmp_path: Path) -> None:
    path = tmp_path / "bytes.bin"
    path.write_bytes(b"".join(f.data for f in polling(5)))
    session = replay_file(path, line_options())
    assert session.store.stamps == Stamp.NONE
    rows = _jsonl(session)
    assert {r["timing"] for r in rows} == {"synthetic"}
    assert all(r.get("transaction", {}).get("latency_ms") is None for r in rows)
    assert session.stats.timing_line().startswith("timing: synthetic")
    assert "-" in session.stats.table().splitlines()[2]  # no poll period
    text = io.StringIO()
    Lister(text, "text", session.describer).write(range(len(session.store)))
    assert text.getvalue().startswith("# timing: synthetic")


# -- ASCII ---------------------------------------------------------------------------------


def _ascii(body: bytes) -> bytes:
    return b":" + (body + bytes([lrc(body)])).hex().upper().encode() + b"\r\n"


def test_an_ascii_retry_is_a_request_not_the_answer() -> None:
    line = LineSettings(baud=9600, bytesize=7, parity="E", mode="ascii")
    request = _ascii(bytes([1, 3, 0, 0, 0, 2]))
    answer = _ascii(bytes([1, 3, 4, 0, 1, 0, 2]))
    chunks = [
        Chunk(request, 1.0),
        Chunk(request, 2.0),  # no answer came: the master asks again
        Chunk(answer, 2.05),
    ]
    session = session_of(chunks, line=line)
    store = session.store
    assert [Kind(k) for k in store.kind] == [Kind.REQUEST, Kind.REQUEST, Kind.RESPONSE]
    assert [Status(s) for s in store.status] == [Status.TIMEOUT, Status.OK, Status.OK]
    assert store.partner[2] == 1
    assert session.describer.detail(1).problems[0].kind == "retry"


def test_an_ascii_answer_must_have_the_predicted_length() -> None:
    line = LineSettings(baud=9600, bytesize=7, parity="E", mode="ascii")
    chunks = [
        Chunk(_ascii(bytes([1, 3, 0, 0, 0, 2])), 1.0),
        Chunk(_ascii(bytes([1, 3, 0, 0, 0, 2])), 1.05),  # a second master's same request
        Chunk(_ascii(bytes([1, 3, 4, 0, 1, 0, 2])), 1.1),
    ]
    store = session_of(chunks, line=line).store
    assert [Kind(k) for k in store.kind] == [Kind.REQUEST, Kind.REQUEST, Kind.RESPONSE]


def test_an_ascii_wait_expires_with_the_response_timeout() -> None:
    line = LineSettings(baud=9600, bytesize=7, parity="E", mode="ascii")
    chunks = [
        Chunk(_ascii(bytes([1, 6, 0, 1, 0, 3])), 1.0),
        # long after the timeout the same bytes again: a new request, not an echo answer
        Chunk(_ascii(bytes([1, 6, 0, 1, 0, 3])), 5.0),
        Chunk(_ascii(bytes([1, 6, 0, 1, 0, 3])), 5.1),
    ]
    store = session_of(chunks, line=line).store
    assert [Kind(k) for k in store.kind] == [Kind.REQUEST, Kind.REQUEST, Kind.RESPONSE]
    assert [Status(s) for s in store.status] == [Status.TIMEOUT, Status.OK, Status.OK]
