"""Which commands take a sidecar index for which captures (`sniffer.session.index.pays`).

A serial recording in pcap or pcapng, framed as RTU by the compiled core, reads about as
fast from the capture as from a sidecar, and writing one doubles a day's `replay
--stats` (17.8 s against 38.0 s, 2026-12-07): `replay` and `export` neither write nor
read one for it. The TUI takes one for any capture (it shows the rows from it). Captures
slow to frame (network, text logs, ASCII, the pure-Python core) get one from `replay`."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from sniffer.session import index
from sniffer.session.session import DEMO_CAPTURE, open_session
from tests.session.test_replay_window import replayed
from tests.support.core import running
from tests.support.netbus import network_bus

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(autouse=True)
def any_size(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Sidecars for captures of any size, in a cache folder of the test's own."""
    monkeypatch.setattr(index, "MIN_SIZE", 0)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv("MODSCOPE_NO_INDEX", raising=False)


def _has_sidecar(path: Path) -> bool:
    return any(side.exists() for side in index.sidecars(path))


def test_a_serial_recording_gets_no_sidecar_from_replay_and_one_from_the_tui(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "demo.pcapng"
    shutil.copy(DEMO_CAPTURE, path)
    first = replayed([str(path)], 5)
    assert first[2] in (0, 1) and "unit  device" in first[0]
    assert not _has_sidecar(path)
    session, capture = open_session(path, interactive=True)  # as the TUI opens it
    session.ingest(capture.chunks())
    assert _has_sidecar(path)
    again, capture = open_session(path, interactive=True)
    again.ingest(capture.chunks())
    assert again.indexed_from is not None  # the TUI reads it back

    def refused(*args: object, **kwargs: object) -> None:
        raise AssertionError("replay read the sidecar of a serial recording")

    monkeypatch.setattr(index, "load", refused)
    assert replayed([str(path)], 5) == first  # framed again, the same table


def test_captures_slow_to_frame_get_a_sidecar_from_replay(tmp_path: Path) -> None:
    net = tmp_path / "net.pcap"
    net.write_bytes(network_bus([(k % 2, "poll") for k in range(40)]))
    log = tmp_path / "pymodbus-debug.log"
    shutil.copy(REPO / "captures" / "pymodbus-debug.log", log)
    for path in (net, log):
        replayed([str(path)], 5)
        assert _has_sidecar(path), path.name
    ascii_mode = tmp_path / "ascii.pcapng"
    shutil.copy(DEMO_CAPTURE, ascii_mode)
    replayed([str(ascii_mode), "--mode", "ascii"], 5)
    assert _has_sidecar(ascii_mode)
    pure = tmp_path / "pure.pcapng"
    shutil.copy(DEMO_CAPTURE, pure)
    with running(None):  # the pure-Python core frames it
        replayed([str(pure)], 5)
    assert _has_sidecar(pure)
