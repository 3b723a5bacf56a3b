"""Provides Home Assistant MQTT discovery configs: a device for the bus, one per unit, and
an entity per named register, each fitting what Home Assistant accepts.

Ids come from the publisher's **base topic**, which is unique across buses (two cabinets
whose ports are both `ttyUSB0` publish under `site/cabinet1` and `site/cabinet2`): the
bus is node `modscope_site_cabinet1`, its unit 3 node `modscope_site_cabinet1_3` (a base
topic with other characters than `a-z 0-9 - /` gets a hash of itself appended, so two
bases never share a node). Configs go, retained, to
`<prefix>/<component>/<node>/<object>/config`:

- the bus: a `binary_sensor` (connectivity) on `<base>/status`, the publisher online;
- each unit seen polled (or bound): a `binary_sensor` (connectivity) on
  `<base>/unit/<N>/status`, on while the unit answers (`online`), off when modscope calls
  it `silent`, with the status message's counts as attributes; the unit's device names
  the bus device as `via_device` and carries `sw_version`/`hw_version` once the bus
  showed them (`versions_from`);
- each named register, once a value of it is seen:
  - numbers: `sensor` with the unit; a device class only where Home Assistant accepts
    that unit for it (`DEVICE_CLASSES`: `kVA` and `kvar` get none, every release from
    2025.7 refuses them); energy (Wh, kWh, MWh) is `total_increasing`, so the Energy
    dashboard takes it, everything else `measurement`. The template hands Home
    Assistant numbers only: a named reading (`off`) or a NaN gives `None` (unknown), and
    the reading itself is the `text` attribute; an entry with named raw values also
    gets an `enum` sensor `<name> state` with those names and `number`;
  - enumerations: `enum` sensor, `options` every documented name plus `undocumented`
    (a raw value the manual does not name shows as that, never as a number);
  - bits: a coil, discrete input or single bit is a `binary_sensor`; a bit field one
    `binary_sensor` per named bit (read from the value message's `bits`);
  - text: `sensor` without unit or class, cut to the 255 characters a state may hold.

Every register entity is available while both the bus (`<base>/status` online) and its
unit (`<base>/unit/<N>/status` state online) are: `availability` with
`availability_mode: all`. tests/support/ha_rules.py checks every config against Home
Assistant's rules.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Mapping
from dataclasses import dataclass

from dissectors.dictionary.model import BIT_TABLES, Entry
from sniffer import __version__

DEFAULT_PREFIX = "homeassistant"
# unit of measurement -> sensor device class, only where every Home Assistant release
# from 2025.7 on accepts the unit for the class (sensor/const.py DEVICE_CLASS_UNITS); a
# unit left out keeps its unit and state class and gets no class. kVA and kvar are left
# out on purpose: apparent_power took only VA and reactive_power only var up to 2025.9,
# and the MQTT sensor refuses the whole config for a unit its class does not take
DEVICE_CLASSES: Mapping[str, str] = {
    "V": "voltage",
    "mV": "voltage",
    "kV": "voltage",
    "A": "current",
    "mA": "current",
    "W": "power",
    "kW": "power",
    "MW": "power",
    "VA": "apparent_power",
    "var": "reactive_power",
    "VAr": "reactive_power",
    "Wh": "energy",
    "kWh": "energy",
    "MWh": "energy",
    "°C": "temperature",
    "°F": "temperature",
    "K": "temperature",
    "Hz": "frequency",
    "kHz": "frequency",
    "s": "duration",
    "ms": "duration",
    "min": "duration",
    "h": "duration",
    "d": "duration",
    "bar": "pressure",
    "mbar": "pressure",
    "Pa": "pressure",
    "hPa": "pressure",
    "kPa": "pressure",
    "psi": "pressure",
}
# Home Assistant spells these units its own way (the same unit, written otherwise)
HA_UNITS: Mapping[str, str] = {"VAr": "var", "kVAr": "kvar"}
# device classes whose value is a running total: the Energy dashboard reads only these
TOTALS = frozenset({"energy"})
UNDOCUMENTED = "undocumented"  # the enum option of a raw value the manual does not name
NUMBER = "number"  # the `<name> state` option of a plain number
STATE_MAX = 255  # characters a Home Assistant state may hold
ONLINE, OFFLINE = "online", "offline"

_NUMERIC = "{% set v = value_json.value %}{{ v if v is number and v is not boolean else 'None' }}"
_READING = "{{ {'text': value_json.text, 'raw': value_json.raw} | tojson }}"
_UNIT_ONLINE = "{{ 'online' if value_json.state == 'online' else 'offline' }}"
_UNIT_ON = "{{ 'ON' if value_json.state == 'online' else 'OFF' }}"
_CANONICAL = re.compile(r"[a-z0-9-]+(?:/[a-z0-9-]+)*\Z")
_SW = re.compile(r"\b(?:firmware|software|fw|sw)\b.*\b(?:version|revision|release)\b", re.I)
_HW = re.compile(r"\b(?:hardware|hw)\b.*\b(?:version|revision)\b", re.I)


@dataclass(frozen=True, slots=True)
class Discovery:
    """One retained discovery message."""

    topic: str
    payload: str


@dataclass(frozen=True, slots=True)
class UnitDevice:
    """What a unit's Home Assistant device says: where it is published and what it is."""

    base: str  # the publisher's base topic
    unit: int
    label: str = ""  # the bus file's label
    model: str = ""  # the dictionary's name, "" for a unit without one
    sw_version: str = ""
    hw_version: str = ""


def topic_of(base: str, *parts: str) -> str:
    """A topic under the publisher's base (the layout docs/mqtt.md describes)."""
    return "/".join((base, *parts))


def base_id(base: str) -> str:
    """The base topic as an id (`[a-z0-9_-]`), different for every base: `site/cab-7` ->
    `site_cab-7`; a base with other characters gets 10 hex digits of its SHA-1 appended
    (`Site/Cab 7` -> `site_cab-7_h2c41f0a9b1`), since lowering and replacing would make
    two bases one."""
    if _CANONICAL.match(base):
        return base.replace("/", "_")
    text = "_".join(
        re.sub(r"[^a-z0-9]+", "-", level.lower()).strip("-") for level in base.split("/")
    )
    digest = hashlib.sha1(base.encode("utf-8")).hexdigest()[:10]
    return f"{text}_h{digest}"


def bus_node(base: str) -> str:
    return f"modscope_{base_id(base)}"


def unit_node(base: str, unit: int) -> str:
    return f"{bus_node(base)}_{unit}"


def entity_kind(entry: Entry) -> str:
    """`binary`, `bits`, `enum`, `text` or `number`: what the entry becomes."""
    spec = entry.spec
    if spec.enum:
        return "enum"
    if entry.table in BIT_TABLES or spec.type == "bool":
        return "binary"
    if spec.bits:
        return "bits"
    if spec.type == "str":
        return "text"
    return "number"


def version_kind(name: str) -> str | None:
    """`sw_version` or `hw_version` for a register or identification object whose name
    says it holds one (`Software revision`, `Firmware version`, `HW version`), else None."""
    if _HW.search(name):
        return "hw_version"
    if _SW.search(name) or name == "MajorMinorRevision":
        return "sw_version"
    return None


def _free(name: str, taken: list[str]) -> str:
    """`name`, or `name (2)`, ...: an option the names do not already use."""
    chosen, n = name, 1
    while chosen in taken:
        n += 1
        chosen = f"{name} ({n})"
    return chosen


def _origin() -> dict[str, str]:
    return {"name": "modscope", "sw_version": __version__}


def _dump(config: dict[str, object]) -> str:
    return json.dumps(config, ensure_ascii=False, sort_keys=True)


def bus_device(base: str, bus: str) -> dict[str, object]:
    return {
        "identifiers": [bus_node(base)],
        "name": f"modscope {base}",
        "model": f"Modbus bus {bus}, published by modscope",
        "sw_version": __version__,
    }


def unit_device(device: UnitDevice) -> dict[str, object]:
    block: dict[str, object] = {
        "identifiers": [unit_node(device.base, device.unit)],
        "name": device.label or f"{device.model or 'Modbus'} unit {device.unit}",
        "via_device": bus_node(device.base),
    }
    if device.model:
        block["model"] = device.model
    if device.sw_version:
        block["sw_version"] = device.sw_version
    if device.hw_version:
        block["hw_version"] = device.hw_version
    return block


def bus_configs(prefix: str, base: str, bus: str) -> list[Discovery]:
    """The bus device: its publisher's connectivity, read from `<base>/status` (the
    connection's last will says `offline`), so it needs no availability of its own."""
    node = bus_node(base)
    config: dict[str, object] = {
        "name": "Publisher",
        "unique_id": f"{node}_publisher",
        "device_class": "connectivity",
        "entity_category": "diagnostic",
        "state_topic": topic_of(base, "status"),
        "payload_on": ONLINE,
        "payload_off": OFFLINE,
        "device": bus_device(base, bus),
        "origin": _origin(),
    }
    return [Discovery(f"{prefix}/binary_sensor/{node}/publisher/config", _dump(config))]


def unit_configs(prefix: str, device: UnitDevice) -> list[Discovery]:
    """A unit's connectivity: on while modscope calls it online, off when silent; the
    status message's counts and latencies as attributes. Available with the bus."""
    node = unit_node(device.base, device.unit)
    status = topic_of(device.base, "unit", str(device.unit), "status")
    config: dict[str, object] = {
        "name": "Answering",
        "unique_id": f"{node}_unit_status",
        "device_class": "connectivity",
        "entity_category": "diagnostic",
        "state_topic": status,
        "value_template": _UNIT_ON,
        "json_attributes_topic": status,
        "json_attributes_template": "{{ value_json | tojson }}",
        "availability_topic": topic_of(device.base, "status"),
        "payload_available": ONLINE,
        "payload_not_available": OFFLINE,
        "device": unit_device(device),
        "origin": _origin(),
    }
    return [Discovery(f"{prefix}/binary_sensor/{node}/unit_status/config", _dump(config))]


def register_configs(
    prefix: str,
    device: UnitDevice,
    entry: Entry,
    register_slug: str,
    state_topic: str,
) -> list[Discovery]:
    """The discovery messages for one named register (one, or one per named bit, or a
    number and its `state`). `register_slug` is unique within the unit (`Slugs`): the
    object ids derived from it carry a `_`, which slugs never hold, so none collides."""
    node = unit_node(device.base, device.unit)
    common: dict[str, object] = {
        "state_topic": state_topic,
        "availability": [
            {
                "topic": topic_of(device.base, "status"),
                "payload_available": ONLINE,
                "payload_not_available": OFFLINE,
            },
            {
                "topic": topic_of(device.base, "unit", str(device.unit), "status"),
                "value_template": _UNIT_ONLINE,
                "payload_available": ONLINE,
                "payload_not_available": OFFLINE,
            },
        ],
        "availability_mode": "all",
        "device": unit_device(device),
        "origin": _origin(),
    }
    out: list[Discovery] = []

    def add(component: str, object_id: str, config: dict[str, object]) -> None:
        config = {**config, **common, "unique_id": f"{node}_{object_id}"}
        out.append(Discovery(f"{prefix}/{component}/{node}/{object_id}/config", _dump(config)))

    spec = entry.spec
    kind = entity_kind(entry)
    if kind == "binary":
        add(
            "binary_sensor",
            register_slug,
            {"name": entry.name, "value_template": "{{ 'ON' if value_json.value else 'OFF' }}"},
        )
    elif kind == "bits":
        for bit, name in sorted(spec.bits.items()):
            add(
                "binary_sensor",
                f"{register_slug}_bit{bit}",
                {
                    "name": f"{entry.name}: {name}",
                    "value_template": "{{ 'ON' if value_json.bits['"
                    + str(bit)
                    + "'] else 'OFF' }}",
                },
            )
    elif kind == "enum":
        names = list(dict.fromkeys([*spec.enum.values(), *spec.special.values()]))
        other = _free(UNDOCUMENTED, names)
        add(
            "sensor",
            register_slug,
            {
                "name": entry.name,
                "device_class": "enum",
                "options": [*names, other],
                "value_template": _named(other),
            },
        )
    elif kind == "text":
        add(
            "sensor",
            register_slug,
            {
                "name": entry.name,
                "value_template": "{% set v = value_json.value %}"
                "{{ v[:" + str(STATE_MAX) + "] if v is string else 'None' }}",
            },
        )
    else:
        config: dict[str, object] = {
            "name": entry.name,
            "value_template": _NUMERIC,
            "json_attributes_topic": state_topic,
            "json_attributes_template": _READING,
        }
        if spec.unit:
            config["unit_of_measurement"] = HA_UNITS.get(spec.unit, spec.unit)
        device_class = DEVICE_CLASSES.get(spec.unit) if spec.unit else None
        if device_class is not None:
            config["device_class"] = device_class
        config["state_class"] = "total_increasing" if device_class in TOTALS else "measurement"
        add("sensor", register_slug, config)
        if spec.special:
            names = list(dict.fromkeys(spec.special.values()))
            other = _free(NUMBER, names)
            add(
                "sensor",
                f"{register_slug}_state",
                {
                    "name": f"{entry.name} state",
                    "device_class": "enum",
                    "options": [*names, other],
                    "value_template": _named(other),
                },
            )
    return out


def _named(other: str) -> str:
    """The template of an enum sensor: the name modscope decoded (every name it can
    decode is an option), else `other` (a raw value the dictionary does not name)."""
    quoted = other.replace("\\", "\\\\").replace("'", "\\'")
    return "{% set v = value_json.value %}{{ v if v is string else '" + quoted + "' }}"


def versions_from(fields: Mapping[str, str]) -> dict[str, str]:
    """`sw_version`/`hw_version` from named values (registers, identification objects)
    whose names say they hold one (`version_kind`); the first of each wins."""
    found: dict[str, str] = {}
    for name, text in fields.items():
        kind = version_kind(name)
        if kind is not None and kind not in found and text.strip():
            found[kind] = text.strip()[:STATE_MAX]
    return found
