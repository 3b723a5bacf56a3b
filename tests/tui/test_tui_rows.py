"""The TUI's data side without Textual: the filter language, column scans checked against a
row-by-row reference, incremental filtering, row views, rendering and the register watch."""

from __future__ import annotations

import itertools
import random
import threading
import time
from array import array

import pytest
from hypothesis import given
from hypothesis import strategies as st
from rich.style import Style

from dissectors.values import Dissection
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.meaning.describe import FrameDetail, register_span
from sniffer.meaning.query import Query, QueryError, TimePoint, parse_query, parse_time_point
from sniffer.meaning.select import FilterJob, Options
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import Session
from sniffer.sources.synth import polling_frames, stress_stream
from sniffer.tui.feed import FeedProgress, Pacing, feed_capture, feed_live, live_status
from sniffer.tui.model import ViewModel
from sniffer.tui.render import (
    ago_text,
    bytes_per_line,
    columns_for,
    delta_text,
    hex_dump,
    plot,
    plot_columns,
    raw_span,
    row_state,
    row_text,
    span_text,
    sparkline,
    time_width,
)
from sniffer.tui.rows import RowView, StoreReader, last_answers
from sniffer.tui.watch import HISTORY, Sample, Series, Watch
from sniffer.vocab import PROBLEM_MASK, Flag, Kind, Status
from tests.support.tui import (
    DEVICE_STRING,
    HOSTILE,
    HOSTILE_SHOWN,
    hostile_chunks,
    hostile_session,
    synthetic_session,
)

# -- the filter language ---------------------------------------------------------------------


def test_the_example_query_parses() -> None:
    q = parse_query('unit:3 fc:3 status:timeout reg:"Under Voltage" t:10-20 text')
    assert q.units == {3} and q.functions == {3} and q.statuses == {"timeout"}
    assert q.registers == ("under voltage",) and q.words == ("text",)
    assert q.time is not None and q.time.start == TimePoint(10.0) and q.time.end == TimePoint(20.0)
    assert q.needs_detail and q.has_columns and not q.empty


@pytest.mark.parametrize(
    ("text", "check"),
    [
        ("unit:1,2 unit:5-7", lambda q: q.units == {1, 2, 5, 6, 7}),
        ("fc:0x10", lambda q: q.functions == {16}),
        ("-fc:3 -unit:0", lambda q: q.not_functions == {3} and q.not_units == {0}),
        ("kind:req,exc", lambda q: q.kinds == {Kind.REQUEST, Kind.EXCEPTION}),
        ("status:crc,problems", lambda q: q.statuses == {"check", "problem"}),
        ("-status:ok", lambda q: q.not_statuses == {"ok"}),
        ('"two words" Pump', lambda q: q.words == ("two words", "pump")),
        ("04.9A: x", lambda q: q.words == ("04.9a:", "x")),
        ("Pump: on", lambda q: q.words == ("pump:", "on")),
        ("t:10-", lambda q: q.time is not None and q.time.end is None),
        ("t:-2m", lambda q: q.time is not None and q.time.end == TimePoint(120.0)),
        ("t:500ms-1.5s", lambda q: q.time is not None and q.time.start == TimePoint(0.5)),
        ("t:14:00-14:05:30.5", lambda q: q.time is not None and q.time.end.clock),
        ("", lambda q: q.empty),
    ],
)
def test_query_terms(text: str, check: object) -> None:
    assert callable(check) and check(parse_query(text))


@pytest.mark.parametrize(
    ("text", "hint"),
    [
        ("foo:1", "unknown key"),
        ("unit:x", "not a number"),
        ("unit:300", "values go from 0 to 255"),
        ("fc:0", "values go from 1 to 127"),
        ("status:fine", "is not known"),
        ("kind:frame", "is not known"),
        ("t:soon", "not a time"),
        ("-reg:x", "can be negated"),
        ("-word", "can be negated"),
        ("reg:", 'needs a value, e.g. reg:"Under Voltage"'),
        ("unit: 3", "needs a value"),
        ("- fc:3", "right after it"),
        ("t:1:2:3:4", "clock time"),
    ],
)
def test_bad_queries_say_what_to_write(text: str, hint: str) -> None:
    with pytest.raises(QueryError, match=None) as info:
        parse_query(text)
    assert hint in str(info.value)


def test_time_points() -> None:
    assert parse_time_point("2m") == TimePoint(120.0)
    assert parse_time_point("250ms") == TimePoint(0.25)
    assert parse_time_point("1h") == TimePoint(3600.0)
    assert parse_time_point("14:03:07.5") == TimePoint(14 * 3600 + 3 * 60 + 7.5, clock=True)


# -- column scans against a row-by-row reference -----------------------------------------------


def _stress_session() -> Session:
    line = LineSettings(baud=115200, parity="N", stopbits=1, mode="rtu")
    stress = stress_stream(polling_frames(3000, seed=7, line=line), seed=3, flip_rate=0.03)
    session = Session(line, source="stress")
    session.ingest(stress.chunks)
    return session


def _reference(s: FrameStore, i: int, q: Query, o: Options) -> bool:
    """Whether row i passes, decided one row at a time from its plain columns."""
    kind, unit, fc, flags, status = s.kind[i], s.unit[i], s.fc[i] & 0x7F, s.flags[i], s.status[i]
    frame = kind not in (Kind.NOISE, Kind.EVENT)

    def named(names: frozenset[str]) -> bool:
        hits = {
            "ok": status == Status.OK,
            "exception": status == Status.EXCEPTION,
            "timeout": status == Status.TIMEOUT,
            "orphan": status == Status.ORPHAN,
            "broadcast": status == Status.BROADCAST,
            "open": status == Status.OPEN,
            "check": bool(flags & (Flag.CHECK_BAD | Flag.NON_HEX)),
            "noise": kind == Kind.NOISE,
            "event": kind == Kind.EVENT,
            "problem": _problem(s, i),
        }
        return any(hits[n] for n in names)

    if q.units and not (frame and unit in q.units):
        return False
    if q.not_units and frame and unit in q.not_units:
        return False
    if q.functions and not (frame and fc in q.functions):
        return False
    if q.not_functions and frame and fc in q.not_functions:
        return False
    if q.kinds and kind not in q.kinds:
        return False
    if q.not_kinds and kind in q.not_kinds:
        return False
    if q.statuses and not named(q.statuses):
        return False
    if q.not_statuses and named(q.not_statuses):
        return False
    answer = kind in (Kind.RESPONSE, Kind.EXCEPTION) and s.partner[i] != NO_PARTNER
    if o.problems_only:
        bad = _problem(s, i)
        if o.transactions and kind == Kind.REQUEST and s.partner[i] != NO_PARTNER:
            bad = bad or _problem(s, s.partner[i])
        if not bad:
            return False
    return not (o.transactions and answer)


def _problem(s: FrameStore, i: int) -> bool:
    return bool(
        s.kind[i] in (Kind.NOISE, Kind.EVENT)
        or s.status[i] in (Status.EXCEPTION, Status.TIMEOUT, Status.ORPHAN)
        or s.flags[i] & PROBLEM_MASK
    )


QUERIES = [
    "",
    "unit:3",
    "unit:0,1,2",
    "-unit:3",
    "fc:3",
    "fc:3,16 -unit:5",
    "-fc:3",
    "kind:response",
    "kind:noise,exception",
    "-kind:request",
    "status:timeout",
    "status:exception",
    "status:check",
    "status:noise",
    "status:problem",
    "status:ok,orphan",
    "-status:ok",
    "status:check unit:1-7",
]


@pytest.fixture(scope="module")
def stress() -> Session:
    return _stress_session()


def test_the_stress_capture_has_every_kind_of_trouble(stress: Session) -> None:
    s = stress.store
    kinds = set(s.kind)
    assert {Kind.NOISE, Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION} <= kinds
    assert any(f & Flag.CHECK_BAD for f in s.flags)
    assert any(st == Status.TIMEOUT for st in s.status)


@pytest.mark.parametrize("text", QUERIES)
@pytest.mark.parametrize(
    ("transactions", "problems"), [(False, False), (True, False), (False, True), (True, True)]
)
def test_column_scan_matches_the_reference(
    stress: Session, text: str, transactions: bool, problems: bool
) -> None:
    q = parse_query(text)
    o = Options(transactions=transactions, problems_only=problems)
    store = StoreReader(stress.store)
    n = len(store)
    job = FilterJob(store, q, o, stress.annotator, store.t[0])
    while job.advance(n, final=True):
        pass
    want = [i for i in range(n) if _reference(stress.store, i, q, o)]
    assert list(job.rows) == want


def test_a_scan_in_small_steps_gives_the_same_rows(
    stress: Session, monkeypatch: pytest.MonkeyPatch
) -> None:
    import sniffer.meaning.select as select_module  # where the matcher reads its step

    q = parse_query("-fc:3 status:ok,exception,timeout")
    o = Options(transactions=True)
    store = StoreReader(stress.store)
    n = len(store)
    whole = FilterJob(store, q, o, stress.annotator, store.t[0])
    whole.advance(n, budget=60, final=True)
    monkeypatch.setattr(select_module, "BLOCK", 97)
    growing = FilterJob(store, q, o, stress.annotator, store.t[0])
    for upto in range(0, n + 1, 250):  # rows arrive as a live capture delivers them
        while growing.advance(upto, budget=0.001):
            pass
    while growing.advance(n, budget=0.001, final=True):
        pass
    assert list(growing.rows) == list(whole.rows)
    assert growing.caught_up and growing.progress == 1.0


def test_time_terms_use_the_store_clock() -> None:
    session = synthetic_session(3000)
    store = StoreReader(session.store)
    n = len(store)
    origin = store.t[0]
    job = FilterJob(store, parse_query("t:0.5-1"), Options(), session.annotator, origin)
    job.advance(n, budget=60)
    assert job.rows
    assert all(origin + 0.5 <= store.t[i] < origin + 1 for i in job.rows)
    inside = [i for i in range(n) if origin + 0.5 <= store.t[i] < origin + 1]
    assert list(job.rows) == inside


def test_register_and_text_terms_dissect_only_candidates() -> None:
    session = hostile_session()
    store = StoreReader(session.store)
    n = len(store)

    def rows(text: str, **options: bool) -> list[int]:
        o = Options(bound=session.annotator.bindings, **options)
        job = FilterJob(store, parse_query(text), o, session.annotator, store.t[0])
        job.advance(n, budget=60)
        return list(job.rows)

    assert rows('reg:"under voltage"') == [3, 4, 5, 16]
    assert rows('reg:"under voltage"', transactions=True) == [2, 4, 15]
    assert rows("reg:voltage unit:5") == []
    assert rows("VendorName") == [11, 12]
    assert rows("acme") == [12]
    assert rows('"illegal data address" unit:3') == [7]
    assert rows("timeout quiet") == [10]  # words in the problems count too
    assert rows("[@click=app.quit] unit:5") == [12]  # markup is just text to search
    assert rows("[@click=app.quit]") == [0, 1, 2, 3, 4, 5, 6, 7, 10, 12, 15, 16]  # labels too


def test_row_view_maps_positions_rows_and_times() -> None:
    session = synthetic_session(500)
    store = StoreReader(session.store)
    every = RowView(None, len(store))
    assert every.row(10) == 10 and every.position(10) == 10 and every.contains(499)
    assert not every.contains(len(store))
    some = RowView(array("Q", [3, 7, 11, 40]), 4)
    assert some.row(2) == 11
    assert some.position(7) == 1 and some.position(8) == 2 and some.position(999) == 3
    assert some.contains(40) and not some.contains(8)
    assert some.at_time(store, store.t[8]) == 2
    assert every.at_time(store, store.t[123]) == 123
    assert RowView(None, 0).position(5) == 0


def test_the_reader_never_grows_the_store() -> None:
    session = synthetic_session(200)
    store = session.store
    reader = StoreReader(store)
    reader.view(5)
    store.t.append(99.0)  # a row the ingest thread is in the middle of appending
    before = len(store.status)
    reader.view(5)
    reader.sync()
    assert len(store.status) == before
    store.t.pop()


def test_last_answers_per_unit() -> None:
    session = hostile_session()
    found = last_answers(session.store, 0, len(session.store))
    assert found == {3: 16, 5: 14}
    assert last_answers(session.store, 0, 0) == {}


# -- view model ----------------------------------------------------------------------------------


def test_view_model_lines_use_the_published_rows() -> None:
    session = hostile_session()
    model = ViewModel(session)
    model.publish(len(session.store))
    model.shown = model.published
    model.update_view()
    cols = columns_for(300, absolute=False)
    first = model.line(0, cols, {}).plain
    assert first.startswith("    0.000000") and "u3" in first and "Read Input Registers" in first
    assert "+20.0ms" in model.line(1, cols, {}).plain
    model.transactions = True
    model.new_job()
    assert model.job is not None
    model.job.advance(model.shown, budget=60)
    model.update_view()
    rows = [model.view.row(k) for k in range(len(model.view))]
    assert 1 not in rows and 0 in rows
    line = model.line(0, cols, {}).plain
    assert "M<>S" in line and "Voltage = 415 V" in line
    model.absolute = True
    assert model.line(0, cols, {}).plain.lstrip()[2] == ":"
    assert model.partner(0) == 1 and model.partner(8) is None
    assert model.answer(0) is not None and model.answer(1) is None


# -- rendering -----------------------------------------------------------------------------------


def test_hostile_strings_stay_plain_text() -> None:
    session = hostile_session()
    d = session.describer.detail(12)
    line = row_text(
        d,
        answer=None,
        when="1.3",
        delta="",
        cols=columns_for(400, False),
        styles={},
    )
    assert "[/][@click=app.quit][bold red]Acme\\x1b]0;owned\\x07" in line.plain
    assert "\x1b" not in line.plain and "\x07" not in line.plain
    assert not line.spans or all(isinstance(s.style, Style | str) for s in line.spans)
    label_line = row_text(
        session.describer.detail(0),
        answer=None,
        when="0",
        delta="",
        cols=columns_for(400, False),
        styles={},
    )
    assert HOSTILE_SHOWN[:13] + "…" in label_line.plain  # the label column is 14 wide
    assert "\x1b" not in label_line.plain
    assert DEVICE_STRING and HOSTILE


def test_row_states_pick_the_colour() -> None:
    session = hostile_session()
    store = session.store
    states = [row_state(store.view(i)) for i in range(len(store))]
    assert states[7] == "exception" and states[8] == "timeout"
    assert states[9] == "noise" and states[10] == "check" and states[0] == ""
    assert states[6] == "exception"  # the request of an exception transaction


def test_hex_dump_highlights_a_span() -> None:
    styles = {"highlight": Style(bold=True)}
    text = hex_dump(bytes(range(20)), (2, 4), 8, styles)
    lines = text.plain.split("\n")
    assert lines[0].startswith("0000  00 01 02 03 04 05 06 07")
    assert lines[2].startswith("0010  10 11 12 13")
    bold = [text.plain[s.start : s.end] for s in text.spans if s.style == styles["highlight"]]
    assert bold == ["02", "03", "·", "·"]  # the hex and the characters
    assert hex_dump(b"", None, 8, {}).plain == "(no bytes)"


def test_ascii_spans_map_to_two_characters_per_byte() -> None:
    assert raw_span((0, 1), ascii_mode=False) == (0, 1)
    assert raw_span((0, 1), ascii_mode=True) == (1, 3)  # ':' then "03"
    assert raw_span((2, 4), ascii_mode=True) == (5, 9)
    assert bytes_per_line(39) == 8 and bytes_per_line(38) == 4 and bytes_per_line(71) == 16
    assert bytes_per_line(10) == 4 and bytes_per_line(500) == 32


def test_register_spans_point_at_their_words() -> None:
    session = hostile_session()
    d = session.describer.detail(3)
    assert isinstance(d.dissection, Dissection)
    spans = {r.name: register_span(d.dissection, r) for r in d.registers}
    assert spans["Overload Trip"] == (3, 5)
    assert spans["Under Voltage Trip"] == (7, 9)
    write = session.describer.detail(4)
    assert register_span(write.dissection, write.registers[0]) == (4, 6)
    assert register_span(None, write.registers[0]) is None


def test_small_texts() -> None:
    assert delta_text(0.0123) == "+12.3ms" and delta_text(2.5) == "+2.500s"
    assert delta_text(125) == "+2m05.0s" and delta_text(7300) == "+2h01m"
    assert delta_text(None) == "" and delta_text(-0.5) == "-500.0ms"
    assert ago_text(0.25) == "250ms" and ago_text(3) == "3.0s" and ago_text(3700) == "1h01m"
    assert (
        sparkline([1, 2, 3, 4], 4) == "▁▃▆█"
        and sparkline([5, 5], 8) == "▄▄"
        and sparkline([], 3) == ""
    )
    drawn = plot([(0.0, 1.0), (1.0, 2.0), (2.0, 3.0)], 40, 6, {}).plain.splitlines()
    assert drawn[0].startswith(" 3│") and drawn[4].startswith(" 1│")
    assert drawn[5].startswith("  └0s") and drawn[5].endswith("+2.0s")
    assert drawn[0].endswith("━") and drawn[4][3] == "━" and drawn[0][3] == " "
    assert plot([], 40, 6, {}).plain == "(no values)"


def test_row_text_fits_the_width() -> None:
    session = synthetic_session(300)
    for width in (80, 100, 120, 200):
        cols = columns_for(width, absolute=False)
        for i in range(50):
            d: FrameDetail = session.describer.detail(i)
            assert (
                row_text(d, answer=None, when="1", delta="", cols=cols, styles={}).cell_len <= width
            )


# -- register watch --------------------------------------------------------------------------------


def test_the_watch_follows_named_registers() -> None:
    session = hostile_session()
    watch = Watch(StoreReader(session.store), session.annotator)
    while watch.advance(len(session.store)):
        pass
    names = {s.name for s in watch.snapshot()}
    assert {"Under Voltage Trip", "Overload Trip", "Current", "Voltage"} <= names
    uv = next(s for s in watch.snapshot() if s.name == "Under Voltage Trip")
    assert [x.text for x in uv.samples] == ["300 V", "320 V", "320 V"]
    assert [x.row for x in uv.samples] == [3, 4, 16]  # the echo (row 5) is not counted twice
    assert uv.changed == session.store.t[4] and uv.unit_text == "V"
    trip = next(s for s in watch.snapshot() if s.name == "Overload Trip")
    assert trip.changed is None and trip.seen == 2


def test_watch_history_stays_bounded() -> None:
    s = Series((1, "holding_registers", 0, "x"), "x", "", "")
    for k in range(HISTORY * 3):
        s.add(Sample(float(k), float(k % 7), str(k % 7), k))
    assert len(s.samples) <= HISTORY and s.seen == HISTORY * 3
    assert s.samples[-1].row == HISTORY * 3 - 1 or s.stride > 1
    assert s.samples[0].row == 0


def test_an_unbound_session_has_nothing_to_watch() -> None:
    session = synthetic_session(100)
    watch = Watch(StoreReader(session.store), session.annotator)
    assert not watch.advance(len(session.store)) and watch.snapshot() == []


# -- feeding ---------------------------------------------------------------------------------------


def test_feed_capture_publishes_batches_then_done() -> None:
    line = LineSettings(baud=19200, parity="E", stopbits=1, mode="rtu")
    fresh = Session(line, exact_timing=True)
    seen: list[FeedProgress] = []
    feed_capture(fresh, hostile_chunks(), Pacing(), seen.append, every=0.0, warnings=["cut short"])
    assert seen[-1].done and seen[-1].rows == len(fresh.store) == 17
    assert all(a.rows <= b.rows for a, b in itertools.pairwise(seen))
    assert fresh.warnings == ["cut short"]


def test_feed_capture_reports_a_reader_failure() -> None:
    def broken() -> list[Chunk]:
        raise RuntimeError("bad record at offset 12")

    def chunks() -> object:
        yield from hostile_chunks()[:4]
        broken()

    fresh = Session(LineSettings(mode="rtu"))
    seen: list[FeedProgress] = []
    feed_capture(fresh, chunks(), Pacing(), seen.append, every=0.0)  # type: ignore[arg-type]
    assert seen[-1].done and "bad record at offset 12" in seen[-1].error


def test_pacing_follows_the_capture_clock_and_pauses() -> None:
    chunks = [Chunk(b"x", t_end=k * 0.05) for k in range(5)]
    pacing = Pacing(speed=1.0)
    start = time.monotonic()
    assert len(list(pacing.pace(chunks))) == 5
    assert time.monotonic() - start >= 0.18
    fast = Pacing()
    start = time.monotonic()
    list(fast.pace([Chunk(b"x", t_end=k * 10.0) for k in range(5)]))
    assert time.monotonic() - start < 0.5
    held = Pacing()
    held.paused = True
    got: list[Chunk] = []
    thread = threading.Thread(target=lambda: got.extend(held.pace(chunks)))
    thread.start()
    time.sleep(0.15)
    assert got == []
    held.paused = False
    thread.join(2)
    assert len(got) == 5
    stopped = Pacing(speed=1.0)
    stopped.stop.set()
    assert list(stopped.pace(chunks)) == []


class _FakeLive:
    """Pumps a prepared list of chunks into a session, a few per call, like LiveCapture."""

    def __init__(self, session: Session, chunks: list[Chunk]) -> None:
        self.session = session
        self.chunks = list(chunks)
        self.messages = __import__("collections").deque(["port lost: /dev/ttyX"])
        self.pumps = 0

    def pump(self, timeout: float = 0.05) -> range:
        self.pumps += 1
        start = len(self.session.store)
        for chunk in self.chunks[:3]:
            self.session.feed(chunk)
        del self.chunks[:3]
        if not self.chunks:
            time.sleep(timeout)
            self.session.idle(time.time() + 2e9)  # the line went quiet
        self.session.refresh()
        return range(start, len(self.session.store))


def test_feed_live_pumps_until_stopped() -> None:
    session = Session(LineSettings(baud=19200, parity="E", mode="rtu"), exact_timing=True)
    live = _FakeLive(session, hostile_chunks())
    pacing = Pacing()
    seen: list[FeedProgress] = []
    notes: list[str] = []
    thread = threading.Thread(
        target=feed_live,
        args=(session, live, pacing, seen.append),
        kwargs={"every": 0.0, "report": notes.append},
    )
    thread.start()
    deadline = time.monotonic() + 5
    while (not seen or seen[-1].rows < 16) and time.monotonic() < deadline:
        time.sleep(0.01)
    pacing.stop.set()
    thread.join(2)
    assert not thread.is_alive()
    assert seen and seen[-1].rows >= 16 and not seen[-1].done
    assert notes == ["port lost: /dev/ttyX"]
    status = live_status(live)
    assert status.recording == "" and status.lost_bytes == 0


def test_an_open_request_at_the_end_waits_until_the_capture_is_indexed() -> None:
    session = hostile_session()
    from dissectors.checks import with_crc

    last = session.store.t_end[len(session.store) - 1]
    raw = with_crc(bytes([3, 3, 0, 0x0B, 0, 3]))
    session.feed(Chunk(raw, t_start=last + 0.01, t_end=last + 0.015))
    session.finish()
    n = len(session.store)
    assert session.store.status[n - 1] == Status.OPEN
    store = StoreReader(session.store)
    job = FilterJob(store, parse_query("unit:3"), Options(), session.annotator, store.t[0])
    assert not job.advance(n)  # nothing to do until more rows come...
    assert n - 1 not in job.rows and not job.caught_up
    assert not job.advance(n, final=True)  # ... or the capture is known to be complete
    assert job.rows[-1] == n - 1 and job.caught_up


@pytest.mark.parametrize(
    ("seconds", "shown"),
    [
        (0.0, "0.000000"),
        (3599.9999994, "3599.999999"),
        (3600.0, "1:00:00.000000"),
        (38499.538707, "10:41:39.538707"),
        (3661.000001, "1:01:01.000001"),
    ],
)
def test_times_past_an_hour_read_as_hours_minutes_seconds(seconds: float, shown: str) -> None:
    assert span_text(seconds) == shown


@given(st.floats(0, 400_000, allow_nan=False))
def test_the_time_column_holds_every_time_of_the_capture(span: float) -> None:
    width = time_width(span, absolute=False)
    for t in (0.0, span / 3, span):
        assert len("●" + span_text(t)) <= width


def test_a_plot_keeps_a_spike_between_columns_and_marks_the_mean() -> None:
    points = [(t / 100, 10.0) for t in range(1000)]
    points[503] = (5.03, 90.0)  # one sample high, far narrower than a column
    columns = plot_columns(points, 40)
    assert max(c[1] for c in columns if c is not None) == 90.0
    spiked = next(c for c in columns if c is not None and c[1] == 90.0)
    assert spiked[0] == 10.0 and 10.0 < spiked[2] < 90.0  # min, max and mean of the column
    drawn = plot(points, 60, 10, {}).plain.splitlines()
    assert "│" in drawn[0] or "━" in drawn[0]  # the spike reaches the top line


@given(st.integers(0, 2**32), st.integers(HISTORY + 1, 4 * HISTORY))
def test_thinning_the_history_keeps_the_extremes(seed: int, n: int) -> None:
    rng = random.Random(seed)
    values = [round(rng.gauss(100, 5), 1) for _ in range(n)]
    s = Series((3, "holding", 0, "x"), "x", "", "")
    for k, v in enumerate(values):
        s.add(Sample(float(k), v, f"{v}", k))
    kept = [x.value for x in s.samples if x.value is not None]
    assert max(kept) == max(values) and min(kept) == min(values)
    assert len(s.samples) <= HISTORY
