"""Provides the bus doctor: a capture's rows turned into ranked findings (what is wrong with
this bus, for whom, the evidence and what to check next).

Each finding has a stable `kind` (part of the interface: JSON, MQTT, the TUI pane), a
severity (`error`, `warning`, `info`), the units it concerns, a one-line summary, what it
means on site, its evidence (counts, times, rows and a short excerpt of the frames) and
advice. `diagnose` reads only the store's columns and bytes; it never imports `meaning`.
What a dictionary documents (a response time) comes in as plain numbers.

Every time a finding states is backed by the row times as far as they vouch for it:
latencies only where `pairing.measure` gives a value (bounds are never taken for
values), timing violations only where the stamps are exact, line load only where the
stamps are times at all. docs/doctor.md says how each finding is detected and its limits.
"""

from __future__ import annotations

from collections.abc import Mapping

from sniffer.analysis.doctor.finding import (
    KINDS,
    RANK,
    Diagnosis,
    Finding,
    finding_lines,
    report,
    response_bounds,
)
from sniffer.analysis.doctor.line import (
    address_conflicts,
    errors_follow_station,
    line_overload,
    timing_violations,
    two_masters,
    wrong_settings,
)
from sniffer.analysis.doctor.rows import look_at, timing_notes
from sniffer.analysis.doctor.units import (
    exception_polls,
    intermittent_units,
    silent_units,
    slow_answers,
    write_effects,
)
from sniffer.framing.store import FrameStore
from sniffer.model import LineSettings

__all__ = [
    "KINDS",
    "Diagnosis",
    "Finding",
    "diagnose",
    "finding_lines",
    "report",
    "response_bounds",
]


def diagnose(
    store: FrameStore,
    line: LineSettings,
    timeout: float,
    bounds: Mapping[int, float] | None = None,
    rows: int | None = None,
) -> Diagnosis:
    """The findings on a paired store, ranked: what to fix first comes first.
    `bounds`: unit -> the response time (s) its dictionary documents.
    `rows`: look at the first `rows` rows only, and leave the store as it is (a store
    another thread fills: the TUI's health pane); by default every row."""
    if rows is None:
        store.sync()
        rows = len(store)
    # (a store being filled: only the rows every column already holds)
    n = min(rows, len(store.t), len(store.flags), len(store.status), len(store.partner))
    look = look_at(store, line, timeout, n)
    said = timing_notes(store)
    settings = wrong_settings(look)
    if settings is not None:  # every other finding would be read from misframed bytes
        return Diagnosis((settings,), said)
    found: list[Finding] = []
    masters = two_masters(look)
    cut = set(masters[1]) if masters else set()  # the first master's requests cut short
    if masters:
        found.append(masters[0])
    conflicts = address_conflicts(look)
    found += conflicts
    conflicted = {u for f in conflicts for u in f.units}
    silent = silent_units(look)
    found += silent
    quiet = {u for f in silent for u in f.units}
    found += intermittent_units(look, quiet | conflicted, cut)
    found += errors_follow_station(look, conflicted)
    found += slow_answers(look, bounds or {}, conflicted)
    found += exception_polls(look)
    found += line_overload(look)
    found += timing_violations(look, set(masters[2]) if masters else set())
    found += write_effects(look)
    ranked = sorted(found, key=lambda f: (RANK[f.severity], KINDS.index(f.kind), f.units))
    return Diagnosis(tuple(ranked), said)
