"""Provides the SunSpec model definitions and the decoding of their points.

SunSpec devices (inverters, meters, batteries) describe themselves on the bus: the
marker `SunS` (0x5375 0x6E53) at a base register, then a chain of models, each a model
id and a length in registers followed by that many registers, until the id 0xFFFF. What
a model's registers mean is defined by the SunSpec Alliance's model definitions, one
JSON file per model; the `pysunspec2` package ships them (`pip install
modscope[sunspec]`). They are read here as data: the package is located, never
imported (it imports pyserial, which `dissectors` never does).

A point's value is scaled by a *scale factor*, the power of ten held in another
register of the same model (a `sunssf` point named in the point's `sf`), so a value
can only be shown scaled when that register's value is known; the caller supplies it.
Every type has a value meaning "not implemented" (0xFFFF for uint16, 0x8000 for int16,
0 for the accumulators, NaN for float32, ...), shown as such rather than as a number.
"""

from __future__ import annotations

import importlib.util
import json
import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

from .model import RegisterValue

MARKER = (0x5375, 0x6E53)  # "SunS"
END_ID = 0xFFFF
HOLDING = "holding_registers"

# registers per value of each fixed-size type, and its "not implemented" raw value
_WORDS: Mapping[str, int] = MappingProxyType(
    {
        "int16": 1,
        "uint16": 1,
        "acc16": 1,
        "enum16": 1,
        "bitfield16": 1,
        "count": 1,
        "sunssf": 1,
        "pad": 1,
        "int32": 2,
        "uint32": 2,
        "acc32": 2,
        "enum32": 2,
        "bitfield32": 2,
        "float32": 2,
        "ipaddr": 2,
        "int64": 4,
        "uint64": 4,
        "acc64": 4,
        "float64": 4,
        "eui48": 4,
        "ipv6addr": 8,
    }
)
_NOT_IMPLEMENTED: Mapping[str, int] = MappingProxyType(
    {
        "int16": 0x8000,
        "uint16": 0xFFFF,
        "acc16": 0,
        "enum16": 0xFFFF,
        "bitfield16": 0xFFFF,
        "count": 0,
        "sunssf": 0x8000,
        "int32": 0x80000000,
        "uint32": 0xFFFFFFFF,
        "acc32": 0,
        "enum32": 0xFFFFFFFF,
        "bitfield32": 0xFFFFFFFF,
        "ipaddr": 0,
        "int64": 0x8000000000000000,
        "uint64": 0xFFFFFFFFFFFFFFFF,
        "acc64": 0,
    }
)
_SIGNED = frozenset({"int16", "int32", "int64", "sunssf"})
UNITS: Mapping[str, str] = MappingProxyType({"Pct": "%", "Secs": "s", "Ohms": "Ohm"})


@dataclass(frozen=True, slots=True)
class PointDef:
    """One point of a model: where it is (registers from the model's ID register), its
    type and size, and what the JSON says about it."""

    name: str
    label: str
    type: str
    offset: int  # from the model's first register (its ID is offset 0, L offset 1)
    size: int
    units: str = ""
    sf: str | int | None = None  # a sunssf point's name in the same model, or a constant
    symbols: Mapping[int, str] = field(default_factory=lambda: MappingProxyType({}))
    access: str = "R"
    group: str = ""  # the repeating group and its number ("module 2"), or ""

    @property
    def title(self) -> str:
        """What the listing calls it: the label (the point's id when it has none)."""
        label = self.label or self.name
        return f"{self.group} {label}" if self.group else label


@dataclass(frozen=True, slots=True)
class GroupDef:
    name: str
    points: tuple[PointDef, ...]  # offsets from the group's start
    size: int
    count: int | str  # 0: as many as fill the model; a name: a point holding the count


@dataclass(frozen=True, slots=True)
class ModelDef:
    """A SunSpec model: its fixed points (offsets from its ID register) and an optional
    repeating group after them."""

    id: int
    name: str
    label: str
    points: tuple[PointDef, ...]
    fixed_size: int  # registers of the fixed part, ID and L included
    repeat: GroupDef | None = None

    def layout(self, length: int) -> tuple[PointDef, ...]:
        """Every point of an instance whose L register says `length`, repeats expanded."""
        if self.repeat is None or self.repeat.size <= 0:
            return self.points
        body = length + 2 - self.fixed_size
        count = max(0, body // self.repeat.size)
        out = list(self.points)
        for k in range(min(count, 1000)):
            base = self.fixed_size + k * self.repeat.size
            for p in self.repeat.points:
                out.append(
                    PointDef(
                        p.name,
                        p.label,
                        p.type,
                        base + p.offset,
                        p.size,
                        p.units,
                        p.sf,
                        p.symbols,
                        p.access,
                        f"{self.repeat.name} {k + 1}",
                    )
                )
        return tuple(out)


def _symbols(raw: object) -> Mapping[int, str]:
    out: dict[int, str] = {}
    if isinstance(raw, list):
        for s in raw:
            if isinstance(s, dict) and isinstance(s.get("value"), int):
                out[s["value"]] = str(s.get("label") or s.get("name") or s["value"])
    return MappingProxyType(out)


def _points(raw: object, group: str = "") -> tuple[tuple[PointDef, ...], int]:
    out: list[PointDef] = []
    offset = 0
    for p in raw if isinstance(raw, list) else []:
        if not isinstance(p, dict):
            continue
        kind = str(p.get("type", "uint16"))
        size = p.get("size")
        size = size if isinstance(size, int) and size > 0 else _WORDS.get(kind, 1)
        sf = p.get("sf")
        out.append(
            PointDef(
                name=str(p.get("name", "")),
                label=str(p.get("label", "")),
                type=kind,
                offset=offset,
                size=size,
                units=UNITS.get(str(p.get("units", "")), str(p.get("units", ""))),
                sf=sf if isinstance(sf, str | int) and not isinstance(sf, bool) else None,
                symbols=_symbols(p.get("symbols")),
                access=str(p.get("access", "R")),
                group=group,
            )
        )
        offset += size
    return tuple(out), offset


def parse_model(data: Mapping[str, object]) -> ModelDef:
    """A model from its JSON definition (as in pysunspec2's `models/json/model_N.json`)."""
    group = data.get("group")
    model_id = data.get("id")
    if not isinstance(group, dict) or not isinstance(model_id, int):
        raise ValueError("not a SunSpec model definition: it needs `id` and `group`")
    points, size = _points(group.get("points"))
    repeat = None
    groups = group.get("groups")
    if isinstance(groups, list) and groups and isinstance(groups[0], dict):
        sub = groups[0]  # models repeat one group (nested groups: read the first level)
        sub_points, sub_size = _points(sub.get("points"))
        count = sub.get("count", 0)
        repeat = GroupDef(
            str(sub.get("name", "group")),
            sub_points,
            sub_size,
            count if isinstance(count, int | str) else 0,
        )
    return ModelDef(
        model_id,
        str(group.get("name", f"model_{model_id}")),
        str(group.get("label", "")),
        points,
        size,
        repeat,
    )


def definitions_folder() -> Path | None:
    """Where pysunspec2 keeps its model JSON files, found without importing it."""
    try:
        spec = importlib.util.find_spec("sunspec2")
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    for root in spec.submodule_search_locations:
        folder = Path(root) / "models" / "json"
        if folder.is_dir():
            return folder
    return None


class ModelLibrary:
    """SunSpec model definitions, read from a folder of `model_N.json` files when first
    asked for (a model that is missing or unreadable is None, and says why in `problems`)."""

    def __init__(self, folder: Path | None) -> None:
        self.folder = folder
        self._models: dict[int, ModelDef | None] = {}
        self.problems: dict[int, str] = {}

    @property
    def available(self) -> bool:
        return self.folder is not None

    def get(self, model_id: int) -> ModelDef | None:
        if model_id in self._models:
            return self._models[model_id]
        found: ModelDef | None = None
        if self.folder is not None:
            path = self.folder / f"model_{model_id}.json"
            try:
                found = parse_model(json.loads(path.read_text(encoding="utf-8")))
            except FileNotFoundError:
                self.problems[model_id] = f"no definition of model {model_id} in {self.folder}"
            except (OSError, ValueError) as exc:
                self.problems[model_id] = f"{path}: {exc}"
        self._models[model_id] = found
        return found

    def ids(self) -> list[int]:
        """The model ids the folder defines."""
        if self.folder is None:
            return []
        out = []
        for path in self.folder.glob("model_*.json"):
            tail = path.stem.removeprefix("model_")
            if tail.isdigit():
                out.append(int(tail))
        return sorted(out)


_DEFAULT: ModelLibrary | None = None


def default_library() -> ModelLibrary:
    """The models pysunspec2 ships (an empty library when it is not installed)."""
    global _DEFAULT
    if _DEFAULT is None:
        _DEFAULT = ModelLibrary(definitions_folder())
    return _DEFAULT


# -- values ----------------------------------------------------------------------------


def _number(words: Sequence[int]) -> int:
    n = 0
    for w in words:
        n = (n << 16) | (w & 0xFFFF)
    return n


def implemented(point: PointDef, words: Sequence[int]) -> bool:
    """False when the registers hold the type's "not implemented" value."""
    if point.type == "float32":
        return not math.isnan(struct.unpack(">f", struct.pack(">HH", *words[:2]))[0])
    if point.type == "string":
        return any(words)
    if point.type in ("acc16", "acc32", "acc64", "count", "ipaddr"):
        return True  # 0 is a real count; the accumulators' 0 is shown as 0
    missing = _NOT_IMPLEMENTED.get(point.type)
    return missing is None or _number(words[: point.size]) != missing


def raw_value(point: PointDef, words: Sequence[int]) -> int | float | str:
    """The point's value before scaling: a number, or the text of a string point."""
    w = [x & 0xFFFF for x in words[: point.size]]
    if point.type == "string":
        data = b"".join(x.to_bytes(2, "big") for x in w)
        return data.rstrip(b"\x00").decode("latin-1")
    if point.type == "float32":
        value: float = struct.unpack(">f", struct.pack(">HH", *w[:2]))[0]
        return value
    if point.type == "float64":
        value = struct.unpack(">d", struct.pack(">HHHH", *w[:4]))[0]
        return value
    n = _number(w)
    bits = 16 * len(w)
    if point.type in _SIGNED and n >= 1 << (bits - 1):
        n -= 1 << bits
    return n


def _shown_number(value: int | float, sf: int | None) -> tuple[int | float, str]:
    if isinstance(value, float):
        return value, f"{value:g}"
    if sf is None or sf == 0:
        return value, str(value)
    if sf > 0:
        scaled = value * 10**sf
        return scaled, str(scaled)
    decimals = -sf
    scaled_f = value / 10**decimals
    return scaled_f, f"{scaled_f:.{decimals}f}"


def decode_point(
    point: PointDef,
    address: int,
    words: Sequence[int],
    sf: int | None,
    *,
    write: bool = False,
    sf_known: bool = True,
) -> RegisterValue:
    """One point's registers as a named value. `sf` is the scale factor's value (None
    when the point has none); `sf_known` False: it has one but its value was never seen,
    so the raw value is shown and said to be unscaled."""
    raw = tuple(x & 0xFFFF for x in words)
    name = point.title
    unit = point.units
    if len(raw) < point.size:
        noun = "register" if point.size == 1 else "registers"
        text = f"{name} = ? (only {len(raw)} of {point.size} {noun} in this frame)"
        return RegisterValue(HOLDING, address, name, None, unit, text, raw, True)
    if point.type == "pad":
        return RegisterValue(HOLDING, address, name, None, "", f"{name} (pad)", raw)
    if not implemented(point, raw):
        text = f"{name} = not implemented"
        return RegisterValue(HOLDING, address, name, None, unit, text, raw)
    value = raw_value(point, raw)
    problems: tuple[str, ...] = ()
    if isinstance(value, str):
        return RegisterValue(HOLDING, address, name, value, "", f"{name} = {value!r}", raw)
    if point.type in ("enum16", "enum32"):
        meaning = point.symbols.get(int(value))
        shown = f"{meaning} ({value})" if meaning else f"{value} (not in the model)"
        return RegisterValue(HOLDING, address, name, meaning or value, "", f"{name} = {shown}", raw)
    if point.type in ("bitfield16", "bitfield32"):
        n = int(value)
        on = [point.symbols.get(b, f"bit {b}") for b in range(32) if n >> b & 1]
        shown = ", ".join(on) if on else "none"
        return RegisterValue(HOLDING, address, name, n, "", f"{name} = {shown}", raw)
    if point.type == "sunssf":
        text = f"{name} = {value} (scale 10^{value})"
        if not -10 <= int(value) <= 10:
            problems = (f"scale factor {value} is outside -10..10",)
        return RegisterValue(HOLDING, address, name, value, "", text, raw, False, problems)
    if point.sf is not None and not sf_known:
        text = f"{name} = {value} (raw; its scale factor {point.sf} not seen yet)"
        return RegisterValue(HOLDING, address, name, value, unit, text, raw)
    scaled, shown = _shown_number(value, sf)
    text = f"{name} = {shown} {unit}".rstrip()
    return RegisterValue(HOLDING, address, name, scaled, unit, text, raw, False, problems)
