"""The layout's promises, checked from the source: who may import whom.

The stages, bottom to top (each may import those below it, never those above):

    dissectors                                   protocol knowledge; never sniffer
    sniffer.vocab, model, text, errors, core     the vocabulary every stage shares
    sniffer.sources                              bytes and time from files
    sniffer.framing                              frames and pairs (only the pipelines
                                                 use the framer, framing.serial)
    sniffer.meaning | sniffer.analysis           what the frames mean | what they add up to
    sniffer.session                              a capture looked at (and its sidecar)
    sniffer.live                                 a serial line listened to
    sniffer.outputs                              listings, exports, MQTT
    sniffer.tui                                  the Textual app
    sniffer.cli                                  the command line (opens the TUI when asked)

The contracts themselves are in pyproject.toml (`[tool.importlinter]`) and
`test_lint_imports_keeps_every_contract` runs `lint-imports` on them: the layers above,
dissectors free of sniffer, Textual and pyserial, Textual only in the TUI, the framer only
in the pipelines, and no cycle between the packages of any package. Those replace the
checks this file made of the same rules by reading the source.

What import-linter cannot say is read here with ast: a cycle that runs through a
package's own `__init__` (acyclic_siblings compares siblings, never a package with its
children), counting imports inside functions, and `from pkg import x` as importing
`pkg`; which imports are made inside functions, and why; and that every exception the
contracts list is an import that never runs when its module loads. Imports under
`if TYPE_CHECKING:` never run, so they count only where a test says so.
"""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("dissectors", "sniffer")
TOP, FUNCTION, TYPING = "module level", "inside a function", "under TYPE_CHECKING"

# Every import made inside a function, by module, with why it waits: keep it that way,
# so a new one is a decision (and not a cycle or a layer break hidden from the load).
LAZY = {
    ("sniffer.cli.replay", "sniffer.tui.app"): "the TUI (Textual) only for a replay shown in it",
    ("sniffer.cli.together", "sniffer.tui.app"): "the TUI only for files replayed in it",
    ("sniffer.cli.tui", "sniffer.tui.app"): "the TUI only for the command that opens it",
    ("sniffer.cli.live", "sniffer.tui.app"): "the TUI only for a live line shown in it",
    ("sniffer.cli.serve", "textual_serve"): "the optional serve extra, for `serve` alone",
    ("sniffer.cli.serve", "aiohttp"): "textual-serve's web server (its guard), for `serve` alone",
    ("sniffer.core", "sniffer._core"): "the compiled core: may be missing or disabled",
    ("sniffer.live.port", "serial"): "pyserial's port enumeration, for `ports` alone",
    ("sniffer.outputs.mqtt.link", "paho"): "the optional MQTT extra, when publishing",
    ("sniffer.outputs.mqtt.subscribe", "paho"): "the optional MQTT extra, when watching",
    ("sniffer.outputs.parquet", "pyarrow"): "the optional analytics extra, for Parquet",
    ("sniffer.outputs.metrics", "prometheus_client"): "the optional metrics extra, for --metrics",
    ("dissectors.checks", "fastcrc"): "the fast CRC where installed, else pure Python",
    ("dissectors.dictionary.imports_ha", "yaml"): "the optional imports extra (PyYAML)",
    ("dissectors.dictionary.limits", "yaml"): "the optional imports extra (PyYAML)",
    ("dissectors.pdu.registry", "dissectors.pdu.vendor"): "a dictionary's own codes, if any",
}


def _name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


MODULES = {_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}
EXTENSIONS = {"sniffer._core"}  # compiled (sniffer/_core.c), not in MODULES


def _imports(name: str) -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """What `name` imports, by where the import statement is (TOP, FUNCTION, TYPING):
    every module whose code the import runs (`from pkg import name` runs `pkg` too, its
    `__init__`), and the modules the statements name (`from pkg import module` names
    `pkg.module` alone). Our modules as modules, anything else by its top-level package."""
    path = MODULES[name]
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    runs: dict[str, set[str]] = {TOP: set(), FUNCTION: set(), TYPING: set()}
    names: dict[str, set[str]] = {TOP: set(), FUNCTION: set(), TYPING: set()}

    def ours(dotted: str) -> str | None:
        while dotted and dotted not in MODULES and dotted not in EXTENSIONS:
            dotted = dotted.rpartition(".")[0]
        return dotted or None

    def module_of(dotted: str) -> str | None:
        return ours(dotted) if dotted.split(".")[0] in PACKAGES else dotted.split(".")[0]

    def add(node: ast.Import | ast.ImportFrom, where: str) -> None:
        if isinstance(node, ast.Import):
            named = {module_of(alias.name) for alias in node.names}
            ran = set(named)
        else:
            base = node.module or ""
            if node.level:
                parts = package[: len(package) - (node.level - 1)]
                base = ".".join([*parts, *([base] if base else [])])
            named = {module_of(f"{base}.{alias.name}") for alias in node.names}
            ran = named | {module_of(base)}
        names[where].update(m for m in named if m is not None and m != name)
        runs[where].update(m for m in ran if m is not None and m != name)

    def visit(nodes: list[ast.stmt], where: str) -> None:
        for node in nodes:
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                visit(node.body, TYPING)
                visit(node.orelse, where)
                continue
            if isinstance(node, ast.Import | ast.ImportFrom):
                add(node, where)
            inner = where
            if where == TOP and isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                inner = FUNCTION
            for field in ("body", "orelse", "finalbody", "handlers"):
                block = getattr(node, field, None)
                if isinstance(block, list):
                    visit([n for n in block if isinstance(n, ast.stmt)], inner)
            for case in getattr(node, "cases", []):  # match statements
                visit(case.body, inner)

    visit(ast.parse(path.read_text(encoding="utf-8")).body, TOP)
    return runs, names


_READ = {m: _imports(m) for m in MODULES}
IMPORTS = {m: runs for m, (runs, _names) in _READ.items()}  # for cycles: what runs
NAMED = {m: names for m, (_runs, names) in _READ.items()}  # what each statement names


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle through each strongly connected group of modules (none: acyclic)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []

    def connect(node: str) -> None:  # Tarjan's algorithm
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in sorted(graph[node]):
            if nxt not in index:
                connect(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            group = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                group.append(member)
                if member == node:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for module in sorted(graph):
        if module not in index:
            connect(module)
    return groups


def _pyproject() -> dict[str, Any]:
    with (ROOT / "pyproject.toml").open("rb") as handle:
        return tomllib.load(handle)


def _contracts() -> list[dict[str, Any]]:
    contracts: list[dict[str, Any]] = _pyproject()["tool"]["importlinter"]["contracts"]
    return contracts


def test_no_import_cycles_even_through_imports_inside_functions() -> None:
    graph = {m: (IMPORTS[m][TOP] | IMPORTS[m][FUNCTION]) & MODULES.keys() for m in MODULES}
    assert _cycles(graph) == []


def test_the_cycle_check_finds_a_cycle_through_a_function() -> None:
    # a guard against the check above passing because it cannot see one
    graph = {m: set(targets) for m, targets in {"a": {"b"}, "b": {"c"}, "c": {"a"}}.items()}
    assert _cycles(graph) == [["a", "b", "c"]]
    graph = {m: (IMPORTS[m][TOP] | IMPORTS[m][FUNCTION]) & MODULES.keys() for m in MODULES}
    graph["sniffer.vocab"] = graph["sniffer.vocab"] | {"sniffer.cli"}  # cli reaches vocab
    assert any("sniffer.vocab" in group for group in _cycles(graph))


def test_imports_inside_functions_are_the_known_lazy_ones() -> None:
    found = {(m, target) for m in MODULES for target in NAMED[m][FUNCTION]}
    assert found == set(LAZY)


def test_the_cli_loads_the_tui_only_inside_the_commands_that_open_it() -> None:
    at_load = {
        (m, t)
        for m in MODULES
        if m.startswith("sniffer.cli")
        for t in IMPORTS[m][TOP] | IMPORTS[m][TYPING]
        if t.startswith("sniffer.tui") or t in ("textual", "textual_serve")
    }
    assert at_load == set()
    lazily = {
        f"{m} -> {t}"
        for m in MODULES
        if m.startswith("sniffer.cli")
        for t in NAMED[m][FUNCTION]
        if t.startswith("sniffer.tui")
    }
    # exactly these are the exceptions of the contract that keeps Textual in the TUI
    (textual,) = [c for c in _contracts() if "sniffer.cli" in c.get("source_modules", ())]
    assert "textual" in textual["forbidden_modules"]
    assert set(textual["ignore_imports"]) == lazily != set()


def test_every_exception_to_a_contract_never_runs_when_its_module_loads() -> None:
    listed = [text for c in _contracts() for text in c.get("ignore_imports", ())]
    assert listed
    for text in listed:
        importer, _, imported = (part.strip() for part in text.partition("->"))
        where = IMPORTS[importer]
        assert imported not in where[TOP], text
        assert imported in where[FUNCTION] | where[TYPING], text


def test_the_sidecar_knows_the_session_state_not_the_session() -> None:
    # it writes and reads back a SessionState; the Session that owns one uses the sidecar
    index = IMPORTS["sniffer.session.index"]
    assert "sniffer.session.state" in index[TOP]
    assert "sniffer.session.session" not in index[TOP] | index[FUNCTION] | index[TYPING]


def test_the_layers_name_every_package_of_sniffer() -> None:
    (layers,) = [c for c in _contracts() if c["type"] == "layers"]
    named = {
        f"sniffer.{part.strip()}"
        for layer in layers["layers"]
        for part in layer.replace("|", ":").split(":")
    }
    children = {m for m in MODULES if m.count(".") == 1 and m.startswith("sniffer.")}
    assert layers["containers"] == ["sniffer"] and layers["exhaustive"] is True
    assert named == children


def test_lint_imports_keeps_every_contract() -> None:
    executable = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    executable = executable or shutil.which("lint-imports")
    if executable is None:
        pytest.skip("lint-imports (pip install import-linter) is not installed")
    # this checkout's packages, whatever the environment has installed
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    }
    done = subprocess.run(
        [executable, "--no-cache"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stdout + done.stderr
    contracts = len(_contracts())
    assert f"Contracts: {contracts} kept, 0 broken." in done.stdout, done.stdout


def test_the_contracts_see_the_whole_tree() -> None:
    # a guard against the checks above passing because they read nothing
    assert {"sniffer.vocab", "sniffer.framing.pipeline", "dissectors.pdu.registry"} <= set(MODULES)
    assert "sniffer.framing.serial" in IMPORTS["sniffer.framing.pipeline"][TOP]
    assert "sniffer.tui.app" in IMPORTS["sniffer.cli.tui"][FUNCTION]
    assert "sniffer.session.index" in IMPORTS["sniffer.session.paged"][TOP]
    assert "textual" in IMPORTS["sniffer.tui.app"][TOP]
