"""Live: an ABL eMH1 wallbox's `>` answers on a port. Over a pseudo-terminal bus (the
command line's streaming JSONL, mode told from the traffic) and as prepared reads cut
anywhere (the engine's pump), they are answers paired with the `:` requests, with the
vendor fact among their problems."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from sniffer.model import Chunk, LineSettings
from tests.support.live import T0, Run
from tests.support.virtual_bus import VirtualBus, wait_ready

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
ABL = LineSettings(baud=38400, bytesize=8, parity="E", stopbits=1, mode="ascii")
READ = b":0303002E0005C7\r\n"
STATUS = b">03030A2EA1B20C025803E803E833\r\n"
STATUS_BAD = b">03030A2EA1B20C025803E803E834\r\n"
SET = b":0310001400010202587C\r\n"
SET_OK = b">031000140001D8\r\n"
VENDOR = "vendor-start"
# a pty takes no even parity (EINVAL): N and two stop bits, as the other live tests
LINE_ARGS = ["--baud", "38400", "--parity", "N", "--stopbits", "2", "--timeout", "0.5"]


@pytest.fixture
def bus(tmp_path: Path) -> Iterator[VirtualBus]:
    with VirtualBus(tmp_path) as b:
        yield b


def kinds(problems: list[dict[str, Any]] | None) -> list[str]:
    return [p["kind"] for p in problems or []]


def test_a_live_port_lists_vendor_answers_paired_as_they_come(bus: VirtualBus) -> None:
    tap = bus.attach("tap")
    bus.attach("master")
    proc = subprocess.Popen(
        [MODSCOPE, "live", str(tap), *LINE_ARGS, "--mode", "auto", "--format", "jsonl"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stderr is not None and proc.stdout is not None
        wait_ready(proc.stderr)
        got = []
        for ask, answer in ((READ, STATUS), (SET, SET_OK), (READ, STATUS_BAD)):
            bus.inject(ask, source="master")
            bus.inject(answer, source="master")
            got.append(json.loads(proc.stdout.readline()))
            got.append(json.loads(proc.stdout.readline()))
    finally:
        proc.send_signal(2)
        _out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert [g["raw"] for g in got] == [
        f.hex() for f in (READ, STATUS, SET, SET_OK, READ, STATUS_BAD)
    ]
    assert [g["kind"] for g in got] == ["request", "response"] * 3
    assert [g["transaction"]["status"] for g in got[:4]] == ["ok"] * 4
    assert got[5]["transaction"]["status"] == "bad answer"
    assert [kinds(g.get("problem_details")) for g in got] == [
        [],
        [VENDOR],
        [],
        [VENDOR],
        [],
        ["check", VENDOR],
    ]
    assert got[1]["transaction"]["partner"] == got[0]["index"]


def test_reads_cut_anywhere_give_the_same_listing_as_whole_frames() -> None:
    """A read may end right after a `>`, or in its hex: the framer waits for the rest,
    and the listing is the one whole frames give."""
    frames = [(READ, 0.0), (STATUS, 0.03), (b"\x00>\xfe", 0.5), (SET, 1.0), (SET_OK, 1.025)]
    whole = [[Chunk(raw, T0 + t + len(raw) * ABL.char_time)] for raw, t in frames]
    data = b"".join(raw for raw, _t in frames)
    cut: list[list[Chunk]] = []
    for k, at in enumerate(range(0, len(data), 3)):  # three bytes a read, 1 ms apart
        cut.append([Chunk(data[at : at + 3], T0 + 0.001 * k)])
    listed = Run(ABL, whole, None).lines
    again = Run(ABL, cut, None).lines

    def frames_of(lines: list[str]) -> list[tuple[str, str, list[str]]]:
        out = []
        for line in lines:
            rec = json.loads(line)
            if "raw" in rec and rec["kind"] != "noise":
                out.append((rec["raw"], rec["kind"], kinds(rec.get("problem_details"))))
        return out

    assert frames_of(again) == frames_of(listed)
    assert [raw for raw, _k, _p in frames_of(listed)] == [
        f.hex() for f in (READ, STATUS, SET, SET_OK)
    ]
    assert [p for _r, _k, p in frames_of(listed)] == [[], [VENDOR], [], [VENDOR]]
