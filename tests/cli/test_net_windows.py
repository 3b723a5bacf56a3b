"""Network captures are read a window of rows at a time too (issue #29): `replay
--stats` (with the per-server table), the listings and the exports keep a window of
rows, dropped at a moment when no request waits for an answer, nor for a late one
(`NetPairer.settled`). What they print must be what one store of every row gives,
byte for byte, on random traffic of several connections (tests/support/netbus:
answers out of order, timeouts, late answers and answers too late to pair, ids reused,
split requests, noise, RTU over TCP), whatever the window; and the rows kept must not
grow with the capture. A sidecar of one store, read back a block at a time, hands on no
request without its answer (`sniffer.session.index.load`), or the per-server latencies
would lose those that span its blocks."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sniffer.framing.tcp import LATE_WAITS, TCP_TIMEOUT
from sniffer.session import index
from sniffer.session.session import open_session
from sniffer.vocab import Flag, Kind, Status
from tests.cli import test_tables_streamed as tables
from tests.cli.test_listing_streamed import Kept, _one_by_one, _same
from tests.session.test_replay_window import replayed
from tests.support.netbus import STEPS, network_bus

__all__ = ["_one_by_one"]  # (reads one by one, cuts counted: test_listing_streamed)

STEP_LISTS = st.lists(st.tuples(st.integers(0, 2), st.sampled_from(STEPS)), max_size=40)


def _capture(folder: Path, steps: list[tuple[int, str]], seed: int = 0) -> str:
    path = folder / "net.pcap"
    path.write_bytes(network_bus(steps, seed))
    return str(path)


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(steps=STEP_LISTS, seed=st.integers(0, 1 << 16), window=st.integers(1, 6))
def test_random_network_traffic_alike_in_windows(
    tmp_path_factory: pytest.TempPathFactory,
    monkeypatch: pytest.MonkeyPatch,
    steps: list[tuple[int, str]],
    seed: int,
    window: int,
) -> None:
    folder = tmp_path_factory.mktemp("net")
    path = _capture(folder, steps, seed)
    assert replayed([path], window) == replayed([path], None)
    _same([path, "--format", "jsonl"], monkeypatch, [(window, window)])
    tables._same([path], "transactions", "csv", folder, monkeypatch, [(window, window + 2)])


def test_the_rows_kept_do_not_grow_with_a_network_capture(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Polls on three connections for 75 s, a timeout now and then: cut about once a
    window, but while a request that timed out may still get its late answer (9 s), so
    each store holds at most about the rows of that wait (180 a connection), not every
    row of the capture."""
    steps = [(k % 3, "timeout" if k % 300 == 10 else "poll") for k in range(1500)]
    path = _capture(tmp_path, steps)
    whole = replayed([path], None)
    late_wait = round(LATE_WAITS * TCP_TIMEOUT / 0.05) * 2  # rows of the wait: 2 a step
    Kept.rows = Kept.cuts = 0
    assert replayed([path], 40) == whole
    assert Kept.cuts > 25
    assert Kept.rows < late_wait + 100  # of 3,000 rows
    Kept.rows = Kept.cuts = 0
    _same([path, "--format", "text"], monkeypatch, [(40, 40)])
    assert Kept.cuts > 50 and Kept.rows < late_wait + 100


def test_a_late_answer_pairs_and_one_past_the_late_wait_is_an_orphan(tmp_path: Path) -> None:
    path = _capture(tmp_path, [(0, "late"), (0, "too_late"), (0, "poll")])
    session, capture = open_session(path, index=False)
    session.ingest(capture.chunks())
    store = session.store
    requests = [i for i in range(len(store)) if store.kind[i] == Kind.REQUEST]
    answers = [i for i in range(len(store)) if store.kind[i] == Kind.RESPONSE]
    late, too_late, poll = requests
    assert store.status[late] == Status.OK and store.flags[store.partner[late]] & Flag.LATE
    assert store.status[too_late] == Status.TIMEOUT
    orphan = [i for i in answers if store.status[i] == Status.ORPHAN]
    assert len(orphan) == 1
    assert store.t[orphan[0]] - store.t_end[too_late] > LATE_WAITS * TCP_TIMEOUT
    assert store.status[poll] == Status.OK


def test_a_sidecar_of_one_store_read_back_in_blocks_cuts_no_pair(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The sidecar of a whole store (written by an ingest with no window) has blocks of
    `BLOCK` rows, ending between a request and its answer; `--stats` reads it back a
    block at a time and must print the latencies framing gives."""
    monkeypatch.setattr(index, "MIN_SIZE", 0)
    monkeypatch.setattr(index, "BLOCK", 7)  # (odd: blocks cut pairs)
    path = _capture(tmp_path, [(k % 3, "poll") for k in range(120)])
    whole = replayed([path], None)
    monkeypatch.delenv("MODSCOPE_NO_INDEX")
    session, capture = open_session(path)
    session.ingest(capture.chunks())  # one store, its sidecar written in blocks of 7
    side = Path(path + index.SUFFIX)
    assert side.exists()
    Kept.cuts = 0
    read_back = replayed([path], 5)
    assert Kept.cuts == 0  # (read back: nothing framed, no segment cut)
    assert read_back == whole
    assert "per server and unit" in read_back[0]
    again, capture = open_session(path)  # read back whole, as the TUI reads it
    again.ingest(capture.chunks())
    assert again.indexed_from is not None
    assert (again.store.peers, again.store.servers) == (session.store.peers, session.store.servers)
    assert again.store.servers[5] == "192.168.1.40:4001"
