"""Provides dictionary files: loading and checking TOML, and the models modscope ships."""

from __future__ import annotations

import re
import tomllib
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

from .build import Builder
from .device import DeviceDictionary
from .errors import DictionaryError
from .limits import load_toml
from .reader import Source
from .tomlpos import LineMap, scan_toml

DEVICES_DIR = Path(__file__).resolve().parent.parent / "devices"
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


def _build(path: Path) -> DeviceDictionary:
    text = read_text(path)
    data, lines = parse_toml(str(path), text)
    return Builder(Source(str(path), lines)).build(data)


@lru_cache(maxsize=64)
def _load_cached(path: str, stamp: tuple[int, ...]) -> DeviceDictionary:
    """One load per file version (`stamp`: its mtime, ctime, size and inode)."""
    return _build(Path(path))


def load_dictionary(path: str | Path) -> DeviceDictionary:
    """Load and check one dictionary file. Raises DictionaryError (with `.more`)."""
    file = Path(path)
    try:
        stat = file.stat()
    except OSError:
        return _build(file)  # read_text reports why
    stamp = (stat.st_mtime_ns, stat.st_ctime_ns, stat.st_size, stat.st_ino)
    return _load_cached(str(file), stamp)


def check_dictionary(path: str | Path) -> list[DictionaryError]:
    """Every problem in a dictionary file, in line order; empty when it is fine."""
    try:
        _build(Path(path))
    except DictionaryError as error:
        return list(error.all)
    return []


def _declared_model(path: Path) -> str | None:
    try:
        data = load_toml(str(path), path.read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, DictionaryError):
        return None
    device = data.get("device")
    model = device.get("model") if isinstance(device, dict) else None
    return model if isinstance(model, str) and model else None


def builtin_models() -> dict[str, Path]:
    """Model name -> shipped file, for every dissectors/devices/*.toml.

    A file whose model cannot be read is listed under its file name, so loading it
    reports what is wrong.
    """
    out: dict[str, Path] = {}
    for file in sorted(DEVICES_DIR.glob("*.toml")):
        out.setdefault(_declared_model(file) or file.stem, file)
    return out


def load_model(model: str, extra: Sequence[Path] = ()) -> DeviceDictionary:
    """The dictionary of `model`: from `extra` files first (--dict), then the shipped ones."""
    known: list[str] = []
    for file in extra:
        loaded = load_dictionary(file)
        if loaded.model == model:
            return loaded
        known.append(loaded.model)
    shipped = builtin_models()
    if model in shipped:
        return load_dictionary(shipped[model])
    known.extend(shipped)
    names = ", ".join(sorted(set(known))) or "(none)"
    raise DictionaryError(
        model,
        None,
        f"no dictionary for model '{model}'",
        f"use one of {names}, or give your own file with --dict FILE",
    )
