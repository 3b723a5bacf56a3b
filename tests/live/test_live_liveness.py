"""Liveness on a live virtual line: the master polls, then stops. With no new frame,
only the clock moving, `live --stats` goes from a live line and an answering unit to an
idle line and a silent unit, and so does the unit status `live --mqtt` publishes (read
from a real Mosquitto broker); a `LiveCapture`'s clock is the one its stamps come from."""

from __future__ import annotations

import json
import re
import shutil
import signal
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from sniffer.analysis.liveness import LineState, UnitState, liveness
from sniffer.live.engine import LiveCapture
from sniffer.live.port import LiveReader, PortSpec
from sniffer.session.session import Session
from tests.live.test_live import LINE, LINE_ARGS, MODSCOPE, answer, pump_until, req
from tests.outputs.test_mqtt_live import Reader, broker
from tests.support.broker import Broker
from tests.support.virtual_bus import VirtualBus, wait_ready

PERIOD = 0.1  # seconds between the master's polls
POLLS = 15
LONG_POLLS = 70  # 7 s of polling


@pytest.fixture
def bus(tmp_path: Path) -> Iterator[VirtualBus]:
    with VirtualBus(tmp_path) as b:
        yield b


def poll(bus: VirtualBus, polls: int = POLLS) -> None:
    """A master reading unit 1 every PERIOD (a slave answering at once), then stopping."""
    for _ in range(polls):
        bus.inject(req(1, 3, 0, 2), source="master")
        time.sleep(0.01)
        bus.inject(answer(1, 3, [7, 8]), source="master")
        time.sleep(PERIOD - 0.01)


def blocks(text: str) -> list[list[str]]:
    """The liveness blocks of --stats output: each `line:` line and the lines under it."""
    out: list[list[str]] = []
    for line in text.splitlines():
        if line.startswith("line: "):
            out.append([line])
        elif out and line.startswith("  unit "):
            out[-1].append(line)
    return out


def test_live_stats_turn_idle_and_silent_from_the_clock(bus: VirtualBus) -> None:
    tap = bus.attach("tap")
    bus.attach("master")
    proc = subprocess.Popen(
        [MODSCOPE, "live", str(tap), *LINE_ARGS, "--stats", "0.5", "--format", "jsonl"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stderr is not None and proc.stdout is not None
        wait_ready(proc.stderr)
        got: list[str] = []
        reader = threading.Thread(target=lambda: got.extend(proc.stderr or []), daemon=True)
        reader.start()
        poll(bus)
        deadline = time.monotonic() + 20
        # wait, sending nothing, until a block says the line is idle
        while time.monotonic() < deadline and not any(
            b[0].startswith("line: idle") for b in blocks("".join(got))
        ):
            time.sleep(0.2)
    finally:
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=10)
        reader.join(5)
    assert proc.returncode == 0, "".join(got)
    found = blocks("".join(got))
    live = [b for b in found if b[0].startswith("line: live")]
    idle = [b for b in found if b[0].startswith("line: idle")]
    assert live and idle, "".join(got)
    assert "  unit 1: ok, last answer " in live[0][1]
    # the period is the master's own (100 ms): idle after its 2 s floor, here
    assert "(idle after 2.0s: 3 x its period)" in idle[0][0]
    assert idle[0][1].startswith("  unit 1: silent, last answer ")
    period = re.search(r", period (\d+)ms, silent after 2\.0s$", idle[0][1])
    assert period is not None, idle[0][1]
    assert PERIOD * 1000 <= int(period.group(1)) < 2 * PERIOD * 1000  # its sleeps, measured
    # the frames listed: requests and answers, nothing after the master stopped
    assert out.count('"kind": "request"') == POLLS


def test_a_capture_measures_ages_to_its_ports_clock(bus: VirtualBus) -> None:
    tap = bus.attach("tap")
    bus.attach("master")
    session = Session(LINE, timeout=0.15)
    capture = LiveCapture(LiveReader([PortSpec(str(tap), LINE)]), session)
    capture.start()
    try:
        poll(bus, 5)
        pump_until(capture, lambda: len(session.store) >= 10)
        session.stats.update()
        store = session.store
        last = store.t_end[len(store) - 1]
        answered = {1: last}
        before = capture.now()
        assert before >= last  # the stamps and now() read one clock
        first = liveness(session.stats.units.values(), answered, before, store.resolution)
        # nothing more on the line: only the clock moves
        end = time.monotonic() + 10
        later = first
        while later.state is not LineState.IDLE and time.monotonic() < end:
            capture.pump(0.1)
            later = liveness(
                session.stats.units.values(), answered, capture.now(), store.resolution
            )
    finally:
        capture.stop()
    assert len(session.store) == 10  # no new frame
    assert first.state is LineState.LIVE and first.units[0].state is UnitState.OK
    assert later.state is LineState.IDLE and later.units[0].state is UnitState.SILENT
    assert later.since_frame is not None and later.idle_after is not None
    assert later.since_frame > later.idle_after


__all__ = ["broker"]  # the Mosquitto fixture of the MQTT tests


@pytest.mark.slow
@pytest.mark.peer
@pytest.mark.skipif(shutil.which("mosquitto") is None, reason="apt-get install mosquitto")
def test_the_published_unit_status_falls_silent_from_the_clock(
    bus: VirtualBus, broker: Broker
) -> None:
    tap = bus.attach("tap")
    bus.attach("master")
    topic = "modscope/tap/unit/1/status"
    reader = Reader(broker.port, topic)
    url = f"mqtt://127.0.0.1:{broker.port}"
    # subscribed before modscope starts: its first status comes with the first answer
    ready = time.monotonic() + 10
    while not reader.client.is_connected() and time.monotonic() < ready:
        time.sleep(0.05)
    time.sleep(0.5)  # (the subscription is acknowledged after the connection)
    proc = subprocess.Popen(
        [MODSCOPE, "live", str(tap), *LINE_ARGS, "--format", "jsonl", "--mqtt", url],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stderr is not None
        wait_ready(proc.stderr)
        # a status goes out every 5 s of the capture's clock: poll across one
        poll(bus, LONG_POLLS)

        def silent() -> bool:
            return any(json.loads(p)["state"] == "silent" for p in reader.on(topic))

        deadline = time.monotonic() + 30  # a status every 5 s of the capture's clock
        while not silent() and time.monotonic() < deadline:
            time.sleep(0.2)
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
        reader.close()
    assert proc.returncode == 0, err
    statuses = [json.loads(p) for p in reader.on(topic)]
    online = [s for s in statuses if s["state"] == "online"]
    gone = [s for s in statuses if s["state"] == "silent"]
    assert online and gone, statuses
    last = gone[0]
    # nothing new on the line: the counts stand, only the ages grew
    assert (last["requests"], last["answers"]) == (LONG_POLLS, LONG_POLLS)
    assert last["since_answer_s"] > last["silent_after_s"] == 2.0
    assert last["since_frame_s"] >= last["since_answer_s"] - 0.05
    assert last["t"] - last["last_answer"] == pytest.approx(last["since_answer_s"], abs=0.01)
    # while it was polled: online, its threshold from its own period (3 x 100 ms is
    # under the 2 s floor)
    polled = [s for s in online if s["silent_after_s"] is not None]
    assert polled, statuses
    assert polled[-1]["silent_after_s"] == 2.0 and polled[-1]["since_answer_s"] <= 2.0
    assert polled[-1]["requests"] < LONG_POLLS
