"""`export -` reads standard input as `replay -` does, and a Parquet export of a
truncated capture exits 1 like every other format (issue 26)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from sniffer.cli import main
from sniffer.session.session import DEMO_CAPTURE

ROOT = Path(__file__).resolve().parent.parent.parent


def _modscope(argv: list[str], stdin: bytes) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run(
        [sys.executable, "-m", "sniffer.cli", *argv],
        input=stdin,
        capture_output=True,
        cwd=ROOT,
        timeout=300,
        check=False,
    )


def test_export_reads_standard_input_as_replay_does(tmp_path: Path) -> None:
    demo = DEMO_CAPTURE.read_bytes()
    piped = _modscope(["export", "-", "-o", "-", "--format", "jsonl"], demo)
    assert piped.returncode == 0, piped.stderr
    named = _modscope(["export", str(DEMO_CAPTURE), "-o", "-", "--format", "jsonl"], b"")
    assert named.returncode == 0
    assert piped.stdout == named.stdout and piped.stdout.count(b"\n") > 1000
    out = tmp_path / "frames.pcapng"
    to_file = _modscope(["export", "-", "-o", str(out)], demo)
    assert to_file.returncode == 0, to_file.stderr
    assert out.read_bytes()[:4] == b"\x0a\x0d\x0d\x0a"  # a pcapng section header block
    # the replay of the same bytes from standard input agrees on every frame
    replayed = _modscope(["replay", "-", "--format", "jsonl"], demo)
    assert [json.loads(x)["raw"] for x in replayed.stdout.splitlines()] == [
        json.loads(x)["raw"] for x in piped.stdout.splitlines()
    ]


def test_export_of_standard_input_says_a_bad_output_name_before_reading() -> None:
    done = _modscope(["export", "-", "-o", "frames.unknown"], b"")
    assert done.returncode == 2
    assert done.stderr.decode().count("\n") == 1 and b"cannot tell the format" in done.stderr


@pytest.mark.parametrize(("cut", "status"), [(None, 0), (50_000, 1)])
def test_a_parquet_export_exits_1_on_a_truncated_capture(
    cut: int | None, status: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    duckdb = pytest.importorskip("duckdb")
    capture = tmp_path / "bus.pcapng"
    demo = DEMO_CAPTURE.read_bytes()
    capture.write_bytes(demo if cut is None else demo[:cut])
    table = tmp_path / "frames.parquet"
    code = main(["export", str(capture), "-o", str(table)])
    err = capsys.readouterr().err
    assert code == status, err
    assert ("truncated pcapng block" in err) == (cut is not None)
    # what was read is in the table, as the JSONL export of the same file has it
    assert main(["export", str(capture), "-o", str(tmp_path / "frames.jsonl")]) == status
    lines = (tmp_path / "frames.jsonl").read_text().splitlines()
    counted = duckdb.sql(f"select count(*) from read_parquet('{table}')").fetchall()
    assert counted[0][0] == len(lines) > 0
