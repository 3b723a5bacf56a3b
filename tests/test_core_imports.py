"""The core works without the TUI: dissectors and sniffer (outside sniffer.tui) never
import Textual, and dissectors never imports sniffer or pyserial."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _core_modules() -> list[str]:
    found = []
    for package in ("dissectors", "sniffer"):
        for path in sorted((ROOT / package).rglob("*.py")):
            rel = path.relative_to(ROOT).with_suffix("")
            parts = list(rel.parts)
            if "tui" in parts:
                continue
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found.append(".".join(parts))
    return found


def _loaded_after_import(modules: list[str]) -> set[str]:
    code = (
        "import importlib, sys\n"
        f"for name in {modules!r}:\n"
        "    importlib.import_module(name)\n"
        "print('\\n'.join(sorted(sys.modules)))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    return set(out.stdout.split())


def test_every_core_module_imports_without_textual() -> None:
    modules = _core_modules()
    assert "sniffer.framing.serial" in modules and "dissectors.dissect" in modules
    loaded = _loaded_after_import(modules)
    assert not {m for m in loaded if m == "textual" or m.startswith("textual.")}


def test_dissectors_import_neither_sniffer_nor_pyserial() -> None:
    modules = [m for m in _core_modules() if m.startswith("dissectors")]
    loaded = _loaded_after_import(modules)
    assert not {m for m in loaded if m.split(".")[0] in ("sniffer", "serial", "textual")}
