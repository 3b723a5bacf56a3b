"""Provides liveness: how long since the line's last frame and each unit's last frame and
last answer, measured against a clock, and whether the line is idle or a unit silent.

Every view asks the same question at a cabinet ("is the master still polling? is unit 7
still answering?") and gets its answer here, from one rule:

- `now` is the live capture's clock (`LiveCapture.now`, the clock the frame stamps come
  from), so the ages grow while no frame comes. For a replay, `now` is the end of the
  capture and `ended` is set: the line is then never called idle because the file
  ended (its state is `ended`), and the units' ages are counted back from that end.
- A unit is `silent` when the time since its last answer passes SILENT_AFTER of its own
  poll periods (the median wait between two requests to it, `UnitStats.period`), and
  never fewer than SILENT_MIN seconds: one late answer on a 50 ms poll is not silence.
  A unit asked but that never answered is silent too. Where its period is not known
  yet (one request so far), nothing is invented: it is `unknown` once SILENT_MIN
  has passed, unless it was asked after its last answer and has not answered for
  SILENT_MIN (that is silence the bytes show, period or not). Unit 0, the broadcast
  address that no device answers, is `broadcast`, never silent.
- The line is `idle` when the time since its last frame passes IDLE_AFTER of its own
  period (the shortest of its units' poll periods: the line carries a frame at least
  that often while the master polls), never fewer than IDLE_MIN seconds; `quiet` when
  that much time passed but no period is known to measure it by; else `live`.

A period known only as a bound (coarse stamps: `<2s`) is used as its bound, the longer
side, so a unit is never called silent sooner than its stamps allow.

The same SILENT_AFTER and SILENT_MIN decide the MQTT unit status and the metrics' up.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from enum import StrEnum
from itertools import compress

from sniffer.analysis.stats import UnitStats
from sniffer.framing.store import FrameStore
from sniffer.text import plain
from sniffer.vocab import BAD_CHECK, Kind

SILENT_AFTER = 3.0  # poll periods without an answer after which a unit is silent
SILENT_MIN = 2.0  # ... but never fewer seconds than this
IDLE_AFTER = 3.0  # line periods without a frame after which the line is idle
IDLE_MIN = 2.0  # ... but never fewer seconds than this
BROADCAST_UNIT = 0  # Modbus: every device takes it and none answers


class LineState(StrEnum):
    LIVE = "live"  # frames come as the line's period says they should
    IDLE = "idle"  # no frame for IDLE_AFTER of its periods: the master stopped polling
    QUIET = "quiet"  # no frame for IDLE_MIN seconds, and no period known to judge it by
    ENDED = "ended"  # a replay: the capture ends there, which says nothing of the line


class UnitState(StrEnum):
    OK = "ok"  # answered within its threshold
    SILENT = "silent"  # asked and not answering, or past SILENT_AFTER of its periods
    UNKNOWN = "unknown"  # quiet for SILENT_MIN, but its period is not known to judge by
    NOT_ASKED = "not asked"  # only heard answering, never asked: nothing to judge
    BROADCAST = "broadcast"  # unit 0: no device answers a broadcast


@dataclass(frozen=True, slots=True)
class UnitLiveness:
    unit: int
    since_frame: float | None  # seconds since its last frame (None: none)
    since_answer: float | None  # seconds since its last answer (None: never answered)
    period: float | None  # its poll period in seconds (None: unknown)
    period_bound: bool  # the period is an upper bound (`<`)
    silent_after: float | None  # seconds without an answer that make it silent
    state: UnitState
    # the stamps' resolution: a frame ended up to this long before its stamp, so an age
    # is at least what is measured and at most this much more (`age_text`)
    resolution: float = 0.0


@dataclass(frozen=True, slots=True)
class LineLiveness:
    state: LineState
    since_frame: float | None  # seconds since the line's last frame (None: none yet)
    period: float | None  # the line's period (its units' shortest), None: unknown
    idle_after: float | None  # seconds without a frame that make it idle (None: unknown)
    units: tuple[UnitLiveness, ...]
    resolution: float = 0.0  # as UnitLiveness.resolution


def _age(now: float, t: float | None) -> float | None:
    # a stamp a hair after `now` (two threads reading one clock) is no negative age
    return None if t is None or t <= 0 else max(0.0, now - t)


def unit_liveness(
    unit: int,
    now: float,
    *,
    asked: bool,
    last_frame: float | None,
    last_answer: float | None,
    last_request: float | None,
    period: float | None,
    period_bound: bool = False,
    resolution: float = 0.0,
) -> UnitLiveness:
    """One unit's ages and state at `now` (see the module's rule). `asked`: requests to it
    were seen; `last_request`: when the newest was sent (None: not known)."""
    since_frame = _age(now, last_frame)
    since_answer = _age(now, last_answer)
    known = period is not None and period == period and period < float("inf")
    limit = max(SILENT_MIN, SILENT_AFTER * period) if known and period is not None else None
    if unit == BROADCAST_UNIT:
        state = UnitState.BROADCAST
    elif not asked:
        state = UnitState.NOT_ASKED
    elif since_answer is None:
        state = UnitState.SILENT
    elif limit is not None:
        state = UnitState.SILENT if since_answer > limit else UnitState.OK
    elif since_answer <= SILENT_MIN:
        state = UnitState.OK
    else:
        unanswered = (
            last_request is not None
            and last_answer is not None
            and last_request > last_answer
            and now - last_request > SILENT_MIN
        )
        state = UnitState.SILENT if unanswered else UnitState.UNKNOWN
    return UnitLiveness(
        unit,
        since_frame,
        since_answer,
        period if known else None,
        period_bound and known,
        limit,
        state,
        resolution,
    )


def line_liveness(
    now: float,
    last_frame: float | None,
    units: Iterable[UnitLiveness],
    *,
    ended: bool = False,
    resolution: float = 0.0,
) -> LineLiveness:
    """The line's state at `now` from its last frame and its units' periods."""
    units = tuple(units)
    since = _age(now, last_frame)
    periods = [u.period for u in units if u.period is not None]
    period = min(periods) if periods else None
    limit = max(IDLE_MIN, IDLE_AFTER * period) if period is not None else None
    if ended:
        state = LineState.ENDED
    elif since is None:
        # nothing heard yet: quiet, for want of a period; the age is unknown, not zero
        state = LineState.QUIET
    elif limit is not None:
        state = LineState.IDLE if since > limit else LineState.LIVE
    else:
        state = LineState.QUIET if since > IDLE_MIN else LineState.LIVE
    return LineLiveness(state, since, period, limit, units, resolution)


def liveness(
    units: Iterable[UnitStats],
    last_answer: Mapping[int, float],
    now: float,
    resolution: float,
    *,
    last_frame: float | None = None,
    ended: bool = False,
) -> LineLiveness:
    """The line and every unit from the session's statistics (`Stats.units`), each unit's
    last answer time, and `now`. `last_frame`: the line's newest frame (default: the
    newest any unit was seen). `resolution`: the stamps' (the store's), so a period is
    one they vouch for (`UnitStats.period`)."""
    out = []
    newest = 0.0
    for st in sorted(units, key=lambda s: s.unit):
        newest = max(newest, st.last_seen)
        measured = st.period(resolution)
        requests = st.newest_requests(1)
        out.append(
            unit_liveness(
                st.unit,
                now,
                asked=st.requests > 0,
                last_frame=st.last_seen or None,
                last_answer=last_answer.get(st.unit),
                last_request=requests[-1] if requests else None,
                period=measured.seconds if measured is not None else None,
                period_bound=measured.bound if measured is not None else False,
                resolution=resolution,
            )
        )
    if last_frame is None and newest > 0:
        last_frame = newest
    return line_liveness(now, last_frame, out, ended=ended, resolution=resolution)


_ANSWERS = bytes(1 if k in (Kind.RESPONSE, Kind.EXCEPTION) else 0 for k in range(256))
_FRAMES = bytes(0 if k in (Kind.NOISE, Kind.EVENT) else 1 for k in range(256))


class Heard:
    """The newest frame of the line and the newest answer (normal or exception, good
    check) of each unit, followed over a store as rows arrive: what a headless live
    capture's `--stats` needs, whose store is emptied now and then (`update` every
    store before it goes; a new store is followed from its first row)."""

    def __init__(self) -> None:
        self.store: FrameStore | None = None
        self.next = 0
        self.last_frame: float | None = None
        self.last_answer: dict[int, float] = {}

    def update(self, store: FrameStore) -> None:
        if store is not self.store:
            self.store, self.next = store, 0
        store.sync()
        n = len(store)
        lo = self.next
        if n <= lo:
            return
        kinds = store.kind[lo:n].tobytes()
        frames = kinds.translate(_FRAMES)
        k = frames.rfind(1)
        if k >= 0:
            t = store.t_end[lo + k]
            self.last_frame = t if self.last_frame is None else max(self.last_frame, t)
        answers = kinds.translate(_ANSWERS)
        if 1 in answers:
            flags, units, ends = store.flags, store.unit, store.t_end
            last = self.last_answer
            for i in compress(range(lo, n), answers):
                if not flags[i] & BAD_CHECK:
                    u, t = units[i], ends[i]
                    if t > last.get(u, 0.0):
                        last[u] = t
        self.next = n


def age_text(seconds: float | None, resolution: float = 0.0) -> str:
    """A compact age: `95ms`, `3.0s`, `2m03s`, `1h02m`; `?` for none. Under the stamps'
    `resolution` it is a bound, `<180ms`: the frame ended up to that long before its
    stamp, so its age is under the measured one plus the resolution."""
    if seconds is None:
        return "?"
    if 0 < resolution < float("inf") and seconds < resolution:
        return "<" + age_text(seconds + resolution)
    if seconds < 1:
        return f"{max(0.0, seconds) * 1000:.0f}ms"
    if seconds < 60:
        return f"{seconds:.1f}s"
    minutes, secs = divmod(int(seconds), 60)
    if minutes < 60:
        return f"{minutes}m{secs:02d}s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours}h{minutes:02d}m"


def liveness_lines(line: LineLiveness, labels: Mapping[int, str] | None = None) -> list[str]:
    """What `live --stats` prints: the line, then one line per unit."""
    labels = labels or {}
    head = f"line: {line.state.value}"
    if line.state is LineState.ENDED:
        head = "line: end of capture"
    else:
        head += f", last frame {_ago(line.since_frame, line.resolution)}"
        if line.idle_after is not None:
            head += f" (idle after {age_text(line.idle_after)}: {IDLE_AFTER:g} x its period)"
        else:
            head += f" (period unknown; quiet after {age_text(IDLE_MIN)})"
    out = [head]
    for u in line.units:
        label = labels.get(u.unit, "")
        name = f"unit {u.unit}" + (f" {plain(label, 16)}" if label else "")
        period = (
            "period unknown"
            if u.period is None
            else f"period {'<' if u.period_bound else ''}{age_text(u.period)}"
        )
        limit = "" if u.silent_after is None else f", silent after {age_text(u.silent_after)}"
        out.append(
            f"  {name}: {u.state.value}, last answer {_ago(u.since_answer, u.resolution)}, "
            f"last frame {_ago(u.since_frame, u.resolution)}, {period}{limit}"
        )
    return out


def _ago(seconds: float | None, resolution: float = 0.0) -> str:
    return "never" if seconds is None else age_text(seconds, resolution) + " ago"
