"""Provides reading dictionary files as text and TOML, with errors that name the line."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from .errors import DictionaryError
from .limits import load_toml
from .tomlpos import LineMap, scan_toml

_TOML_WHERE = re.compile(r"\s*\(at line (\d+), column (\d+)\)\s*$")


def read_text(path: Path) -> str:
    """A file's text, or a DictionaryError saying why it cannot be read."""
    try:
        data = path.read_bytes()
    except OSError as error:
        reason = error.strerror or str(error)
        raise DictionaryError(
            str(path), None, f"cannot read the file ({reason})", "check the path and permissions"
        ) from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = data[: error.start].count(b"\n") + 1
        raise DictionaryError(
            str(path), line, "the file is not UTF-8 text", "save it as UTF-8"
        ) from None


def parse_toml(path: str, text: str) -> tuple[dict[str, object], LineMap]:
    """tomllib's data and the lines of its keys; syntax errors carry tomllib's line."""
    try:
        data = load_toml(path, text)
    except tomllib.TOMLDecodeError as error:
        message = str(error)
        where = _TOML_WHERE.search(message)
        line = int(where.group(1)) if where else None
        column = where.group(2) if where else None
        message = _TOML_WHERE.sub("", message) if where else message
        fix = "correct the TOML syntax"
        if column is not None:
            fix += f" at column {column}"
        fix += (
            " (strings in double quotes, [table] and [[array]] headers, key = value, each key once)"
        )
        raise DictionaryError(path, line, f"TOML syntax: {message}", fix) from None
    lines = scan_toml(text)
    lines.set((), 1)
    return data, lines
