"""What the timing can back: each source's stamp resolution is measured from its stamps,
and no latency, timeout verdict, poll period or gap is shown finer than it; a bound is
never exceeded by the true latency, even from a loaded machine's late reads."""

from __future__ import annotations

import io
import json
import random
import re
from pathlib import Path
from typing import Any

import pytest

from dissectors.checks import with_crc
from sniffer.analysis.pollcycle import cycle_table, poll_cycles
from sniffer.framing.pairing import clock_step, measure
from sniffer.model import Chunk, LineSettings, Stamp
from sniffer.outputs.listing import Lister
from sniffer.session.session import Session, replay_file
from sniffer.vocab import Flag, Kind, Status

LOGS = Path(__file__).parent.parent / "captures" / "logs"
LINE = LineSettings(baud=19200, parity="E", mode="rtu")
REQ = with_crc(bytes.fromhex("010300000002"))
ANS = with_crc(bytes.fromhex("010304000a000d"))


def jsonl(session: Session) -> list[dict[str, Any]]:
    out = io.StringIO()
    Lister(out, "jsonl", session.describer).write(range(len(session.store)))
    return [json.loads(line) for line in out.getvalue().splitlines()]


def text(session: Session) -> str:
    out = io.StringIO()
    Lister(out, "text", session.describer).write(range(len(session.store)))
    return out.getvalue()


# -- a clock that ticks once a second ------------------------------------------------------


def test_a_log_stamped_to_the_second_shows_nothing_finer_than_a_second() -> None:
    # a serial monitor printing whole seconds: several polls a second, some answers
    # printed in the next second (as CAS Modbus Scanner and evcc traces show them)
    session = replay_file(LOGS / "monitor_seconds.log")
    store = session.store
    assert store.stamps is Stamp.PRINT and store.resolution == 1.0
    rows = jsonl(session)
    answers = [r for r in rows if r["kind"] == "response"]
    assert len(answers) == 34
    for r in rows:
        transaction = r["transaction"]
        # a 1 s clock cannot show a 347 ms timeout: no request timed out by it, no
        # answer called late
        assert transaction["status"] == "ok", r
        assert all(p["kind"] != "late" for p in r.get("problem_details", ())), r
        # print times bound the latency: never a value, and no bound finer than 1 s
        assert transaction["latency_ms"] is None, r
        bound = transaction["latency_max_ms"]
        if r["kind"] == "response":
            assert bound in (1000.0, 2000.0), r
    assert not any(f & Flag.LATE for f in store.flags)
    # said once: the listing's first line, the first JSONL row, --stats
    listing = text(session)
    assert listing.startswith("# timing: when each line was logged, resolution 1 s")
    assert "came after the response timeout" not in listing
    assert set(re.findall(r" (<?\d+(?:\.\d+)?m?s)  ", listing)) <= {"<1s", "<2s"}
    assert "resolution 1 s" in rows[0]["timing_note"]
    assert all("timing_note" not in r for r in rows[1:])
    assert "resolution 1 s" in session.stats.timing_line()


def test_periods_and_gaps_of_a_second_clock_are_no_finer_than_a_second() -> None:
    session = replay_file(LOGS / "monitor_seconds.log")
    table = session.stats.table()
    periods = [line.split()[-1] for line in table.splitlines()[2:4]]
    assert periods == ["<2s", "<2s"]  # not the 5 ms the squeezed print times give
    cycles = poll_cycles(session.store)
    for cycle in cycles.values():
        assert not cycle.gaps  # a second's wait between prints is no gap in the polling
        for poll in cycle.polls:
            assert poll.period_bound and poll.period >= 1.0
            assert poll.jitter_bound and poll.jitter >= 1.0
    shown = cycle_table(cycles)
    assert "ms" not in shown and "gap at" not in shown


def test_a_log_printing_zero_milliseconds_has_a_one_second_clock(tmp_path: Path) -> None:
    # `.000` on every line: the fraction digits are there, the clock is not
    lines = ["Modbus poll log, COM4 19200 8E1"]
    for k in range(12):
        lines += [
            f"12:34:{10 + k:02d}.000 TX: 01 03 00 00 00 02 C4 0B",
            f"12:34:{10 + k:02d}.000 RX: 01 03 04 00 0A 00 0D 1B F4",
        ]
    path = tmp_path / "poll.log"
    path.write_bytes(("\n".join(lines) + "\n").encode())
    session = replay_file(path)
    assert session.pipeline.clock.declared == pytest.approx(1e-3)  # what the digits say
    assert session.pipeline.clock.step == 1.0
    assert session.store.resolution == 1.0
    # measured, and said once; stamps that coarse are not "faster than the baud rate"
    assert any("every stamp is a whole multiple of 1 s" in n for n in session.notes)
    assert not [w for w in session.warnings if w.startswith("timestamps")]
    assert {
        r["transaction"]["latency_max_ms"] for r in jsonl(session) if r["kind"] == "response"
    } == {1000.0}


def test_esphome_prints_sends_late_so_its_times_bound_nothing() -> None:
    session = replay_file(LOGS / "esphome_hex_seconds.log")
    assert session.store.resolution == float("inf")
    for r in jsonl(session):
        assert r["transaction"]["latency_ms"] is None
        assert r["transaction"]["latency_max_ms"] is None
        assert r["transaction"]["status"] == "ok"
    assert "ESPHome prints what it sent" in session.stats.timing_line()
    assert any("ESPHome" in n for n in session.notes)


# -- host reads of a USB adapter on a loaded machine ----------------------------------------


def loaded_reads(
    seed: int, latency_timer: float, late_mean: float, late_most: float
) -> tuple[list[Chunk], list[float]]:
    """A master polling three units, as a host reads it through a USB adapter: the
    adapter hands bytes over `latency_timer` after the first byte it holds, and the
    loaded machine wakes its reader up to `late_most` later (exponential, mean
    `late_mean`), which then takes all that arrived. The reads, and each answer's true
    latency (end of request to start of answer)."""
    rng = random.Random(seed)
    char = LINE.char_time
    t = 1_700_000_000.0
    arrivals: list[tuple[float, int]] = []
    truth = []
    for k in range(400):
        unit = 1 + k % 3
        request = with_crc(bytes([unit, 3, 0, 0, 0, 2]))
        answer = with_crc(bytes([unit, 3, 4, 0, 1, 0, 2]))
        arrivals += [(t + (i + 1) * char, b) for i, b in enumerate(request)]
        latency = rng.uniform(0.002, 0.04)
        start = t + len(request) * char + latency
        arrivals += [(start + (i + 1) * char, b) for i, b in enumerate(answer)]
        truth.append(latency)
        t = start + len(answer) * char + rng.uniform(0.01, 0.12)
    packets: list[tuple[float, bytearray]] = []
    for at, byte in arrivals:
        if not packets or at > packets[-1][0]:
            packets.append((at + latency_timer, bytearray()))
        packets[-1][1].append(byte)
    reads: list[Chunk] = []
    woke = 0.0
    k = 0
    while k < len(packets):
        late = min(late_most, rng.expovariate(1 / late_mean)) if late_mean else 0.0
        woke = max(woke, packets[k][0] + late)
        data = bytearray()
        while k < len(packets) and packets[k][0] <= woke:
            data += packets[k][1]
            k += 1
        reads.append(Chunk(bytes(data), woke))
    return reads, truth


@pytest.mark.parametrize(
    ("latency_timer", "late_mean", "late_most"),
    [(0.016, 0.0, 0.0), (0.016, 0.003, 0.012), (0.016, 0.008, 0.03), (0.001, 0.002, 0.01)],
)
@pytest.mark.parametrize("seed", range(3))
def test_a_host_read_bound_holds_on_a_loaded_machine(
    seed: int, latency_timer: float, late_mean: float, late_most: float
) -> None:
    reads, truth = loaded_reads(seed, latency_timer, late_mean, late_most)
    session = Session(LINE, stamps=Stamp.READ_END)
    session.ingest(reads)
    store = session.store
    answers = [i for i in range(len(store)) if store.kind[i] == Kind.RESPONSE]
    assert len(answers) == len(truth)
    assert all(store.status[i] == Status.OK for i in answers)
    # the resolution allows for the reader's lateness, measured from its reads
    clock = session.pipeline.clock
    assert store.resolution >= clock.read_quantum + clock.read_delay > 0
    for i, latency in zip(answers, truth, strict=True):
        told = measure(store, i)
        assert told is not None
        if told.bound:
            assert latency < told.seconds, (i, latency, told)
        else:  # a value, good to the resolution
            assert abs(told.seconds - latency) <= store.resolution, (i, latency, told)
        assert told.seconds > 0


def test_a_clock_step_is_a_whole_multiple_not_a_share_of_one() -> None:
    """Microsecond capture times 30 µs past each tenth of a second are microsecond
    times: a tolerance of a share of the step would call them a 0.1 s clock (and every
    latency then a bound of 100 ms)."""
    epoch = 1_750_000_000.0
    tenths = [epoch + 0.1 * k for k in range(10)]
    assert clock_step(tenths) == pytest.approx(0.1)
    assert clock_step(tenths + [t + 0.00003 for t in tenths]) < 1e-3
    # a log printing milliseconds at epoch scale keeps its millisecond step
    assert clock_step([epoch + k + 0.123 * (k % 3) for k in range(20)]) == pytest.approx(1e-3)
    # and so do times counted from the start of a capture
    assert clock_step([k * 0.25 for k in range(20)]) == pytest.approx(0.01)
