"""Provides the units panel: per-unit requests, answers, exceptions, timeouts, check errors,
latency median and p95, last seen; units that stopped answering stand out."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from rich.style import Style
from rich.text import Text
from textual.widgets import DataTable

from sniffer.stats import UnitStats
from sniffer.text import plain
from sniffer.tui.render import ago_text, fit_columns

# fixed widths: columns that grew with whatever was shown first would jump about
COLUMNS = (
    ("unit", 4),
    ("device", 16),
    ("state", 6),
    ("req", 7),
    ("ans", 7),
    ("exc", 5),
    ("t/o", 5),
    ("chk", 5),
    ("median", 7),
    ("p95", 7),
    ("seen", 10),
)
# what stays when the pane is narrow, most important first
PRIORITY = ("unit", "state", "seen", "exc", "t/o", "chk", "median", "p95", "ans", "req", "device")
SILENT_AFTER = 2.0  # seconds without an answer, at least, before a polled unit is silent


@dataclass(frozen=True, slots=True)
class UnitRow:
    unit: int
    label: str
    requests: int
    answers: int
    exceptions: int
    timeouts: int
    check_errors: int
    median_ms: float | None
    p95_ms: float | None
    last_seen: float
    last_answer: float | None
    silent: bool


Cache = dict[tuple[int, str], tuple[int, float | None, float | None]]


def latency_quantiles(st: UnitStats, cache: Cache) -> tuple[float | None, float | None]:
    """Median and p95 latency in ms (one sort, redone only when there are new answers)."""
    n = len(st.latencies)
    found = cache.get((st.unit, "latency"))
    if found is not None and found[0] == n:
        return found[1], found[2]
    median = p95 = None
    if n:
        ordered = sorted(st.latencies)
        median = ordered[min(n - 1, round(0.5 * (n - 1)))] * 1000
        p95 = ordered[min(n - 1, round(0.95 * (n - 1)))] * 1000
    cache[(st.unit, "latency")] = (n, median, p95)
    return median, p95


def polling_period(st: UnitStats, cache: Cache) -> float | None:
    """Median seconds between requests (redone only when there are new requests)."""
    n = len(st.request_times)
    found = cache.get((st.unit, "period"))
    if found is not None and found[0] == n:
        return found[1]
    period = st.polling_period()
    cache[(st.unit, "period")] = (n, period, None)
    return period


def unit_rows(
    units: list[UnitStats],
    labels: dict[int, str],
    last_answer: dict[int, float],
    now: float,
    cache: Cache | None = None,
) -> list[UnitRow]:
    """The panel's rows. A unit is silent when it is polled but has not answered for
    five polling periods (at least SILENT_AFTER seconds), or never answered."""
    out = []
    cache = cache if cache is not None else {}
    for st in sorted(units, key=lambda s: s.unit):
        median, p95 = latency_quantiles(st, cache)
        answered = last_answer.get(st.unit)
        period = polling_period(st, cache) or 1.0
        quiet = now - answered if answered is not None else None
        silent = st.requests > 0 and (
            answered is None or (quiet is not None and quiet > max(SILENT_AFTER, 5 * period))
        )
        out.append(
            UnitRow(
                st.unit,
                labels.get(st.unit, ""),
                st.requests,
                st.responses,
                st.exception_count,
                st.timeouts,
                st.check_errors,
                median,
                p95,
                st.last_seen,
                answered,
                silent,
            )
        )
    return out


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v:.1f}"


class UnitsPanel(DataTable[Text]):
    """The per-unit table (refreshed by the app while it is shown)."""

    COMPONENT_CLASSES: ClassVar[set[str]] = {"units-panel--silent", "units-panel--bad"}

    def on_mount(self) -> None:
        self.cursor_type = "row"
        self.zebra_stripes = True
        self.shown: list[str] = []
        self.last: tuple[list[UnitRow], float] = ([], 0.0)
        self._columns(fit_columns(COLUMNS, PRIORITY, 200))

    def _columns(self, names: list[str]) -> None:
        self.clear(columns=True)
        self.shown = names
        widths = dict(COLUMNS)
        for name in names:
            self.add_column(
                Text(name, justify="left" if name in ("device", "state") else "right"),
                key=name,
                width=widths[name],
            )

    def on_resize(self) -> None:
        names = fit_columns(COLUMNS, PRIORITY, self.size.width - 1)
        if names != self.shown:
            self._columns(names)
            self.show(*self.last)

    def show(self, rows: list[UnitRow], now: float) -> None:
        self.last = (rows, now)
        silent = self.get_component_rich_style("units-panel--silent", partial=True)
        bad = self.get_component_rich_style("units-panel--bad", partial=True)
        keys = [str(r.unit) for r in rows]
        current = [str(k.value) for k in self.rows]
        names = [name for name, _ in COLUMNS]
        if keys != current:
            self.clear()
            for r in rows:
                cells = dict(zip(names, self._cells(r, now, silent, bad), strict=True))
                self.add_row(*(cells[n] for n in self.shown), key=str(r.unit))
            return
        for r in rows:
            for name, cell in zip(names, self._cells(r, now, silent, bad), strict=True):
                if name in self.shown:
                    self.update_cell(str(r.unit), name, cell)

    def _cells(self, r: UnitRow, now: float, silent: Style, bad: Style) -> list[Text]:
        def cell(value: str, style: Style | None = None, right: bool = True) -> Text:
            return Text(value, style=style or "", justify="right" if right else "left")

        row_style = silent if r.silent else None
        seen = ago_text(now - r.last_seen) + " ago" if r.last_seen else "-"
        return [
            cell(str(r.unit), row_style),
            cell(plain(r.label, 16), row_style, right=False),
            cell("SILENT" if r.silent else "ok", silent if r.silent else None, right=False),
            cell(str(r.requests)),
            cell(str(r.answers)),
            cell(str(r.exceptions), bad if r.exceptions else None),
            cell(str(r.timeouts), bad if r.timeouts else None),
            cell(str(r.check_errors), bad if r.check_errors else None),
            cell(_ms(r.median_ms)),
            cell(_ms(r.p95_ms)),
            cell(seen),
        ]
