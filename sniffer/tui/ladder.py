"""Provides the ladder diagram's lines: the master and the slaves as columns, each
transaction as an arrow across them, time running down.

Only the lines on screen are built (from a view position down), so a capture of
millions of frames draws as fast as a small one. Latencies are those `pairing.measure`
vouches for: a value, a bound (`<16ms`) or unknown (`?`). When the source's stamps are
exact (a logic analyser), the quiet time between frames is drawn to scale: one line per
`scale` seconds, a long gap shortened to a `┄ 2.350s ┄` line; other stamps give one
line per frame, with the gap written in the time column. Nothing here imports Textual.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import pairwise

from rich.text import Text

from sniffer.framing.pairing import measure
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.model import Stamp
from sniffer.text import plain
from sniffer.tui.render import Styles, flag_tags, span_text, time_text
from sniffer.tui.rows import RowView
from sniffer.vocab import BAD_CHECK, Flag, Kind, Status

MAX_GAP_LINES = 6  # a gap longer than this many lines is drawn as one `┄` line
LANE_MIN = 5  # cells between two lanes, at the least
NOTE_MIN = 26  # cells kept for the notes on the right
SCALES = (0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0)


@dataclass(frozen=True, slots=True)
class LadderLine:
    row: int | None  # the store row this line stands for (None: a gap line)
    text: Text


@dataclass(frozen=True, slots=True)
class Lanes:
    """Where each column is: x of the master and of each slave shown; the notes' x."""

    time: int
    master: int
    slaves: dict[int, int]
    notes: int
    width: int


def exact(store: FrameStore) -> bool:
    """Whether gaps can be drawn to scale: the row times are when the bytes were on the wire."""
    return store.stamps == Stamp.EXACT


def pick_scale(store: FrameStore, rows: Sequence[int]) -> float:
    """A scale (seconds a line) at which the typical gap between `rows` takes one line."""
    gaps = sorted(store.t[b] - store.t_end[a] for a, b in pairwise(rows) if b > a)
    gaps = [g for g in gaps if g > 0]
    if not gaps:
        return 0.01
    typical = gaps[len(gaps) // 4]  # the shorter gaps: a poll's answer, not the poll period
    for s in SCALES:
        if s >= typical:
            return s
    return SCALES[-1]


def scale_text(scale: float) -> str:
    return f"{scale * 1000:g}ms" if scale < 1 else f"{scale:g}s"


def lanes_for(width: int, time_width: int, units: Sequence[int]) -> Lanes:
    """Lanes for the master and as many of `units` as fit (in their order)."""
    left = time_width + 2
    room = max(LANE_MIN, width - left - NOTE_MIN)
    fit = max(1, room // LANE_MIN - 1)
    shown = list(units[:fit])
    step = max(LANE_MIN, min(14, room // (len(shown) + 1))) if shown else LANE_MIN
    master = left + 1
    slaves = {u: master + step * (k + 1) for k, u in enumerate(shown)}
    last = max(slaves.values(), default=master)
    return Lanes(time_width, master, slaves, last + 3, width)


def lane_header(lanes: Lanes, styles: Styles) -> Text:
    cells = [" "] * lanes.width
    _put(cells, lanes.master - 1, "M")
    for unit, x in lanes.slaves.items():
        name = f"u{unit}"
        _put(cells, x - len(name) // 2, name)
    _put(cells, lanes.notes, "what")
    text = Text(no_wrap=True)
    text.append("".join(cells).rstrip(), styles.get("head"))
    text.pad_right(lanes.width - len(text))
    return text


def _put(cells: list[str], x: int, s: str) -> None:
    for k, ch in enumerate(s):
        if 0 <= x + k < len(cells):
            cells[x + k] = ch


def latency_label(store: FrameStore, row: int) -> str:
    """A transaction's latency as `measure` vouches for it: `12.3ms`, `<16ms` or `?`."""
    m = measure(store, row)
    return "?" if m is None else m.text()


class Ladder:
    """Builds the ladder's lines for a view of a store's rows."""

    def __init__(
        self,
        store: FrameStore,
        view: RowView,
        *,
        origin: float,
        absolute: bool,
        scale: float | None,
        summary: Callable[[int], str] | None = None,
    ) -> None:
        self.store = store
        self.view = view
        self.origin = origin
        self.absolute = absolute
        self.scale = scale  # None: one line a frame (the stamps are not exact)
        self.summary = summary  # a row's summary for the notes (register values)

    def rows_from(self, k: int, limit: int) -> list[int]:
        """Store rows to draw from view position `k`: each shown row, and a shown
        request's answer right after it when the view hides it (transactions)."""
        out: list[int] = []
        view, store = self.view, self.store
        while k < view.count and len(out) < limit:
            row = view.row(k)
            out.append(row)
            j = store.partner[row]
            if (
                store.kind[row] == Kind.REQUEST
                and j != NO_PARTNER
                and j > row
                and j < len(store.status)
                and not view.contains(j)
            ):
                out.append(j)
            k += 1
        return out

    def lines(
        self,
        k: int,
        height: int,
        lanes: Lanes,
        styles: Styles,
        cursor: int | None = None,
        previous: int | None = None,
    ) -> list[LadderLine]:
        """The lines from view position `k`; `previous` is the row above (for the gap)."""
        out: list[LadderLine] = []
        store = self.store
        for row in self.rows_from(k, height):
            if previous is not None and out is not None:
                gap = store.t[row] - store.t_end[previous]
                out.extend(self._gap(gap, lanes, styles, len(out) > 0))
            out.append(LadderLine(row, self.line(row, previous, lanes, styles, row == cursor)))
            previous = row
            if len(out) >= height:
                break
        return out[:height]

    def _gap(self, gap: float, lanes: Lanes, styles: Styles, inside: bool) -> list[LadderLine]:
        if self.scale is None or gap <= 0 or not inside:
            return []
        n = int(gap / self.scale + 0.5) - 1
        if n <= 0:
            return []
        if n > MAX_GAP_LINES:
            text = self._rails(lanes, styles, fill="┄")
            label = f" {span_text(gap) if gap >= 1 else f'{gap * 1000:.1f}ms'} not to scale "
            text = _overlay(text, lanes.time - len(label) + 1, label, styles.get("dim"))
            return [LadderLine(None, text)]
        return [LadderLine(None, self._rails(lanes, styles)) for _ in range(n)]

    def _rails(self, lanes: Lanes, styles: Styles, fill: str = " ") -> Text:
        cells = [" "] * lanes.width
        xs = [lanes.master, *lanes.slaves.values()]
        if fill != " ":
            for x in range(lanes.master, max(xs) + 1):
                cells[x] = fill
        for x in xs:
            cells[x] = "│"
        text = Text(no_wrap=True)
        text.append("".join(cells), styles.get("rail"))
        return text

    def line(
        self, row: int, previous: int | None, lanes: Lanes, styles: Styles, selected: bool
    ) -> Text:
        store = self.store
        kind = store.kind[row]
        unit = store.unit[row]
        flags = store.flags[row]
        status = store.status[row]
        t = store.t[row]
        if self.scale is None and previous is not None:
            when = "+" + _short(t - store.t_end[previous])
        else:
            when = time_text(t, self.origin, self.absolute)
        text = self._rails(lanes, styles)
        text = _overlay(text, 0, when.rjust(lanes.time)[-lanes.time :], styles.get("time"))
        x0 = lanes.master
        xu = lanes.slaves.get(unit)
        far = max(lanes.slaves.values(), default=x0 + LANE_MIN)
        end = xu if xu is not None else far + 2  # off the side: to the edge (notes say who)
        note = Text(no_wrap=True)
        state = ""
        if kind == Kind.NOISE:
            state = "noise"
            text = _overlay(text, x0, "≈" * (far - x0 + 1), styles.get("noise"))
            note.append(f"noise, {store.length[row]} bytes", styles.get("noise"))
        elif kind == Kind.EVENT:
            state = "event"
            text = _overlay(text, x0, "━" * (far - x0 + 1), styles.get("event"))
            note.append(plain(store.notes.get(row, "event"), 200), styles.get("event"))
        elif kind == Kind.REQUEST:
            retry = bool(flags & Flag.RETRY)
            state = {Status.TIMEOUT: "timeout"}.get(Status(status), "")
            if flags & BAD_CHECK:
                state = "check"
            dash = "╌" if retry else "─"
            if unit == 0:  # a broadcast: to every slave
                arrow = dash * (far - x0 - 1) + "▶"
                text = _overlay(text, x0 + 1, arrow, styles.get(state or "request"))
                for x in lanes.slaves.values():
                    text = _overlay(text, x - 1, "▷", styles.get(state or "request"))
            else:
                head = "╳" if status == Status.TIMEOUT else "▶"
                arrow = dash * max(0, end - x0 - 2) + head
                text = _overlay(text, x0 + 1, arrow, styles.get(state or "request"))
            note.append(f"u{unit} ", styles.get("unit"))
            note.append(f"fc{store.fc[row]} ")
            tags = flag_tags(flags)
            if flags & BAD_CHECK:
                note.append("BAD CHECK ", styles.get("check"))
            if tags:
                note.append(tags, styles.get("problem"))
            if status == Status.TIMEOUT:
                note.append("timeout ", styles.get("timeout"))
            elif unit == 0:
                note.append("broadcast ", styles.get("dim"))
        else:  # an answer, an exception, an unknown frame
            exc = kind == Kind.EXCEPTION or bool(store.fc[row] & 0x80)
            orphan = status == Status.ORPHAN
            state = "exception" if exc else "orphan" if orphan else ""
            if flags & BAD_CHECK:
                state = "check"
            dash = "╌" if orphan else "─"
            lat = latency_label(store, row) if not orphan else ""
            start = x0 + 1
            arrow = "◀" + dash * max(0, end - start - 1)
            if lat and len(lat) + 4 <= len(arrow):
                mid = (len(arrow) - len(lat)) // 2
                arrow = arrow[:mid] + lat + arrow[mid + len(lat) :]
            text = _overlay(text, start, arrow, styles.get(state or "answer"))
            note.append(f"u{unit} ", styles.get("unit"))
            if lat:
                note.append(lat + " ", styles.get("latency"))
            if flags & BAD_CHECK:
                note.append("BAD CHECK ", styles.get("check"))
            tags = flag_tags(flags)
            if tags:
                note.append(tags, styles.get("problem"))
            if orphan:
                note.append("orphan ", styles.get("orphan"))
            if exc and self.summary is None:  # the summary says which exception
                note.append("exception ", styles.get("exception"))
        if self.summary is not None and kind not in (Kind.NOISE, Kind.EVENT):
            note.append(plain(self.summary(row), 300), styles.get(state) if state else None)
        text = Text.assemble(text[: lanes.notes], note)
        text.truncate(lanes.width, overflow="ellipsis", pad=True)
        text.no_wrap = True
        if selected:
            text.stylize(styles.get("cursor", ""))
        return text


def _short(dt: float) -> str:
    if dt < 1:
        return f"{max(0.0, dt) * 1000:.1f}ms"
    if dt < 60:
        return f"{dt:.3f}s"
    return span_text(dt)


def _overlay(text: Text, x: int, s: str, style: object) -> Text:
    """`text` with `s` written over it from cell `x` (cut at the end)."""
    if x < 0:
        s, x = s[-x:], 0
    s = s[: max(0, len(text) - x)]
    if not s:
        return text
    out = text[:x]
    out.append(s, style)  # type: ignore[arg-type]
    out.append_text(text[x + len(s) :])
    return out
