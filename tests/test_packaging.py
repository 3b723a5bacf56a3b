"""A wheel installed without the source tree works: the demo capture and the device
dictionaries are package data, `modscope` runs from any folder (issue 15, item 9)."""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
import tomllib
import venv
from pathlib import Path
from typing import Any

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


# -- extras and floors that are true (issue 26) ----------------------------------------------


def _project() -> dict[str, Any]:
    with (ROOT / "pyproject.toml").open("rb") as f:
        project: dict[str, Any] = tomllib.load(f)["project"]
    return project


def _names(requirements: list[str]) -> set[str]:
    return {re.split(r"[<>=!~\[; ]", r, maxsplit=1)[0].lower() for r in requirements}


def _third_party_imports(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "importorskip":
            arg = node.args[0]
            if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                found.add(arg.value.split(".")[0])
        elif isinstance(node, ast.Import):
            found |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module.split(".")[0])
    ours = {"sniffer", "dissectors", "tests", "pytest", "hypothesis", "__future__"}
    return {m for m in found if m not in sys.stdlib_module_names and m not in ours}


def test_the_analytics_extra_has_what_its_recipes_need() -> None:
    """docs/analytics.md's queries are run by tests/outputs/test_analytics_queries.py:
    what that test imports is what `pip install 'modscope[analytics]'` must bring."""
    extra = _names(_project()["optional-dependencies"]["analytics"])
    needed = _third_party_imports(ROOT / "tests" / "outputs" / "test_analytics_queries.py")
    assert {"duckdb", "pyarrow"} <= needed
    assert needed <= extra, f"missing from [analytics]: {sorted(needed - extra)}"


def test_the_textual_floor_is_the_one_check_sh_tests() -> None:
    """One `textual>=X` in the dependencies; ./check.sh reads X from pyproject.toml and runs
    tests/tui against exactly that release; docs/install.md names it."""
    floors = [
        m[1]
        for d in _project()["dependencies"]
        if (m := re.fullmatch(r"textual>=([0-9.]+)", d.replace(" ", "")))
    ]
    assert len(floors) == 1, "textual needs one floor, written textual>=X"
    check = (ROOT / "check.sh").read_text()
    assert '"textual==$FLOOR"' in check and 'PYTHONPATH="$FLOOR_DIR"' in check
    # the floor run is pytest over files of tests/tui, listed by name in FLOOR_TESTS
    floor_run = r'PYTHONPATH="\$FLOOR_DIR" "\$VENV/bin/pytest"[^\n]*\n[^\n]*floor_files'
    assert re.search(floor_run, check)
    listed = re.search(r'FLOOR_TESTS="([^"]*)"', check)
    assert listed and 'floor_files+=("tests/tui/$name.py")' in check
    for name in listed[1].split():
        assert (ROOT / "tests" / "tui" / f"{name}.py").is_file(), f"FLOOR_TESTS names {name}"
    assert f"Textual {floors[0]}" in (ROOT / "docs" / "install.md").read_text()
    # (the floor the check computes, by the same rule as this test, is the declared one)
    script = check.split("FLOOR=$(\"$VENV/bin/python\" - <<'PY'\n", 1)[1].split("\nPY\n", 1)[0]
    done = subprocess.run(
        [sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == floors[0]
