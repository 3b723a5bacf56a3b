"""The ladder (`l`): master and slaves as columns, transactions as arrows down the time
axis, latencies as `pairing.measure` vouches for them, gaps to scale only when the stamps
are exact, timeouts and retries visible; only the lines on screen are built."""

from __future__ import annotations

import time
from array import array

import pytest

from dissectors.checks import with_crc
from sniffer.meaning.describe import Describer
from sniffer.model import Chunk, Stamp
from sniffer.session.session import Session
from sniffer.tui.app import ModscopeApp
from sniffer.tui.ladder import Ladder, Lanes, lanes_for, latency_label
from sniffer.tui.rows import RowView
from sniffer.tui.screens.ladder import LadderScreen
from tests.support.tui import (
    LINE,
    FakeLive,
    hostile_chunks,
    ready,
    screen_text,
    synthetic_session,
    wait_rows,
)

T0 = 1_700_000_000.0


def exact_session() -> Session:
    """The hostile fixture (an exception, a timeout, noise, a bad CRC) with exact stamps."""
    session = Session(LINE, exact_timing=True, source="x.sr", stamps=Stamp.EXACT)
    session.ingest(hostile_chunks())
    return session


def draw(
    session: Session,
    k: int = 0,
    height: int = 60,
    scale: float | None = 0.02,
    view: RowView | None = None,
) -> tuple[list[tuple[int | None, str]], Lanes]:
    store = session.store
    lanes = lanes_for(100, 12, [3, 5])
    describer = Describer(store, session.annotator)
    ladder = Ladder(
        store,
        view or RowView(None, len(store)),
        origin=store.t[0],
        absolute=False,
        scale=scale,
        summary=lambda row: describer.detail(row).summary,
    )
    return [(line.row, line.text.plain) for line in ladder.lines(k, height, lanes, {})], lanes


def test_a_transaction_is_an_arrow_out_and_an_arrow_back_with_its_latency() -> None:
    lines, lanes = draw(exact_session())
    out = next(t for r, t in lines if r == 0)
    back = next(t for r, t in lines if r == 1)
    # the request runs from the master's column to unit 3's, the answer back
    assert out[lanes.master + 1] == "─" and out[lanes.slaves[3] - 1] == "▶"
    assert back[lanes.master + 1] == "◀"
    # latency: the answer starts 20 ms after the request started; the 8-byte request took
    # 8 character times at 19200 8E1 (11 bits each)
    expected = (0.020 - 8 * 11 / 19200) * 1000
    assert f"{expected:.1f}ms" in back
    assert "u3 fc4" in out


def test_gaps_are_drawn_to_scale_when_the_stamps_are_exact() -> None:
    session = exact_session()
    store = session.store
    lines, _ = draw(session, scale=0.02)
    rows = [r for r, _ in lines]
    # between the answer (row 1) and the next request (row 2): one line per 20 ms
    gap = store.t[2] - store.t_end[1]
    blank = rows.index(2) - rows.index(1) - 1
    assert blank == round(gap / 0.02) - 1
    # at twice the scale, about half the lines
    lines2, _ = draw(session, scale=0.04)
    rows2 = [r for r, _ in lines2]
    assert rows2.index(2) - rows2.index(1) - 1 == round(gap / 0.04) - 1
    # the timeout's 0.6 s wait is too long to draw: one line says so
    after = rows.index(8) + 1
    assert rows[after] is None and "not to scale" in lines[after][1]
    assert rows[after + 1] == 9


def test_without_exact_stamps_one_line_a_frame_and_the_gap_in_the_time_column() -> None:
    session = Session(LINE, exact_timing=True, source="x.pcapng")
    session.ingest(hostile_chunks())
    lines, _ = draw(session, scale=None)
    assert [r for r, _ in lines] == list(range(17))
    assert lines[1][1].strip().startswith("+")


def test_timeouts_exceptions_noise_and_bad_checks_are_marked() -> None:
    lines, lanes = draw(exact_session())
    text = {r: t for r, t in lines if r is not None}
    assert "╳" in text[8] and "timeout" in text[8]  # unit 5 never answered
    assert text[8][lanes.slaves[5] - 1] == "╳"
    assert "exception 02" in text[7]
    assert "≈" in text[9] and "noise, 3 bytes" in text[9]
    assert "BAD CHECK" in text[10]


def test_a_retry_is_dashed() -> None:
    char = LINE.char_time
    request = with_crc(bytes([3, 3, 0, 0, 0, 1]))
    answer = with_crc(bytes([3, 3, 2, 0, 7]))
    frames = [(0.0, request), (1.0, request), (1.02, answer)]
    session = Session(LINE, exact_timing=True, source="x.sr", stamps=Stamp.EXACT)
    session.ingest(
        [Chunk(raw, t_start=T0 + t, t_end=T0 + t + len(raw) * char) for t, raw in frames]
    )
    lines, lanes = draw(session)
    text = {r: t for r, t in lines if r is not None}
    assert "retry" in text[1] and "╌" in text[1][lanes.master : lanes.slaves[3]]
    assert "timeout" in text[0]


@pytest.mark.parametrize(
    ("stamps", "resolution", "label"),
    [(Stamp.READ_END, 0.016, "<16ms"), (Stamp.FRAME_END, 0.0, "?")],
)
def test_latency_says_what_the_timing_vouches_for(
    stamps: Stamp, resolution: float, label: str
) -> None:
    """A request and its answer that arrived in one read: their times coincide, so the
    latency is below the read's resolution, or unknown when no resolution is known."""
    session = Session(LINE, source="x", stamps=stamps, resolution=resolution)
    request = with_crc(bytes([3, 3, 0, 0, 0, 1]))
    answer = with_crc(bytes([3, 3, 2, 0, 7]))
    session.ingest([Chunk(request + answer, t_end=T0 + 1.0)])
    store = session.store
    assert store.kind[1] == 2 and store.partner[1] == 0
    assert latency_label(store, 1) == label
    lines, _ = draw(session, scale=None)
    assert label in lines[1][1]


def test_only_the_lines_on_screen_are_built() -> None:
    session = synthetic_session(3000)
    store = session.store
    view = RowView(None, len(store))
    lines, _ = draw(session, k=2500, height=20, scale=None, view=view)
    rows = [r for r, _ in lines if r is not None]
    assert len(lines) == 20 and rows[0] == 2500 and max(rows) < 2500 + 20


def test_transactions_show_the_hidden_answers() -> None:
    session = exact_session()
    store = session.store
    requests = array("Q", [i for i in range(len(store)) if store.kind[i] == 1])
    lines, _ = draw(session, view=RowView(requests, len(requests)), scale=None)
    rows = [r for r, _ in lines]
    assert rows[:4] == [0, 1, 2, 3]  # each request, then its answer


@pytest.mark.asyncio
async def test_l_opens_the_ladder_and_enter_goes_back_to_the_row() -> None:
    app = ModscopeApp(exact_session())
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        await pilot.press("j", "j", "l")
        assert isinstance(app.screen, LadderScreen)
        text = screen_text(app)
        assert "a line = " in text and "REPLAY" in text
        await pilot.press("j", "j", "j")
        await pilot.press("enter")
        assert not isinstance(app.screen, LadderScreen)
        assert app.frames.cursor_row == 5
        await pilot.press("l", "escape")
        assert not isinstance(app.screen, LadderScreen) and app.frames.cursor_row == 5


@pytest.mark.asyncio
async def test_the_ladder_follows_a_live_line() -> None:
    session = Session(LINE, exact_timing=True, source="/dev/ttyUSB0")
    live = FakeLive(session)
    app = ModscopeApp(session, live=live)
    chunks = hostile_chunks()
    async with app.run_test(size=(80, 24)) as pilot:
        live.waiting.extend(chunks[:4])
        await wait_rows(pilot, app, 4)
        await pilot.press("l")
        assert isinstance(app.screen, LadderScreen)
        live.waiting.extend(chunks[4:9])
        await wait_rows(pilot, app, 9)
        deadline = time.monotonic() + 5
        while app.screen.view.cursor_row != 8:
            assert time.monotonic() < deadline
            await pilot.pause(0.05)
        assert "LIVE" in screen_text(app) and "timeout" in screen_text(app)
