"""User errors print as one line and exit 2; anything else is a bug: traceback, a request
to report it, exit 70 (EX_SOFTWARE)."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path
from typing import TextIO

import pytest

import sniffer.cli.replay
from sniffer.cli import EX_SOFTWARE, main

ROOT = Path(__file__).resolve().parent.parent.parent


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("error", [RuntimeError, ValueError, KeyError, AttributeError])
def test_a_bug_shows_its_traceback_and_asks_for_a_report(
    error: type[Exception], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def broken(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
        raise error("the frame index went negative")

    monkeypatch.setattr(sniffer.cli.replay, "cmd_replay", broken)
    code, out, err = run(["replay", "--stats"], capsys)
    assert code == EX_SOFTWARE == 70
    assert out == ""
    assert "Traceback (most recent call last)" in err
    assert f"{error.__name__}: " in err and "in broken" in err
    last = err.strip().splitlines()[-1]
    assert "bug in modscope" in last and "report" in last
    assert "modscope replay --stats" in last  # the command line to put in the report


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["replay", "/no/such/capture.pcapng"], "no such file"),
        (["replay", "--baud", "0"], "baud rate must be positive"),
        (["export", "/no/such.pcapng", "-o", "x.unknown"], "cannot tell the format"),
        (["live", "/dev/null", "--baud", "0"], "baud rate must be positive"),
        (["record", "/dev/null", "-w", "x.pcapng", "--rotate-size", "ten"], "--rotate-size"),
        (["record", "/dev/null", "-w", "x.pcapng", "--duration=0s"], "--duration"),
        (["replay", "--timeout", "-1"], "--timeout"),
        (["tui", "/no/such/capture.pcapng"], "no such file"),
        (["replay", "--unit", "3=no-such-model"], "no-such-model"),
    ],
)
def test_user_errors_print_one_line(
    argv: list[str], says: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    argv = [str(tmp_path / a) if a.startswith("x.") else a for a in argv]
    code, out, err = run(argv, capsys)
    assert code == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith("modscope: error: ") and says in err
    assert "Traceback" not in err


def test_the_installed_entry_point_reports_user_errors_in_one_line() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "sniffer.cli", "replay", "/no/such/capture.pcapng"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "no such file" in done.stderr


def test_no_module_outside_the_cli_imports_it() -> None:
    offenders = []
    for path in sorted((ROOT / "sniffer").rglob("*.py")):
        if "cli" in path.relative_to(ROOT / "sniffer").parts:
            continue
        text = path.read_text(encoding="utf-8")
        if "sniffer.cli" in text or "from sniffer import cli" in text:
            offenders.append(str(path.relative_to(ROOT)))
    assert offenders == []


def test_a_missing_peer_program_is_named_in_the_skip_reason(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    from tests.conftest import missing_reason

    (tmp_path / "socat").write_text("#!/bin/sh\n")
    (tmp_path / "socat").chmod(0o755)
    monkeypatch.setenv("PATH", str(tmp_path))  # socat here, nothing else
    assert missing_reason(("socat",)) is None
    reason = missing_reason(("socat", "mosquitto_pub", "tshark"))
    assert reason == (
        "mosquitto_pub, tshark not installed (apt-get install mosquitto-clients tshark)"
    )
