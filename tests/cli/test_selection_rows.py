"""The rows `--filter` and `-c` hand a listing: the same rows as before, in order, and,
with no filter, without a list of every row's number (it cost about 40 bytes a row: 115 MB
through the export of 3M rows)."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

from sniffer.cli.filtering import Selection
from sniffer.meaning.query import parse_query
from sniffer.session.session import replay_file

DEMO = Path(__file__).resolve().parents[2] / "captures" / "demo.pcapng"


def test_unfiltered_rows_are_handed_out_in_order_without_a_list_of_them() -> None:
    session = replay_file(DEMO)
    selection = Selection(session, None, None)
    tracemalloc.start()
    try:
        first = selection.take(600_000)
        second = selection.take(1_000_000)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 64_000  # a list of 1M row numbers is about 40 MB
    assert list(first) == list(range(600_000))
    assert list(second) == list(range(600_000, 1_000_000))
    assert list(selection.take(1_000_000)) == []


def test_a_count_cuts_the_rows_and_ends_the_selection() -> None:
    session = replay_file(DEMO)
    selection = Selection(session, None, 5)
    assert list(selection.take(3)) == [0, 1, 2]
    assert list(selection.take(len(session.store))) == [3, 4]
    assert selection.done
    assert list(selection.take(len(session.store))) == []


def test_filtered_rows_are_the_matches_in_order_cut_by_the_count() -> None:
    session = replay_file(DEMO)
    store = session.store
    wanted = [i for i in range(len(store)) if store.unit[i] == 1]
    assert len(wanted) > 3
    selection = Selection(session, parse_query("unit:1"), len(wanted) - 1)
    rows = selection.take(len(store), final=True)
    assert list(rows) == wanted[:-1]
    assert selection.done
