"""Provides the `needs` marker and the suite's progress lines (tests/support/progress.py).

A test marked `needs` runs an external program: where the program is missing it is
skipped, with a reason naming the program and the package that brings it (./check.sh
installs them with apt where it can; the rest of the suite runs anyway)."""

from __future__ import annotations

import os
import shutil

import pytest
from hypothesis import settings

from tests.support import progress

PACKAGES = {  # program -> the Debian package that has it
    "tshark": "tshark",
    "text2pcap": "wireshark-common (comes with tshark)",
    "socat": "socat",
    "mbpoll": "mbpoll",
    "mosquitto": "mosquitto",
    "mosquitto_pub": "mosquitto-clients",
    "mosquitto_sub": "mosquitto-clients",
    "tcpdump": "tcpdump",
    "tmux": "tmux",
    "prometheus": "prometheus",
}


# Property tests draw new examples on a developer's run; CI (CI=true) replays a fixed set,
# so that a submission lands or not on its own merits (an input a local run finds becomes
# an explicit @example beside its test).
# No example has a deadline: ./check.sh runs two workers a CPU, and an example that takes
# 200 ms on a quiet machine takes more there; speed is measured in benchmarks/, not here.
settings.register_profile("modscope", deadline=None)
settings.register_profile("ci", parent=settings.get_profile("modscope"), derandomize=True)
settings.load_profile("ci" if os.environ.get("CI") else "modscope")


def pytest_configure(config: pytest.Config) -> None:
    progress.register(config)
    config.addinivalue_line(
        "markers", "needs(*programs): skip, naming the program, where one is not installed"
    )


def find_program(name: str) -> str | None:
    """The program's path: on PATH, or in /usr/sbin (mosquitto), which a user's PATH may
    lack."""
    return shutil.which(name) or shutil.which(name, path="/usr/sbin")


def missing_reason(programs: tuple[str, ...]) -> str | None:
    """Why a test needing `programs` cannot run here, or None when all are installed."""
    missing = [p for p in programs if find_program(p) is None]
    if not missing:
        return None
    packages = sorted({PACKAGES.get(p, p) for p in missing})
    return f"{', '.join(missing)} not installed (apt-get install {' '.join(packages)})"


def pytest_runtest_setup(item: pytest.Item) -> None:
    for mark in item.iter_markers("needs"):
        reason = missing_reason(tuple(str(a) for a in mark.args))
        if reason is not None:
            pytest.skip(reason)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The tests marked `slow` first, the others in their order: with several workers a
    long test started near the end keeps one busy while the others have finished (an
    installed wheel's test takes about a minute of the suite's eight)."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
