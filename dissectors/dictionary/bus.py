"""Provides bus files and --unit bindings: which slave address on a line is which model."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

from .model import MODEL_PATTERN
from .reader import Source, Table
from .textfile import parse_toml, read_text

BUS_KEYS = ("format", "line", "dictionaries", "unit")
LINE_KEYS = ("baud", "parity", "stopbits", "bytesize", "mode")
UNIT_KEYS = ("address", "model", "label", "notes")
PARITY_WORDS = {"n": "N", "none": "N", "e": "E", "even": "E", "o": "O", "odd": "O", "m": "M",
                "mark": "M", "s": "S", "space": "S"}  # fmt: skip
_BINDING = re.compile(r"\s*(0[xX][0-9a-fA-F]+|[0-9]+)\s*=\s*([^:\s]+)\s*(?::(.*))?\Z", re.DOTALL)
BINDING_FORM = "write ADDRESS=MODEL or ADDRESS=MODEL:LABEL, e.g. 3=rvs-dn:Pump 1 (ADDRESS 1-247)"


@dataclass(frozen=True)
class UnitBinding:
    """One slave address bound to a device model, with an optional label."""

    address: int
    model: str
    label: str = ""
    line: int | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Bus:
    """A bus file: units by address, and line settings (baud, parity, ...) if given."""

    units: Mapping[int, UnitBinding]
    line: Mapping[str, int | str]
    path: str = ""
    dictionaries: tuple[Path, ...] = ()  # own files (TOML, HA YAML, CSV), beside the bus file


def parse_unit_binding(text: str) -> UnitBinding:
    """`3=rvs-dn` or `3=rvs-dn:Pump 1`. Bad text raises ValueError saying the form."""
    found = _BINDING.match(text)
    if found is None:
        raise ValueError(f"bad unit binding {text!r}: {BINDING_FORM}")
    address = int(found.group(1), 0)
    model = found.group(2)
    if not 1 <= address <= 247:
        raise ValueError(
            f"bad unit binding {text!r}: address {address} is not 1-247; {BINDING_FORM}"
        )
    if not MODEL_PATTERN.match(model):
        raise ValueError(
            f"bad unit binding {text!r}: model {model!r} is not a name; {BINDING_FORM}"
        )
    return UnitBinding(address, model, (found.group(3) or "").strip())


def _line_settings(src: Source, raw: object) -> dict[str, int | str]:
    table = Table(src, ("line",), raw, "[line]", LINE_KEYS)
    out: dict[str, int | str] = {}
    baud = table.integer("baud", 1, 10_000_000)
    if baud is not None:
        out["baud"] = baud
    parity = table.opt_text("parity")
    if parity is not None:
        letter = PARITY_WORDS.get(parity.lower())
        if letter is None:
            raise table.error("parity", f"[line]: parity '{parity}'", 'use "N", "E" or "O"')
        out["parity"] = letter
    stopbits = table.integer("stopbits")
    if stopbits is not None:
        if stopbits not in (1, 2):
            raise table.error("stopbits", f"[line]: stopbits = {stopbits}", "use 1 or 2")
        out["stopbits"] = stopbits
    bytesize = table.integer("bytesize")
    if bytesize is not None:
        if bytesize not in (7, 8):
            raise table.error("bytesize", f"[line]: bytesize = {bytesize}", "use 7 or 8")
        out["bytesize"] = bytesize
    mode = table.opt_text("mode")
    if mode is not None:
        if mode.lower() not in ("rtu", "ascii", "auto"):
            raise table.error("mode", f"[line]: mode '{mode}'", 'use "rtu", "ascii" or "auto"')
        out["mode"] = mode.lower()
    return out


def load_bus(path: str | Path) -> Bus:
    """Load and check a bus file. Raises DictionaryError naming the line and the fix."""
    name = str(path)
    data, lines = parse_toml(name, read_text(Path(path)))
    src = Source(name, lines)
    top = Table(src, (), data, "the bus file", BUS_KEYS)
    version = top.integer("format")
    if version is not None and version != 1:
        raise top.error(
            "format", f"format = {version} is not a bus format modscope reads", "write format = 1"
        )
    settings = _line_settings(src, top.get("line")) if top.has("line") else {}
    here = Path(path).parent
    own = tuple(here / Path(name).expanduser() for name in top.texts("dictionaries"))
    for file in own:
        if not file.is_file():
            raise top.error(
                "dictionaries",
                f"dictionary file {file} does not exist",
                'give paths relative to the bus file, e.g. dictionaries = ["pump.yaml"]',
            )
    units: dict[int, UnitBinding] = {}
    for index, raw in enumerate(top.tables("unit", "[[unit]]")):
        at = ("unit", index)
        table = Table(src, at, raw, f"unit #{index + 1}", UNIT_KEYS)
        address = table.integer("address", 1, 247)
        if address is None:
            raise table.missing("address", "address = 3 (the slave address, 1-247)")
        model = table.need_text("model", 'model = "rvs-dn"')
        if not MODEL_PATTERN.match(model):
            raise table.error(
                "model",
                f"unit {address}: model '{model}' is not a model name",
                "write the model as its dictionary's [device] model names it",
            )
        table.texts("notes")
        line = lines.line(at)
        before = units.get(address)
        if before is not None:
            raise table.error(
                "address",
                f"unit {address} (line {line}) is already bound to "
                f"'{before.model}' (line {before.line})",
                "give each address one [[unit]]",
            )
        units[address] = UnitBinding(address, model, table.label("label") or "", line)
    return Bus(MappingProxyType(units), MappingProxyType(settings), name, own)
