"""`modscope doctor` as a program: text and JSON, exit statuses 0, 1 and 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOCTOR = ROOT / "tests" / "captures" / "doctor"


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "sniffer.cli", "doctor", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )


def test_clean_bus_exits_0_with_no_findings() -> None:
    done = run(str(DOCTOR / "clean.csv"), "--baud", "19200")
    assert done.returncode == 0, done.stderr
    assert "no findings" in done.stdout
    done = run(str(DOCTOR / "clean.csv"), "--baud", "19200", "--format", "json")
    assert done.returncode == 0 and json.loads(done.stdout) == []


def test_json_findings_and_exit_1() -> None:
    done = run(str(DOCTOR / "silent-unit.csv"), "--baud", "19200", "--format", "json")
    assert done.returncode == 1, done.stderr
    findings = json.loads(done.stdout)
    first = findings[0]
    assert (first["kind"], first["severity"], first["unit"]) == ("silent-unit", "error", 7)
    assert first["evidence"]["requests"] == 40 and first["advice"]


def test_text_report_names_unit_evidence_and_advice() -> None:
    done = run(str(DOCTOR / "exception-poll.csv"), "--baud", "19200")
    assert done.returncode == 1
    out = done.stdout
    assert "1. WARNING exception-poll [unit 3]" in out
    assert "exception 02 (illegal data address)" in out
    assert "03 03 01 00 00 02" in out  # the request that earns it, quoted
    assert "check next:" in out and "on site:" in out


def test_info_only_exits_0() -> None:
    done = run(str(DOCTOR / "write-effect.csv"), "--baud", "19200", "--format", "json")
    assert done.returncode == 0, done.stdout
    assert [f["kind"] for f in json.loads(done.stdout)] == ["write-effect"]


def test_unreadable_input_exits_2(tmp_path: Path) -> None:
    missing = run(str(tmp_path / "nothing.pcapng"))
    assert missing.returncode == 2
    assert "nothing.pcapng" in missing.stderr and missing.stderr.count("\n") == 1
    empty = tmp_path / "empty.pcapng"
    empty.write_bytes(b"")
    done = run(str(empty))
    assert done.returncode == 2 and "empty.pcapng" in done.stderr


def test_dictionary_bound_makes_slow_answers_on_the_demo() -> None:
    demo = ROOT / "captures" / "demo.pcapng"
    bare = json.loads(run(str(demo), "--format", "json").stdout)
    bound = json.loads(
        run(str(demo), "--format", "json", "--bus", str(ROOT / "captures" / "demo-bus.toml")).stdout
    )
    alarms = {(f["kind"], f.get("unit")) for f in bare if f["severity"] != "info"}
    assert alarms == {("silent-unit", 4), ("exception-poll", 3)}
    slow = [f for f in bound if f["kind"] == "slow-answers"]
    assert slow and slow[0]["unit"] == 3 and slow[0]["evidence"]["documented_ms"] == 40.0
    assert "slower than the 40 ms its dictionary documents" in slow[0]["summary"]
    # the demo's healthy units give no warning or error with their dictionaries either
    assert not [f for f in bound if f["severity"] != "info" and f.get("unit") in (1, 2)]


def test_a_missing_port_is_named_as_a_port_and_duration_needs_one() -> None:
    done = run("/dev/ttyMODSCOPE-NONE", "--duration", "1s")
    assert done.returncode == 2
    assert "/dev/ttyMODSCOPE-NONE: no such serial port" in done.stderr
    assert done.stderr.count("\n") == 1
    done = run(str(DOCTOR / "clean.csv"), "--duration", "1s")
    assert done.returncode == 2 and "--duration is for listening to a port" in done.stderr
