"""Provides the text of the TUI's rows, hex dumps and plots as rich Text built from plain strings.

Nothing that came from a device is ever parsed as markup: every string goes through
`sniffer.text.plain` (control characters escaped, length capped) and into `Text`
objects with explicit styles. Styles come from the widgets (their CSS component
classes), keyed by the names below.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

from rich.style import Style
from rich.text import Text

from dissectors.dictionary import RegisterValue
from sniffer.analysis.liveness import age_text
from sniffer.framing.pairing import latency_words
from sniffer.framing.store import FrameView
from sniffer.meaning.describe import FrameDetail
from sniffer.text import plain
from sniffer.vocab import BAD_CHECK, FLAGS, PROBLEM_MASK, STATUS_NAMES, Flag, Kind, Status

Styles = Mapping[str, Style]

# what colours a row: the first that applies
ROW_STATES = ("noise", "event", "check", "timeout", "exception", "orphan", "problem", "open")
SPARK = "▁▂▃▄▅▆▇█"


# short tags for the flags a row's summary starts with (the detail pane says it in full)
FLAG_TAGS: tuple[tuple[Flag, str], ...] = tuple((flag, m.tag) for flag, m in FLAGS if m.tag)


def flag_tags(flags: int) -> str:
    """`slow retry ` for a row with those flags ('' for none)."""
    return "".join(tag + " " for flag, tag in FLAG_TAGS if flags & flag)


def row_state(v: FrameView) -> str:
    """The name of the state a row is coloured by ('' for a plain good frame)."""
    if v.kind == Kind.NOISE:
        return "noise"
    if v.kind == Kind.EVENT:
        return "event"
    if v.flags & BAD_CHECK:
        return "check"
    if v.status == Status.TIMEOUT:
        return "timeout"
    if v.status == Status.EXCEPTION or v.exception:
        return "exception"
    if v.status == Status.ORPHAN:
        return "orphan"
    if v.flags & PROBLEM_MASK:
        return "problem"
    if v.status == Status.OPEN:
        return "open"
    return ""


def time_text(t: float, origin: float, absolute: bool) -> str:
    """Wall-clock `14:03:07.123` or time from the start: `12.345678` below an hour,
    `1:02:03.456789` (h:mm:ss.ffffff) past it."""
    if absolute:
        stamp = datetime.fromtimestamp(t, tz=UTC).astimezone()
        return stamp.strftime("%H:%M:%S.%f")[:-3]
    return span_text(t - origin)


def span_text(seconds: float) -> str:
    """Seconds as `12.345678`, or `h:mm:ss.ffffff` from an hour on (to the microsecond)."""
    if seconds < 3600:
        return f"{seconds:.6f}"
    micros = round(seconds * 1e6)
    whole, frac = divmod(micros, 1_000_000)
    minutes, secs = divmod(whole, 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}.{frac:06d}"


def time_width(span: float, absolute: bool) -> int:
    """Cells the time column needs for a capture lasting `span` seconds (one more for a
    mark), so no time is ever cut."""
    if absolute:
        return 13
    if span < 3600:
        return 12
    return len(span_text(span)) + 1


def delta_text(dt: float | None) -> str:
    if dt is None:
        return ""
    if dt < 0:
        return "-" + delta_text(-dt)[1:]
    if dt < 1:
        return f"+{dt * 1000:.1f}ms"
    if dt < 60:
        return f"+{dt:.3f}s"
    minutes, seconds = divmod(dt, 60)
    if minutes < 60:
        return f"+{int(minutes)}m{seconds:04.1f}s"
    hours, minutes = divmod(minutes, 60)
    return f"+{int(hours)}h{int(minutes):02d}m"


def ago_text(seconds: float) -> str:
    """A compact age, `95ms`, `3.0s`, `2m03s`, `1h02m`: the one spelling of ages
    (`liveness.age_text`, which the units pane and `--stats` use)."""
    return age_text(seconds)


def latency_text(d: FrameDetail | None) -> str:
    """A row's latency as every listing says it (`pairing.latency_words`): the value, the
    bound (`<16ms`) where the timing only bounds it, or nothing where it cannot say."""
    if d is None:
        return ""
    return latency_words(d.latency_ms, d.latency_max_ms)


@dataclass(frozen=True, slots=True)
class Columns:
    """Widths of the frame list's columns for one terminal width."""

    width: int
    time: int
    delta: int  # 0: hidden
    label: int  # 0: hidden
    name: int
    latency: int
    number: int = 0  # the row number (`#1234`, as `g` and the details say it); 0: hidden


def number_width(rows: int) -> int:
    """Cells for row numbers up to `rows` (`#` and the digits; grows in steps, so a live
    list does not shift at every new digit)."""
    digits = len(str(max(0, rows - 1)))
    return 1 + max(4, digits + (digits % 2))


def columns_for(width: int, absolute: bool, span: float = 0.0, rows: int = 0) -> Columns:
    """The columns for a width: narrower terminals drop the delta and the device label
    first and shorten function names; the time column fits the capture's length; the row
    numbers fit the row count (`rows`; 0: no row numbers)."""
    time = time_width(span, absolute)
    number = number_width(rows) if rows else 0
    if width >= 110:
        return Columns(width, time, 9, 14, 24, 8, number)
    if width >= 90:
        return Columns(width, time, 9, 10, 18, 8, number)
    return Columns(width, time, 0, 0, 15, 7, number)


def fit_columns(
    columns: Sequence[tuple[str, int]], priority: Sequence[str], width: int, pad: int = 2
) -> list[str]:
    """The names of the columns that fit in `width` cells (each takes its width plus
    `pad`): whole columns are left out, the least important first (`priority` lists the
    names most important first), and the others keep their order."""
    keep = list(priority)
    while keep and sum(w + pad for n, w in columns if n in keep) > width:
        keep.pop()
    return [n for n, _ in columns if n in keep]


# shorter names for narrow terminals, used only when the full name does not fit
SHORT_NAMES = {
    "Read Coils": "Read Coils",
    "Read Discrete Inputs": "Read Inputs",
    "Read Holding Registers": "Read Holding",
    "Read Input Registers": "Read Input Regs",
    "Write Single Coil": "Write Coil",
    "Write Single Register": "Write Register",
    "Read Exception Status": "Exc Status",
    "Get Comm Event Counter": "Event Counter",
    "Get Comm Event Log": "Event Log",
    "Write Multiple Coils": "Write Coils",
    "Write Multiple Registers": "Write Registers",
    "Report Server ID": "Server ID",
    "Read File Record": "Read File",
    "Write File Record": "Write File",
    "Mask Write Register": "Mask Write",
    "Read/Write Multiple Registers": "Read/Write Regs",
    "Read FIFO Queue": "Read FIFO",
    "Encapsulated Interface Transport": "Encapsulated",
}


def short_name(name: str, width: int) -> str:
    if len(name) <= width:
        return name
    return SHORT_NAMES.get(name, name)


def _fit(text: str, width: int) -> str:
    if len(text) <= width:
        return text.ljust(width)
    return text[: max(0, width - 1)] + "…"


def header_text(cols: Columns) -> Text:
    """The column titles above the frame list."""
    parts = (["#".rjust(cols.number)] if cols.number else []) + ["time".rjust(cols.time)]
    if cols.delta:
        parts.append("delta".rjust(cols.delta))
    unit = "unit" + (" " + "device".ljust(cols.label) if cols.label else "")
    parts += [unit.ljust(4 + (cols.label + 1 if cols.label else 0)), "dir "]
    parts += [_fit("function", cols.name), "latency".rjust(cols.latency), "summary"]
    text = Text(" ".join(parts), no_wrap=True, overflow="ellipsis")
    text.truncate(cols.width)
    return text


def row_text(
    d: FrameDetail,
    *,
    answer: FrameDetail | None,
    when: str,
    delta: str,
    cols: Columns,
    styles: Styles,
    number: str = "",
) -> Text:
    """One line of the frame list. `answer` is given for a transaction row (the request's
    paired answer): its values, status and latency stand for the transaction."""
    v = d.view
    state = row_state(answer.view) if answer is not None else ""
    state = state or row_state(v)
    text = Text(no_wrap=True, overflow="ellipsis")
    if cols.number:
        text.append(number.rjust(cols.number) + " ", styles.get("dim"))
    text.append(when.rjust(cols.time), styles.get("time"))
    if cols.delta:
        text.append(" " + delta.rjust(cols.delta - 1), styles.get("dim"))
    text.append(" ")
    if v.kind in (Kind.NOISE, Kind.EVENT):
        text.append(" " * 4 + (" " * (cols.label + 1) if cols.label else ""))
        direction = "??? " if v.kind == Kind.NOISE else "--- "
    else:
        text.append(f"u{v.unit:<3d}", styles.get("unit"))
        if cols.label:
            text.append(" " + _fit(plain(d.label, 80), cols.label), styles.get("label"))
        direction = (d.direction + " ") if answer is None else "M<>S"
    text.append(" " + direction + " ", styles.get("dim"))
    summary = d.summary
    latency = d if v.kind != Kind.REQUEST or answer is not None else None
    if answer is not None:
        a = answer.view
        if a.exception or answer.registers:
            summary = answer.summary
        latency = answer
    name = plain(d.name, 80)
    if v.kind == Kind.NOISE:
        name = "noise"
        summary = v.raw[:32].hex(" ") + (" …" if len(v.raw) > 32 else "")
    text.append(_fit(short_name(name, cols.name), cols.name), styles.get(state or "name"))
    text.append(" " + latency_text(latency).rjust(cols.latency - 1), styles.get("dim"))
    text.append(" ")
    if v.flags & BAD_CHECK:
        text.append("BAD CHECK ", styles.get("check"))
    tags = flag_tags(v.flags | (answer.view.flags if answer is not None else 0))
    if tags:
        text.append(tags, styles.get("problem"))
    if v.status in (Status.TIMEOUT, Status.ORPHAN) and answer is None:
        text.append(STATUS_NAMES[v.status] + " ", styles.get(row_state(v)))
    text.append(plain(summary, 600), styles.get(state) if state in ("noise", "event") else None)
    text.truncate(cols.width, overflow="ellipsis")
    return text


# -- hex dump --------------------------------------------------------------------------------


def raw_span(span: tuple[int, int], ascii_mode: bool) -> tuple[int, int]:
    """A body span (unit byte at 0) as offsets in the raw frame. RTU frames hold the body
    as is; an ASCII frame holds ':' then two hex characters per body byte."""
    start, end = span
    if ascii_mode:
        return 1 + 2 * start, 1 + 2 * end
    return start, end


def bytes_per_line(width: int) -> int:
    """How many bytes a hex dump line of `width` cells holds (a multiple of 4): each
    line is the offset (5), three cells per byte, two spaces, one cell per byte."""
    fit = max(4, (width - 7) // 4)
    return min(32, fit - fit % 4)


def hex_dump(raw: bytes, highlight: tuple[int, int] | None, per_line: int, styles: Styles) -> Text:
    """Offset, hex and printable characters; bytes in `highlight` (raw offsets) stand out."""
    out = Text(no_wrap=True)
    mark = styles.get("highlight")
    offset_style = styles.get("offset")
    lo, hi = highlight if highlight is not None else (0, 0)
    if not raw:
        out.append("(no bytes)", styles.get("dim"))
        return out
    for start in range(0, len(raw), per_line):
        if start:
            out.append("\n")
        out.append(f"{start:04x} ", offset_style)
        chunk = raw[start : start + per_line]
        for k, b in enumerate(chunk):
            at = start + k
            out.append(" ")
            out.append(f"{b:02x}", mark if lo <= at < hi else None)
        out.append("   " * (per_line - len(chunk)) + "  ")
        for k, b in enumerate(chunk):
            at = start + k
            ch = chr(b) if 0x20 <= b < 0x7F else "·"
            out.append(ch, mark if lo <= at < hi else styles.get("dim"))
    return out


# -- registers -------------------------------------------------------------------------------


def register_text(r: RegisterValue) -> str:
    """`Under Voltage Trip = 300 V  [0x012C]`"""
    words = " ".join(f"0x{w:04X}" for w in r.raw[:8]) + (" …" if len(r.raw) > 8 else "")
    return plain(f"{r.text}  [{words}]" if words else r.text)


def register_label(r: RegisterValue, width: int) -> str:
    """`Under Voltage Trip = 300 V  [0x012C]` in `width` cells: the raw words go first,
    then the name is shortened (`Under Volt… = 300 V`); the value is never cut."""
    full = register_text(r)
    if len(full) <= width:
        return full
    head = r.name + " = "
    value = plain(r.text[len(head) :] if r.text.startswith(head) else r.text)
    name = plain(r.name)
    room = width - len(value) - 3
    if room >= len(name):
        return f"{name} = {value}"
    if room >= 4:
        return f"{name[: room - 1]}… = {value}"
    return value


def fit_words(text: str, width: int) -> str:
    """`text` in `width` cells: whole, or cut after the last whole word that fits and
    marked `…` (never `0x000` for `0x000D`); a first word too long is cut at the edge."""
    if len(text) <= width:
        return text
    if width <= 1:
        return "…"[:width]
    cut = text.rfind(" ", 0, width - 1)  # the word, a space and `…` fit
    if cut <= 0:
        return text[: width - 1] + "…"
    return text[:cut].rstrip(" :,;") + " …"


def sparkline(values: Sequence[float], width: int) -> str:
    """The last `width` values as block characters, scaled to their own range."""
    tail = list(values[-width:])
    if not tail:
        return ""
    low, high = min(tail), max(tail)
    if high == low:
        return SPARK[3] * len(tail)
    top = len(SPARK) - 1
    return "".join(SPARK[round((v - low) / (high - low) * top)] for v in tail)


def plot(points: Sequence[tuple[float, float]], width: int, height: int, styles: Styles) -> Text:
    """A plot of (t, value) points: each column spans the lowest to the highest value that
    fell in it (so no spike or sag between columns is lost) with its mean marked `━`;
    the range of values on the left, the time below."""
    out = Text(no_wrap=True)
    if not points or width < 16 or height < 3:
        out.append("(no values)", styles.get("dim"))
        return out
    values = [p[1] for p in points]
    low, high = min(values), max(values)
    label_w = max(len(_num(low)), len(_num(high))) + 1
    cols = max(4, width - label_w - 1)
    rows = max(1, height - 1)
    columns = plot_columns(points, cols)
    scale = (high - low) or 1.0

    def row_of(v: float) -> int:  # 0 is the top line
        if high == low:
            return rows // 2
        return rows - 1 - min(rows - 1, int((v - low) / scale * rows))

    cells = [[" "] * cols for _ in range(rows)]
    kinds = [[""] * cols for _ in range(rows)]
    for k, col in enumerate(columns):
        if col is None:
            continue
        lo_v, hi_v, mean = col
        top, bottom = row_of(hi_v), row_of(lo_v)
        for r in range(top, bottom + 1):
            cells[r][k], kinds[r][k] = "│" if top != bottom else "─", "plot"
        m = row_of(mean)
        cells[m][k], kinds[m][k] = "━", "mean"
    for r in range(rows):
        label = _num(high) if r == 0 else _num(low) if r == rows - 1 else ""
        out.append(label.rjust(label_w) + "│", styles.get("dim"))
        for k in range(cols):
            kind = kinds[r][k]
            out.append(cells[r][k], styles.get(kind) if kind else None)
        out.append("\n")
    t0, t1 = points[0][0], points[-1][0]
    span = t1 - t0
    axis = "0s".ljust(cols // 2) + f"+{span_text(span) if span >= 3600 else f'{span:.1f}s'}".rjust(
        cols - cols // 2
    )
    out.append(" " * label_w + "└" + axis, styles.get("dim"))
    return out


def plot_columns(
    points: Sequence[tuple[float, float]], cols: int
) -> list[tuple[float, float, float] | None]:
    """(min, max, mean) of the values that fall in each of `cols` equal time slices
    (None for a slice with none)."""
    t0, t1 = points[0][0], points[-1][0]
    span = (t1 - t0) or 1.0
    acc: list[list[float] | None] = [None] * cols
    for t, v in points:
        k = min(cols - 1, int((t - t0) / span * cols))
        a = acc[k]
        if a is None:
            acc[k] = [v, v, v, 1.0]
        else:
            a[0], a[1], a[2], a[3] = min(a[0], v), max(a[1], v), a[2] + v, a[3] + 1
    return [None if a is None else (a[0], a[1], a[2] / a[3]) for a in acc]


def _num(v: float) -> str:
    return f"{v:.6g}"
