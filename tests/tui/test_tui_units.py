"""The units pane's poll cycle: period, jitter and gaps of each unit's main poll, followed
incrementally, agreeing with `sniffer.analysis.pollcycle` (the --stats table); snapshots of the
pane at 80x24 and 160x48.

Review the SVGs in tests/__snapshots__/ when they change; regenerate them with
`pytest --snapshot-update tests/tui/test_tui_units.py`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from itertools import pairwise
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from textual.pilot import Pilot

from dissectors.checks import with_crc
from sniffer.analysis.pollcycle import PollCycles, poll_cycles
from sniffer.cli import main
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import Session, replay_file
from sniffer.tui.app import ModscopeApp
from sniffer.tui.widgets.units import PollWatch, UnitsPanel
from sniffer.vocab import Flag
from tests.support.gateway import mbap_frame
from tests.support.netbuild import Conversation, pcap

LINE = LineSettings(19200, 8, "E", 1)
SnapCompare = Callable[..., bool]


def read(unit: int, start: int, count: int) -> tuple[bytes, bytes]:
    request = with_crc(bytes([unit, 3, 0, start, 0, count]))
    answer = with_crc(bytes([unit, 3, 2 * count]) + bytes(2 * count))
    return request, answer


def bus(polls: dict[tuple[int, int], list[float]]) -> Session:
    """A session where each (unit, start) read is sent at the given times and answered."""
    sends = sorted((t, unit, start) for (unit, start), times in polls.items() for t in times)
    for (a, _, _), (b, _, _) in pairwise(sends):
        assert b - a >= 0.025, "transactions would overlap on the line"
    session = Session(LINE)
    for t, unit, start in sends:
        request, answer = read(unit, start, 2)
        session.feed(Chunk(request, 1_700_000_000 + t + 0.005))
        session.feed(Chunk(answer, 1_700_000_000 + t + 0.02))
    session.finish()
    return session


def troubled_bus() -> Session:
    """Unit 1 polled steadily every 250 ms; unit 2 every 500 ms with a 5 s stall; unit 3
    every second, irregularly, and read once more every 4 s."""
    steady = [k * 0.25 for k in range(120)]
    stalled = [0.05 + k * 0.5 for k in range(20)] + [15.05 + k * 0.5 for k in range(30)]
    uneven = [0.1 + k * 1.0 + (0.12 if k % 3 == 0 else 0.0) for k in range(30)]
    every4 = [0.68 + k * 4.0 for k in range(8)]
    return bus({(1, 0): steady, (2, 0): stalled, (3, 0): uneven, (3, 10): every4})


def test_the_main_poll_of_each_unit_agrees_with_the_stats_table() -> None:
    session = troubled_bus()
    watch = PollWatch()
    watch.update(session.store, len(session.store))
    cycles = poll_cycles(session.store)
    got = watch.summaries()
    assert sorted(got) == [1, 2, 3]
    for unit, cycle in cycles.items():
        main = max(cycle.polls, key=lambda p: p.count)
        assert got[unit].period == pytest.approx(main.period)
        assert got[unit].jitter == pytest.approx(main.jitter)
        assert got[unit].gaps == len(cycle.gaps)
    assert got[1].period == pytest.approx(0.25) and got[1].gaps == 0
    assert got[2].period == pytest.approx(0.5) and got[2].gaps == 1  # the 5.5 s stall
    assert got[3].period == pytest.approx(1.0, abs=1e-5)
    assert got[3].jitter == pytest.approx(0.24, abs=1e-5)


def test_rows_arriving_in_pieces_give_the_same_cycle() -> None:
    session = troubled_bus()
    whole = PollWatch()
    whole.update(session.store, len(session.store))
    pieces = PollWatch()
    for upto in range(0, len(session.store) + 1, 7):
        pieces.update(session.store, upto)
    pieces.update(session.store, len(session.store))
    assert pieces.summaries() == whole.summaries()


def test_a_bounded_follow_leaves_rows_for_later_and_ends_with_the_same_cycle(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import sniffer.tui.widgets.units as units

    monkeypatch.setattr(units, "CHUNK", 16)
    session = troubled_bus()
    n = len(session.store)
    whole = PollWatch()
    assert not whole.update(session.store, n)
    bounded = PollWatch()
    calls = 0
    while bounded.update(session.store, n, budget=0.0):  # one chunk a call
        calls += 1
        assert bounded.next == 16 * calls
    assert calls + 1 == -(-n // 16) > 3 and bounded.next == n
    assert bounded.summaries() == whole.summaries()


def test_a_request_sent_again_is_one_poll_with_the_frames_remembered_or_not(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import sniffer.tui.widgets.units as units

    session = troubled_bus()
    remembered = PollWatch()
    remembered.update(session.store, len(session.store))
    monkeypatch.setattr(units, "SEEN", 0)  # every frame keyed again
    forgotten = PollWatch()
    forgotten.update(session.store, len(session.store))
    assert forgotten.summaries() == remembered.summaries()
    assert not forgotten._seen and remembered._seen


def test_writes_are_one_poll_whatever_they_write() -> None:
    """Writes of other values are one poll, as --stats counts them; reads of other
    quantities, and FC 5 of a value that is no coil state, are not."""
    exchanges = [
        (bytes([4, 16, 0, 5, 0, 1, 2, 0, k]), bytes([4, 16, 0, 5, 0, 1])) for k in range(3)
    ]
    exchanges += [(bytes([4, 6, 0, 5, 0, k]),) * 2 for k in range(3)]
    exchanges += [(bytes([4, 3, 0, 5, 0, 1 + k % 2]), bytes([4, 3, 2, 0, 0])) for k in range(2)]
    exchanges += [(bytes([4, 5, 0, 7, 0x12, k]),) * 2 for k in range(2)]
    session = Session(LINE)
    for k, (request, answer) in enumerate(exchanges):
        session.feed(Chunk(with_crc(request), 1_700_000_000 + k * 0.1))
        session.feed(Chunk(with_crc(answer), 1_700_000_000 + k * 0.1 + 0.03))
    session.finish()
    watch = PollWatch()
    watch.update(session.store, len(session.store))
    counts = sorted(p.count for p in watch.polls[4].values())
    assert counts == [1, 1, 1, 1, 3, 3]
    stats = PollCycles()
    stats.add(session.store)
    assert counts == sorted(s.count for s in stats.sendings[4].values())


# -- Modbus TCP: polls counted as --stats counts them -------------------------------------

T0 = 1_750_000_000.0


def tcp_capture(path: Path) -> Path:
    """A master polling over Modbus TCP, each request with a transaction id of its own:
    unit 1 read every 500 ms (12 times), unit 2 written every second with changing values
    (6 times), each answered 20 ms later."""
    conv = Conversation()
    sends: list[tuple[float, bytes, bytes]] = []
    for k in range(12):
        sends.append((k * 0.5, bytes.fromhex("0103000a0002"), bytes.fromhex("01030400010002")))
    for k in range(6):
        write = bytes([2, 16, 0, 20, 0, 1, 2, 0, k])
        sends.append((0.25 + k * 1.0, write, bytes([2, 16, 0, 20, 0, 1])))
    packets = [(T0 - 1 + k * 0.01, p) for k, p in enumerate(conv.handshake())]
    for tid, (t, request, answer) in enumerate(sorted(sends), start=1):
        packets.append((T0 + t, conv.client(mbap_frame(tid, request))))
        packets.append((T0 + t + 0.02, conv.server(mbap_frame(tid, answer))))
    path.write_bytes(pcap(1, packets))
    return path


def test_modbus_tcp_polls_are_counted_as_the_stats_count_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Each request's transaction id makes its frame differ from the last: the pane still
    counts one poll of 12 sendings every 500 ms for unit 1, and one of 6 every second for
    unit 2, as PollCycles and `modscope replay --stats` do (the pane once took each
    request for a poll of its own, the MBAP header for a body)."""
    path = tcp_capture(tmp_path / "tcp.pcap")
    store = replay_file(path).store
    requests = [i for i in range(len(store)) if store.flags[i] & Flag.MBAP and store.fc[i] == 3]
    assert len({store.raw(i) for i in requests}) == 12 * 2  # requests and answers differ
    watch = PollWatch()
    watch.update(store, len(store))
    cycles = poll_cycles(store)
    for unit, count, period in ((1, 12, 0.5), (2, 6, 1.0)):
        (poll,) = cycles[unit].polls
        (mine,) = watch.polls[unit].values()
        assert mine.count == poll.count == count
        assert watch.summary(unit).period == pytest.approx(poll.period)
        assert poll.period == pytest.approx(period, abs=1e-5)
    assert main(["replay", str(path), "--stats"]) in (0, 1)
    stats = capsys.readouterr().out
    assert "read holding 10-11" in stats and "write holding 20" in stats
    lines = [line.split() for line in stats.splitlines()]
    assert ["1", "read", "holding", "10-11", "12", "500ms"] in [line[:6] for line in lines]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.03, 30.0, allow_nan=False), min_size=2, max_size=300))
def test_period_jitter_and_gaps_match_pollcycle(waits: list[float]) -> None:
    times = [0.0]
    for w in waits:
        times.append(times[-1] + w)
    session = bus({(1, 0): times})
    watch = PollWatch()
    watch.update(session.store, len(session.store))
    main = poll_cycles(session.store)[1].polls[0]
    got = watch.summary(1)
    assert got.period == pytest.approx(main.period)
    assert got.jitter == pytest.approx(main.jitter)
    # (gaps are judged by the period known when the wait ended, --stats by the final
    # period: they agree on a steady cycle, as the troubled bus above shows)


# -- the pane ------------------------------------------------------------------------------


def app_on(session: Session) -> ModscopeApp:
    return ModscopeApp(session, blink=False)


async def _shown(pilot: Pilot[Any]) -> None:
    app = pilot.app
    assert isinstance(app, ModscopeApp)
    deadline = time.monotonic() + 20
    while app.model.published < len(app.session.store):
        assert time.monotonic() < deadline
        await pilot.pause(0.05)
    await pilot.press("u")
    await pilot.pause(0.3)
    await pilot.pause()


@pytest.mark.asyncio
async def test_the_pane_shows_period_jitter_and_gaps() -> None:
    app = app_on(troubled_bus())
    async with app.run_test(size=(160, 48)) as pilot:
        await _shown(pilot)
        table = app.main.query_one("#units", UnitsPanel)
        assert {"period", "jitter", "gaps"} <= set(table.shown)
        names = table.shown
        unit2 = dict(zip(names, (str(c) for c in table.get_row("2")), strict=True))
        assert (unit2["period"], unit2["gaps"]) == ("500ms", "1")
        unit3 = dict(zip(names, (str(c) for c in table.get_row("3")), strict=True))
        assert (unit3["period"], unit3["jitter"], unit3["gaps"]) == ("1000ms", "240ms", "-")


@pytest.mark.asyncio
async def test_at_80_columns_the_period_stays() -> None:
    app = app_on(troubled_bus())
    async with app.run_test(size=(80, 24)) as pilot:
        await _shown(pilot)
        table = app.main.query_one("#units", UnitsPanel)
        assert "period" in table.shown
        assert {"unit", "state", "answer", "exc", "t/o", "median", "p95"} <= set(table.shown)


@pytest.mark.asyncio
async def test_the_pane_shows_the_period_of_modbus_tcp_polls(tmp_path: Path) -> None:
    app = app_on(replay_file(tcp_capture(tmp_path / "tcp.pcap")))
    async with app.run_test(size=(160, 48)) as pilot:
        await _shown(pilot)
        table = app.main.query_one("#units", UnitsPanel)
        names = table.shown
        for unit, period in (("1", "500ms"), ("2", "1000ms")):
            row = dict(zip(names, (str(c) for c in table.get_row(unit)), strict=True))
            assert (row["period"], row["gaps"]) == (period, "-")


@pytest.mark.parametrize("size", [(80, 24), (160, 48)], ids=lambda s: f"{s[0]}x{s[1]}")
def test_units_pane_snapshot(snap_compare: SnapCompare, size: tuple[int, int]) -> None:
    assert snap_compare(app_on(troubled_bus()), terminal_size=size, run_before=_shown)
