"""Provides a checker of Home Assistant MQTT discovery configs, written for modscope's tests
from Home Assistant's own rules (no Home Assistant installed: our code, our tables).

What it checks, and where Home Assistant says it (home-assistant/core, read for this):

- `homeassistant/components/sensor/const.py`: the device classes, which units each takes
  (`DEVICE_CLASS_UNITS`), which state classes each takes (`DEVICE_CLASS_STATE_CLASSES`),
  the non-numeric classes (`NON_NUMERIC_DEVICE_CLASSES`: date, enum, timestamp) and the
  state classes (measurement, total, total_increasing; measurement_angle only with `°`,
  `STATE_CLASS_UNITS`);
- `homeassistant/components/sensor/__init__.py` (`_numeric_state_expected`): a sensor
  with a numeric device class, a unit or a state class must get a number;
- `homeassistant/components/mqtt/sensor.py` (`validate_sensor_state_and_device_class_config`,
  `_update_state`): `options` only with device class `enum`, never empty, never with a
  unit or state class; a unit its device class does not take makes the whole config
  invalid; a payload `None` sets the state to unknown; an enum payload outside `options`
  is ignored (the old state stays);
- `homeassistant/components/mqtt/schemas.py`: `availability_topic` and `availability`
  exclusive; each `availability` item needs `topic` and may have `payload_available`,
  `payload_not_available`, `value_template`; `availability_mode` is all, any or latest;
  a device needs `identifiers` or `connections`, its other fields are strings; `origin`
  needs `name`;
- `homeassistant/components/mqtt/discovery.py` (`TOPIC_MATCHER`): the config topic is
  `<prefix>/<component>/[<node_id>/]<object_id>/config`, ids of `[a-zA-Z0-9_-]`;
- `homeassistant/components/mqtt/binary_sensor.py`: payloads `ON`/`OFF` unless
  `payload_on`/`payload_off` say otherwise, `None` for unknown; any other payload is
  ignored ("No matching payload found for entity");
- the MQTT integration's documentation (home-assistant.io, "MQTT Discovery" and "MQTT
  Sensor"): `unique_id` unique across every MQTT entity; with `availability_mode: all`
  every availability topic must say available.

The units are the ones every release from 2025.7 on takes: `apparent_power` took only
`VA` and `reactive_power` only `var` until 2025.9 (home-assistant/core issue #138440
shows the refusal: "not a valid unit for the device class"), so `kVA` and `kvar` count as
refused here. Templates are rendered with Jinja2 as Home Assistant's MQTT templates are
given the payload: `value` (the text) and `value_json` (the payload parsed as JSON).
"""

from __future__ import annotations

import functools
import json
import math
import re
from collections.abc import Iterable, Mapping
from typing import Any

import jinja2
import jinja2.sandbox

AVAILABILITY_MODES = frozenset({"all", "any", "latest"})
STATE_CLASSES = frozenset({"measurement", "total", "total_increasing", "measurement_angle"})
NON_NUMERIC = frozenset({"date", "enum", "timestamp"})
ALL_STATES = STATE_CLASSES - {"measurement_angle"}
MEASURE = frozenset({"measurement"})
TOTALS = frozenset({"total", "total_increasing"})
ENERGY_UNITS = frozenset(
    {"J", "kJ", "MJ", "GJ", "mWh", "Wh", "kWh", "MWh", "GWh", "TWh", "cal", "kcal", "Mcal", "Gcal"}
)
PRESSURE_UNITS = frozenset({"Pa", "hPa", "kPa", "bar", "cbar", "mbar", "mmHg", "inHg", "psi"})
VOLUME_UNITS = frozenset({"L", "mL", "m³", "ft³", "CCF", "gal", "fl. oz."})
# device class -> (units it takes, state classes it takes); None in the units for
# "no unit"
SENSOR_CLASSES: Mapping[str, tuple[frozenset[str | None], frozenset[str]]] = {
    "apparent_power": (frozenset({"VA"}), MEASURE),
    "aqi": (frozenset({None}), MEASURE),
    "atmospheric_pressure": (PRESSURE_UNITS, MEASURE),
    "battery": (frozenset({"%"}), MEASURE),
    "carbon_dioxide": (frozenset({"ppm"}), MEASURE),
    "carbon_monoxide": (frozenset({"ppm"}), MEASURE),
    "current": (frozenset({"A", "mA"}), MEASURE),
    "data_rate": (
        frozenset({"bit/s", "kbit/s", "Mbit/s", "Gbit/s", "B/s", "kB/s", "MB/s", "GB/s"}),
        MEASURE,
    ),
    "date": (frozenset({None}), frozenset()),
    "distance": (frozenset({"km", "m", "cm", "mm", "mi", "yd", "ft", "in"}), ALL_STATES),
    "duration": (frozenset({"d", "h", "min", "s", "ms"}), ALL_STATES),
    "energy": (ENERGY_UNITS, TOTALS),
    "energy_storage": (ENERGY_UNITS, MEASURE),
    "enum": (frozenset({None}), frozenset()),
    "frequency": (frozenset({"Hz", "kHz", "MHz", "GHz"}), MEASURE),
    "gas": (frozenset({"m³", "ft³", "CCF"}), TOTALS),
    "humidity": (frozenset({"%"}), MEASURE),
    "illuminance": (frozenset({"lx"}), MEASURE),
    "moisture": (frozenset({"%"}), MEASURE),
    "power": (frozenset({"mW", "W", "kW", "MW", "GW", "TW"}), MEASURE),
    "power_factor": (frozenset({"%", None}), MEASURE),
    "pressure": (PRESSURE_UNITS, MEASURE),
    "reactive_power": (frozenset({"var"}), MEASURE),
    "signal_strength": (frozenset({"dB", "dBm"}), MEASURE),
    "temperature": (frozenset({"°C", "°F", "K"}), MEASURE),
    "timestamp": (frozenset({None}), frozenset()),
    "voltage": (frozenset({"µV", "mV", "V", "kV", "MV"}), MEASURE),
    "volume": (VOLUME_UNITS, TOTALS),
    "volume_storage": (VOLUME_UNITS, MEASURE),
    "water": (frozenset({"m³", "ft³", "CCF", "gal", "L"}), TOTALS),
    "wind_direction": (frozenset({"°"}), frozenset({"measurement_angle"})),
}
BINARY_CLASSES = frozenset(
    {
        "battery",
        "battery_charging",
        "carbon_monoxide",
        "cold",
        "connectivity",
        "door",
        "garage_door",
        "gas",
        "heat",
        "light",
        "lock",
        "moisture",
        "motion",
        "moving",
        "occupancy",
        "opening",
        "plug",
        "power",
        "presence",
        "problem",
        "running",
        "safety",
        "smoke",
        "sound",
        "tamper",
        "update",
        "vibration",
        "window",
    }
)
ENTITY_CATEGORIES = frozenset({"config", "diagnostic"})
DEVICE_KEYS = frozenset(
    {
        "identifiers",
        "connections",
        "manufacturer",
        "model",
        "model_id",
        "name",
        "hw_version",
        "serial_number",
        "sw_version",
        "via_device",
        "suggested_area",
        "configuration_url",
    }
)
COMMON_KEYS = frozenset(
    {
        "availability",
        "availability_mode",
        "availability_topic",
        "availability_template",
        "payload_available",
        "payload_not_available",
        "device",
        "origin",
        "enabled_by_default",
        "entity_category",
        "icon",
        "json_attributes_topic",
        "json_attributes_template",
        "object_id",
        "unique_id",
        "name",
        "qos",
        "encoding",
        "state_topic",
        "value_template",
    }
)
COMPONENT_KEYS: Mapping[str, frozenset[str]] = {
    "sensor": COMMON_KEYS
    | {
        "device_class",
        "expire_after",
        "force_update",
        "last_reset_value_template",
        "options",
        "suggested_display_precision",
        "state_class",
        "unit_of_measurement",
    },
    "binary_sensor": COMMON_KEYS
    | {"device_class", "expire_after", "force_update", "off_delay", "payload_on", "payload_off"},
}
TOPIC = re.compile(
    r"(?P<prefix>[^/]+)/(?P<component>\w+)/(?:(?P<node>[a-zA-Z0-9_-]+)/)?"
    r"(?P<object>[a-zA-Z0-9_-]+)/config\Z"
)
STATE_MAX = 255
PAYLOAD_NONE = "None"

_ENV = jinja2.sandbox.ImmutableSandboxedEnvironment(undefined=jinja2.StrictUndefined)


def render(template: str, payload: str) -> str:
    """`template` as Home Assistant renders an MQTT value template for `payload`."""
    try:
        value_json: Any = json.loads(payload)
    except ValueError:
        value_json = None
    return _compiled(template).render(value=payload, value_json=value_json)


@functools.lru_cache(maxsize=4096)
def _compiled(template: str) -> jinja2.Template:
    """Each template compiled once, as Home Assistant keeps an entity's compiled template
    (compiling took 0.003 s a render: 21 s of one test's 25)."""
    return _ENV.from_string(template)


def numeric_expected(config: Mapping[str, Any]) -> bool:
    """Whether Home Assistant wants a number from this sensor (`_numeric_state_expected`)."""
    device_class = config.get("device_class")
    if device_class in NON_NUMERIC:
        return False
    if any(config.get(k) is not None for k in ("state_class", "unit_of_measurement")):
        return True
    if config.get("suggested_display_precision") is not None:
        return True
    return device_class is not None


def component_of(topic: str) -> str:
    found = TOPIC.match(topic)
    return found["component"] if found else ""


def _strings(where: str, block: Mapping[str, Any], keys: Iterable[str]) -> list[str]:
    return [
        f"{where}: {k} must be a string, not {block[k]!r}"
        for k in keys
        if k in block and not isinstance(block[k], str)
    ]


def _template(where: str, text: Any) -> list[str]:
    if not isinstance(text, str):
        return [f"{where}: a template must be a string, not {text!r}"]
    try:
        _ENV.parse(text)
    except jinja2.TemplateSyntaxError as exc:
        return [f"{where}: template does not compile: {exc}"]
    return []


def check_config(topic: str, config: Mapping[str, Any]) -> list[str]:
    """What Home Assistant would refuse, or do otherwise than meant, in one config."""
    where = topic
    found = TOPIC.match(topic)
    if found is None:
        return [f"{where}: not <prefix>/<component>/[<node_id>/]<object_id>/config"]
    component = found["component"]
    keys = COMPONENT_KEYS.get(component)
    if keys is None:
        return [f"{where}: component {component!r} is not one this checker knows"]
    problems = [f"{where}: {k!r} is not a {component} option" for k in config if k not in keys]
    problems += _strings(where, config, ("name", "unique_id", "state_topic", "object_id"))
    if not config.get("state_topic"):
        problems.append(f"{where}: no state_topic")
    for key in ("value_template", "json_attributes_template"):
        if key in config:
            problems += _template(f"{where} {key}", config[key])
    problems += _availability(where, config)
    problems += _device(where, config)
    if "entity_category" in config and config["entity_category"] not in ENTITY_CATEGORIES:
        problems.append(f"{where}: entity_category {config['entity_category']!r}")
    if component == "sensor":
        problems += _sensor(where, config)
    else:
        device_class = config.get("device_class")
        if device_class is not None and device_class not in BINARY_CLASSES:
            problems.append(f"{where}: binary sensor device class {device_class!r}")
    return problems


def _availability(where: str, config: Mapping[str, Any]) -> list[str]:
    problems: list[str] = []
    if "availability" in config and "availability_topic" in config:
        problems.append(f"{where}: availability and availability_topic together")
    problems += _strings(where, config, ("payload_available", "payload_not_available"))
    mode = config.get("availability_mode", "latest")
    if mode not in AVAILABILITY_MODES:
        problems.append(f"{where}: availability_mode {mode!r} is not all, any or latest")
    items = config.get("availability", [])
    if not isinstance(items, list):
        return [*problems, f"{where}: availability must be a list"]
    for n, item in enumerate(items):
        at = f"{where} availability[{n}]"
        if not isinstance(item, dict):
            problems.append(f"{at}: not a mapping")
            continue
        extra = set(item) - {
            "topic",
            "payload_available",
            "payload_not_available",
            "value_template",
        }
        if extra:
            problems.append(f"{at}: unknown keys {sorted(extra)}")
        if not isinstance(item.get("topic"), str) or not item["topic"]:
            problems.append(f"{at}: needs a topic")
        problems += _strings(at, item, ("payload_available", "payload_not_available"))
        if "value_template" in item:
            problems += _template(at, item["value_template"])
    return problems


def _device(where: str, config: Mapping[str, Any]) -> list[str]:
    problems: list[str] = []
    device = config.get("device")
    if device is not None:
        if not isinstance(device, dict):
            return [f"{where}: device must be a mapping"]
        extra = set(device) - DEVICE_KEYS
        if extra:
            problems.append(f"{where}: device keys {sorted(extra)} are not device options")
        ids = device.get("identifiers")
        if not device.get("connections") and not (
            isinstance(ids, list) and ids and all(isinstance(i, str) and i for i in ids)
        ):
            problems.append(f"{where}: device needs identifiers (strings) or connections")
        problems += _strings(
            f"{where} device", device, DEVICE_KEYS - {"identifiers", "connections"}
        )
    origin = config.get("origin")
    if origin is not None and (not isinstance(origin, dict) or not origin.get("name")):
        problems.append(f"{where}: origin needs a name")
    return problems


def _sensor(where: str, config: Mapping[str, Any]) -> list[str]:
    problems: list[str] = []
    device_class = config.get("device_class")
    state_class = config.get("state_class")
    unit = config.get("unit_of_measurement")
    options = config.get("options")
    if unit is not None and not isinstance(unit, str):
        problems.append(f"{where}: unit {unit!r} is not a string")
    if state_class is not None and state_class not in STATE_CLASSES:
        problems.append(f"{where}: state class {state_class!r}")
    if state_class == "measurement_angle" and unit != "°":
        problems.append(f"{where}: measurement_angle needs the unit °")
    if options is not None:
        if not isinstance(options, list) or not options:
            problems.append(f"{where}: options must be a list that is not empty")
        elif len(set(map(str, options))) != len(options):
            problems.append(f"{where}: options repeat")
        elif any(not isinstance(o, str) or len(o) > STATE_MAX for o in options):
            problems.append(f"{where}: every option must be a string of at most {STATE_MAX}")
        if state_class or unit:
            problems.append(f"{where}: options with a unit or a state class")
        if device_class != "enum":
            problems.append(f"{where}: options without device class enum")
    if device_class is None:
        return problems
    rules = SENSOR_CLASSES.get(device_class)
    if rules is None:
        return [*problems, f"{where}: sensor device class {device_class!r}"]
    units, state_classes = rules
    if unit not in units:
        problems.append(f"{where}: unit {unit!r} is not one {device_class} takes")
    if state_class is not None and state_class not in state_classes:
        problems.append(f"{where}: state class {state_class!r} is not one {device_class} takes")
    if device_class == "enum" and not options:
        problems.append(f"{where}: an enum sensor needs options")
    return problems


def check_state(topic: str, config: Mapping[str, Any], payload: str) -> list[str]:
    """What Home Assistant would make of `payload` on the state topic: a problem when a
    numeric sensor gets no number, an enum no option, a binary sensor neither payload,
    or a text more than a state holds."""
    template = config.get("value_template")
    try:
        state = render(template, payload) if template is not None else payload
    except jinja2.TemplateError as exc:
        return [f"{topic}: template fails on {payload[:120]}: {exc}"]
    where = f"{topic}: {state!r} from {payload[:160]}"
    if component_of(topic) == "binary_sensor":
        accepted = {config.get("payload_on", "ON"), config.get("payload_off", "OFF"), PAYLOAD_NONE}
        return [] if state in accepted else [f"{where}: neither {sorted(accepted)}"]
    if state == PAYLOAD_NONE:
        return []
    if numeric_expected(config):
        try:
            number = float(state)
        except ValueError:
            return [f"{where}: a numeric sensor gets no number"]
        return [] if math.isfinite(number) else [f"{where}: not a finite number"]
    options = config.get("options")
    if options is not None and state not in options:
        return [f"{where}: not one of the options (Home Assistant keeps the old state)"]
    if len(state) > STATE_MAX:
        return [f"{where}: longer than {STATE_MAX} characters"]
    return []


def check_attributes(topic: str, config: Mapping[str, Any], payload: str) -> list[str]:
    """The attributes template must give a JSON object for `payload`."""
    template = config.get("json_attributes_template")
    if template is None:
        return []
    try:
        found = json.loads(render(template, payload))
    except (jinja2.TemplateError, ValueError) as exc:
        return [f"{topic}: attributes template fails on {payload[:120]}: {exc}"]
    return [] if isinstance(found, dict) else [f"{topic}: attributes are not a JSON object"]


def availability_of(config: Mapping[str, Any], retained: Mapping[str, str]) -> bool | None:
    """Whether Home Assistant shows the entity available given the `retained` messages
    (None: an availability topic said neither payload, or has said nothing)."""
    items = config.get("availability")
    if items is None:
        topic = config.get("availability_topic")
        if topic is None:
            return True
        items = [
            {
                "topic": topic,
                "payload_available": config.get("payload_available", "online"),
                "payload_not_available": config.get("payload_not_available", "offline"),
                **(
                    {"value_template": config["availability_template"]}
                    if "availability_template" in config
                    else {}
                ),
            }
        ]
    answers: list[bool | None] = []
    for item in items:
        payload = retained.get(item["topic"])
        if payload is None:
            answers.append(None)
            continue
        said = render(item["value_template"], payload) if "value_template" in item else payload
        if said == item.get("payload_available", "online"):
            answers.append(True)
        elif said == item.get("payload_not_available", "offline"):
            answers.append(False)
        else:
            answers.append(None)
    mode = config.get("availability_mode", "latest")
    if mode == "all":
        if False in answers:
            return False
        return True if all(a is True for a in answers) else None
    if mode == "any":
        return True if True in answers else (False if False in answers else None)
    return answers[-1] if answers else True


def check_all(configs: Mapping[str, str]) -> list[str]:
    """Every config (topic -> payload) on its own, and `unique_id` unique across them."""
    problems: list[str] = []
    owners: dict[str, str] = {}
    for topic, payload in sorted(configs.items()):
        try:
            config = json.loads(payload)
        except ValueError:
            problems.append(f"{topic}: not JSON")
            continue
        problems += check_config(topic, config)
        unique = config.get("unique_id")
        if not isinstance(unique, str) or not unique:
            problems.append(f"{topic}: no unique_id")
        elif unique in owners:
            problems.append(f"{topic}: unique_id {unique!r} also used by {owners[unique]}")
        else:
            owners[unique] = topic
    return problems
