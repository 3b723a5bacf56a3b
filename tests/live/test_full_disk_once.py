"""`modscope live -w FILE` whose recording stops (a full disk, or the file size limit of
the process) says so in one line, once, and exits with record's status for the same
stop (2); the listing and the summary go on to their end."""

from __future__ import annotations

import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

from dissectors.checks import with_crc
from tests.support.virtual_bus import VirtualBus, wait_ready

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
FRAME = with_crc(bytes.fromhex("010300000005"))
LIMIT = 4096  # bytes: the file size limit of the live process


def _limit_file_size() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of a killing signal
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def test_live_recording_that_stops_says_so_once(tmp_path: Path) -> None:
    path = tmp_path / "bus.pcapng"
    argv = [MODSCOPE, "live", "--parity", "N", "--stopbits", "2", "-w", str(path)]
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        proc = subprocess.Popen(
            [*argv, str(tap), "--format", "text"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=_limit_file_size,
        )
        try:
            wait_ready(proc.stderr)
            deadline = time.monotonic() + 30
            while proc.poll() is None and time.monotonic() < deadline:
                bus.inject(FRAME, source="master")
                time.sleep(0.003)
        finally:
            if proc.poll() is None:
                proc.terminate()
            _out, err = proc.communicate(timeout=10)
    assert "Traceback" not in err and "bug" not in err
    errors = [line for line in err.splitlines() if "error" in line]
    assert len(errors) == 1, err
    assert errors[0].startswith(f"modscope: error: {path}: ") and "size limit" in errors[0]
    assert proc.returncode == 2, err
    assert 0 < path.stat().st_size <= LIMIT
