"""Provides Home Assistant MQTT discovery configs for the named registers of bound units.

One device per bound unit (identifiers `modscope_<bus>_<unit>`, model from the
dictionary, label as its name), one entity per named register, published retained at
`<prefix>/<component>/modscope_<bus>_<unit>/<register-slug>/config`:

- numbers: `sensor` with the unit, a device class where the unit says what is measured
  (V voltage, A current, W power, ...) and state class `measurement`;
- enumerations: `sensor` with device class `enum` and the names as `options`;
- bits: a coil, discrete input or single bit is a `binary_sensor`; a bit field gets one
  `binary_sensor` per named bit (read from the value message's `bits`);
- text: `sensor` with no state class.

All entities are available while the bus's `status` topic says `online`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

from dissectors.dictionary.device import DeviceDictionary
from dissectors.dictionary.model import Entry
from sniffer import __version__
from sniffer.outputs.mqtt.payload import slug

DEFAULT_PREFIX = "homeassistant"
BIT_TABLES = ("coils", "discrete_inputs")
# unit of measurement -> Home Assistant sensor device class (only where it is certain)
DEVICE_CLASSES = {
    "V": "voltage",
    "mV": "voltage",
    "kV": "voltage",
    "A": "current",
    "mA": "current",
    "W": "power",
    "kW": "power",
    "MW": "power",
    "VA": "apparent_power",
    "kVA": "apparent_power",
    "var": "reactive_power",
    "VAr": "reactive_power",
    "kvar": "reactive_power",
    "kVAr": "reactive_power",
    "Wh": "energy",
    "kWh": "energy",
    "MWh": "energy",
    "°C": "temperature",
    "°F": "temperature",
    "K": "temperature",
    "Hz": "frequency",
    "s": "duration",
    "ms": "duration",
    "min": "duration",
    "h": "duration",
    "bar": "pressure",
    "Pa": "pressure",
    "kPa": "pressure",
}
# Home Assistant spells some units its own way
HA_UNITS = {"VAr": "var", "kVAr": "kvar"}


@dataclass(frozen=True, slots=True)
class Discovery:
    """One retained discovery message."""

    topic: str
    payload: str


def entity_kind(entry: Entry) -> str:
    """`binary`, `bits`, `enum`, `text` or `number`: what the entry becomes."""
    spec = entry.spec
    if spec.enum:
        return "enum"
    if entry.table in BIT_TABLES or spec.type == "bool" or spec.bit is not None:
        return "binary"
    if spec.bits:
        return "bits"
    if spec.type == "str":
        return "text"
    return "number"


def node_id(bus: str, unit: int) -> str:
    return f"modscope_{slug(bus).replace('-', '_')}_{unit}"


def device_block(
    bus: str, unit: int, label: str, dictionary: DeviceDictionary
) -> dict[str, object]:
    return {
        "identifiers": [node_id(bus, unit)],
        "name": label or f"{bus} unit {unit}",
        "model": dictionary.name or dictionary.model,
        "manufacturer": "via modscope",
        "serial_number": f"{bus} unit {unit}",
    }


def discovery_configs(
    *,
    prefix: str,
    bus: str,
    unit: int,
    label: str,
    dictionary: DeviceDictionary,
    entry: Entry,
    register_slug: str,
    state_topic: str,
    availability_topic: str,
) -> list[Discovery]:
    """The discovery messages for one named register (one, or one per named bit)."""
    node = node_id(bus, unit)
    common: dict[str, object] = {
        "state_topic": state_topic,
        "availability_topic": availability_topic,
        "payload_available": "online",
        "payload_not_available": "offline",
        "device": device_block(bus, unit, label, dictionary),
        "origin": {"name": "modscope", "sw_version": __version__},
    }
    kind = entity_kind(entry)
    out: list[Discovery] = []

    def add(component: str, object_id: str, config: dict[str, object]) -> None:
        config = {**config, **common, "unique_id": f"{node}_{object_id.replace('-', '_')}"}
        topic = f"{prefix}/{component}/{node}/{object_id}/config"
        out.append(Discovery(topic, json.dumps(config, ensure_ascii=False, sort_keys=True)))

    spec = entry.spec
    if kind == "binary":
        add(
            "binary_sensor",
            register_slug,
            {
                "name": entry.name,
                "value_template": "{{ 'ON' if value_json.value else 'OFF' }}",
            },
        )
    elif kind == "bits":
        for bit, name in sorted(spec.bits.items()):
            add(
                "binary_sensor",
                f"{register_slug}-bit{bit}",
                {
                    "name": f"{entry.name}: {name}",
                    "value_template": "{{ 'ON' if value_json.bits['"
                    + str(bit)
                    + "'] else 'OFF' }}",
                },
            )
    elif kind == "enum":
        add(
            "sensor",
            register_slug,
            {
                "name": entry.name,
                "device_class": "enum",
                "options": list(dict.fromkeys(spec.enum.values())),
                "value_template": "{{ value_json.value }}",
            },
        )
    elif kind == "text":
        add(
            "sensor",
            register_slug,
            {"name": entry.name, "value_template": "{{ value_json.value }}"},
        )
    else:
        config: dict[str, object] = {
            "name": entry.name,
            "value_template": "{{ value_json.value }}",
            "state_class": "measurement",
        }
        if spec.unit:
            config["unit_of_measurement"] = HA_UNITS.get(spec.unit, spec.unit)
            device_class = DEVICE_CLASSES.get(spec.unit)
            if device_class is not None:
                config["device_class"] = device_class
        add("sensor", register_slug, config)
    return out
