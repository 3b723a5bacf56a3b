"""A damaged sidecar does not stop listings (issue #30, item 6): `replay --format jsonl`
(which reports progress but shows no rows while reading) takes back the rows of a
sidecar damaged in a later block, indexes the capture and rewrites the sidecar, on the
first run and every one after; the temporary files of a sidecar writer killed with
SIGKILL are removed by the next run, those of a writer at work are not."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from sniffer.cli import main
from sniffer.session import index
from tests.session.test_index_blocks import _damage
from tests.support.index import _ingested

ROOT = Path(__file__).resolve().parent.parent.parent


def _listing(capture: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str]]:
    code = main(["replay", str(capture), "--format", "jsonl"])
    out = capsys.readouterr().out
    return code, out.splitlines()


def test_a_sidecar_damaged_in_a_later_block_is_rebuilt_by_replay(
    capture: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, fresh = _listing(capture, capsys)  # indexes, writes the sidecar
    side = Path(str(capture) + index.SUFFIX)
    assert code in (0, 1) and side.exists() and len(fresh) > 3 * index.BLOCK
    _damage(side, 3)
    for _ in range(2):  # the first run rebuilds it; the next reads the rebuilt one
        again = _listing(capture, capsys)
        assert again == (code, fresh)
    assert _ingested(capture).indexed_from == side  # whole again, and read


def _writer_script(capture: Path, cache: Path, then: str) -> str:
    """A process that begins writing the sidecar of `capture` a segment at a time, then
    does `then` (with `writer` in scope)."""
    return textwrap.dedent(
        f"""
        import os, signal, sys, time
        os.environ["XDG_CACHE_HOME"] = {str(cache)!r}
        from pathlib import Path
        from sniffer.session import index
        from sniffer.session.session import open_session
        index.MIN_SIZE = 0
        session, cap = open_session(Path({str(capture)!r}), index=False)
        session.ingest(cap.chunks())
        writer = index.Writer(Path({str(capture)!r}))
        writer.add(session.state)
        print("writing", flush=True)
        {then}
        """
    )


def _temporaries(folder: Path) -> list[Path]:
    return sorted(folder.glob(index.TEMP_PREFIX + "*"))


def test_a_killed_writers_temporary_files_are_removed_by_the_next_run(capture: Path) -> None:
    cache = capture.parent / "cache"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for _ in range(3):  # kill -9 while the sidecar is being written, three times
        done = subprocess.run(
            [sys.executable, "-c", _writer_script(capture, cache, "os.kill(os.getpid(), 9)")],
            capture_output=True,
            text=True,
            env=env,
            timeout=60,
        )
        assert done.returncode == -signal.SIGKILL, done.stderr
        left = _temporaries(capture.parent)
        # one file at most: each new writer removed the one the writer before left
        assert len(left) == 1 and left[0].stat().st_size > 0
    # a writer still at work: its file is locked and stays
    alive = subprocess.Popen(
        [sys.executable, "-c", _writer_script(capture, cache, "time.sleep(60)")],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        assert alive.stdout is not None and alive.stdout.readline() == "writing\n"
        working = _temporaries(capture.parent)
        assert len(working) == 1 and working != left  # the killed writer's file is gone
        session = _ingested(capture)  # another run meanwhile: indexes, writes the sidecar
        assert session.indexed_from is None
        assert _temporaries(capture.parent) == working  # the working one stays
    finally:
        alive.kill()  # killed halfway too
        alive.wait()
    assert _ingested(capture).indexed_from == Path(str(capture) + index.SUFFIX)
    assert _temporaries(capture.parent) == []  # removed by this run
    header_start = len(index.MAGIC) + index._PREFIX.size
    data = Path(str(capture) + index.SUFFIX).read_bytes()
    size = index._PREFIX.unpack_from(data, len(index.MAGIC))[0]
    assert json.loads(data[header_start : header_start + size])["format"] == index.FORMAT
