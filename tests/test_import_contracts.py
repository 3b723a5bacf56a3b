"""The layout's promises, checked from the source: who may import whom.

Read statically (ast), so a contract holds for every module whether or not a test runs
it. Module-level imports make the graph; imports inside functions (a command loading the
TUI only when asked) and under `TYPE_CHECKING` are counted only where a contract says
"anywhere". The flow, bottom to top:

    dissectors  (protocol knowledge; never sniffer)
    sniffer.vocab, model, text, errors          the vocabulary every stage shares
    sniffer.sources                              bytes and time from files
    framing (only pipelines use it), store, pairing, pipeline
    annotate, describe, stats, session           what a capture means
    outputs: listing, export, parquet, mqtt, capture (live), recorder ...
    sniffer.cli                                  the command line
    sniffer.tui                                  the Textual app (launched by the CLI)
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("dissectors", "sniffer")
# sniffer.core: which core runs (the compiled extension or pure Python), below everything
FOUNDATION = {"sniffer.vocab", "sniffer.model", "sniffer.text", "sniffer.errors", "sniffer.core"}
PIPELINES = {
    "sniffer.framing.pipeline",
    "sniffer.framing.tcp",
}  # tcpframing: the TCP framer and pipeline
# Upward imports made on purpose, each inside a function, each with its reason:
ALLOWED_UPWARD = {
    # a sigrok capture replayed without --baud measures the line by framing its bytes at
    # each candidate setting; only then is the estimator loaded
    ("sniffer.sources.sigrok", "sniffer.analysis.baud"),
}


def _name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


MODULES = {_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _imports(name: str, *, anywhere: bool) -> set[str]:
    """Modules of ours that `name` imports: at module level, or `anywhere`."""
    path = MODULES[name]
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found: set[str] = set()

    def targets(node: ast.Import | ast.ImportFrom) -> Iterator[str]:
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
            return
        base = node.module or ""
        if node.level:
            parts = package[: len(package) - (node.level - 1)]
            base = ".".join([*parts, *([base] if base else [])])
        yield base
        yield from (f"{base}.{alias.name}" for alias in node.names)

    def visit(nodes: list[ast.stmt], top: bool) -> None:
        for node in nodes:
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                if anywhere:
                    visit(node.body, False)
                continue
            if isinstance(node, ast.Import | ast.ImportFrom) and (top or anywhere):
                found.update(t for t in targets(node) if t in MODULES or _external(t))
            inner = top and not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
            for field in ("body", "orelse", "finalbody", "handlers"):
                block = getattr(node, field, None)
                if isinstance(block, list):
                    visit([n for n in block if isinstance(n, ast.stmt)], inner)

    visit(ast.parse(path.read_text(encoding="utf-8")).body, True)
    found.discard(name)
    return found


def _external(name: str) -> bool:
    return name.split(".")[0] in ("textual", "textual_serve", "serial")


def _ours(imports: set[str]) -> set[str]:
    return {m for m in imports if m in MODULES}


def test_no_import_cycles() -> None:
    graph = {m: _ours(_imports(m, anywhere=False)) for m in MODULES}
    state: dict[str, int] = {}  # 1 on the path, 2 done
    cycles: list[list[str]] = []

    def walk(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                cycles.append([*path[path.index(nxt) :], nxt])
            elif nxt not in state:
                walk(nxt, [*path, nxt])
        state[node] = 2

    for module in sorted(graph):
        if module not in state:
            walk(module, [module])
    assert cycles == []


def test_dissectors_never_import_sniffer() -> None:
    bad = {
        (m, t)
        for m in MODULES
        if m.startswith("dissectors")
        for t in _imports(m, anywhere=True)
        if t.startswith("sniffer") or _external(t)
    }
    assert bad == set()


def test_only_the_tui_imports_textual() -> None:
    bad = {
        (m, t)
        for m in MODULES
        if not m.startswith("sniffer.tui")
        for t in _imports(m, anywhere=False)
        if t.split(".")[0] == "textual"
    }
    assert bad == set()


def test_only_pipelines_import_the_framer() -> None:
    users = {m for m in MODULES if "sniffer.framing.serial" in _imports(m, anywhere=True)}
    assert users <= PIPELINES


def test_the_vocabulary_imports_nothing_above_it() -> None:
    bad = {
        (m, t)
        for m in FOUNDATION
        for t in _ours(_imports(m, anywhere=True))
        if t.startswith("sniffer") and t not in FOUNDATION and t != "sniffer"
    }
    assert bad == set()


def test_sources_import_only_the_vocabulary_and_each_other() -> None:
    bad = {
        (m, t)
        for m in MODULES
        if m.startswith("sniffer.sources")
        for t in _ours(_imports(m, anywhere=True))
        if t.startswith("sniffer")
        and not t.startswith("sniffer.sources")
        and t not in FOUNDATION
        and t != "sniffer"
        and (m, t) not in ALLOWED_UPWARD
    }
    assert bad == set()


def test_nothing_below_the_cli_imports_it() -> None:
    bad = {
        (m, t)
        for m in MODULES
        if not m.startswith("sniffer.cli")
        for t in _ours(_imports(m, anywhere=True))
        if t.startswith("sniffer.cli")
    }
    assert bad == set()


def test_only_the_cli_launches_the_tui_and_only_when_asked() -> None:
    # the core never imports the TUI; the CLI loads it inside the command that opens it,
    # so `modscope replay --format jsonl` never loads Textual
    anywhere = {
        (m, t)
        for m in MODULES
        if not m.startswith(("sniffer.tui", "sniffer.cli"))
        for t in _ours(_imports(m, anywhere=True))
        if t.startswith("sniffer.tui")
    }
    assert anywhere == set()
    at_load = {
        (m, t)
        for m in MODULES
        if m.startswith("sniffer.cli")
        for t in _ours(_imports(m, anywhere=False))
        if t.startswith("sniffer.tui")
    }
    assert at_load == set()


def test_the_contracts_see_the_whole_tree() -> None:
    # a guard against the checks above passing because they read nothing
    assert {"sniffer.vocab", "sniffer.framing.pipeline", "dissectors.pdu.registry"} <= set(MODULES)
    assert "sniffer.framing.serial" in _ours(_imports("sniffer.framing.pipeline", anywhere=False))
    assert "sniffer.tui.app" in _ours(_imports("sniffer.cli.tui", anywhere=True))
