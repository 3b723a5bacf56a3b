"""Provides the Home Assistant import: `modbus:` YAML to device dictionaries.

The YAML becomes the data a TOML dictionary holds and is checked by the same builder,
so errors name the file and line too.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .build import FORMAT, Builder
from .device import DeviceDictionary
from .errors import DictionaryError, nearest, raise_all
from .limits import check_yaml
from .model import TYPES
from .reader import Source, kind
from .textfile import read_text
from .tomlpos import LineMap

if TYPE_CHECKING:
    import yaml

HA_TAGS = (
    "!secret",
    "!include",
    "!include_dir_list",
    "!include_dir_named",
    "!include_dir_merge_list",
    "!include_dir_merge_named",
    "!env_var",
    "!input",
)
HA_TABLES: Mapping[str, str] = {
    "holding": "holding_registers",
    "holdings": "holding_registers",
    "input": "input_registers",
    "coil": "coils",
    "coils": "coils",
    "discrete_input": "discrete_inputs",
    "discrete": "discrete_inputs",
}
HA_TYPES: Mapping[str, str] = {
    "int8": "s8",
    "uint8": "u8",
    "int16": "s16",
    "uint16": "u16",
    "int32": "s32",
    "uint32": "u32",
    "int64": "s64",
    "uint64": "u64",
    "float32": "f32",
    "float64": "f64",
    "string": "str",
}
HA_STRUCTS: Mapping[str, str] = {
    "h": "s16",
    "H": "u16",
    "i": "s32",
    "I": "u32",
    "l": "s32",
    "L": "u32",
    "q": "s64",
    "Q": "u64",
    "f": "f32",
    "d": "f64",
}
HA_SWAPS: Mapping[str, str] = {
    "none": "high_first",
    "byte": "high_first_swapped",
    "word": "low_first",
    "word_byte": "low_first_swapped",
}
HA_PLATFORMS = ("sensors", "binary_sensors", "switches", "fans", "lights", "climates", "covers")


class _LineDict(dict[str, Any]):
    """A YAML mapping that remembers the line it starts on."""

    line: int = 0


def _yaml_loader() -> type[yaml.SafeLoader]:
    import yaml

    class HomeAssistantLoader(yaml.SafeLoader):
        """yaml.SafeLoader that keeps mapping lines and reads HA's own tags as text."""

    def mapping(loader: yaml.SafeLoader, node: yaml.MappingNode) -> Any:
        data = _LineDict()
        data.line = node.start_mark.line + 1
        yield data
        for key, value in loader.construct_mapping(node).items():
            data[str(key)] = value

    def placeholder(loader: yaml.SafeLoader, node: yaml.Node) -> str:
        # HA's tags point elsewhere (secrets, other files, the environment): never followed.
        value = node.value if isinstance(node, yaml.ScalarNode) else ""
        return f"{node.tag} {value}".strip()

    HomeAssistantLoader.add_constructor("tag:yaml.org,2002:map", mapping)
    for tag in HA_TAGS:
        HomeAssistantLoader.add_constructor(tag, placeholder)
    return HomeAssistantLoader


def _read_yaml(path: str, text: str) -> object:
    try:
        import yaml
    except ImportError:  # pragma: no cover - PyYAML is in the `imports` extra
        raise DictionaryError(
            path, None, "Home Assistant import needs PyYAML", "pip install 'modscope[imports]'"
        ) from None
    try:
        # A SafeLoader: only plain YAML types are built, no tag ever runs code.
        check_yaml(path, text)
        return yaml.load(text, Loader=_yaml_loader())
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        line = mark.line + 1 if mark is not None else None
        problem = error.problem or "not valid YAML"
        if "constructor" in problem:
            raise DictionaryError(
                path,
                line,
                f"YAML tag not allowed: {problem}",
                "remove the tag; modscope reads plain YAML and never runs tags",
            ) from None
        raise DictionaryError(
            path, line, f"YAML syntax: {problem}", "correct the YAML at that line"
        ) from None
    except yaml.YAMLError as error:
        raise DictionaryError(path, None, f"YAML: {error}", "correct the YAML") from None


@dataclass
class _Unit:
    """The entries one HA hub has for one slave address, being collected."""

    hub: str
    slave: int
    line: int
    entries: list[dict[str, object]] = field(default_factory=list)
    lines: list[int] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


class _HomeAssistant:
    def __init__(self, path: str) -> None:
        self.path = path
        self.units: dict[tuple[str, int], _Unit] = {}

    def error(self, line: int | None, message: str, fix: str) -> DictionaryError:
        return DictionaryError(self.path, line, message, fix)

    def hubs(self, data: object) -> list[object]:
        if isinstance(data, dict) and "modbus" in data:
            data = data["modbus"]
        if isinstance(data, dict) and any(key in data for key in HA_PLATFORMS):
            data = [data]
        if isinstance(data, str) and data.startswith("!include"):
            raise self.error(
                None,
                f"the modbus section is '{data}', kept in another file",
                "import the included file itself",
            )
        if not isinstance(data, list):
            raise self.error(
                getattr(data, "line", 1),
                f"no Home Assistant modbus hubs here (found {kind(data)})",
                "give the configuration.yaml with a modbus: list, or the file it includes",
            )
        return data

    def run(self, data: object) -> list[DeviceDictionary]:
        problems: list[DictionaryError] = []
        for number, hub in enumerate(self.hubs(data)):
            if not isinstance(hub, _LineDict):
                raise self.error(None, f"modbus hub #{number + 1} is not a mapping", "see HA docs")
            name = str(hub.get("name") or "modbus_hub")
            for platform in HA_PLATFORMS:
                items = hub.get(platform) or []
                if not isinstance(items, list):
                    raise self.error(
                        hub.line, f"hub '{name}': {platform} is not a list", "use a list"
                    )
                for item in items:
                    if not isinstance(item, _LineDict):
                        raise self.error(
                            hub.line,
                            f"hub '{name}': an item of {platform} is not a mapping",
                            "fix it",
                        )
                    try:
                        self.item(name, hub.line, platform, item)
                    except DictionaryError as error:
                        problems.append(error)  # report every item, not only the first
        raise_all(problems)
        if not self.units:
            raise self.error(
                1,
                "no Home Assistant modbus sensors, switches or the like found",
                "give a file whose modbus: hubs list sensors, binary_sensors, switches, ...",
            )
        out: list[DeviceDictionary] = []
        for unit in self.units.values():
            try:
                out.append(self.dictionary(unit))
            except DictionaryError as error:
                problems.append(error)
        raise_all(problems)
        return out

    def unit(self, hub: str, hub_line: int, item: _LineDict) -> _Unit:
        slave = item.get("slave", item.get("device_address", item.get("unit", 0)))
        if isinstance(slave, bool) or not isinstance(slave, int) or not 0 <= slave <= 255:
            raise self.error(item.line, f"slave {slave!r} is not an address 0-255", "fix slave")
        key = (hub, slave)
        if key not in self.units:
            self.units[key] = _Unit(hub, slave, hub_line)
        return self.units[key]

    def add(self, unit: _Unit, line: int, entry: dict[str, object]) -> None:
        unit.entries.append(entry)
        unit.lines.append(line)

    def address(self, item: _LineDict, key: str = "address") -> int:
        value = item.get(key)
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 65535:
            raise self.error(
                item.line,
                f"'{item.get('name', '?')}': {key} {value!r} is not a register address 0-65535",
                f"write {key}: N",
            )
        return value

    def table(self, item: _LineDict, key: str, default: str) -> str:
        given = str(item.get(key, default))
        found = HA_TABLES.get(given)
        if found is None:
            close = nearest(given, HA_TABLES)
            fix = f"write '{close}'" if close else f"use one of {', '.join(HA_TABLES)}"
            raise self.error(item.line, f"'{item.get('name', '?')}': {key} '{given}'", fix)
        return found

    def value(self, item: _LineDict, unit: _Unit) -> dict[str, object] | None:
        """The value keys of a sensor or climate: type, scale, unit, order."""
        out: dict[str, object] = {}
        name = str(item.get("name", "?"))
        data_type = str(item.get("data_type", "int16"))
        count = item.get("count")
        count = count if isinstance(count, int) and not isinstance(count, bool) else None
        legacy = {"int": "s", "uint": "u", "float": "f"}
        if data_type in HA_TYPES:
            type_name = HA_TYPES[data_type]
        elif data_type in legacy:
            words = count or (2 if data_type == "float" else 1)
            bits = {1: 16, 2: 32, 4: 64}.get(words)
            if bits is None or (data_type == "float" and bits == 16):
                unit.notes.append(f"'{name}': {data_type} over {words} registers left out")
                return None
            type_name = f"{legacy[data_type]}{bits}"
        elif data_type in ("custom", "struct"):
            structure = str(item.get("structure", "")).lstrip("<>!=@")
            type_name = HA_STRUCTS.get(structure, "")
            if not type_name:
                unit.notes.append(f"'{name}': custom structure '{structure}' left out")
                return None
        else:
            unit.notes.append(f"'{name}': data_type {data_type} has no dictionary type; left out")
            return None
        out["type"] = type_name
        if type_name in ("u8", "s8"):
            out["byte"] = "low"
        if type_name == "str":
            out["length"] = count or 1
        swap = str(item.get("swap", "none"))
        order = HA_SWAPS.get(swap)
        if order is None:
            raise self.error(
                item.line, f"'{name}': swap '{swap}'", "use none, byte, word or word_byte"
            )
        if type_name in ("u16", "s16", "str") and order.startswith("low_first"):
            order = "high_first_swapped" if order.endswith("swapped") else "high_first"
        if type_name not in ("u8", "s8") and order != "high_first":
            out["word_order"] = order
        elif type_name not in ("u8", "s8", "u16", "s16", "str"):
            out["word_order"] = "high_first"
        for ha_key, key in (("scale", "scale"), ("offset", "offset"), ("precision", "precision")):
            given = item.get(ha_key)
            if given is not None and type_name != "str":
                if isinstance(given, bool) or not isinstance(given, (int, float)):
                    raise self.error(item.line, f"'{name}': {ha_key} {given!r}", "use a number")
                out[key] = given
        if out.get("scale") == 1 and "precision" not in out:
            out.pop("scale")
        unit_text = item.get("unit_of_measurement")
        if isinstance(unit_text, str):
            out["unit"] = unit_text
        return out

    def item(self, hub: str, hub_line: int, platform: str, item: _LineDict) -> None:
        unit = self.unit(hub, hub_line, item)
        name = str(item.get("name") or f"{platform} at line {item.line}")
        extra = item.get("slave_count", item.get("virtual_count", 0))
        extra = extra if isinstance(extra, int) and not isinstance(extra, bool) else 0
        if platform == "sensors":
            value = self.value(item, unit)
            if value is None:
                return
            table = self.table(item, "input_type", "holding")
            if table not in ("holding_registers", "input_registers"):
                raise self.error(
                    item.line, f"'{name}': a sensor reads registers", "use holding or input"
                )
            self.series(unit, item, name, table, self.address(item), value, extra)
        elif platform == "binary_sensors":
            table = self.table(item, "input_type", "coil")
            value = {} if table in ("coils", "discrete_inputs") else {"bit": 0, "type": "bool"}
            self.series(unit, item, name, table, self.address(item), value, extra)
        elif platform in ("switches", "fans", "lights"):
            self.switch(unit, item, name)
        elif platform == "climates":
            self.climate(unit, item, name)
        else:
            self.cover(unit, item, name)

    def series(
        self,
        unit: _Unit,
        item: _LineDict,
        name: str,
        table: str,
        address: int,
        value: dict[str, object],
        extra: int,
    ) -> None:
        """One entry, or 1 + slave_count of them at consecutive places."""
        type_name = str(value.get("type", "bool"))
        length = value.get("length")
        size = length if isinstance(length, int) else TYPES[type_name].words
        for k in range(extra + 1):
            entry: dict[str, object] = {
                "name": name if k == 0 else f"{name} {k}",
                "pdu": address + k * size,
                "table": table,
                **value,
            }
            if table in ("input_registers", "discrete_inputs"):
                entry["access"] = "r"
            self.add(unit, item.line, entry)

    def on_off(self, on: object, off: object) -> dict[str, str]:
        names: dict[str, str] = {}
        if isinstance(on, int) and not isinstance(on, bool):
            names[str(on)] = "on"
        if isinstance(off, int) and not isinstance(off, bool) and str(off) not in names:
            names[str(off)] = "off"
        return names

    def switch(self, unit: _Unit, item: _LineDict, name: str) -> None:
        write_type = str(item.get("write_type", "holding"))
        table = self.table(item, "write_type", "holding")
        address = self.address(item)
        on, off = item.get("command_on", 1), item.get("command_off", 0)
        entry: dict[str, object] = {"name": name, "pdu": address, "table": table}
        if table == "holding_registers":
            names = self.on_off(on, off)
            if names:
                entry["enum"] = names
        self.add(unit, item.line, entry)
        verify = item.get("verify")
        if isinstance(verify, _LineDict):
            state_table = self.table(verify, "input_type", write_type)
            state_address = verify.get("address", address)
            if (state_table, state_address) != (table, address):
                state: dict[str, object] = {
                    "name": f"{name} state",
                    "pdu": self.address(verify) if "address" in verify else address,
                    "table": state_table,
                }
                if state_table in ("holding_registers", "input_registers"):
                    names = self.on_off(verify.get("state_on", on), verify.get("state_off", off))
                    if names:
                        state["enum"] = names
                if state_table in ("input_registers", "discrete_inputs"):
                    state["access"] = "r"
                self.add(unit, verify.line, state)

    def climate(self, unit: _Unit, item: _LineDict, name: str) -> None:
        value = self.value(item, unit)
        if value is not None:
            degrees = {"C": "°C", "F": "°F"}.get(str(item.get("temperature_unit", "C")), "")
            value.setdefault("unit", degrees)
            table = self.table(item, "input_type", "holding")
            self.series(unit, item, f"{name} temperature", table, self.address(item), value, 0)
            targets = item.get("target_temp_register")
            addresses = targets if isinstance(targets, list) else [targets]
            seen: set[int] = set()
            for index, target in enumerate(addresses):
                if isinstance(target, int) and not isinstance(target, bool) and target not in seen:
                    seen.add(target)
                    label = f"{name} target temperature" + (f" {index + 1}" if index else "")
                    self.series(unit, item, label, "holding_registers", target, dict(value), 0)
        for key, label in (
            ("hvac_mode_register", "HVAC mode"),
            ("fan_mode_register", "fan mode"),
            ("swing_mode_register", "swing mode"),
            ("hvac_action_register", "HVAC action"),
        ):
            register = item.get(key)
            if not isinstance(register, _LineDict):
                continue
            names: dict[str, str] = {}
            values = register.get("values")
            for mode, codes in values.items() if isinstance(values, dict) else []:
                for code in codes if isinstance(codes, list) else [codes]:
                    if isinstance(code, int) and not isinstance(code, bool):
                        names.setdefault(str(code), str(mode).removeprefix("state_"))
            entry: dict[str, object] = {
                "name": f"{name} {label}",
                "pdu": self.address(register),
                "table": self.table(register, "input_type", "holding"),
            }
            if names:
                entry["enum"] = names
            self.add(unit, register.line, entry)
        onoff = item.get("hvac_onoff_register")
        if isinstance(onoff, int) and not isinstance(onoff, bool):
            entry = {
                "name": f"{name} on/off",
                "pdu": onoff,
                "table": "holding_registers",
                "enum": {"0": "off", "1": "on"},
            }
            self.add(unit, item.line, entry)

    def cover(self, unit: _Unit, item: _LineDict, name: str) -> None:
        states: dict[str, str] = {}
        for key, default in (
            ("state_open", 1),
            ("state_closed", 0),
            ("state_opening", 2),
            ("state_closing", 3),
        ):
            code = item.get(key, default)
            if isinstance(code, int) and not isinstance(code, bool):
                states.setdefault(str(code), key.removeprefix("state_"))
        if "coil" in item:
            table, address = "coils", self.address(item, "coil")
        elif "register" in item:
            table, address = "holding_registers", self.address(item, "register")
        else:
            table = self.table(item, "input_type", "holding")
            address = self.address(item)
        entry: dict[str, object] = {"name": name, "pdu": address, "table": table}
        if table == "holding_registers":
            entry["enum"] = states
        self.add(unit, item.line, entry)
        if "status_register" in item:
            status: dict[str, object] = {
                "name": f"{name} status",
                "pdu": self.address(item, "status_register"),
                "table": self.table(item, "status_register_type", "holding"),
                "enum": states,
            }
            if status["table"] == "input_registers":
                status["access"] = "r"
            self.add(unit, item.line, status)

    def dictionary(self, unit: _Unit) -> DeviceDictionary:
        hub = re.sub(r"[^A-Za-z0-9._+-]+", "-", unit.hub).strip("-") or "hub"
        model = f"{hub}-unit{unit.slave}"
        lines = LineMap({(): 1, ("device",): unit.line})
        for index, line in enumerate(unit.lines):
            lines.set(("entry", index), line)
        data: dict[str, object] = {
            "format": FORMAT,
            "device": {
                "model": model,
                "name": f"{unit.hub}, slave {unit.slave} (Home Assistant)",
                "manual": f"Home Assistant modbus configuration {Path(self.path).name}",
                "notes": unit.notes,
            },
            "entry": unit.entries,
        }
        builder = Builder(Source(self.path, lines), drop_overlaps=True)
        return builder.build(data, unit_hint=unit.slave)


def import_home_assistant(path: str | Path) -> list[DeviceDictionary]:
    """Dictionaries from a Home Assistant `modbus:` YAML file: one per hub and slave.

    Read with a safe loader: plain YAML types only; HA's own tags (!secret, !include,
    ...) are kept as text and never followed; any other tag is a DictionaryError.
    """
    name = str(path)
    data = _read_yaml(name, read_text(Path(path)))
    return _HomeAssistant(name).run(data)
