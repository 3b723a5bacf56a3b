"""modscope against real peers on a virtual RS-485 bus: pymodbus's serial server and client
(and mbpoll), modscope listening, recording, replaying and exporting for tshark. Every
transaction a client made is seen, paired and decoded with the values the client got,
live and from the recording."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from tests.support.virtual_bus import (
    ModbusServer,
    VirtualBus,
    coils,
    holding,
    inputs,
    modbus_client,
    wait_ready,
)

pytest.importorskip("pymodbus")
pytestmark = pytest.mark.peer

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
LINE_ARGS = ["--baud", "19200", "--parity", "N", "--stopbits", "2", "--mode", "rtu"]
TSHARK = shutil.which("tshark")
MBPOLL = shutil.which("mbpoll")


@dataclass
class Done:
    """One transaction as the client saw it: unit, function, and what it got back."""

    unit: int
    function: int
    values: list[int] | None  # read values; None for writes
    outcome: str  # ok | exception | timeout


class Bench:
    """A bus with a pymodbus server (units 1 and 2), a client, and a tap for modscope."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.bus = VirtualBus(tmp)
        self.server = ModbusServer(self.bus.attach("server")).start()
        self.client_port = self.bus.attach("client")
        self.tap = self.bus.attach("tap", raw=False)
        self.client: Any = None
        self.done: list[Done] = []

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
        self.server.stop()
        self.bus.close()

    def modscope(self, *args: str) -> subprocess.Popen[bytes]:
        proc = subprocess.Popen(
            [MODSCOPE, "live", str(self.tap), *LINE_ARGS, "--timeout", "0.6", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        assert proc.stderr is not None
        wait_ready(_Lines(proc.stderr))
        return proc

    def run(self, call: str, unit: int, function: int, *args: Any, **kwargs: Any) -> None:
        from pymodbus.exceptions import ModbusIOException

        if self.client is None:
            self.client = modbus_client(self.client_port, timeout=0.5)
        try:
            result = getattr(self.client, call)(*args, device_id=unit, **kwargs)
        except ModbusIOException:
            self.done.append(Done(unit, function, None, "timeout"))
            return
        if result.isError():
            self.done.append(Done(unit, function, None, "exception"))
            return
        values: list[int] | None = None
        if call.startswith("read_") and call.endswith("registers"):
            values = list(result.registers)
        elif call.startswith("read_"):
            values = [int(b) for b in result.bits[: kwargs["count"]]]
        self.done.append(Done(unit, function, values, "ok"))

    def traffic(self) -> None:
        """A master's day in miniature: every common function code, an exception, a
        silent unit, writes that later reads see."""
        self.run("read_holding_registers", 1, 3, 0, count=5)
        self.run("read_input_registers", 2, 4, 3, count=4)
        self.run("read_coils", 1, 1, 0, count=10)
        self.run("read_discrete_inputs", 2, 2, 2, count=13)
        self.run("write_register", 2, 6, 7, 4242)
        self.run("write_registers", 1, 16, 10, [1, 2, 3])
        self.run("write_coil", 1, 5, 4, True)
        self.run("write_coils", 2, 15, 0, [True, False, True])
        self.run("read_holding_registers", 1, 3, 8, count=6)
        self.run("read_holding_registers", 2, 3, 7, count=1)
        self.run("read_holding_registers", 1, 3, 500, count=2)  # exception: no such register
        self.run("read_holding_registers", 7, 3, 0, count=1)  # nobody is unit 7
        self.run("read_input_registers", 1, 4, 0, count=2)


class _Lines:
    """Text lines from a binary pipe (modscope's stderr while stdout is binary)."""

    def __init__(self, stream: Any) -> None:
        self.stream = stream

    def readline(self) -> str:
        line: bytes = self.stream.readline()
        return line.decode("utf-8", errors="replace")


@pytest.fixture
def bench(tmp_path: Path) -> Iterator[Bench]:
    b = Bench(tmp_path)
    try:
        yield b
    finally:
        b.close()


def stop(proc: subprocess.Popen[bytes]) -> tuple[bytes, str]:
    time.sleep(0.4)  # let the last answer reach the listing
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=15)
    assert proc.returncode == 0, err.decode()
    return out, err.decode()


def records(jsonl: bytes | str) -> list[dict[str, Any]]:
    """Rows by index, each listed once, with the update records of the live listing (a
    request's answer came, or it timed out) applied to the rows they name."""
    text = jsonl.decode() if isinstance(jsonl, bytes) else jsonl
    by_index: dict[int, dict[str, Any]] = {}
    for line in text.splitlines():
        rec = json.loads(line)
        if "update" in rec:
            assert "raw" not in rec
            by_index[rec.pop("update")].update(rec)
            continue
        assert rec["index"] not in by_index, "a frame listed twice"
        by_index[rec["index"]] = rec
    return [by_index[i] for i in sorted(by_index)]


def values_of(rec: dict[str, Any]) -> list[int] | None:
    for f in rec.get("fields", []):
        if f["name"] == "values":
            return list(f["value"])
    return None


def check_transactions(rows: list[dict[str, Any]], done: list[Done]) -> None:
    """Every transaction the client made is in `rows`, in order, paired, with its values."""
    requests = [r for r in rows if r["kind"] == "request"]
    assert [(r["unit"], r["function"]) for r in requests] == [(d.unit, d.function) for d in done]
    answers = {
        r["transaction"]["partner"]: r
        for r in rows
        if r["kind"] != "request" and r.get("transaction", {}).get("partner") is not None
    }
    for req, d in zip(requests, done, strict=True):
        # a request is listed as soon as it is framed ("open"); its answer's row tells
        # the transaction, and an update record gives the request its outcome
        answer = answers.get(req["index"])
        if d.outcome == "timeout":
            assert answer is None
            assert req["transaction"]["status"] == "timeout"
            continue
        assert answer is not None, (req, d)
        assert answer["transaction"]["status"] == d.outcome, (answer, d)
        assert answer["unit"] == d.unit and answer["function"] == d.function
        assert answer["check_ok"] is True
        # measured, or bounded; unknown only where request and answer came in one read
        # (their row times touch) and the read resolution is not yet known
        lat = answer["transaction"]
        touching = abs(answer["t"] - req["t_end"]) < 1e-6
        assert lat["latency_ms"] is not None or lat["latency_max_ms"] is not None or touching
        assert lat["latency_ms"] is None or lat["latency_ms"] > 0
        if d.values is not None:
            assert values_of(answer) == d.values, (answer, d)
    # nothing was heard that the client did not cause
    assert {r["kind"] for r in rows} <= {"request", "response", "exception"}


def test_every_transaction_is_seen_live_and_from_the_recording(
    bench: Bench, tmp_path: Path
) -> None:
    rec = tmp_path / "rec.pcapng"
    proc = bench.modscope("--format", "jsonl", "--write", str(rec))
    bench.traffic()
    out, _err = stop(proc)
    assert [d.outcome for d in bench.done].count("ok") == 11
    live = records(out)
    check_transactions(live, bench.done)
    assert bench.bus.sent_by("tap") == b""
    # the written values reach later reads, as the client saw them
    assert bench.done[8].values == [*holding(1)[8:10], 1, 2, 3, holding(1)[13]]
    assert bench.done[9].values == [4242]
    assert bench.done[0].values == holding(1)[:5]
    assert bench.done[1].values == inputs(2)[3:7]
    assert bench.done[2].values == [int(b) for b in coils(1)[:10]]

    replayed = subprocess.run(
        [MODSCOPE, "replay", str(rec), "--format", "jsonl", "--timeout", "0.6"],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert replayed.returncode == 0, replayed.stderr
    again = records(replayed.stdout)
    check_transactions(again, bench.done)

    def frames(rows: list[dict[str, Any]]) -> list[tuple[Any, ...]]:
        # the updates applied, live and replay agree on every frame and outcome
        return [(r["raw"], r["kind"], r.get("transaction", {}).get("status")) for r in rows]

    assert frames(again) == frames(live)
    # every key of every frame, the updates applied, with the differences docs/output.md
    # names for frames that shared one read: times and latencies 1 us apart at most, and
    # a latency bound from the read interval known so far (live) or from the whole file
    for a, b in zip(again, live, strict=True):
        for key in ("t", "t_end"):
            assert abs(a.pop(key) - b.pop(key)) <= 1.5e-6
        a.pop("timing_note", None)
        b.pop("timing_note", None)
        ta, tb = a.get("transaction"), b.get("transaction")
        if ta is not None and tb is not None:
            la, lb = ta.pop("latency_ms"), tb.pop("latency_ms")
            # the pair follows the read interval known so far (live) or in the whole
            # recording: where both give a value, it is the same but for the rounding
            # to what each resolution holds (a millisecond at most, here)
            if la is not None and lb is not None:
                assert abs(la - lb) <= 0.5015, (la, lb)
            ta.pop("latency_max_ms")
            tb.pop("latency_max_ms")
    assert again == live  # every key of every frame, the updates applied (docs/output.md)


@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed")
def test_tshark_reads_the_export_of_a_live_recording(bench: Bench, tmp_path: Path) -> None:
    assert TSHARK is not None
    rec = tmp_path / "rec.pcapng"
    proc = bench.modscope("--format", "jsonl", "--write", str(rec))
    bench.traffic()
    out, _ = stop(proc)
    live = records(out)
    exported = tmp_path / "wireshark.pcapng"
    result = subprocess.run(
        [MODSCOPE, "export", str(rec), "-o", str(exported)],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert result.returncode == 0, result.stderr
    malformed = subprocess.run(
        [TSHARK, "-r", str(exported), "-Y", "_ws.malformed"], capture_output=True, text=True
    )
    assert malformed.returncode == 0 and malformed.stdout == ""
    fields = subprocess.run(
        [TSHARK, "-r", str(exported), "-T", "fields", "-e", "mbtcp.unit_id", "-e",
         "modbus.func_code"],
        capture_output=True,
        text=True,
    )  # fmt: skip
    got = [tuple(int(x) for x in line.split("\t")) for line in fields.stdout.splitlines()]
    assert got == [(r["unit"], r["function"]) for r in live]


@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed")
def test_pcap_to_stdout_feeds_tshark_and_nothing_else(bench: Bench, tmp_path: Path) -> None:
    assert TSHARK is not None
    proc = bench.modscope("--pcap", "-")
    bench.traffic()
    out, _ = stop(proc)
    assert out[:4] == b"\x0a\x0d\x0d\x0a"
    stream = tmp_path / "stdout.pcapng"
    stream.write_bytes(out)
    read = subprocess.run(
        [TSHARK, "-r", "-", "-T", "fields", "-e", "mbtcp.unit_id", "-e", "modbus.func_code",
         "-e", "_ws.malformed"],
        input=out,
        capture_output=True,
        timeout=30,
    )  # fmt: skip
    assert read.returncode == 0, read.stderr
    lines = read.stdout.decode().splitlines()
    requests = [d for d in bench.done]
    answered = [d for d in bench.done if d.outcome != "timeout"]
    assert len(lines) == len(requests) + len(answered)
    assert all(line.count("\t") == 2 and not line.split("\t")[2] for line in lines)
    units = [int(line.split("\t")[0]) for line in lines]
    assert units.count(7) == 1, "|".join(lines)  # the silent unit's request, unanswered


@pytest.mark.skipif(MBPOLL is None, reason="mbpoll is not installed")
def test_mbpoll_transactions_are_decoded_with_its_values(bench: Bench) -> None:
    assert MBPOLL is not None
    proc = bench.modscope("--format", "jsonl")
    master = bench.bus.attach("mbpoll")
    polls = [(1, "4", 1, 5), (2, "3", 3, 4), (2, "0", 1, 8)]  # unit, table, ref, count
    printed: list[list[int]] = []
    for unit, table, ref, count in polls:
        result = subprocess.run(
            [MBPOLL, "-m", "rtu", "-a", str(unit), "-t", table, "-r", str(ref), "-c", str(count),
             "-b", "19200", "-P", "none", "-s", "2", str(master), "-1"],
            capture_output=True,
            text=True,
            timeout=20,
        )  # fmt: skip
        assert result.returncode == 0, result.stderr
        printed.append(
            [int(line.split()[-1]) for line in result.stdout.splitlines() if line.startswith("[")]
        )
    out, _ = stop(proc)
    rows = records(out)
    answers = [r for r in rows if r["kind"] == "response"]
    assert [(r["unit"], r["function"]) for r in answers] == [(1, 3), (2, 4), (2, 1)]
    assert [values_of(r) for r in answers] == printed
    assert all(r["transaction"]["status"] == "ok" for r in answers)


def test_closing_the_port_under_modscope_is_survived(bench: Bench) -> None:
    proc = bench.modscope("--format", "jsonl")
    bench.run("read_holding_registers", 1, 3, 0, count=2)
    time.sleep(0.2)
    bench.bus.unplug("tap")
    time.sleep(0.8)
    bench.bus.plug("tap")
    time.sleep(1.5)  # the reader retries every 0.5 s
    bench.run("read_holding_registers", 2, 3, 1, count=3)
    out, err = stop(proc)
    rows = records(out)
    kinds = [r["kind"] for r in rows]
    assert kinds == ["request", "response", "event", "event", "request", "response"]
    events = [r["summary"] for r in rows if r["kind"] == "event"]
    assert events[0].startswith("port lost: ")
    assert events[1].startswith("reconnect: ")
    assert values_of(rows[-1]) == holding(2)[1:4]
    assert "port lost" in err and "reconnect" in err
