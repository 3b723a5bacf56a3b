"""SunSpec devices recognised on the bus with no dictionary: a master reads the SunS
marker, the model chain (common model 1, inverter 103, meter 203) and then polls values;
the listing names them, with units and the _SF scale factors applied.

The register maps below are laid out by hand from the SunSpec model tables (model 1:
ID, L, Mn[16], Md[16], Opt[8], Vr[8], SN[16], DA, Pad; model 103: A at offset 2, A_SF 6,
PhVphA 10, V_SF 13, W 14, W_SF 15, Hz 16, Hz_SF 17, WH 24-25, WH_SF 26, St 38; model
203: A 2, A_SF 6, Hz 16, Hz_SF 17, W 18, W_SF 22, TotWhExp 38-39, TotWhImp 46-47,
TotWh_SF 54), not taken from the code under test."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.dictionary.sunspec import (
    ModelLibrary,
    PointDef,
    decode_point,
    default_library,
    definitions_folder,
    parse_model,
)
from dissectors.functions import FUNCTIONS
from sniffer.cli import main
from sniffer.framing.store import FrameStore
from sniffer.meaning import sunspec
from sniffer.meaning.annotate import Annotator
from sniffer.meaning.sunspec import READS, SunSpecTracker
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import Session, replay_file
from sniffer.sources.base import ReadOptions
from sniffer.sources.pcapng_writer import PcapngWriter
from sniffer.vocab import Flag, Kind
from tests.support.sunspec import (
    LINE,
    UNIT,
    as_ascii,
    as_mbap,
    device_image,
    discovery,
    frames_of,
    network_capture,
    read,
    s16,
    session_of,
)

needs_models = pytest.mark.skipif(
    definitions_folder() is None, reason="pysunspec2 (extra [sunspec], in dev) not installed"
)


def texts(session: Session, row: int) -> list[str]:
    return [r.text for r in session.describer.detail(row).registers]


# -- the definitions ---------------------------------------------------------------------


@needs_models
def test_pysunspec2_models_are_read_without_importing_it() -> None:
    import sys

    lib = default_library()
    assert {1, 103, 203} <= set(lib.ids())
    inverter = lib.get(103)
    assert inverter is not None and inverter.fixed_size == 52
    w = next(p for p in inverter.points if p.name == "W")
    assert (w.offset, w.units, w.sf) == (14, "W", "W_SF")
    assert "sunspec2" not in sys.modules  # located as data, never imported


def test_a_model_json_parses_with_a_repeating_group() -> None:
    data = {
        "id": 64999,
        "group": {
            "name": "test",
            "points": [
                {"name": "ID", "type": "uint16", "size": 1},
                {"name": "L", "type": "uint16", "size": 1},
                {"name": "DCA_SF", "type": "sunssf", "size": 1},
            ],
            "groups": [
                {
                    "name": "module",
                    "count": 0,
                    "points": [
                        {"name": "IDStr", "type": "string", "size": 4},
                        {"name": "DCA", "type": "uint16", "size": 1, "sf": "DCA_SF"},
                    ],
                }
            ],
        },
    }
    model = parse_model(data)
    layout = model.layout(1 + 2 * 5)  # L = fixed body 1 + two modules of 5
    assert [(p.title, p.offset) for p in layout[3:]] == [
        ("module 1 IDStr", 3),
        ("module 1 DCA", 7),
        ("module 2 IDStr", 8),
        ("module 2 DCA", 12),
    ]
    with pytest.raises(ValueError, match="needs `id` and `group`"):
        parse_model({"id": 1})


@pytest.mark.parametrize(
    ("kind", "words", "sf", "text"),
    [
        ("int16", [0x8000], -1, "X = not implemented"),
        ("uint16", [0xFFFF], None, "X = not implemented"),
        ("int16", [s16(-1500)], 0, "X = -1500 W"),
        ("uint16", [1234], -2, "X = 12.34 W"),
        ("uint16", [12], 3, "X = 12000 W"),
        ("acc32", [0x0001, 0x0000], -3, "X = 65.536 W"),
        ("float32", [0x4148, 0x0000], None, "X = 12.5 W"),
        ("float32", [0x7FC0, 0x0000], None, "X = not implemented"),
        ("sunssf", [s16(-3)], None, "X = -3 (scale 10^-3)"),
    ],
)
def test_point_values(kind: str, words: list[int], sf: int | None, text: str) -> None:
    point = PointDef("X", "", kind, 2, len(words), "W", "X_SF" if sf is not None else None)
    assert decode_point(point, 100, words, sf).text == text


def test_a_point_whose_scale_factor_was_never_seen_is_shown_raw_and_says_so() -> None:
    point = PointDef("W", "Watts", "int16", 14, 1, "W", "W_SF")
    got = decode_point(point, 40084, [8190], None, sf_known=False)
    assert got.text == "Watts = 8190 (raw; its scale factor W_SF not seen yet)"


# -- recognition and annotation ------------------------------------------------------------


@needs_models
@pytest.mark.parametrize("base", [40000, 50000, 0, 40001])
def test_discovery_then_polls_annotate_with_no_dictionary(base: int) -> None:
    reg = device_image(base)
    m103, m203 = base + 70, base + 122
    polls = [(m103 + 2, 50), (m203 + 2, 53), (m103 + 14, 1)]
    session = session_of(frames_of(reg, discovery(reg, base) + polls))
    tracker = session.annotator.sunspec
    su = tracker.units[UNIT]
    assert su.base == base and su.complete
    assert [(m.id, m.start, m.length) for m in su.models] == [
        (1, base + 2, 66),
        (103, m103, 50),
        (203, m203, 105),
    ]
    assert session.annotator.label(UNIT) == "SunSpec Acme Solar Inverter 3000"
    rows = len(session.store)
    marker = texts(session, 1)
    assert marker == ["SunSpec marker = SunS"]
    header = texts(session, 3)
    assert header == ["Model ID = model 1 (Common)", "Model length = 66 registers"]
    common = texts(session, 5)
    assert "Manufacturer = 'Acme Solar'" in common and "Serial Number = 'SN-0042'" in common
    inverter = texts(session, rows - 5)  # the poll of model 103's values
    for want in (
        "Amps = 12.34 A",
        "Phase Voltage AN = 230.1 V",
        "Watts = 819.0 W",
        "Hz = 50.01 Hz",
        "WattHours = 100000000 Wh",
        "Operating State = MPPT (4)",
        "Amps PhaseB = not implemented",
    ):
        assert want in inverter
    meter = texts(session, rows - 3)
    for want in (
        "Amps = -5.2 A",
        "Hz = 49.99 Hz",
        "Watts = -1500 W",
        "Total Watt-hours Exported = 123450 Wh",
        "Total Watt-hours Imported = 1010 Wh",
    ):
        assert want in meter
    # W alone: its scale factor is not in the frame, so the last one read applies
    assert texts(session, rows - 1) == ["Watts = 819.0 W"]


@needs_models
def test_a_changed_scale_factor_applies_from_the_frame_that_shows_it() -> None:
    reg = device_image()
    m103 = 40070
    first = frames_of(reg, [*discovery(reg, 40000), (m103 + 14, 2), (m103 + 14, 1)])
    reg[m103 + 14], reg[m103 + 15] = 820, 0  # the device changes W_SF to 0
    later = [(t + 10, f) for t, f in frames_of(reg, [(m103 + 14, 2), (m103 + 14, 1)])]
    session = session_of(first + later)
    rows = len(session.store)
    assert texts(session, rows - 7) == ["Watts = 819.0 W", "W_SF = -1 (scale 10^-1)"]
    assert texts(session, rows - 5) == ["Watts = 819.0 W"]
    assert texts(session, rows - 3) == ["Watts = 820 W", "W_SF = 0 (scale 10^0)"]
    assert texts(session, rows - 1) == ["Watts = 820 W"]
    # shown again later, an early frame keeps the scale factor of its own time
    session.describer = type(session.describer)(session.store, session.annotator)
    assert texts(session, rows - 5) == ["Watts = 819.0 W"]


def test_without_the_definitions_models_are_named_by_id_and_say_what_to_install() -> None:
    reg = device_image()
    tracker = SunSpecTracker(ModelLibrary(None))
    for start, count in discovery(reg, 40000):
        tracker.take(UNIT, 0, start, [reg[start + k] for k in range(count)])
    su = tracker.units[UNIT]
    assert [m.id for m in su.models] == [1, 103, 203] and su.complete
    got = tracker.decode(su, 1, 40072, [reg[40072 + k] for k in range(50)])
    assert got[0].text == (
        "model 103 (unknown model): 50 registers (install modscope[sunspec] (pysunspec2) "
        "to name its values)"
    )


def test_a_unit_that_does_not_show_the_marker_is_left_alone() -> None:
    reg = {40000 + k: k for k in range(10)}  # something else at 40000
    session = session_of(frames_of(reg, [(40000, 4), (40002, 2)]))
    assert session.annotator.sunspec.units == {}
    assert texts(session, 1) == []


@needs_models
def test_a_unit_with_a_dictionary_is_not_taken_for_sunspec(tmp_path: Path) -> None:
    from sniffer.meaning.annotate import load_bindings

    path = tmp_path / "d.toml"
    path.write_text(
        'format = 1\n[device]\nmodel = "mine"\nname = "Mine"\n'
        '[[entry]]\npdu = 40000\ntable = "holding"\nname = "Magic"\ntype = "u32"\n',
        encoding="utf-8",
    )
    reg = device_image()
    bindings = load_bindings(None, [f"{UNIT}=mine"], [path])
    session = session_of(frames_of(reg, discovery(reg, 40000)), bindings=bindings)
    assert session.annotator.sunspec.units == {}
    assert texts(session, 1) == ["Magic = 1400204883"]  # 0x53756E53


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from([0, 1, 2, 40000, 40001, 40002, 40070, 50000]),
            st.lists(st.sampled_from([0, 1, 2, 103, 0x5375, 0x6E53, 0xFFFF, 0x8000]), max_size=8),
        ),
        max_size=12,
    )
)
def test_any_reads_never_break_the_tracker(reads: list[tuple[int, list[int]]]) -> None:
    tracker = SunSpecTracker(default_library())
    for row, (start, words) in enumerate(reads):
        tracker.take(UNIT, row, start, words)
        su = tracker.units.get(UNIT)
        if su is not None:
            tracker.decode(su, row, start, words)
            assert all(m.start >= su.base + 2 for m in su.models)
            tracker.label(UNIT)


def annotate_row_by_row(annotator: Annotator, store: FrameStore) -> None:
    """Annotator.update's definition: every row looked at in order."""
    for i in range(annotator.next, len(store)):
        u = store.unit[i]
        if u not in annotator.bindings:
            if store.fc[i] in READS and store.kind[i] == Kind.RESPONSE:
                annotator.sunspec.follow(store, i)
            continue
        k = store.kind[i]
        if k == Kind.REQUEST:
            annotator._request(store, i, u)
        elif k in (Kind.RESPONSE, Kind.EXCEPTION):
            annotator._answer(store, i, u)
    annotator.next = len(store)


def test_rows_picked_from_the_columns_are_annotated_as_row_by_row() -> None:
    """A SunSpec device, a unit read at address 0 with no marker and the demo's bound
    devices (with their own timing rules and parameter windows), interleaved, fed in
    pieces: the same SunSpec state, windows and flags as a walk over every row."""
    from sniffer.meaning.annotate import load_bindings
    from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, replay_file

    bindings = load_bindings(DEMO_BUS)
    demo = replay_file(DEMO_CAPTURE, bindings=bindings).store
    reg = device_image()
    sunspec = frames_of(reg, discovery(reg, 40000) + [(40070, 50)] * 5)
    other = {k: k for k in range(10)}
    others = [frame for k in range(6) for frame in read(other, 0, 4, unit=9)]
    frames: list[tuple[float, bytes]] = []
    for k in range(min(len(demo), 600)):
        frames.append((demo.t_end[k] - demo.t_end[0], demo.raw(k)))
    for n, (t, data) in enumerate(sunspec + [(k * 0.7, f) for k, f in enumerate(others)]):
        frames.append((t + 0.001 * n, data))
    frames.sort(key=lambda f: f[0])
    session = Session(LINE, bindings=bindings)
    for k, (t, data) in enumerate(frames):
        session.feed(Chunk(data, 1_700_000_000 + t + 0.02 * k))
        if k % 37 == 0:
            session.refresh()
    session.finish()
    store = session.store
    # the same rows, with the annotator's own flags taken off, annotated row by row
    again = FrameStore(store.streams)
    again.stamps, again.resolution = store.stamps, store.resolution  # (what slow is: measure)
    mine = int(Flag.QUIET_VIOLATED | Flag.DEVICE_SLOW)
    for i in range(len(store)):
        again.copy_row(store, i)
        again.sync()
        again.flags[i] &= ~mine
        again.partner[i], again.status[i] = store.partner[i], store.status[i]
    expected = Annotator(bindings)
    annotate_row_by_row(expected, again)
    got = session.annotator
    assert got.sunspec.units == expected.sunspec.units
    assert UNIT in got.sunspec.units and 9 not in got.sunspec.units
    assert got.tracks == expected.tracks
    assert got.last_write == expected.last_write
    assert store.flags == again.flags
    assert any(f & mine for f in store.flags)  # the bound devices' rules did flag rows


# -- as the user sees it: replay with no dictionary ----------------------------------------


def write_capture(path: Path, frames: list[tuple[float, bytes]]) -> Path:
    with path.open("wb") as f:
        writer = PcapngWriter(f)
        port = writer.add_interface(147, name="rs485")
        for t, data in frames:
            writer.write_packet(port, 1_700_000_000 + t + 0.005, data)
    return path


@needs_models
def test_replay_lists_named_scaled_values(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    reg = device_image()
    polls = [(40072, 50), (40124, 53)]
    capture = write_capture(
        tmp_path / "sunspec.pcapng", frames_of(reg, [*discovery(reg, 40000), *polls])
    )
    assert main(["replay", str(capture), "--format", "text"]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert "SunSpec marker = SunS" in rows[1]
    assert "Amps = 12.34 A, Amps PhaseA = not implemented" in rows[-3]
    assert "Amps = -5.2 A" in rows[-1]
    assert main(["replay", str(capture), "--format", "jsonl"]) == 0
    last = json.loads(capsys.readouterr().out.splitlines()[-3])
    values = {r["name"]: r for r in last["registers"]}
    assert values["Watts"]["value"] == pytest.approx(819.0) and values["Watts"]["unit"] == "W"
    # the filter language finds named values of a recognised unit: the two reads of the
    # model bodies while the master discovered them, and the two polls
    assert main(["replay", str(capture), "--format", "text", "--filter", "Watts"]) == 0
    out, err = capsys.readouterr()
    assert len(out.splitlines()) == 4 and err == ""
    assert main(["replay", str(capture), "--format", "text", "--filter", "reg:Watts"]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 4


@needs_models
def test_a_sunspec_device_on_modbus_ascii() -> None:
    from dissectors.checks import lrc

    def ascii_frame(rtu: bytes) -> bytes:
        body = rtu[:-2]
        return b":" + (body + bytes([lrc(body)])).hex().upper().encode() + b"\r\n"

    line = LineSettings(9600, 7, "E", 1, "ascii")
    reg = device_image()
    session = Session(line)
    for k, (start, count) in enumerate([*discovery(reg, 40000), (40084, 2)]):
        request, answer = read(reg, start, count)
        session.feed(Chunk(ascii_frame(request), 1_700_000_000 + k * 1.0 + 0.02))
        session.feed(Chunk(ascii_frame(answer), 1_700_000_000 + k * 1.0 + 0.5))
    session.finish()
    assert [m.id for m in session.annotator.sunspec.units[UNIT].models] == [1, 103, 203]
    assert texts(session, len(session.store) - 1) == [
        "Watts = 819.0 W",
        "W_SF = -1 (scale 10^-1)",
    ]


# -- every carrier, FC 3 or FC 4: one rule -------------------------------------------------

CARRIERS = ["rtu", "ascii", "modbus-tcp", "rtu-over-tcp"]
POLLS = [(40072, 50), (40124, 53), (40084, 2)]  # model 103's values, 203's, W and W_SF


def session_over(carrier: str, function: int, tmp_path: Path) -> Session:
    """A master discovers the device and polls it, over `carrier`, with `function`."""
    reg = device_image()
    reads = [*discovery(reg, 40000), *POLLS]
    if carrier == "rtu":
        return session_of(frames_of(reg, reads, function))
    if carrier == "ascii":
        session = Session(LineSettings(9600, 7, "E", 1, "ascii"))
        for t, frame in frames_of(reg, reads, function):
            session.feed(Chunk(as_ascii(frame), 1_700_000_000 + t))
        session.finish()
        return session
    path = tmp_path / f"{carrier}.pcap"
    path.write_bytes(
        network_capture(reg, reads, function=function, carrier=carrier.removeprefix("modbus-"))
    )
    return replay_file(path, ReadOptions(carrier=carrier.removeprefix("modbus-")))


def answers(session: Session) -> list[int]:
    store = session.store
    return [i for i in range(len(store)) if store.kind[i] == Kind.RESPONSE]


@needs_models
@pytest.mark.parametrize("function", [3, 4])
@pytest.mark.parametrize("carrier", CARRIERS)
def test_a_sunspec_device_is_recognised_over_every_carrier(
    carrier: str, function: int, tmp_path: Path
) -> None:
    session = session_over(carrier, function, tmp_path)
    store = session.store
    if carrier in ("modbus-tcp", "rtu-over-tcp"):  # what the rule reads the request from
        mbap = carrier == "modbus-tcp"
        assert all(bool(store.flags[i] & Flag.MBAP) == mbap for i in answers(session))
    su = session.annotator.sunspec.units[UNIT]
    assert (su.base, su.complete, su.function) == (40000, True, function)
    assert [m.id for m in su.models] == [1, 103, 203]
    assert session.annotator.label(UNIT) == "SunSpec Acme Solar Inverter 3000"
    inverter, meter, watts = answers(session)[-3:]
    assert "Amps = 12.34 A" in texts(session, inverter)
    assert "Total Watt-hours Exported = 123450 Wh" in texts(session, meter)
    assert texts(session, watts) == ["Watts = 819.0 W", "W_SF = -1 (scale 10^-1)"]
    table = "holding_registers" if function == 3 else "input_registers"
    values = session.describer.detail(watts).registers
    assert {v.table for v in values} == {table}  # named in the table that was read


@needs_models
def test_every_carrier_gives_the_tracker_the_same_device(tmp_path: Path) -> None:
    """The same reads in four envelopes: the same image, chain and scale factors."""

    def state(session: Session) -> object:
        su = session.annotator.sunspec.units[UNIT]
        scale = {a: h.values for a, h in su.scale.items()}
        return su.base, su.image, [(m.id, m.start, m.length) for m in su.models], scale

    rtu = state(session_over("rtu", 3, tmp_path))
    for carrier in CARRIERS[1:]:
        assert state(session_over(carrier, 3, tmp_path)) == rtu, carrier


def test_reads_of_the_other_table_than_the_markers_are_left_alone() -> None:
    """SunSpec's registers are holding registers; a device may serve them as input
    registers too, but nothing says a unit's input registers are its SunSpec map: the
    tracker keeps to the table the marker was read from."""
    reg = device_image()
    frames = frames_of(reg, discovery(reg, 40000))
    later = [(t + 30, f) for t, f in frames_of(reg, [(40084, 2)], function=4)]
    session = session_of(frames + later)
    su = session.annotator.sunspec.units[UNIT]
    assert su.function == 3 and su.complete
    assert texts(session, len(session.store) - 1) == []  # the FC 4 answer: plain words
    tracker = SunSpecTracker(ModelLibrary(None))
    tracker.take(UNIT, 0, 40000, [0x5375, 0x6E53, 1, 66], function=4)
    tracker.take(UNIT, 1, 40002, [0xFFFF, 0], function=3)  # the holding table: not taken
    assert tracker.units[UNIT].image == {40000: 0x5375, 40001: 0x6E53, 40002: 1, 40003: 66}


def test_the_rule_reads_what_the_registry_and_the_envelopes_say() -> None:
    """The reads SunSpec takes are the registry's reads of registers, each naming its
    table; a request's PDU lies where each envelope puts it (the numbers the compiled
    first look is given at each call)."""
    registry = {c for c, spec in FUNCTIONS.items() if spec.family == "read"}
    registry &= {c for c, spec in FUNCTIONS.items() if spec.table in set(sunspec.TABLES.values())}
    assert set(sunspec.READS) == registry == set(sunspec.TABLES)
    assert all(FUNCTIONS[c].table == sunspec.TABLES[c] for c in sunspec.READS)
    assert bytes(c in sunspec.READS for c in range(256)) == sunspec._READS_MASK
    request, _answer = read(device_image(), 40000, 2, function=4)
    pdu = request[1:-2]  # function code, first register, count
    assert len(pdu) == sunspec._READ_PDU
    for frame, (head, tail) in (
        (request, sunspec._RTU_FRAME),
        (as_mbap(request, 9), sunspec._MBAP_FRAME),
    ):
        assert frame[head : len(frame) - tail] == pdu
    assert list(sunspec._FRAMES) == [*sunspec._RTU_FRAME, *sunspec._MBAP_FRAME, len(pdu)]
