"""The TUI in rooms: no class of the project grows past what one reader keeps in mind, and
every key of the main screen reaches a room through an action of the App."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

from sniffer.tui.app import ModscopeApp
from sniffer.tui.keys import KEYS
from sniffer.tui.rooms.feeding import Flag

ROOT = Path(__file__).resolve().parents[2]
LIMIT = 500  # lines of a class, from its first decorator to its last line


def class_lengths() -> dict[str, int]:
    """Every class (nested ones too) in sniffer/ and dissectors/: 'path: Name' -> lines."""
    out: dict[str, int] = {}
    for package in ("sniffer", "dissectors"):
        for path in sorted((ROOT / package).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
            for node in ast.walk(tree):
                if isinstance(node, ast.ClassDef):
                    first = min([node.lineno] + [d.lineno for d in node.decorator_list])
                    end = node.end_lineno or node.lineno
                    out[f"{path.relative_to(ROOT).as_posix()}: {node.name}"] = end - first + 1
    return out


def test_the_walk_measures_the_classes_it_must() -> None:
    lengths = class_lengths()
    assert any(name.startswith("dissectors/") for name in lengths)
    # as long as Python itself says (the source lines `inspect` finds for the class)
    assert lengths["sniffer/tui/app.py: ModscopeApp"] == len(inspect.getsourcelines(ModscopeApp)[0])
    assert lengths["sniffer/tui/rooms/feeding.py: Flag"] == len(inspect.getsourcelines(Flag)[0])


def test_no_class_is_longer_than_the_limit() -> None:
    too_long = {name: n for name, n in class_lengths().items() if n > LIMIT}
    assert too_long == {}, f"classes over {LIMIT} lines: {too_long}"


def test_every_key_of_the_main_screen_has_an_action_on_the_app() -> None:
    for key in KEYS:
        name = key.action.split("(")[0]
        assert callable(getattr(ModscopeApp, f"action_{name}", None)), key.action
