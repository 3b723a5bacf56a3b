"""The DuckDB queries of docs/analytics.md, run on the demo's Parquet export, give the
numbers `modscope replay --stats` (the Stats object) gives."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from sniffer.framing.pairing import shown_step
from sniffer.meaning.annotate import load_bindings
from sniffer.outputs.parquet import write_parquet
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, replay_file

duckdb = pytest.importorskip("duckdb")
pytest.importorskip("pyarrow")


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> tuple[Session, Path]:
    folder = tmp_path_factory.mktemp("parquet")
    session = replay_file(DEMO_CAPTURE, bindings=load_bindings(DEMO_BUS))
    rows = range(len(session.store))
    for what in ("frames", "transactions", "registers"):
        write_parquet(folder / f"{what}.parquet", what, session.describer, rows, row_group=500)
    return session, folder


def _sql(folder: Path, query: str) -> list[tuple[Any, ...]]:
    con = duckdb.connect()
    con.execute(f"SET file_search_path = '{folder}'")
    rows: list[tuple[Any, ...]] = con.execute(query).fetchall()
    return rows


# the queries exactly as docs/analytics.md prints them
LATENCY = """
SELECT unit,
       date_trunc('hour', time) AS hour,
       count(latency_ms) AS answers,
       list_sort(list(latency_ms))[round_even(0.5 * (count(latency_ms) - 1), 0)::INT + 1]
         AS median_ms,
       list_sort(list(latency_ms))[round_even(0.95 * (count(latency_ms) - 1), 0)::INT + 1]
         AS p95_ms,
       max(latency_ms) AS max_ms
FROM 'transactions.parquet'
WHERE latency_ms IS NOT NULL AND answer_check_ok
GROUP BY unit, hour
ORDER BY unit, hour
"""
REGISTER_DAY = """
SELECT time, value, value_unit
FROM 'registers.parquet'
WHERE unit = 2 AND name = 'Voltage' AND access = 'read'
  AND time >= TIMESTAMPTZ '2026-01-15 00:00:00+00' AND time < TIMESTAMPTZ '2026-01-16 00:00:00+00'
ORDER BY time
"""
EXCEPTIONS = """
SELECT unit, exception_code, count(*) AS answers
FROM 'transactions.parquet'
WHERE exception_code IS NOT NULL
GROUP BY unit, exception_code
ORDER BY unit, exception_code
"""
SLOWEST = """
SELECT request, time, unit, device, name, latency_ms
FROM 'transactions.parquet'
WHERE latency_ms IS NOT NULL AND answer_check_ok
ORDER BY latency_ms DESC
LIMIT 10
"""
UNANSWERED = """
SELECT unit, count(*) AS unanswered, min(time) AS first, max(time) AS last
FROM 'transactions.parquet'
WHERE status = 'timeout'
GROUP BY unit
ORDER BY unit
"""


def test_latency_percentiles_per_unit_per_hour(demo: tuple[Session, Path]) -> None:
    session, folder = demo
    found = _sql(folder, LATENCY)
    stats = session.stats.units
    expected = [
        (u, stats[u].latencies and len(stats[u].latencies), stats[u].latency_ms(0.5),
         stats[u].latency_ms(0.95), stats[u].latency_ms(1))
        for u in sorted(stats) if stats[u].latencies
    ]  # fmt: skip
    assert len({row[1] for row in found}) == 1  # the demo is one minute: one hour
    got = [(row[0], row[2], row[3], row[4], row[5]) for row in found]
    assert [g[:2] for g in got] == [e[:2] for e in expected]
    step = shown_step(session.store.resolution) * 1000  # what the stamps hold, in ms
    for g, e in zip(got, expected, strict=True):
        for a, b in zip(g[2:], e[2:], strict=True):
            # the table gives each latency to what the stamps hold, the statistics the
            # difference of the row times it was rounded from
            assert a == pytest.approx(b, abs=step / 2 + 5e-4)


def test_every_value_of_a_register_over_a_day(demo: tuple[Session, Path]) -> None:
    session, folder = demo
    found = _sql(folder, REGISTER_DAY)
    expected = [
        r.value
        for i in range(len(session.store))
        if session.store.unit[i] == 2 and session.store.kind[i] == 2
        for r in session.describer.detail(i).registers
        if r.name == "Voltage"
    ]
    assert [row[1] for row in found] == expected and len(expected) > 100
    assert {row[2] for row in found} == {"V"}


def test_exceptions_by_code(demo: tuple[Session, Path]) -> None:
    session, folder = demo
    expected = [
        (u, code, n)
        for u, st in sorted(session.stats.units.items())
        for code, n in sorted(st.exceptions.items())
    ]
    assert _sql(folder, EXCEPTIONS) == expected == [(3, 2, 5), (3, 3, 1)]


def test_slowest_transactions(demo: tuple[Session, Path]) -> None:
    session, folder = demo
    found = _sql(folder, SLOWEST)
    worst = max(max(st.latencies) for st in session.stats.units.values() if st.latencies)
    step = shown_step(session.store.resolution) * 1000
    assert found[0][5] == pytest.approx(worst * 1000, abs=step / 2 + 5e-4)
    assert [row[5] for row in found] == sorted((row[5] for row in found), reverse=True)
    assert session.store.partner[found[0][0]] >= 0


def test_requests_never_answered(demo: tuple[Session, Path]) -> None:
    session, folder = demo
    found = {row[0]: row[1] for row in _sql(folder, UNANSWERED)}
    expected = {u: st.timeouts for u, st in session.stats.units.items() if st.timeouts}
    assert found == expected == {4: 12}


def test_frames_table_counts_every_row(demo: tuple[Session, Path]) -> None:
    session, folder = demo
    kinds = {
        str(r[0]): int(str(r[1]))
        for r in _sql(folder, "SELECT kind, count(*) FROM 'frames.parquet' GROUP BY kind")
    }
    assert sum(kinds.values()) == len(session.store)
    assert kinds["noise"] == session.stats.noise_spans
    types = {str(r[0]): r[1] for r in _sql(folder, "DESCRIBE SELECT * FROM 'frames.parquet'")}
    assert types["time"] == "TIMESTAMP WITH TIME ZONE" and types["unit"] == "UTINYINT"
