"""The progress line of long commands: only on a terminal, after a second, on stderr."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from sniffer.cli import progress as progress_module
from sniffer.cli.progress import Progress


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_reading_shows_the_share_of_the_file_and_the_time_left(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    capture = tmp_path / "big.pcapng"
    capture.write_bytes(bytes(1000))
    clock, read = Clock(), [5000]
    monkeypatch.setattr("sniffer.cli.progress.time.monotonic", clock)
    monkeypatch.setattr(progress_module, "_bytes_read", lambda: read[0])
    err = Terminal()
    progress = Progress(err, "big.pcapng", capture)
    progress.reading(100, 10)
    assert err.getvalue() == ""  # not in the first second
    clock.now += 2.0
    read[0] += 250  # a quarter of the file read in two seconds
    progress.reading(100, 1234)
    assert "reading big.pcapng: 25%, 1,234 rows, about 6 s left" in err.getvalue()
    progress.done()
    assert err.getvalue().endswith("\r\x1b[K")


def test_writing_shows_the_share_of_the_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = Clock()
    monkeypatch.setattr("sniffer.cli.progress.time.monotonic", clock)
    err = Terminal()
    progress = Progress(err, "out.jsonl")
    seen = []
    for row in progress.rows(range(1024), 1024):
        seen.append(row)
        if row == 511:
            clock.now += 3.0  # half the rows in three seconds
    assert seen == list(range(1024))
    assert "writing out.jsonl: 50%, about 3 s left" in err.getvalue()


def test_nothing_when_stderr_is_not_a_terminal(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    clock = Clock()
    monkeypatch.setattr("sniffer.cli.progress.time.monotonic", clock)
    err = io.StringIO()
    progress = Progress(err, "x", tmp_path)
    clock.now += 10
    progress.reading(1, 1)
    assert list(progress.rows(range(3), 3)) == [0, 1, 2]
    progress.done()
    assert err.getvalue() == ""
