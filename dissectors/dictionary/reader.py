"""Provides typed, line-aware reading of parsed TOML tables, with errors that say the fix."""

from __future__ import annotations

import math
from collections.abc import Sequence

from .errors import DictionaryError, nearest
from .tomlpos import KeyPath, LineMap


def kind(value: object) -> str:
    """How a TOML value is described in messages."""
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, int):
        return f"the integer {value}"
    if isinstance(value, float):
        return f"the number {value!r}"
    if isinstance(value, str):
        short = value if len(value) <= 30 else value[:29] + "…"
        return f'the string "{short}"'
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    return f"a {type(value).__name__}"


class Source:
    """The file being read: its name for messages and where its keys are."""

    def __init__(self, path: str, lines: LineMap) -> None:
        self.path = path
        self.lines = lines

    def error(self, at: KeyPath, message: str, fix: str) -> DictionaryError:
        return DictionaryError(self.path, self.lines.line(at), message, fix)


class Table:
    """One table of the file, checked for unknown keys on creation."""

    def __init__(
        self, src: Source, at: KeyPath, data: object, what: str, known: Sequence[str]
    ) -> None:
        self.src = src
        self.at = at
        self.what = what
        if not isinstance(data, dict):
            raise src.error(at, f"{what} must be a table, not {kind(data)}", "write it as a table")
        self.data: dict[str, object] = data
        for key in data:
            if key not in known:
                close = nearest(key, known)
                if close is not None:
                    fix = f"write '{close}' instead of '{key}'"
                else:
                    fix = f"remove it; {what} takes {', '.join(known)}"
                raise self.error(key, f"{what}: unknown key '{key}'", fix)

    def error(self, key: str | None, message: str, fix: str) -> DictionaryError:
        at = self.at if key is None else (*self.at, key)
        return self.src.error(at, message, fix)

    def has(self, key: str) -> bool:
        return key in self.data

    def get(self, key: str) -> object:
        return self.data.get(key)

    def missing(self, key: str, example: str) -> DictionaryError:
        return self.error(None, f"{self.what}: '{key}' is missing", f"add {example}")

    def wrong(self, key: str, expected: str, example: str) -> DictionaryError:
        value = self.data[key]
        return self.error(
            key, f"{self.what}: '{key}' must be {expected}, not {kind(value)}", f"write {example}"
        )

    def text(self, key: str, default: str = "") -> str:
        found = self.opt_text(key)
        return default if found is None else found

    def need_text(self, key: str, example: str) -> str:
        found = self.label(key)
        if found is None:
            raise self.missing(key, example)
        if not found.strip():
            raise self.error(key, f"{self.what}: '{key}' is empty", f"write {example}")
        return found

    def label(self, key: str) -> str | None:
        """A string shown on one line (a name, a unit): no control characters."""
        found = self.opt_text(key)
        if found is not None and not found.isprintable():
            raise self.error(
                key,
                f"{self.what}: '{key}' holds a control character or line break",
                "keep it to one line of printable text",
            )
        return found

    def opt_text(self, key: str) -> str | None:
        value = self.data.get(key)
        if value is None:
            return None
        if not isinstance(value, str):
            raise self.wrong(key, "a string", f'{key} = "..." with quotes')
        return value

    def integer(self, key: str, low: int | None = None, high: int | None = None) -> int | None:
        value = self.data.get(key)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.wrong(key, "an integer", f"{key} = 12 (decimal) or 0x0C (hex), no quotes")
        if (low is not None and value < low) or (high is not None and value > high):
            limits = f"from {low} to {high}" if high is not None else f"of at least {low}"
            raise self.error(
                key, f"{self.what}: {key} = {value} is out of range", f"use a value {limits}"
            )
        return value

    def need_integer(self, key: str, low: int | None = None, high: int | None = None) -> int:
        found = self.integer(key, low, high)
        if found is None:
            raise self.missing(key, f"{key} = N")
        return found

    def number(self, key: str) -> int | float | None:
        value = self.data.get(key)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.wrong(key, "a number", f"{key} = 0.1 (no quotes)")
        if isinstance(value, float) and not math.isfinite(value):
            raise self.wrong(key, "a finite number", f"{key} = 0.1")
        return value

    def flag(self, key: str) -> bool | None:
        value = self.data.get(key)
        if value is None:
            return None
        if not isinstance(value, bool):
            raise self.wrong(key, "true or false", f"{key} = true")
        return value

    def texts(self, key: str) -> tuple[str, ...]:
        """A string or an array of strings."""
        value = self.data.get(key)
        if value is None:
            return ()
        if isinstance(value, str):
            return (value,)
        if isinstance(value, list) and all(isinstance(item, str) for item in value):
            return tuple(str(item) for item in value)
        raise self.wrong(key, "a string or an array of strings", f'{key} = ["...", "..."]')

    def tables(self, key: str, header: str) -> list[object]:
        """An array of tables (`[[key]]` or `key = [ {...} ]`)."""
        value = self.data.get(key)
        if value is None:
            return []
        if not isinstance(value, list):
            raise self.error(
                key,
                f"{self.what}: '{key}' must be an array of tables, not {kind(value)}",
                f"write each one under its own {header} header",
            )
        return list(value)

    def subtable(self, key: str) -> dict[str, object] | None:
        value = self.data.get(key)
        if value is None:
            return None
        if not isinstance(value, dict):
            raise self.wrong(key, "a table", f'{key} = {{ "0" = "..." }} or a [{key}] section')
        return value
