"""The retained `findings` topic against a real Mosquitto broker: `modscope replay --mqtt`
publishes the same findings `modscope doctor --format json` prints."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.broker import Broker, broker

__all__ = ["broker"]  # (the fixture)

ROOT = Path(__file__).resolve().parents[2]
DOCTOR = ROOT / "tests" / "captures" / "doctor"


def modscope(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "sniffer.cli", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )


def retained(broker: Broker, topic: str) -> list[str]:
    done = subprocess.run(
        ["mosquitto_sub", "-p", str(broker.port), "-W", "2", "--retained-only", "-t", topic],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    return done.stdout.splitlines()


@pytest.mark.parametrize("name", ["two-masters", "clean"])
def test_replay_publishes_the_doctors_findings_retained(broker: Broker, name: str) -> None:
    capture = str(DOCTOR / f"{name}.csv")
    url = f"mqtt://127.0.0.1:{broker.port}/modscope/{name}"
    done = modscope("replay", capture, "--baud", "19200", "--mqtt", url)
    assert done.returncode == 0, done.stderr
    messages = retained(broker, f"modscope/{name}/findings")
    assert len(messages) == 1
    message = json.loads(messages[0])
    printed = json.loads(modscope("doctor", capture, "--baud", "19200", "--format", "json").stdout)
    assert message["findings"] == printed
    assert message["errors"] == sum(f["severity"] == "error" for f in printed)
    assert message["rows"] > 0 and message["t"] > 0
    assert message["first_row"] == 0  # a replay holds every row
    # (the capture's times count from its start, not from 1970: no wall-clock time)
    assert message["time"] is None
