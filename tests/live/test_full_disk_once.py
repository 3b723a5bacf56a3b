"""`modscope live -w FILE` whose recording stops (a full disk, or the file size limit of
the process) says so in one line, once; the listing goes on to its end (`-c`), and the
exit status is record's for the same stop (1)."""

from __future__ import annotations

import json
import resource
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from dissectors.checks import with_crc
from sniffer.sources import open_capture
from tests.support.virtual_bus import VirtualBus, wait_ready

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
FRAME = with_crc(bytes.fromhex("010300000005"))
LIMIT = 4096  # bytes: the file size limit of the live process
ROWS = 400  # rows listed: many more than the file can hold (about 50 reads)


def _limit_file_size() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of a killing signal
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def test_live_recording_that_stops_says_so_once_and_the_listing_goes_on(tmp_path: Path) -> None:
    path = tmp_path / "bus.pcapng"
    argv = [MODSCOPE, "live", "--parity", "N", "--stopbits", "2", "-w", str(path)]
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        proc = subprocess.Popen(
            [*argv, str(tap), "--format", "jsonl", "-c", str(ROWS)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=_limit_file_size,
        )
        stdout, stderr = proc.stdout, proc.stderr
        assert stdout is not None and stderr is not None
        lines: list[str] = []  # read as it comes: a full pipe would drop rows (the backlog)
        taker = threading.Thread(target=lambda: lines.extend(stdout), daemon=True)
        taker.start()
        try:
            wait_ready(stderr)
            deadline = time.monotonic() + 60
            while proc.poll() is None and time.monotonic() < deadline:
                bus.inject(FRAME, source="master")
                time.sleep(0.003)
        finally:
            if proc.poll() is None:
                proc.terminate()
            err = stderr.read()
            proc.wait(timeout=10)
            taker.join(10)
    assert "Traceback" not in err and "bug" not in err
    errors = [line for line in err.splitlines() if "error" in line]
    assert len(errors) == 1, err
    assert errors[0].startswith(f"modscope: error: {path}: ") and "size limit" in errors[0]
    assert proc.returncode == 1, err
    assert 0 < path.stat().st_size <= LIMIT
    # the listing went on after the recording stopped: every row asked for, well past
    # what the file holds
    rows = [json.loads(line) for line in lines]
    recorded = [c for c in open_capture(path).chunks() if c.data]
    assert len([r for r in rows if r.get("kind") == "request"]) == ROWS
    assert len(recorded) < ROWS // 2
