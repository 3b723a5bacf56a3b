"""Tests that the live text listing numbers the rows its updates cite (`update #0: ok,
answer #1`): `modscope live` on a pseudo-terminal, a master's requests written to it,
one answered late and one never; every `#N` an update names ends a listed line.

(Here with the TUI's tests: the numbering was asked for with the TUI's issue, #28.)"""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

from dissectors.checks import with_crc
from tests.support.virtual_bus import VirtualBus, wait_ready

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
LINE_ARGS = ["--baud", "19200", "--parity", "N", "--stopbits", "2", "--timeout", "0.2"]
READ = with_crc(bytes.fromhex("010300000002"))
READ_ANSWER = with_crc(bytes.fromhex("01030400070008"))
SILENT = with_crc(bytes.fromhex("040300000001"))


def test_every_row_an_update_cites_is_numbered_in_the_listing(tmp_path: Path) -> None:
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        proc = subprocess.Popen(
            [MODSCOPE, "live", str(tap), *LINE_ARGS, "--format", "text"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            assert proc.stderr is not None
            wait_ready(proc.stderr)
            for frame, pause in [(READ, 0.15), (READ_ANSWER, 0.3), (SILENT, 0.6)]:
                bus.inject(frame, source="master")
                time.sleep(pause)
        finally:
            proc.send_signal(2)
            out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    lines = out.splitlines()
    updates = [line.strip() for line in lines if line.strip().startswith("update #")]
    assert updates, out  # the test proves nothing without an update
    cited = {int(n) for u in updates for n in re.findall(r"#(\d+)", u)}
    numbered = {int(m.group(1)) for line in lines if (m := re.search(r"  #(\d+)$", line))}
    assert cited <= numbered, out
    assert "update #2: timeout" in updates  # the request no one answered, cited and numbered
