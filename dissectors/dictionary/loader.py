"""Provides dictionary files: loading and checking TOML, Home Assistant YAML and CSV, and
the models modscope ships.

Every place that takes a dictionary file (--dict, a bus file's `dictionaries`, `dict
show`, `dict check`) comes through `load_dictionaries`, which tells the formats apart by
the file name: `.yaml`/`.yml` is a Home Assistant `modbus:` configuration (one dictionary
per hub and slave), `.csv` a register list, anything else a modscope TOML dictionary.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

from .build import Builder
from .device import DeviceDictionary
from .errors import DictionaryError
from .imports_csv import import_csv
from .imports_ha import import_home_assistant
from .limits import load_toml
from .reader import Source
from .textfile import parse_toml, read_text

__all__ = [
    "DEVICES_DIR",
    "builtin_models",
    "check_dictionary",
    "file_format",
    "load_dictionaries",
    "load_dictionary",
    "load_model",
    "parse_toml",
    "read_text",
]

DEVICES_DIR = Path(__file__).resolve().parent.parent / "devices"
FORMAT_NAMES = {
    "toml": "TOML dictionary",
    "yaml": "Home Assistant YAML",
    "csv": "CSV register list",
}


def file_format(path: str | Path) -> str:
    """`toml`, `yaml` or `csv`: how a dictionary file is read, from its name."""
    suffix = Path(path).suffix.lower()
    if suffix in (".yaml", ".yml"):
        return "yaml"
    if suffix == ".csv":
        return "csv"
    return "toml"


def _build(path: Path) -> tuple[DeviceDictionary, ...]:
    kind = file_format(path)
    if kind == "yaml":
        return tuple(import_home_assistant(path))
    if kind == "csv":
        return (import_csv(path),)
    text = read_text(path)
    data, lines = parse_toml(str(path), text)
    return (Builder(Source(str(path), lines)).build(data),)


@lru_cache(maxsize=64)
def _load_cached(path: str, stamp: tuple[int, ...]) -> tuple[DeviceDictionary, ...]:
    """One load per file version (`stamp`: its mtime, ctime, size and inode)."""
    return _build(Path(path))


def load_dictionaries(path: str | Path) -> tuple[DeviceDictionary, ...]:
    """Every dictionary one file holds (TOML and CSV: one; Home Assistant YAML: one per
    hub and slave). Raises DictionaryError (with `.more` for further problems)."""
    file = Path(path)
    try:
        stat = file.stat()
    except OSError:
        return _build(file)  # read_text reports why
    return _load_cached(str(file), _stamp(stat))


def _stamp(stat: os.stat_result) -> tuple[int, ...]:
    """What tells one version of a file from the next: mtime, ctime, size and inode."""
    return (stat.st_mtime_ns, stat.st_ctime_ns, stat.st_size, stat.st_ino)


def load_dictionary(path: str | Path) -> DeviceDictionary:
    """The one dictionary of a file; a file holding several is a DictionaryError naming them."""
    found = load_dictionaries(path)
    if len(found) != 1:
        models = ", ".join(d.model for d in found)
        raise DictionaryError(
            str(path),
            None,
            f"the file holds {len(found)} device dictionaries ({models})",
            "name the one you mean by its model, e.g. --unit 3=MODEL with --dict FILE",
        )
    return found[0]


def check_dictionary(path: str | Path) -> list[DictionaryError]:
    """Every problem in a dictionary file of any format, in line order; empty when fine."""
    try:
        _build(Path(path))
    except DictionaryError as error:
        return list(error.all)
    return []


def _declared_model(path: Path) -> str | None:
    try:
        stat = path.stat()
    except OSError:
        return None
    return _declared_model_cached(str(path), _stamp(stat))


@lru_cache(maxsize=64)
def _declared_model_cached(path: str, stamp: tuple[int, ...]) -> str | None:
    """The model a shipped file declares, read once per file version: every --unit and
    bus-file line looks its model up here, and parsing the shipped files (ved903b's is
    87 KB of TOML) cost about 0.17 s a lookup, 5 s for a bus of 32 such units."""
    try:
        data = load_toml(path, Path(path).read_text(encoding="utf-8-sig"))
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


def load_model(
    model: str,
    extra: Sequence[str | Path] = (),
    *,
    named_in: str | None = None,
    line: int | None = None,
) -> DeviceDictionary:
    """The dictionary of `model`: from `extra` files first (--dict), then the shipped ones.

    `named_in` and `line` say where the model was asked for (a bus file and its line), so
    an unknown model is reported there.
    """
    known: list[str] = []
    for file in extra:
        for loaded in load_dictionaries(file):
            if loaded.model == model:
                return loaded
            known.append(loaded.model)
    shipped = builtin_models()
    if model in shipped:
        return load_dictionary(shipped[model])
    known.extend(shipped)
    names = ", ".join(sorted(set(known))) or "(none)"
    raise DictionaryError(
        named_in or model,
        line,
        f"no dictionary for model '{model}'",
        f"use one of {names}, or give your own file with --dict FILE",
    )
