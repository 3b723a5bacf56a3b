"""Provides the suite's progress lines: each test file named when its first test starts, and
a line naming what still runs when nothing has been said for a while.

pytest's quiet mode prints only dots, and with pytest-xdist a long test (the bounded fuzz
harness, a real broker restarting) leaves the screen unchanged for a minute: whoever runs
`./check.sh` cannot tell a slow test from a hung one. This plugin runs in the process that
reports (the controller under xdist, which is told when each test starts on a worker), so
the lines come out in the order the work does.
"""

from __future__ import annotations

import os
import threading
import time

import pytest

QUIET_AFTER = float(os.environ.get("MODSCOPE_TEST_HEARTBEAT", "20"))  # seconds


class Progress:
    """Names each test file as it starts, and what runs after QUIET_AFTER seconds of quiet."""

    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.seen: set[str] = set()
        self.running: dict[str, float] = {}  # node id -> when it started
        self.said = time.monotonic()
        self.lock = threading.Lock()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._watch, name="progress", daemon=True)

    def _say(self, text: str) -> None:
        reporter = self.config.pluginmanager.get_plugin("terminalreporter")
        with self.lock:
            self.said = time.monotonic()
            if reporter is not None:
                writer = reporter._tw  # the dots' line is ended first, if one is open
                if writer.width_of_current_line:
                    writer.line()
                reporter.write_line(text)

    @pytest.hookimpl
    def pytest_sessionstart(self) -> None:
        self.thread.start()

    @pytest.hookimpl
    def pytest_sessionfinish(self) -> None:
        self.stop.set()

    @pytest.hookimpl
    def pytest_runtest_logstart(self, nodeid: str) -> None:
        path = nodeid.split("::", 1)[0]
        with self.lock:
            self.running[nodeid] = time.monotonic()
            new = path not in self.seen
            self.seen.add(path)
        if new:
            self._say(f"> {path}")

    @pytest.hookimpl
    def pytest_runtest_logfinish(self, nodeid: str) -> None:
        with self.lock:
            self.running.pop(nodeid, None)

    def _watch(self) -> None:
        while not self.stop.wait(1.0):
            now = time.monotonic()
            with self.lock:
                quiet = now - self.said
                running = sorted(self.running.items(), key=lambda item: item[1])
            if quiet >= QUIET_AFTER and running:
                names = ", ".join(f"{node} ({now - start:.0f} s)" for node, start in running[:3])
                self._say(f"  still running: {names}")


def register(config: pytest.Config) -> None:
    """Add the progress lines where they help: the reporting process, in quiet mode."""
    if hasattr(config, "workerinput") or config.get_verbosity() > 0:
        return  # an xdist worker reports nothing itself; -v already names every test
    if config.getoption("collectonly", False):
        return
    config.pluginmanager.register(Progress(config), "modscope-progress")
