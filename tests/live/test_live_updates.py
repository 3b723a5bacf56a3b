"""The live listing lists each frame once (issue 10): what is learnt later about a row
(its answer came, it timed out) is an update record naming the row and carrying no
`raw`. So `select(.raw)` of the live JSONL is the frames in order, and with each update
applied to its row it is byte for byte the replay of the recording made with -w (no
volatile field)."""

from __future__ import annotations

import io
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from dissectors.checks import with_crc
from sniffer.model import Chunk, LineSettings
from sniffer.outputs.listing import Lister
from sniffer.session.session import Session
from sniffer.text import json_line
from tests.support.live import applied
from tests.support.virtual_bus import VirtualBus, wait_ready

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
LINE = LineSettings(baud=19200, parity="N", stopbits=2, mode="rtu")
LINE_ARGS = ["--baud", "19200", "--parity", "N", "--stopbits", "2", "--timeout", "0.2"]

READ = with_crc(bytes.fromhex("010300000002"))
READ_ANSWER = with_crc(bytes.fromhex("01030400070008"))
SILENT = with_crc(bytes.fromhex("040300000001"))
FAILING = with_crc(bytes.fromhex("020300640001"))
EXCEPTION = with_crc(bytes.fromhex("028302"))
WRITE = with_crc(bytes.fromhex("010600050007"))


@pytest.fixture
def bus(tmp_path: Path) -> Any:
    with VirtualBus(tmp_path) as b:
        yield b


def test_live_jsonl_is_the_replay_of_its_recording(bus: VirtualBus, tmp_path: Path) -> None:
    tap = bus.attach("tap")
    bus.attach("master")
    rec = tmp_path / "rec.pcapng"
    proc = subprocess.Popen(
        [MODSCOPE, "live", str(tap), *LINE_ARGS, "--format", "jsonl", "-w", str(rec)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stderr is not None
        wait_ready(proc.stderr)
        for frame, pause in [
            (READ, 0.1),  # listed open, then an update: ok
            (READ_ANSWER, 0.3),
            (SILENT, 0.5),  # listed open, then an update: timeout
            (FAILING, 0.1),
            (EXCEPTION, 0.3),
            (WRITE, 0.1),
            (with_crc(bytes.fromhex("010600050007")), 0.5),  # the echo
        ]:
            bus.inject(frame, source="master")
            time.sleep(pause)
    finally:
        proc.send_signal(2)
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    lines = out.splitlines()
    records = [json.loads(line) for line in lines]
    frames = [r for r in records if "raw" in r]
    updates = [r for r in records if "update" in r]
    assert [f["index"] for f in frames] == list(range(len(frames)))  # each once, in order
    assert len(frames) == 7
    assert sorted(u["update"] for u in updates) == sorted(
        {u["update"] for u in updates}
    )  # one update per row at most
    assert {u["update"]: u["transaction"]["status"] for u in updates}.get(2) == "timeout"
    for u in updates:  # an update comes after the row it updates
        assert lines.index(json_line(u)) > [r.get("index") for r in records].index(u["update"])
    replayed = subprocess.run(
        [MODSCOPE, "replay", str(rec), *LINE_ARGS, "--format", "jsonl"],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert replayed.returncode == 0, replayed.stderr
    # byte for byte: times to the microsecond (as recordings keep them), latencies the
    # difference of the times shown
    assert applied(lines) == replayed.stdout.splitlines()


def test_an_answered_update_names_its_answer() -> None:
    s = Session(LINE, exact_timing=True, timeout=0.1)
    s.feed(Chunk(READ, 10.0 + len(READ) * LINE.char_time, t_start=10.0))
    s.feed(Chunk(READ_ANSWER, 10.02 + len(READ_ANSWER) * LINE.char_time, t_start=10.02))
    s.finish()
    text = io.StringIO()
    Lister(text, "text", s.describer).write_updates([0])
    gap_ms = (0.02 - len(READ) * LINE.char_time) * 1000
    assert text.getvalue().strip() == f"update #0: ok, answer #1 {gap_ms:.1f}ms"


def test_updates_in_text_and_csv() -> None:
    s = Session(LINE, exact_timing=True, timeout=0.1)
    s.feed(Chunk(READ, 10.0 + len(READ) * LINE.char_time, t_start=10.0))
    s.feed(Chunk(SILENT, 11.0 + len(SILENT) * LINE.char_time, t_start=11.0))
    s.finish()
    text, csv_out, jsonl = io.StringIO(), io.StringIO(), io.StringIO()
    Lister(text, "text", s.describer).write_updates([0])
    assert text.getvalue().strip() == "update #0: timeout"
    Lister(csv_out, "csv", s.describer).write_updates([0])
    row = csv_out.getvalue().splitlines()[1].split(",")
    assert (row[0], row[4], row[10]) == ("0", "update", "timeout")
    assert row[14] == ""  # no raw: not a frame
    Lister(jsonl, "jsonl", s.describer).write_updates([0])
    update = json.loads(jsonl.getvalue())
    assert update["update"] == 0 and update["transaction"]["status"] == "timeout"
