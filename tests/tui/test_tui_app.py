"""Pilot tests of the TUI: every key and panel, driven as a person would, asserting state."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from textual.pilot import Pilot
from textual.widgets import ContentSwitcher, Input, Static

from sniffer.live.port import PortSpec
from sniffer.live.recorder import Recorder
from sniffer.model import Chunk, SourceInfo
from sniffer.session.session import Session, open_session
from sniffer.sources import Capture
from sniffer.tui.app import ModscopeApp
from sniffer.tui.screens.dialogs import HelpScreen
from sniffer.tui.screens.register import RegisterScreen
from sniffer.tui.widgets.detail import DetailPane, FieldTree, HexView
from sniffer.tui.widgets.frame_list import FrameList
from sniffer.tui.widgets.units import UnitsPanel
from sniffer.tui.widgets.watch import WatchPanel
from tests.support.netbus import network_bus
from tests.support.tui import (
    HOSTILE_SHOWN,
    LINE,
    FakeLive,
    burst,
    hostile_chunks,
    hostile_session,
    ready,
    screen_text,
    settle,
    synthetic_session,
    wait_rows,
)

SIZE = (120, 36)
pytestmark = pytest.mark.asyncio


async def wait_said(pilot: Pilot[int], app: ModscopeApp, text: str, timeout: float = 10.0) -> None:
    """Wait until the app has told the user something containing `text`."""
    deadline = time.monotonic() + timeout
    while not any(text in said for said in app.said):
        assert time.monotonic() < deadline, f"{text!r} never said; said {list(app.said)}"
        await pilot.pause(0.05)


def capture_of(chunks: list[Chunk], path: str = "test.pcapng") -> Capture:
    return Capture(info=SourceInfo(path=path, format="test"), _chunks=iter(chunks))


def lines(app: ModscopeApp) -> list[str]:
    """The frame list's lines without their row number column (`numbers` gives those)."""
    frames = app.frames
    cut = frames.columns().number + 1 if frames.columns().number else 0
    return [frames.render_line(y).text[cut:] for y in range(frames.page_height)]


def numbers(app: ModscopeApp) -> list[str]:
    """The row numbers the frame list shows, top to bottom."""
    frames = app.frames
    cut = frames.columns().number
    return [frames.render_line(y).text[:cut].strip() for y in range(frames.page_height)]


# -- opening and moving ---------------------------------------------------------------------


async def test_a_capture_opens_at_the_first_row_and_indexes_in_the_background() -> None:
    session = Session(LINE, exact_timing=True, source="hostile.pcapng")
    app = ModscopeApp(session, capture_of(hostile_chunks()))
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        assert app.model.published == app.frames.count == 17
        assert app.frames.cursor_row == 0 and not app.frames.following
        assert "hostile.pcapng" in screen_text(app)
        assert "17 fr " in screen_text(app)


async def test_cursor_keys_move_and_end_follows() -> None:
    app = ModscopeApp(synthetic_session(500))
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        frames = app.frames
        await pilot.press("down", "down", "j")
        assert frames.cursor == 3
        await pilot.press("k")
        assert frames.cursor == 2
        await pilot.press("pagedown")
        assert frames.cursor == 2 + frames.page_height
        assert frames.scroll_offset.y > 0
        await pilot.press("end")
        assert frames.cursor == 499 and frames.following
        assert "REPLAY ▼" in screen_text(app)
        await pilot.press("up")
        assert frames.cursor == 498 and not frames.following
        await pilot.press("f")
        assert frames.cursor == 499 and frames.following
        await pilot.press("home")
        assert frames.cursor == 0 and frames.scroll_offset.y == 0 and not frames.following
        await pilot.press("pageup")
        assert frames.cursor == 0


async def test_a_click_selects_the_row() -> None:
    app = ModscopeApp(synthetic_session(200))
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.click("#frames", offset=(10, 4))
        await pilot.pause()
        assert app.frames.cursor == 4
        assert app.main.query_one("#detail", DetailPane).detail is not None
        assert app.main.query_one("#detail", DetailPane).detail.view.index == 4  # type: ignore[union-attr]


# -- details -------------------------------------------------------------------------------


async def test_the_detail_pane_shows_fields_registers_and_highlights_bytes() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("down", "down", "down")  # row 3: the holding registers answer
        await pilot.pause()
        pane = app.main.query_one("#detail", DetailPane)
        assert pane.detail is not None and pane.detail.view.index == 3
        title = app.main.query_one("#detail-title", Static).content
        assert "#3" in str(title) and "answer" not in str(title).split("(")[0]
        tree = app.main.query_one("#fields", FieldTree)
        labels = [str(n.label) for n in tree.root.children]
        assert labels[0].startswith("byte_count") and "registers (3)" in labels
        hexview = app.main.query_one("#hex", HexView)
        assert hexview.highlight == (2, 3)  # the first field, byte_count
        await pilot.press("enter")  # into the field tree
        assert tree.has_focus
        await pilot.press("down")
        assert hexview.highlight == (3, 9)  # the values
        # values[0], [1], [2], the registers section, Overload Trip
        await pilot.press("down", "down", "down", "down", "down")
        await pilot.pause()
        node = tree.cursor_node
        assert node is not None and "Overload Trip = 115 %" in str(node.label)
        assert hexview.highlight == (3, 5)
        assert "03 03 06 00 73" in hexview.render().plain
        await pilot.press("escape")
        assert app.frames.has_focus


async def test_a_cursor_message_for_a_row_not_published_shows_no_detail() -> None:
    # a restart (a damaged sidecar, `R`) empties the rows while a cursor message sent
    # for the old ones may still be on its way: it must not reach into the new store
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("down")
        await pilot.pause()
        pane = app.main.query_one("#detail", DetailPane)
        assert pane.detail is not None
        app.frames.post_message(FrameList.CursorMoved(app.model.published + 5))
        await pilot.pause()
        assert pane.detail is None
        await pilot.press("down")  # and the next move shows its row again
        await pilot.pause()
        assert pane.detail is not None and pane.detail.view.index == 2


async def test_p_jumps_to_the_paired_frame_and_shows_hidden_answers() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("p")
        assert app.frames.cursor_row == 1
        await pilot.press("p")
        assert app.frames.cursor_row == 0
        await pilot.press("t")
        await settle(pilot, app)
        await pilot.press("p")  # the answer is folded into the transaction row
        await pilot.pause()
        pane = app.main.query_one("#detail", DetailPane)
        assert pane.detail is not None and pane.detail.view.index == 1
        assert pane.partner_detail is not None and pane.partner_detail.view.index == 0
        await pilot.press("down", "down", "down", "down", "p")  # row 8: a timeout
        await pilot.pause()
        assert app.frames.cursor_row == 8
        await wait_said(pilot, app, "no paired request or answer")


# -- views and filters ------------------------------------------------------------------------


async def test_t_shows_one_row_per_transaction() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("down", "down", "down")
        await pilot.press("t")
        await settle(pilot, app)
        rows = [app.model.view.row(k) for k in range(app.frames.count)]
        assert rows == [0, 2, 4, 6, 8, 9, 10, 11, 13, 15]
        assert app.frames.cursor_row == 4  # the nearest row to where the cursor was
        assert "M<>S" in lines(app)[0] and "Logic Status = bit 0" in lines(app)[0]
        assert app.main.query_one("#filter-bar").has_class("-transactions")
        await pilot.press("t")
        await settle(pilot, app)
        assert app.frames.count == 17 and app.model.job is None


async def test_bang_shows_only_problems() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("exclamation_mark")
        await settle(pilot, app)
        rows = [app.model.view.row(k) for k in range(app.frames.count)]
        assert rows == [6, 7, 8, 9, 10]
        assert app.main.query_one("#filter-bar").has_class("-problems")
        text = screen_text(app)
        assert "timeout" in text and "BAD CHECK" in text and "noise" in text
        assert "problems · 5 of 17" in text
        await pilot.press("exclamation_mark")
        await settle(pilot, app)
        assert app.frames.count == 17


async def test_the_filter_bar_applies_a_query() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("slash")
        assert app.main.query_one("#filter", Input).has_focus
        for key in 'unit:3 fc:3 reg:"under voltage"':
            await pilot.press(key if key != " " else "space")
        await pilot.press("enter")
        await settle(pilot, app)
        rows = [app.model.view.row(k) for k in range(app.frames.count)]
        assert rows == [3, 16]
        assert app.frames.has_focus
        assert "2 of 17" in screen_text(app)


async def test_a_bad_query_says_what_to_write_and_keeps_the_rows() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        app.main.query_one("#filter", Input).value = "unti:3"
        await pilot.press("slash", "enter")
        await pilot.pause()
        bar = app.main.query_one("#filter-bar")
        assert bar.has_class("-error")
        assert "unknown key 'unti'" in screen_text(app)
        assert app.frames.count == 17
        app.main.query_one("#filter", Input).value = "status:timeout"
        await pilot.press("enter")
        await settle(pilot, app)
        assert not bar.has_class("-error") and app.frames.count == 2


async def test_a_is_absolute_time() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        assert lines(app)[0].startswith("    0.000000")
        await pilot.press("a")
        await pilot.pause()
        first = lines(app)[0].strip()
        assert first[2] == ":" and first[5] == ":"
        await pilot.press("a")
        await pilot.pause()
        assert lines(app)[0].startswith("    0.000000")


# -- go to, export ------------------------------------------------------------------------------


async def test_g_goes_to_a_time_or_a_row() -> None:
    app = ModscopeApp(synthetic_session(2000))
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("g")
        assert app.main.prompt.open and app.main.prompt.input.has_focus
        await pilot.press(*"0.5", "enter")
        await pilot.pause()
        reader = app.model.reader
        row = app.frames.cursor_row
        assert row is not None and reader.t[row] >= reader.t[0] + 0.5 > reader.t[row - 1]
        top = app.frames.scroll_offset.y
        assert top <= app.frames.cursor < top + app.frames.page_height
        await pilot.press("g", *"#1234", "enter")
        await pilot.pause()
        assert app.frames.cursor_row == 1234
        await pilot.press("g", *"soon", "enter")
        await pilot.pause()
        await wait_said(pilot, app, "not a time")
        assert app.frames.cursor_row == 1234
        await pilot.press("g", "escape")
        await pilot.pause()
        assert not app.main.prompt.open and app.frames.has_focus


@pytest.mark.parametrize("name", ["rows.jsonl", "rows.csv", "rows.txt"])
async def test_e_exports_the_rows_shown(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    monkeypatch.chdir(tmp_path)  # a short name to type: each key is a frame of the app
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("exclamation_mark")
        await settle(pilot, app)
        await pilot.press("e")
        assert app.main.prompt.open
        target = tmp_path / name
        await pilot.press(*name, "enter")
        await wait_said(pilot, app, "wrote 5 rows")
    written = target.read_text(encoding="utf-8").splitlines()
    if name.endswith(".jsonl"):
        assert [json.loads(x)["index"] for x in written] == [6, 7, 8, 9, 10]
    elif name.endswith(".csv"):
        assert written[0].startswith("index,") and len(written) == 6
    else:
        assert len(written) == 5 and "noise" in written[3]


async def test_an_export_that_cannot_be_written_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("e", *"missing/rows.jsonl", "enter")
        await wait_said(pilot, app, "cannot write")


# -- panels --------------------------------------------------------------------------------------


async def test_u_shows_units_and_marks_silent_ones() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("u")
        await pilot.pause()
        assert app.main.query_one("#lower", ContentSwitcher).current == "units"
        table = app.main.query_one("#units", UnitsPanel)
        assert table.row_count == 2
        unit3 = [str(c) for c in table.get_row("3")]
        # unit, device, state, requests, answers, exceptions, timeouts, check errors
        assert unit3[:8] == ["3", HOSTILE_SHOWN[:15] + "…", "ok", "5", "5", "1", "0", "1"]
        assert unit3[8:10] == ["15.4", "15.4"]
        unit5 = [str(c) for c in table.get_row("5")]
        assert unit5[:8] == ["5", "", "ok", "3", "2", "0", "1", "0"]  # answered after a timeout
        await pilot.press("d")
        assert app.main.query_one("#lower", ContentSwitcher).current == "detail"


async def test_a_unit_that_stopped_answering_is_silent() -> None:
    session = synthetic_session(400)
    store = session.store
    late = store.t_end[len(store) - 1] + 30
    from dissectors.checks import with_crc

    for k in range(3):  # unit 9 is polled for 30 s and never answers
        raw = with_crc(bytes([9, 3, 0, 0, 0, 1]))
        session.feed(Chunk(raw, t_start=late - 30 + 10 * k, t_end=late - 30 + 10 * k + 0.001))
    session.finish()
    app = ModscopeApp(session)
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("u")
        await pilot.pause()
        table = app.main.query_one("#units", UnitsPanel)
        assert str(table.get_row("9")[2]) == "SILENT"
        assert str(table.get_row("1")[2]) == "SILENT"  # nobody answered in the last 30 s


async def test_w_watches_registers_and_opens_one() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("w")
        deadline = time.monotonic() + 10
        panel = app.main.query_one("#watch", WatchPanel)
        while panel.row_count < 7:
            assert time.monotonic() < deadline
            await pilot.pause(0.1)
            app.watching.show()
        names = [k[3] for k in panel.keys]
        assert "Under Voltage Trip" in names
        k = names.index("Under Voltage Trip")
        row = [str(c) for c in panel.get_row_at(k)]
        assert row[2] == "320 V" and row[5] == "3"
        panel.focus()
        panel.move_cursor(row=k)
        await pilot.press("enter")
        await pilot.pause()
        assert isinstance(app.screen, RegisterScreen)
        assert "Under Voltage Trip" in screen_text(app) and "latest: 320 V" in screen_text(app)
        await pilot.press("down", "enter")  # the second newest sample: row 4
        await pilot.pause()
        assert not isinstance(app.screen, RegisterScreen)
        assert app.frames.cursor_row == 4
        assert app.main.query_one("#lower", ContentSwitcher).current == "detail"


async def test_help_and_zoom() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        height = app.frames.page_height
        await pilot.press("z")
        await pilot.pause()
        assert app.main.has_class("-zoom") and app.frames.page_height > height
        await pilot.press("z")
        await pilot.pause()
        assert app.frames.page_height == height
        await pilot.press("question_mark")
        assert isinstance(app.screen, HelpScreen)
        assert "F n N" in screen_text(app)
        await pilot.press("end")
        await pilot.pause()
        assert 'reg:"Under Voltage"' in screen_text(app)
        await pilot.press("t")  # the main screen's keys do nothing under the help
        assert app.model.transactions is False
        await pilot.press("escape")
        assert not isinstance(app.screen, HelpScreen)


# -- hostile strings -----------------------------------------------------------------------------


async def test_device_strings_are_shown_as_text_never_as_markup() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(200, 40)) as pilot:
        await ready(pilot, app)
        text = screen_text(app)
        assert HOSTILE_SHOWN[:13] in text  # the label, cut to its column
        assert "\x1b" not in text
        await pilot.press(*["down"] * 12)
        await pilot.pause()
        text = screen_text(app)
        assert "VendorName=[/][@click=app.quit][bold red]Acme\\x1b]0;owned\\x07" in text
        title = str(app.main.query_one("#detail-title", Static).content)
        assert "[bold red]Pump[/]" not in title  # unit 5 has no label
        await pilot.press("down", "down")  # Report Server ID: the string is in the hex dump
        await pilot.pause()
        assert "··.B·[/][@click=" in app.main.query_one("#hex", HexView).render().plain
        await pilot.press("u")
        await pilot.pause()
        assert HOSTILE_SHOWN[:15] in screen_text(app)
        await pilot.press("w")
        await pilot.pause(0.5)
        app.watching.show()
        await pilot.pause()
        assert "[bold red]P" in screen_text(app)
        assert app.is_running  # nothing clicked app.quit


# -- live, pause, speed --------------------------------------------------------------------------


async def test_live_rows_arrive_followed_and_pause_freezes_the_view() -> None:
    session = Session(LINE, exact_timing=True, source="/dev/ttyUSB0")
    live = FakeLive(session)
    app = ModscopeApp(session, live=live)
    chunks = hostile_chunks()
    async with app.run_test(size=SIZE) as pilot:
        live.waiting.extend(chunks[:4])
        await wait_rows(pilot, app, 4)
        assert app.frames.following and app.frames.cursor_row == 3
        assert "/dev/ttyUSB0" in screen_text(app)
        await pilot.press("space")
        assert app.paused and app.main.query_one("#status").has_class("-paused")
        live.waiting.extend(chunks[4:8])
        await wait_rows(pilot, app, 8)
        assert app.frames.count == 4 and "PAUSED" in screen_text(app)
        await pilot.press("space")
        await pilot.pause()
        assert app.frames.count == 8 and app.frames.cursor_row == 7
        await pilot.press("up")
        live.waiting.extend(chunks[8:12])
        await wait_rows(pilot, app, 12)
        assert app.frames.cursor_row == 6 and not app.frames.following
        await pilot.press("f")
        assert app.frames.cursor_row == 11
        live.messages.append("port lost: /dev/ttyUSB0 [bold]gone[/]")
        live.waiting.extend(chunks[12:])
        await wait_rows(pilot, app, 17)
        await wait_said(pilot, app, "port lost: /dev/ttyUSB0 [bold]gone[/]")
        assert app.frames.cursor_row == 16
        await pilot.press("s")
        assert app.pacing.speed is None


class RecordingLive(FakeLive):
    """A live source that can record, like `sniffer.live.engine.LiveCapture`."""

    def __init__(self, session: Session, folder: Path) -> None:
        super().__init__(session)
        self.folder = folder
        self.recorder: Recorder | None = None

    def start_recording(self, path: Path) -> Recorder:
        self.recorder = Recorder(path, [PortSpec("/dev/ttyUSB0", LINE)])
        return self.recorder

    def stop_recording(self) -> list[Path]:
        recorder, self.recorder = self.recorder, None
        assert recorder is not None
        recorder.close()
        return list(recorder.files)


async def test_r_starts_and_stops_a_recording_of_the_live_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # a short name to type
    session = Session(LINE, exact_timing=True, source="/dev/ttyUSB0")
    live = RecordingLive(session, tmp_path)
    app = ModscopeApp(session, live=live)
    target = tmp_path / "from-the-tui.pcapng"
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("r")
        await pilot.pause()
        assert app.main.prompt.open
        await pilot.press(*target.name, "enter")
        await wait_said(pilot, app, f"recording to {target.name}")
        assert live.recorder is not None and target.exists()
        assert "from-the-tui.pcapng" in screen_text(app)  # the status bar names it
        await pilot.press("r")  # asks first: r again stops
        await pilot.pause()
        assert live.recorder is not None and app.main.prompt.confirming
        await pilot.press("r")
        await wait_said(pilot, app, f"recording stopped: {target.name}")
        assert live.recorder is None


async def test_r_on_a_capture_file_explains_instead() -> None:
    session = Session(LINE, exact_timing=True, source="hostile.pcapng")
    app = ModscopeApp(session, capture_of(hostile_chunks()))
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("r")
        await wait_said(pilot, app, "recording is for a live line")


async def test_s_replays_at_the_original_speed() -> None:
    reopened: list[int] = []

    def reopen() -> tuple[Session, Capture]:
        reopened.append(1)
        session = Session(LINE, exact_timing=True, source="hostile.pcapng")
        return session, capture_of(hostile_chunks())

    session, capture = reopen()
    app = ModscopeApp(session, capture, reopen=reopen)
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("s")  # the capture is indexed: replay it from the start
        assert reopened == [1, 1] and app.pacing.speed == 1.0
        assert app.session is not session and app.frames.following
        await pilot.pause(0.3)
        assert 0 < app.model.published < 17  # 1.64 s of traffic, in real time
        assert "1x" in screen_text(app)
        await pilot.press("space")
        assert app.pacing.paused
        shown = app.model.published
        await pilot.pause(0.4)
        assert app.model.published <= shown + 3
        await pilot.press("space")
        await pilot.press("s")  # as fast as possible from here on
        assert app.pacing.speed is None
        await ready(pilot, app)
        assert app.model.published == 17 and app.frames.count == 17


async def test_a_feed_that_fails_keeps_the_rows_and_says_why() -> None:
    def chunks() -> object:
        yield from hostile_chunks()[:6]
        raise RuntimeError("pcapng block at offset 812 is cut short")

    session = Session(LINE, exact_timing=True, source="broken.pcapng")
    capture = Capture(info=SourceInfo(path="broken", format="test"), _chunks=chunks())  # type: ignore[arg-type]
    app = ModscopeApp(session, capture)
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        assert app.main.query_one("#status").has_class("-stopped")
        await wait_said(pilot, app, "cut short")
        assert app.frames.count == app.model.published


async def test_q_quits_with_status_zero() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("q")
    assert app.return_code == 0 and app.pacing.stop.is_set()


async def test_ascii_frames_highlight_two_characters_per_byte() -> None:
    from dissectors.checks import ascii_frame
    from sniffer.model import LineSettings

    line = LineSettings(baud=9600, bytesize=7, parity="E", stopbits=1, mode="ascii")
    frames = [bytes([3, 3, 0, 0x0B, 0, 3]), bytes([3, 3, 6, 0, 115, 0, 4, 1, 44])]
    session = Session(line, source="ascii.log")
    t = 100.0
    for body in frames:
        raw = ascii_frame(body)
        session.feed(Chunk(raw, t_start=t, t_end=t + len(raw) * line.char_time))
        t += 0.1
    session.finish()
    app = ModscopeApp(session)
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("down", "enter", "down")  # the answer, its fields, the values
        await pilot.pause()
        hexview = app.main.query_one("#hex", HexView)
        assert hexview.highlight == (3, 9)  # body bytes: the three words
        assert hexview.raw_highlight() == (7, 19)  # ':' + 2 chars per byte
        raw = app.model.reader.raw(1)
        assert raw[7:19] == b"00730004012C"


async def test_an_empty_capture_is_calm() -> None:
    session = Session(LINE, source="empty.pcapng")
    app = ModscopeApp(session, capture_of([]))
    async with app.run_test(size=(80, 24)) as pilot:
        await ready(pilot, app)
        assert app.frames.count == 0 and app.frames.cursor_row is None
        for key in ("down", "pagedown", "end", "home", "p", "t", "exclamation_mark", "a", "z"):
            await pilot.press(key)
        await settle(pilot, app)
        await pilot.press("u", "w", "d", "g", "escape", "e", "escape")
        await pilot.pause()
        assert app.is_running and app.frames.count == 0
        assert "0 fr " in screen_text(app)


async def test_an_export_then_s_writes_the_rows_that_were_shown(tmp_path: Path) -> None:
    """`s` starts the capture again (a new store) while the export is being written: the
    file still holds the rows shown when Enter was pressed (found in tmux: IndexError)."""

    def reopen() -> tuple[Session, Capture]:
        session = Session(LINE, exact_timing=True, source="hostile.pcapng")
        return session, capture_of(hostile_chunks())

    session, capture = reopen()
    app = ModscopeApp(session, capture, reopen=reopen)
    out = tmp_path / "rows.jsonl"
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        burst(app, ["e", *str(out), "enter", "s"])
        await wait_said(pilot, app, f"wrote 17 rows to {out}")
    lines = out.read_text().splitlines()
    assert [json.loads(line)["index"] for line in lines] == list(range(17))


async def test_a_word_spelled_as_the_unit_column_is_answered_with_the_unit_term() -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        app.main.query_one("#filter", Input).value = "u3"
        await pilot.press("slash", "enter")
        await wait_said(pilot, app, "for unit 3 write unit:3")
        app.main.query_one("#filter", Input).value = "unit:3"
        await pilot.press("slash", "enter")
        await settle(pilot, app)
        rows = [app.model.view.row(k) for k in range(app.frames.count)]
        assert rows and all(app.session.store.unit[r] == 3 for r in rows)


async def test_the_status_bar_says_what_a_network_capture_carries(tmp_path: Path) -> None:
    """A network capture has no serial line: the status bar names its carriers, never
    the default 19200 8E1 it once showed (`StatusLine`, `carried`)."""
    path = tmp_path / "net.pcap"
    path.write_bytes(network_bus([(k % 3, "poll") for k in range(30)]))
    session, capture = open_session(path, index=False)
    app = ModscopeApp(session, capture)
    async with app.run_test(size=(120, 30)) as pilot:
        await ready(pilot, app)
        text = screen_text(app)
        assert "network: modbus-tcp, rtu-over-tcp" in text
        assert "8E1" not in text and "19200" not in text
