"""docs/architecture.md names every module of sniffer/ and dissectors/ exactly once.

The convention: a module table row is a Markdown table row whose first cell is one
backquoted path from the repository root ending in `.py`, for example
`` | `sniffer/framing/pipeline.py` | what it holds | ``. Every module appears in the
first cell of exactly one such row. Prose may mention modules as often as it likes.

A package's `__init__.py` counts as a module only where it holds code, meaning anything
besides its docstring, imports and `__all__`. One that only describes its package is
not listed.

Every path the page names under `sniffer/`, `dissectors/`, `tests/` or `benchmarks/` must
exist, so that a renamed or removed module cannot linger in the prose either.
"""

from __future__ import annotations

import ast
import re
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "architecture.md"
PACKAGES = ("sniffer", "dissectors")

ROW = re.compile(r"^\|\s*`([^`\s]+\.py)`\s*\|")  # a table row whose first cell is a module
PATH = re.compile(r"`((?:sniffer|dissectors|tests|benchmarks)/[\w./-]*\.\w+)`")


def holds_code(path: Path) -> bool:
    """Whether a module says more than its docstring, imports and `__all__`."""
    body = ast.parse(path.read_text(encoding="utf-8")).body
    for node in body:
        if isinstance(node, ast.Import | ast.ImportFrom):
            continue
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
            continue  # the docstring
        if isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if all(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
                continue
        return True
    return False


def modules() -> set[str]:
    """Every module the page must name, as its path from the repository root."""
    found = set()
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            if path.name != "__init__.py" or holds_code(path):
                found.add(path.relative_to(ROOT).as_posix())
    return found


def named() -> Counter[str]:
    """How many module table rows name each path."""
    lines = DOC.read_text(encoding="utf-8").splitlines()
    return Counter(m.group(1) for line in lines if (m := ROW.match(line)))


def test_every_module_is_in_a_module_table() -> None:
    missing = sorted(modules() - set(named()))
    assert missing == [], f"add a row for each to its stage's table in {DOC.name}: {missing}"


def test_no_module_is_in_the_tables_twice() -> None:
    twice = sorted(path for path, count in named().items() if count > 1)
    assert twice == [], f"named in more than one table row of {DOC.name}: {twice}"


def test_the_tables_name_only_modules_that_must_be_there() -> None:
    # a renamed or removed module, or an `__init__.py` that only describes its package
    extra = sorted(set(named()) - modules())
    assert extra == [], f"not a module to list (gone, renamed, or an empty __init__): {extra}"


def test_every_path_the_page_names_exists() -> None:
    text = DOC.read_text(encoding="utf-8")
    gone = sorted({p for p in PATH.findall(text) if not (ROOT / p).exists()})
    assert gone == [], f"{DOC.name} names paths that do not exist: {gone}"


def test_the_reading_sees_what_it_must() -> None:
    # guards against the checks above passing because they read nothing
    rows = named()
    assert len(rows) > 100 and "sniffer/framing/pipeline.py" in rows
    assert holds_code(ROOT / "sniffer" / "sources" / "__init__.py")  # open_capture
    assert not holds_code(ROOT / "sniffer" / "framing" / "__init__.py")  # a docstring
    assert not holds_code(ROOT / "dissectors" / "dictionary" / "__init__.py")  # re-exports
    assert ROW.match("| `sniffer/vocab.py` | the vocabulary |")
    assert not ROW.match("| `rtu_scan` | the RTU framer's fast paths |")
