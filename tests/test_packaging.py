"""A wheel installed without the source tree works: the demo capture and the device
dictionaries are package data, `modscope` runs from any folder (issue 15, item 9)."""

from __future__ import annotations

import os
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _run(argv: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)


@pytest.mark.slow
def test_an_installed_wheel_runs_without_the_source_tree(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    wheels = tmp_path / "wheels"
    # the wheel and its dependencies (from pip's cache, else the index), then an offline
    # install of exactly those into a fresh venv that cannot see this checkout
    built = _run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "-w", str(wheels), "-q"], tmp_path, env
    )
    assert built.returncode == 0, built.stderr
    ours = sorted(wheels.glob("modscope-*.whl"))
    assert len(ours) == 1
    home = tmp_path / "venv"
    venv.create(home, with_pip=True)
    python = home / "bin" / "python"
    installed = _run(
        [str(python), "-m", "pip", "install", "-q", "--no-index", "--find-links", str(wheels),
         str(ours[0])],
        tmp_path,
        env,
    )  # fmt: skip
    assert installed.returncode == 0, installed.stderr
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    where = _run([str(python), "-c", "import sniffer; print(sniffer.__file__)"], elsewhere, env)
    assert where.returncode == 0 and str(home) in where.stdout  # not this checkout
    modscope = str(home / "bin" / "modscope")

    stats = _run([modscope, "replay", "--stats"], elsewhere, env)
    assert stats.returncode == 0, stats.stderr
    assert "demo.pcapng (19200 8E1" in stats.stdout
    assert "Pump 1 starter" in stats.stdout  # the demo's bus file came along

    models = _run([modscope, "dict", "list"], elsewhere, env)
    assert models.returncode == 0, models.stderr
    assert {"rvs-dn", "dcrl"} <= {line.split()[0] for line in models.stdout.splitlines()}

    serve = _run([modscope, "serve"], elsewhere, env)
    assert serve.returncode == 2
    assert "pip install 'modscope[serve]'" in serve.stderr  # as the README says
