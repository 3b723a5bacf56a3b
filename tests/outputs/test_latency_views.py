"""One meaning of latency everywhere: the JSONL pair (`latency_ms`, `latency_max_ms`) is
what the text listing, CSV, Parquet, the TUI and a Wireshark export read back carry, for
every kind of stamps; no view shows a latency of 0 or less, nor a value where the
timing only bounds it."""

from __future__ import annotations

import csv
import io
import json
import random
import re
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.framing.pairing import shown_step
from sniffer.model import Chunk, Direction, Labels, LineSettings, Stamp
from sniffer.outputs.export import PcapExporter
from sniffer.outputs.listing import Lister
from sniffer.session.session import DEMO_CAPTURE, Session, open_session, replay_file
from sniffer.tui.render import latency_text

LOGS = Path(__file__).parent.parent / "captures" / "logs"
LINE = LineSettings(baud=19200, parity="E", mode="rtu")
LATENCY = re.compile(r"  +(<?)(\d+(?:\.\d+)?)(ms|s)  ")


def bus(seed: int, stamps: Stamp, resolution: float) -> Session:
    """A master polling three units, the answers after random waits (0 to 60 ms, a few
    slower), stamped as `stamps` say: per frame (its end, or print times with labels),
    exactly, or as host reads of every 16 ms."""
    rng = random.Random(seed)
    char = LINE.char_time
    frames: list[tuple[bytes, float, bool]] = []
    t = 1_700_000_000.0
    for k in range(rng.randrange(20, 80)):
        unit = 1 + k % 3
        request = with_crc(bytes([unit, 3, 0, 0, 0, 1 + k % 4]))
        answer = with_crc(bytes([unit, 3, 2 * (1 + k % 4)]) + bytes(2 * (1 + k % 4)))
        frames.append((request, t, True))
        t += len(request) * char + rng.choice((0.0, rng.uniform(0, 0.06), rng.uniform(0, 0.3)))
        frames.append((answer, t, False))
        t += len(answer) * char + rng.uniform(0.005, 0.2)
    chunks: list[Chunk] = []
    if stamps is Stamp.READ_END:
        data, due = bytearray(), frames[0][1] + 0.016
        for raw, start, _ in frames:
            for i, byte in enumerate(raw):
                while start + (i + 1) * char > due:
                    if data:
                        chunks.append(Chunk(bytes(data), due))
                        data.clear()
                    due += 0.016
                data.append(byte)
        chunks.append(Chunk(bytes(data), due))
    for raw, start, master in frames if stamps is not Stamp.READ_END else ():
        end = start + len(raw) * char
        direction = Direction.MASTER if master else Direction.SLAVE
        if stamps is Stamp.EXACT:
            chunks.append(Chunk(raw, end, t_start=start))
        else:  # a frame's end, or its print time (to the declared resolution's digits)
            stamp = round(end + rng.uniform(0, 0.002), 3) if stamps is Stamp.PRINT else end
            chunks.append(Chunk(raw, stamp, direction=direction))
    labels = Labels.HINT if stamps is Stamp.PRINT else Labels.NONE
    session = Session(
        LINE,
        stamps=stamps,
        resolution=resolution,
        labels=labels,
        exact_timing=stamps is Stamp.EXACT,
    )
    session.ingest(chunks)
    return session


def pairs_of_jsonl(session: Session) -> list[tuple[float | None, float | None]]:
    out = io.StringIO()
    Lister(out, "jsonl", session.describer).write(range(len(session.store)))
    rows = [json.loads(line) for line in out.getvalue().splitlines()]
    return [
        (r["transaction"]["latency_ms"], r["transaction"]["latency_max_ms"])
        for r in rows
        if r["kind"] in ("response", "exception") and "transaction" in r
    ]


def pairs_of_csv(session: Session) -> list[tuple[float | None, float | None]]:
    out = io.StringIO()
    Lister(out, "csv", session.describer).write(range(len(session.store)))
    rows = list(csv.DictReader(io.StringIO(out.getvalue())))

    def number(cell: str) -> float | None:
        return None if cell == "" else float(cell)

    return [
        (number(r["latency_ms"]), number(r["latency_max_ms"]))
        for r in rows
        if r["kind"] in ("response", "exception") and r["status"]
    ]


def words_of_text(session: Session) -> list[str]:
    """The latency each answer's text line shows (`12.3ms`, `<16ms`, `<2s`; '' none)."""
    out = io.StringIO()
    Lister(out, "text", session.describer).write(range(len(session.store)))
    words = []
    for line in out.getvalue().splitlines():
        if line.startswith("#") or "  S>M  " not in line:
            continue
        found = LATENCY.search(line[70:])  # past the time, unit and function columns
        words.append("".join(found.groups()) if found else "")
    return words


def shown(pair: tuple[float | None, float | None]) -> tuple[bool | None, float | None]:
    """(bound?, ms) of a pair: (None, None) for unknown."""
    value, bound = pair
    assert value is None or bound is None, pair  # never both
    if value is not None:
        return False, value
    if bound is not None:
        return True, bound
    return None, None


def ms_of(word: str) -> tuple[bool | None, float | None]:
    if not word:
        return None, None
    bound = word.startswith("<")
    number = float(re.sub(r"[<ms]", "", word))
    return bound, number * 1000 if word.endswith("s") and not word.endswith("ms") else number


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    stamps=st.sampled_from((Stamp.EXACT, Stamp.READ_END, Stamp.FRAME_END, Stamp.PRINT)),
    resolution=st.sampled_from((0.0, 1e-6, 1e-3, 0.016, 1.0)),
)
def test_every_view_agrees_on_value_and_bound(seed: int, stamps: Stamp, resolution: float) -> None:
    session = bus(seed, stamps, resolution)
    store = session.store
    jsonl = pairs_of_jsonl(session)
    assert jsonl == pairs_of_csv(session)
    answers = [
        i
        for i in range(len(store))
        if store.kind[i] in (2, 3) and store.partner[i] >= 0 and store.status[i]
    ]
    tui = [latency_text(session.describer.detail(i)) for i in answers]
    text = words_of_text(session)
    assert len(jsonl) == len(tui) == len(text) == len(answers)
    for pair, in_text, in_tui in zip(jsonl, text, tui, strict=True):
        bound, ms = shown(pair)
        assert ms is None or ms > 0, pair  # never 0.0 or negative
        assert in_text == in_tui, (pair, in_text, in_tui)
        got_bound, got_ms = ms_of(in_text)
        assert got_bound is bound, (pair, in_text)
        if ms is not None and got_ms is not None:
            assert got_ms == pytest.approx(ms, abs=0.051), (pair, in_text)
    if stamps is Stamp.PRINT:  # print times bound a latency, never give it
        assert all(value is None for value, _ in jsonl)
    # nothing finer than the resolution: a value is at least two resolutions long
    u = store.resolution
    assert all(value is None or value >= 2 * u * 1000 - 1e-6 for value, _ in jsonl)


# -- Parquet ----------------------------------------------------------------------------------

pq = pytest.importorskip("pyarrow.parquet")


@pytest.mark.parametrize("what", ["frames", "transactions"])
@pytest.mark.parametrize(
    "source", [DEMO_CAPTURE, LOGS / "monitor_seconds.log", LOGS / "pymodbus_3x.log"]
)
def test_parquet_carries_the_pair_and_no_latency_of_zero_or_less(
    tmp_path: Path, what: str, source: Path
) -> None:
    from sniffer.outputs.parquet import write_parquet

    session = replay_file(source)
    path = tmp_path / f"{what}.parquet"
    write_parquet(path, what, session.describer, range(len(session.store)))
    table = pq.read_table(path).to_pydict()
    values, bounds = table["latency_ms"], table["latency_max_ms"]
    assert all(v is None or v > 0 for v in values)
    assert all(b is None or b > 0 for b in bounds)
    assert all(v is None or b is None for v, b in zip(values, bounds, strict=True))
    # the answers' pairs are the listing's
    if what == "frames":
        got = [
            (v, b)
            for k, v, b in zip(table["kind"], values, bounds, strict=True)
            if k in ("response", "exception") and (v, b) != (None, None)
        ]
        want = [p for p in pairs_of_jsonl(session) if p != (None, None)]
        assert got == want
    else:
        assert any(b is not None for b in bounds) or any(v is not None for v in values)


# -- the Wireshark export, read back ---------------------------------------------------------


def export_of(session: Session, path: Path) -> Path:
    out = io.BytesIO()
    PcapExporter(out, session.describer, session.line).write(range(len(session.store)))
    path.write_bytes(out.getvalue())
    return path


@pytest.mark.parametrize(
    "make",
    [
        lambda: replay_file(DEMO_CAPTURE),
        lambda: replay_file(LOGS / "monitor_seconds.log"),
        lambda: replay_file(LOGS / "pymodbus_3x.log"),
        lambda: bus(7, Stamp.READ_END, 0.0),
        lambda: bus(8, Stamp.EXACT, 0.0),
    ],
    ids=["demo", "second-clock", "pymodbus", "usb-reads", "exact"],
)
def test_the_wireshark_export_read_back_gives_the_same_latencies(tmp_path: Path, make: Any) -> None:
    """Each packet has one time, its frame's end: what a capture knew besides (a frame
    split over two reads starts earlier than its line time says) widens the resolution
    the export declares, and the latencies read back agree with the capture's to it."""
    session = make()
    again, capture = open_session(export_of(session, tmp_path / "x.pcapng"), None)
    again.ingest(capture.chunks())
    before_u, after_u = session.store.resolution, again.store.resolution
    assert after_u >= before_u
    before, after = pairs_of_jsonl(session), pairs_of_jsonl(again)
    assert len(after) == len(before)
    slack = (after_u + shown_step(after_u) + 1e-6) * 1000  # and the rounding shown
    for a, b in zip(before, after, strict=True):
        kind_a, ms_a = shown(a)
        kind_b, ms_b = shown(b)
        if kind_a is None:  # what the capture could not tell, its export cannot measure
            assert kind_b is not False, (a, b)
            continue
        assert kind_b is not None and ms_a is not None and ms_b is not None, (a, b)
        if not kind_a and not kind_b:  # values: the same to the resolution
            assert abs(ms_b - ms_a) <= slack, (a, b)
        elif not kind_a:  # a value, now bounded: the bound holds it
            assert ms_a < ms_b + slack, (a, b)
        elif not kind_b:  # a bound, now a value: it holds the value
            assert ms_b < ms_a + slack, (a, b)
    if after_u == before_u:  # nothing lost: the very same latencies
        assert after == before


@pytest.mark.parametrize("source", [DEMO_CAPTURE, LOGS / "monitor_seconds.log"])
def test_an_export_of_an_export_keeps_its_latencies(tmp_path: Path, source: Path) -> None:
    """Once exported, the frames are one per packet: exporting them again loses nothing."""
    first, capture = open_session(export_of(replay_file(source), tmp_path / "a.pcapng"), None)
    first.ingest(capture.chunks())
    second, capture = open_session(export_of(first, tmp_path / "b.pcapng"), None)
    second.ingest(capture.chunks())
    assert second.store.resolution == first.store.resolution
    assert pairs_of_jsonl(second) == pairs_of_jsonl(first)
