"""Home Assistant discovery that Home Assistant takes: every config modscope publishes, for
the demo and for every dictionary it has, checked against tests/support/ha_rules.py (a
checker written from Home Assistant's source and documentation), and every value it
publishes rendered through the configs' templates as Home Assistant would.

No broker: the publisher is given a link that keeps what it is handed (retained
messages last, as a broker keeps them)."""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from dissectors.dictionary.decode import decode_entry, decode_flag
from dissectors.dictionary.device import DeviceDictionary
from dissectors.dictionary.loader import builtin_models, load_dictionaries, load_model
from dissectors.dictionary.model import BIT_TABLES, Entry, ValueSpec
from sniffer.meaning.annotate import Binding, load_bindings
from sniffer.model import Chunk, LineSettings
from sniffer.outputs.mqtt.ha import (
    UnitDevice,
    base_id,
    bus_configs,
    entity_kind,
    register_configs,
    unit_configs,
    unit_node,
    version_kind,
)
from sniffer.outputs.mqtt.link import LinkCounts, MqttLink
from sniffer.outputs.mqtt.payload import json_value, slug
from sniffer.outputs.mqtt.publish import BusPublisher, PublisherOptions, publish_replay
from sniffer.outputs.mqtt.target import MqttTarget, parse_target
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, open_session
from tests.support import ha_rules

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
PREFIX = "homeassistant"
# not dictionaries: a bus file, and a YAML file made to be refused
SKIPPED = {"bus", "home_assistant_unsafe"}


class KeepingLink(MqttLink):
    """A link with no broker: retained messages land in `retained` (shared by several
    publishers, as one broker is), the others in `messages`."""

    def __init__(self, target: MqttTarget, retained: dict[str, str] | None = None) -> None:
        self.target = target
        self.counts = LinkCounts()
        self._on_connect_hook = None
        self.retained: dict[str, str] = {} if retained is None else retained
        self.messages: list[tuple[str, bytes | str]] = []

    def publish(
        self, topic: str, payload: bytes | str, *, retain: bool = False, block: bool = False
    ) -> bool:
        self.messages.append((topic, payload))
        if retain:
            assert isinstance(payload, str)
            self.retained[topic] = payload
        return True

    def close(self, drain: float = 10.0, last: tuple[str, str] | None = None) -> LinkCounts:
        if last is not None:
            self.publish(last[0], last[1], retain=True)
        return self.counts

    def report(self) -> str:
        return "kept"


def _publish_demo(base: str, bus: str, retained: dict[str, str]) -> KeepingLink:
    bindings = load_bindings(DEMO_BUS)
    session, capture = open_session(DEMO_CAPTURE, bindings=bindings)
    link = KeepingLink(parse_target(f"mqtt://127.0.0.1/{base}", bus=bus), retained)
    options = PublisherOptions(bus=bus, ha_prefix=PREFIX)
    publisher = BusPublisher(link, session, bindings, options, info=capture.info)
    assert link._on_connect_hook is not None
    link._on_connect_hook()  # connected: the publisher says `online`
    publisher.announce()
    publish_replay(session, capture.chunks(), publisher)
    publisher.rows(final=True)
    return link


def _configs(retained: Mapping[str, str]) -> dict[str, str]:
    return {t: p for t, p in retained.items() if t.startswith(PREFIX + "/")}


def _by_state_topic(configs: Mapping[str, str]) -> dict[str, list[tuple[str, dict[str, Any]]]]:
    found: dict[str, list[tuple[str, dict[str, Any]]]] = {}
    for topic, payload in configs.items():
        config = json.loads(payload)
        found.setdefault(config["state_topic"], []).append((topic, config))
    return found


def _states(
    configs: Mapping[str, str], messages: Iterable[tuple[str, bytes | str]]
) -> tuple[list[str], int]:
    """Every message on a state topic rendered through its configs: the problems, and
    how many renderings there were."""
    by_topic = _by_state_topic(configs)
    problems: list[str] = []
    rendered = 0
    for topic, payload in messages:
        for config_topic, config in by_topic.get(topic, []):
            assert isinstance(payload, str)
            problems += ha_rules.check_state(config_topic, config, payload)
            problems += ha_rules.check_attributes(config_topic, config, payload)
            rendered += 1
    return problems, rendered


# -- the fleet: bases, not bus names, make the ids -----------------------------------------------


def test_two_cabinets_whose_ports_share_a_name_keep_every_entity() -> None:
    """docs/fleet.md: every cabinet's port is ttyUSB0, each publishes under its own
    base. One broker then holds both cabinets' configs, none overwriting the other's
    (ids from the bus name left 36 of 72)."""
    retained: dict[str, str] = {}
    _publish_demo("site/cabinet1", "ttyUSB0", retained)
    one = len(_configs(retained))
    _publish_demo("site/cabinet2", "ttyUSB0", retained)
    configs = _configs(retained)
    assert one == 41 and len(configs) == 2 * one  # the publisher, 4 units, 36 registers
    assert ha_rules.check_all(configs) == []
    uniques = {json.loads(p)["unique_id"] for p in configs.values()}
    assert len(uniques) == len(configs)
    devices = {
        json.loads(p)["device"]["identifiers"][0]
        for t, p in configs.items()
        if "/modscope_site_cabinet2_" in t
    }
    assert devices == {f"modscope_site_cabinet2_{u}" for u in (1, 2, 3, 4)}


@given(st.text(min_size=1, max_size=12), st.text(min_size=1, max_size=12))
def test_different_bases_never_share_an_id(a: str, b: str) -> None:
    if a == b:
        return
    assert base_id(a) != base_id(b)
    assert ha_rules.TOPIC.match(f"p/sensor/{unit_node(a, 7)}/x/config")
    assert unit_node(a, 1) != unit_node(b, 1)


def test_ids_read_plainly_for_plain_bases() -> None:
    assert base_id("site/cabinet-7") == "site_cabinet-7"
    assert base_id("Site/Cab 7").startswith("site_cab-7_h")
    assert base_id("site/cab_7") != base_id("site/cab/7")


# -- every config and every value of the demo ----------------------------------------------------


def test_every_demo_config_and_value_fits_home_assistant() -> None:
    retained: dict[str, str] = {}
    link = _publish_demo("modscope/demo", "demo", retained)
    configs = _configs(retained)
    assert ha_rules.check_all(configs) == []
    problems, rendered = _states(configs, link.messages)
    assert problems == []
    assert rendered > 1000
    # the unit statuses through the connectivity sensors and the availability templates
    for topic, payload in configs.items():
        config = json.loads(payload)
        if config["state_topic"].endswith("/status"):
            state = retained[config["state_topic"]]
            assert ha_rules.check_state(topic, config, state) == []
            assert ha_rules.check_attributes(topic, config, state) == []
    node = "modscope_modscope_demo"
    unit4 = json.loads(configs[f"{PREFIX}/binary_sensor/{node}_4/unit_status/config"])
    assert ha_rules.render(unit4["value_template"], retained["modscope/demo/unit/4/status"]) == (
        "OFF"
    )
    unit3 = json.loads(configs[f"{PREFIX}/binary_sensor/{node}_3/unit_status/config"])
    assert ha_rules.render(unit3["value_template"], retained["modscope/demo/unit/3/status"]) == (
        "ON"
    )
    voltage = json.loads(configs[f"{PREFIX}/sensor/{node}_2/voltage/config"])
    assert voltage["device"]["via_device"] == node
    assert ha_rules.availability_of(voltage, retained) is True


def test_a_silent_unit_makes_its_entities_unavailable_while_the_bus_is_online() -> None:
    retained: dict[str, str] = {}
    _publish_demo("modscope/demo", "demo", retained)
    config = json.loads(retained[f"{PREFIX}/sensor/modscope_modscope_demo_2/voltage/config"])
    assert config["availability_mode"] == "all"
    status = json.loads(retained["modscope/demo/unit/2/status"])
    assert ha_rules.availability_of(config, retained) is True
    retained["modscope/demo/unit/2/status"] = json.dumps({**status, "state": "silent"})
    assert ha_rules.availability_of(config, retained) is False
    retained["modscope/demo/unit/2/status"] = json.dumps(status)
    retained["modscope/demo/status"] = "offline"
    assert ha_rules.availability_of(config, retained) is False


def test_demo_kvar_keeps_its_unit_without_a_class_home_assistant_refuses() -> None:
    retained: dict[str, str] = {}
    _publish_demo("modscope/demo", "demo", retained)
    config = json.loads(retained[f"{PREFIX}/sensor/modscope_modscope_demo_2/delta-kvar/config"])
    assert config["unit_of_measurement"] == "kvar" and "device_class" not in config
    assert config["state_class"] == "measurement"


# -- every dictionary modscope has ---------------------------------------------------------------


def _dictionaries() -> list[DeviceDictionary]:
    found = [load_model(m) for m in sorted(builtin_models())]
    for path in sorted((FIXTURES / "dictionaries").iterdir()):
        if path.suffix in (".toml", ".yaml", ".csv") and path.stem not in SKIPPED:
            found += load_dictionaries(path)
    for path in sorted((FIXTURES / "tutorial").glob("*.toml")):
        found += load_dictionaries(path)
    return found


def _entries(d: DeviceDictionary) -> list[Entry]:
    params = [
        Entry("holding_registers", 0, p.name, p.spec)
        for w in d.windows
        for p in w.parameters.values()
    ]
    return [*d.entries, *params]


def _message(entry: Entry, words: list[int]) -> str:
    """The value message the publisher sends for `entry` read as `words` (its fields
    that templates read: value, text, raw, bits)."""
    if entry.table in BIT_TABLES:
        r = decode_flag(entry, bool(words[0] & 1), False)
    else:
        r = decode_entry(entry, words, 0, False)
    message: dict[str, Any] = {"value": json_value(r.value), "text": r.text, "raw": list(r.raw)}
    if entry.spec.bits and isinstance(r.value, int) and not isinstance(r.value, bool):
        message["bits"] = {str(b): bool(r.value >> b & 1) for b in sorted(entry.spec.bits)}
    return json.dumps(message, ensure_ascii=False)


def _telling_words(entry: Entry) -> list[list[int]]:
    """Raw words worth trying: zeros, ones, all bits set, each named value, one the
    dictionary does not name, NaN for floats."""
    size = max(1, entry.spec.size)
    out = [[0] * size, [1] * size, [0xFFFF] * size, [0x7FC0] + [0] * (size - 1)]
    spec = entry.spec
    for key in [*spec.enum, *spec.special]:
        out.append(([0] * (size - 1)) + [key & 0xFFFF])
    undocumented = max([*spec.enum, *spec.special, 0]) + 1
    out.append(([0] * (size - 1)) + [undocumented & 0xFFFF])
    return out


def _device(d: DeviceDictionary) -> UnitDevice:
    return UnitDevice("site/cabinet7", 5, label="Test unit", model=d.name or d.model)


def test_every_dictionary_entry_gives_configs_home_assistant_takes() -> None:
    configs: dict[str, str] = {}
    rendered = 0
    problems: list[str] = []
    for d in _dictionaries():
        device = _device(d)
        for n, entry in enumerate(_entries(d)):
            key = f"{d.model}-{n}-{slug(entry.name)}"
            topic = f"site/cabinet7/unit/5/{key}"
            for c in register_configs(PREFIX, device, entry, key, topic):
                assert c.topic not in configs
                configs[c.topic] = c.payload
                config = json.loads(c.payload)
                for words in _telling_words(entry):
                    payload = _message(entry, words)
                    problems += ha_rules.check_state(c.topic, config, payload)
                    problems += ha_rules.check_attributes(c.topic, config, payload)
                    rendered += 1
        configs.update({c.topic: c.payload for c in unit_configs(PREFIX, device)})
    configs.update({c.topic: c.payload for c in bus_configs(PREFIX, "site/cabinet7", "ttyUSB0")})
    assert ha_rules.check_all(configs) == []
    assert problems == []
    assert len(configs) > 300 and rendered > 2000


@settings(max_examples=60, deadline=None)
@given(st.data())
def test_any_raw_value_reaches_home_assistant_as_a_state_it_takes(data: st.DataObject) -> None:
    dictionaries = _DICTS
    d = data.draw(st.sampled_from(dictionaries))
    entry = data.draw(st.sampled_from(_entries(d)))
    words = data.draw(
        st.lists(st.integers(0, 0xFFFF), min_size=entry.spec.size, max_size=entry.spec.size)
        if entry.spec.size
        else st.just([0])
    )
    for c in register_configs(PREFIX, _device(d), entry, "x", "t/unit/5/x"):
        config = json.loads(c.payload)
        payload = _message(entry, words)
        assert ha_rules.check_state(c.topic, config, payload) == []


_DICTS = _dictionaries()


# -- what each kind of register becomes ----------------------------------------------------------

DEVICE = UnitDevice("site/cabinet7", 3, label="Pump 1", model="Pump starter")


def _one(entry: Entry) -> list[dict[str, Any]]:
    found = register_configs(PREFIX, DEVICE, entry, slug(entry.name), "s/unit/3/x")
    assert ha_rules.check_all({c.topic: c.payload for c in found}) == []
    return [{"topic": c.topic, **json.loads(c.payload)} for c in found]


def _state(config: Mapping[str, Any], value: object, text: str = "") -> str:
    return ha_rules.render(
        str(config["value_template"]), json.dumps({"value": value, "text": text, "raw": [0]})
    )


def test_energy_counts_for_the_energy_dashboard() -> None:
    (c,) = _one(Entry("input_registers", 2, "Active Energy", ValueSpec(type="u32", unit="kWh")))
    assert (c["device_class"], c["state_class"], c["unit_of_measurement"]) == (
        "energy",
        "total_increasing",
        "kWh",
    )
    (c,) = _one(Entry("input_registers", 4, "Voltage", ValueSpec(unit="V")))
    assert (c["device_class"], c["state_class"]) == ("voltage", "measurement")
    assert c["topic"] == f"{PREFIX}/sensor/modscope_site_cabinet7_3/voltage/config"
    assert c["unique_id"] == "modscope_site_cabinet7_3_voltage"


def test_kva_keeps_its_unit_and_loses_a_class_home_assistant_refuses() -> None:
    (c,) = _one(Entry("input_registers", 2, "Apparent Power", ValueSpec(unit="kVA")))
    assert c["unit_of_measurement"] == "kVA" and "device_class" not in c
    (c,) = _one(Entry("input_registers", 2, "Reactive", ValueSpec(unit="VAr")))
    assert (c["unit_of_measurement"], c["device_class"]) == ("var", "reactive_power")


def test_a_named_reading_never_reaches_the_numeric_sensor() -> None:
    entry = Entry(
        "holding_registers",
        0x41,
        "Insulation Alarm",
        ValueSpec(unit="MOhm", scale=0.1, special={1: "off"}),
    )
    number, state = _one(entry)
    assert _state(number, "off", "Insulation Alarm = off") == "None"
    assert _state(number, 2.5) == "2.5"
    assert _state(number, None) == "None"  # NaN
    reading = ha_rules.render(
        str(number["json_attributes_template"]),
        json.dumps({"value": "off", "text": "Insulation Alarm = off", "raw": [1]}),
    )
    assert json.loads(reading)["text"] == "Insulation Alarm = off"
    assert state["options"] == ["off", "number"] and state["device_class"] == "enum"
    assert _state(state, "off") == "off" and _state(state, 2.5) == "number"
    assert state["topic"].endswith("/insulation-alarm_state/config")


def test_an_undocumented_enum_value_is_a_state_not_a_number() -> None:
    entry = Entry(
        "input_registers", 3, "Phase Sequence", ValueSpec(enum={0: "Wrong", 1: "Correct"})
    )
    (c,) = _one(entry)
    assert c["options"] == ["Wrong", "Correct", "undocumented"]
    assert _state(c, "Correct") == "Correct" and _state(c, 7) == "undocumented"
    taken = Entry("input_registers", 3, "Mode", ValueSpec(enum={0: "undocumented", 1: "b"}))
    (c,) = _one(taken)
    assert c["options"] == ["undocumented", "b", "undocumented (2)"]
    assert _state(c, 9) == "undocumented (2)"


def test_bits_binaries_and_text() -> None:
    coil = Entry("coils", 2, "Start", ValueSpec(type="bool"))
    assert entity_kind(coil) == "binary"
    (c,) = _one(coil)
    assert c["topic"] == f"{PREFIX}/binary_sensor/modscope_site_cabinet7_3/start/config"
    field = Entry("holding_registers", 0, "Speed step", ValueSpec(bit=4, width=3))
    assert entity_kind(field) == "number"  # a field of three bits is a number, not on/off
    bits = Entry("input_registers", 0, "Logic Status", ValueSpec(bits={6: "Stopped", 9: "Run"}))
    found = _one(bits)
    assert [c["topic"].split("/")[3] for c in found] == ["logic-status_bit6", "logic-status_bit9"]
    assert found[1]["name"] == "Logic Status: Run"
    text = Entry("holding_registers", 0, "Serial", ValueSpec(type="str", length=200))
    (c,) = _one(text)
    assert len(_state(c, "x" * 400)) == 255


# -- device versions -------------------------------------------------------------------------------

LINE = LineSettings(baud=19200, bytesize=8, parity="E", stopbits=1, mode="rtu")


def _session(frames: list[bytes], bindings: Mapping[int, Binding]) -> Session:
    session = Session(LINE, bindings=bindings)
    t = 1_768_464_000.0
    for frame in frames:
        t += 0.05
        session.feed(Chunk(frame, t))
    session.finish()
    return session


def _publish(session: Session, bindings: Mapping[int, Binding]) -> KeepingLink:
    link = KeepingLink(parse_target("mqtt://127.0.0.1/site/cabinet7"))
    publisher = BusPublisher(
        link, session, bindings, PublisherOptions(bus="ttyUSB0", ha_prefix=PREFIX)
    )
    publisher.announce()
    publisher.rows(final=True)
    return link


def _device_of(link: KeepingLink, unit: int) -> dict[str, Any]:
    topic = f"{PREFIX}/binary_sensor/modscope_site_cabinet7_{unit}/unit_status/config"
    device: dict[str, Any] = json.loads(link.retained[topic])["device"]
    return device


def test_read_device_identification_gives_the_software_version() -> None:
    """FC 43 / MEI 14 answer: VendorName, ProductCode, MajorMinorRevision = V2.11."""
    objects = [(0, b"Acme"), (1, b"PX-10"), (2, b"V2.11")]
    body = b"".join(bytes([i, len(v)]) + v for i, v in objects)
    request = with_crc(bytes([7, 0x2B, 0x0E, 0x01, 0x00]))
    answer = with_crc(bytes([7, 0x2B, 0x0E, 0x01, 0x01, 0x00, 0x00, len(objects)]) + body)
    link = _publish(_session([request, answer], {}), {})
    device = _device_of(link, 7)
    assert device["sw_version"] == "V2.11" and "hw_version" not in device
    assert device["name"] == "Modbus unit 7"


def test_version_registers_give_the_device_its_versions() -> None:
    d = DeviceDictionary(
        model="px",
        name="PX meter",
        path="px.toml",
        entries=(
            Entry("holding_registers", 0, "Firmware version", ValueSpec(type="u16")),
            Entry("holding_registers", 1, "Hardware revision", ValueSpec(type="u16")),
        ),
    )
    bindings = {9: Binding(9, "Meter", d)}
    request = with_crc(bytes([9, 3, 0, 0, 0, 2]))
    answer = with_crc(bytes([9, 3, 4, 0, 12, 0, 3]))
    link = _publish(_session([request, answer], bindings), bindings)
    assert _device_of(link, 9) | {} == {
        "identifiers": ["modscope_site_cabinet7_9"],
        "name": "Meter",
        "model": "PX meter",
        "via_device": "modscope_site_cabinet7",
        "sw_version": "12",
        "hw_version": "3",
    }
    firmware = json.loads(
        link.retained[f"{PREFIX}/sensor/modscope_site_cabinet7_9/firmware-version/config"]
    )
    assert firmware["device"]["sw_version"] == "12"  # republished with the versions


@pytest.mark.parametrize(
    ("name", "kind"),
    [
        ("Software revision", "sw_version"),
        ("Firmware version", "sw_version"),
        ("FW version", "sw_version"),
        ("MajorMinorRevision", "sw_version"),
        ("Hardware revision", "hw_version"),
        ("HW Version", "hw_version"),
        ("Parameter revision", None),
        ("Voltage", None),
    ],
)
def test_which_names_hold_versions(name: str, kind: str | None) -> None:
    assert version_kind(name) == kind
