"""Liveness: ages from the clock, a unit silent after SILENT_AFTER of its own periods, a
line idle after IDLE_AFTER of its period, unknown where no period is known, and a replay
never called idle because its file ended."""

from __future__ import annotations

from dissectors.checks import with_crc
from sniffer.analysis.liveness import (
    IDLE_MIN,
    SILENT_MIN,
    Heard,
    LineState,
    UnitState,
    age_text,
    line_liveness,
    liveness,
    liveness_lines,
    unit_liveness,
)
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import Session
from sniffer.vocab import Kind
from tests.support.live import T0

LINE = LineSettings(baud=19200, parity="E", stopbits=1, mode="rtu")


def read(unit: int) -> tuple[bytes, bytes]:
    """FC 3 of two registers at 0 and its answer."""
    return with_crc(bytes([unit, 3, 0, 0, 0, 2])), with_crc(bytes([unit, 3, 4, 0, 7, 0, 8]))


def polled(period: float, polls: int, *, unit: int = 1, answers: int | None = None) -> Session:
    """A session of `polls` reads of `unit` every `period` seconds from T0, the first
    `answers` of them answered."""
    session = Session(LINE, exact_timing=True, source="test")
    answers = polls if answers is None else answers
    for k in range(polls):
        t = T0 + k * period
        asked, answer = read(unit)
        session.feed(Chunk(asked, t))
        session.idle(t + 0.01)
        if k < answers:
            session.feed(Chunk(answer, t + 0.02))
            session.idle(t + 0.03)
    session.idle(T0 + polls * period + 10)
    session.stats.update()
    return session


def unit_at(since_answer: float, period: float | None, **kw: object) -> UnitState:
    now = 1000.0
    args: dict[str, object] = {
        "asked": True,
        "last_frame": now - since_answer,
        "last_answer": now - since_answer,
        "last_request": now - since_answer - 0.02,
        "period": period,
    }
    args.update(kw)
    return unit_liveness(1, now, **args).state  # type: ignore[arg-type]


def test_a_unit_falls_silent_after_three_of_its_own_periods() -> None:
    assert unit_at(29.0, 10.0) is UnitState.OK
    assert unit_at(31.0, 10.0) is UnitState.SILENT
    # a fast poll: never sooner than SILENT_MIN
    assert unit_at(SILENT_MIN - 0.1, 0.1) is UnitState.OK
    assert unit_at(SILENT_MIN + 0.1, 0.1) is UnitState.SILENT


def test_without_a_period_nothing_is_invented() -> None:
    assert unit_at(1.0, None) is UnitState.OK
    assert unit_at(60.0, None) is UnitState.UNKNOWN
    # ... unless it was asked after its last answer and has not answered since
    now = 1000.0
    asked = unit_liveness(
        1,
        now,
        asked=True,
        last_frame=now - 5,
        last_answer=now - 60,
        last_request=now - 5,
        period=None,
    )
    assert asked.state is UnitState.SILENT and asked.silent_after is None
    never = unit_liveness(
        1, now, asked=True, last_frame=now, last_answer=None, last_request=now, period=None
    )
    assert never.state is UnitState.SILENT and never.since_answer is None


def test_a_line_goes_idle_from_the_clock_and_a_replay_ends_instead() -> None:
    session = polled(0.5, 20)
    last = session.stats.units[1].last_seen
    answered = {1: last}
    res = session.store.resolution
    alive = liveness(session.stats.units.values(), answered, last + 0.1, res)
    assert alive.state is LineState.LIVE and alive.period == 0.5
    assert alive.units[0].state is UnitState.OK
    assert alive.idle_after == max(IDLE_MIN, 3 * 0.5)
    # no new frame: only the clock moves
    later = liveness(session.stats.units.values(), answered, last + 2.5, res)
    assert later.state is LineState.IDLE and later.since_frame == 2.5
    assert later.units[0].state is UnitState.SILENT and later.units[0].since_answer == 2.5
    # a replay's `now` is its end: the line is not idle because the file ends
    ended = liveness(session.stats.units.values(), answered, last + 2.5, res, ended=True)
    assert ended.state is LineState.ENDED
    assert liveness_lines(ended)[0] == "line: end of capture"


def test_a_line_without_a_known_period_is_quiet_not_idle() -> None:
    session = polled(5.0, 1)  # one request: no period yet
    last = session.stats.units[1].last_seen
    alive = liveness(session.stats.units.values(), {1: last}, last + 30, 0.0)
    assert alive.period is None and alive.state is LineState.QUIET
    assert alive.units[0].state is UnitState.UNKNOWN and alive.units[0].period is None
    assert line_liveness(T0, None, ()).state is LineState.QUIET


def test_heard_follows_the_newest_answer_of_each_unit_across_stores() -> None:
    session = polled(1.0, 10, answers=6)
    heard = Heard()
    heard.update(session.store)
    store = session.store
    answers = [store.t_end[i] for i in range(len(store)) if store.kind[i] == Kind.RESPONSE]
    assert heard.last_answer == {1: max(answers)}
    assert heard.last_frame == max(
        store.t_end[i] for i in range(len(store)) if store.kind[i] != Kind.EVENT
    )
    lines = liveness_lines(
        liveness(session.stats.units.values(), heard.last_answer, T0 + 20, 0.0),
        {1: "Pump\x1b[2J"},
    )
    assert lines[1].startswith("  unit 1 Pump\\x1b[2J: silent, last answer 15.0s ago")


def test_a_unit_never_asked_is_not_judged() -> None:
    heard = unit_liveness(
        7, 100.0, asked=False, last_frame=40.0, last_answer=40.0, last_request=None, period=None
    )
    assert heard.state is UnitState.NOT_ASKED and heard.since_answer == 60.0


def test_an_age_under_the_stamps_resolution_is_a_bound() -> None:
    # a frame stamped at the end of a host read ended up to one resolution earlier
    assert age_text(0.011, 0.169) == "<180ms"
    assert age_text(0.011, 0.0) == "11ms"
    assert age_text(2.5, 0.169) == "2.5s"
    assert age_text(None) == "?"
    now = 100.0
    alive = unit_liveness(
        1,
        now,
        asked=True,
        last_frame=now - 0.011,
        last_answer=now - 0.011,
        last_request=now - 0.02,
        period=0.1,
        resolution=0.169,
    )
    assert liveness_lines(line_liveness(now, now - 0.011, [alive], resolution=0.169)) == [
        "line: live, last frame <180ms ago (idle after 2.0s: 3 x its period)",
        "  unit 1: ok, last answer <180ms ago, last frame <180ms ago, period 100ms, "
        "silent after 2.0s",
    ]


def test_the_broadcast_address_is_never_silent() -> None:
    sent = unit_liveness(
        0, 100.0, asked=True, last_frame=40.0, last_answer=None, last_request=40.0, period=1.0
    )
    assert sent.state is UnitState.BROADCAST and sent.since_answer is None
