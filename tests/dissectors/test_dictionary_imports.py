"""Importing Home Assistant modbus YAML and CSV register lists."""

from __future__ import annotations

from pathlib import Path

import pytest

from dissectors.dictionary import (
    DeviceDictionary,
    DictionaryError,
    check_dictionary,
    import_csv,
    import_home_assistant,
    load_dictionaries,
    load_dictionary,
    load_model,
)
from sniffer.meaning.annotate import load_bindings

FIXTURES = Path(__file__).parent.parent / "fixtures" / "dictionaries"


@pytest.fixture(scope="module")
def boiler() -> DeviceDictionary:
    found = import_home_assistant(FIXTURES / "home_assistant.yaml")
    assert [d.model for d in found] == ["Boiler-room-unit3", "hub2-unit0"]
    return found[0]


def test_ha_sensor_types_and_scale(boiler: DeviceDictionary) -> None:
    assert boiler.unit_hint == 3
    flow = boiler.decode("input", 100, [215])[0]
    assert flow.text == "Flow temperature = 21.5 °C"
    # swap: word = low word first; 400.0 is 0x43C80000
    energy = boiler.decode("holding", 102, [0x0000, 0x43C8])[0]
    assert (energy.value, energy.unit) == (400.0, "kWh")
    serial = boiler.decode("holding", 110, [0x4142, 0x4344, 0, 0])[0]
    assert serial.value == "ABCD"


def test_ha_slave_count_makes_consecutive_entries(boiler: DeviceDictionary) -> None:
    names = [
        (e.address, e.name) for e in boiler.entries_in("holding") if e.name.startswith("Counter")
    ]
    assert names == [(120, "Counter"), (122, "Counter 1"), (124, "Counter 2")]


def test_ha_binary_sensors_switches_verify(boiler: DeviceDictionary) -> None:
    assert boiler.decode_bits("discrete_inputs", 5, [True])[0].text == "Burner on = on"
    assert boiler.decode("holding", 200, [1])[0].text == "Pump running = on"
    assert boiler.decode_bits("coils", 10, [False])[0].text == "Pump = off"
    assert boiler.decode("holding", 300, [5], write=True)[0].text == "Mode switch = on"
    assert boiler.decode("input", 301, [0])[0].text == "Mode switch state = off"


def test_ha_left_out_entries_are_noted(boiler: DeviceDictionary) -> None:
    notes = " ".join(boiler.notes)
    assert "'Half float'" in notes
    assert "'Same place again' left out" in notes


def test_ha_climate_cover_and_secret_tag() -> None:
    hub2 = import_home_assistant(FIXTURES / "home_assistant.yaml")[1]
    texts = [v.text for v in hub2.decode("holding", 10, [44, 45, 3, 1])]
    assert texts == [
        "Bedroom temperature = 22.0 °C",
        "Bedroom target temperature = 22.5 °C",
        "Bedroom HVAC mode = heat",
        "Bedroom on/off = on",
    ]
    assert hub2.decode("input", 14, [2])[0].text == "Door status = opening"
    assert hub2.decode_bits("coils", 1, [True])[0].name == "Door"


def test_ha_unsafe_tag_is_a_clean_error() -> None:
    with pytest.raises(DictionaryError) as info:
        import_home_assistant(FIXTURES / "home_assistant_unsafe.yaml")
    error = info.value
    assert error.line == 5
    assert "YAML tag not allowed" in error.message
    assert "python/object" in error.message
    assert "never runs tags" in error.fix


def test_ha_included_modbus_list(tmp_path: Path) -> None:
    path = tmp_path / "modbus.yaml"
    path.write_text("- name: hub\n  sensors:\n    - name: T\n      address: 1\n", encoding="utf-8")
    (d,) = import_home_assistant(path)
    assert d.model == "hub-unit0"
    assert d.entries[0].table == "holding_registers"


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("modbus: !include modbus.yaml\n", None, "kept in another file"),
        ("homeassistant:\n  name: x\n", 1, "no Home Assistant modbus hubs"),
        ("modbus:\n  - name: h\n", 1, "no Home Assistant modbus sensors"),
        (
            "modbus:\n  - name: h\n    sensors:\n      - name: T\n        address: 1\n"
            "        input_type: holdin\n",
            4,
            "input_type 'holdin'",
        ),
        (
            "modbus:\n  - name: h\n    sensors:\n      - name: T\n        address: -1\n",
            4,
            "address -1",
        ),
        (
            "modbus:\n  - name: h\n    sensors:\n      - name: T\n        address: 1\n"
            "        swap: all\n",
            4,
            "swap 'all'",
        ),
        ("modbus: [\n", 2, "YAML syntax"),
    ],
)
def test_ha_errors(tmp_path: Path, text: str, line: int | None, message: str) -> None:
    path = tmp_path / "configuration.yaml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(DictionaryError) as info:
        import_home_assistant(path)
    assert info.value.line == line, str(info.value)
    assert message in info.value.message, str(info.value)


def test_csv_import() -> None:
    d = import_csv(FIXTURES / "registers.csv")
    assert d.model == "registers"
    setpoint = d.decode("holding", 0, [700], write=True)[0]
    assert setpoint.problems == ("written value 700 V above the documented maximum 600 V",)
    assert d.decode("holding", 2, [0x0000, 0x43C8])[0].text == "Energy = 400.0 kWh"
    assert d.decode("input", 5, [600])[0].text == "Temperature = 20.0 °C"
    assert d.decode("holding", 10, [2])[0].value == "Fault"
    assert d.decode_bits("coils", 3, [True])[0].text == "Start = on"
    entry = d.lookup("holding", 0)
    assert entry is not None and entry.spec.description == "Under voltage trip"


def test_csv_semicolons_and_decimal_commas() -> None:
    d = import_csv(FIXTURES / "registers_semicolon.csv")
    assert d.decode("holding", 4, [2301])[0].text == "Voltage = 230.1 V"


@pytest.mark.parametrize(
    ("text", "line", "message", "fix"),
    [
        ("table,adress,name\n", 1, "unknown CSV column 'adress'", "rename it 'address'"),
        ("table,name\n", 1, "no 'address' column", "table,address,name"),
        ("table,address,name,name\n", 1, "'name' twice", "keep one"),
        (
            "table,address,name\nholding,1,A\nholding,x2,B\n",
            3,
            "address 'x2' is not an integer",
            "0x0C",
        ),
        (
            "table,address,name,scale\n# note\nholding,1,A,big\n",
            3,
            "scale 'big' is not a number",
            "",
        ),
        (
            "table,address,name,type\nholding,1,A,u16\nholding,1,B,u16\n",
            3,
            "overlaps entry 'A' (line 2)",
            "",
        ),
        (
            "table,address,name,type\nholding,1,A,uint32\n",
            2,
            "unknown type 'uint32'",
            "write 'u32'",
        ),
        ("table,address,name\nholdng,1,A\n", 2, "unknown table 'holdng'", "holding"),
        ("table,address,name,enum\nholding,1,A,0=x;y\n", 2, "enum part 'y'", "0=Stop; 1=Run"),
        ("table,address,name\nholding,1,A,extra\n", 2, "4 cells for 3 columns", "quote"),
        ("", None, "the CSV file is empty", "header row"),
    ],
)
def test_csv_errors(tmp_path: Path, text: str, line: int | None, message: str, fix: str) -> None:
    path = tmp_path / "list.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(DictionaryError) as info:
        import_csv(path)
    error = info.value
    assert error.line == line, str(error)
    assert message in error.message, str(error)
    assert fix in error.fix, str(error)


# -- every place that takes a dictionary takes all three formats ---------------------------


def test_load_dictionaries_reads_each_format_by_name() -> None:
    ha = load_dictionaries(FIXTURES / "home_assistant.yaml")
    assert [d.model for d in ha] == ["Boiler-room-unit3", "hub2-unit0"]
    (csv_dict,) = load_dictionaries(FIXTURES / "registers.csv")
    assert csv_dict.model == "registers"
    (toml_dict,) = load_dictionaries(FIXTURES / "every_type.toml")
    assert toml_dict.model == "every-type"


def test_load_model_finds_models_in_yaml_and_csv() -> None:
    extra = [FIXTURES / "home_assistant.yaml", FIXTURES / "registers.csv"]
    assert load_model("Boiler-room-unit3", extra).unit_hint == 3
    assert load_model("registers", extra).decode("holding", 10, [1])[0].value == "Run"


def test_load_dictionary_of_a_file_with_several_devices_names_them() -> None:
    with pytest.raises(DictionaryError) as info:
        load_dictionary(FIXTURES / "home_assistant.yaml")
    assert "Boiler-room-unit3, hub2-unit0" in info.value.message


def test_bindings_from_ha_yaml_bind_its_slave_addresses() -> None:
    bindings = load_bindings(None, [], [FIXTURES / "home_assistant.yaml"])
    assert bindings[3].dictionary.model == "Boiler-room-unit3"
    assert 0 not in bindings  # slave 0 is a broadcast: never bound by itself
    # --unit wins over the address the file names
    bindings = load_bindings(None, ["3=registers"], [FIXTURES / "registers.csv"])
    assert bindings[3].dictionary.model == "registers"


def test_bus_file_names_dictionaries_beside_it(tmp_path: Path) -> None:
    (tmp_path / "regs.csv").write_text(
        (FIXTURES / "registers.csv").read_text(encoding="utf-8"), encoding="utf-8"
    )
    bus = tmp_path / "bus.toml"
    bus.write_text(
        'format = 1\ndictionaries = ["regs.csv"]\n\n[[unit]]\naddress = 7\nmodel = "regs"\n',
        encoding="utf-8",
    )
    bindings = load_bindings(bus)
    assert bindings[7].dictionary.decode("holding", 10, [2])[0].value == "Fault"


def test_bus_file_with_a_missing_dictionary_file(tmp_path: Path) -> None:
    bus = tmp_path / "bus.toml"
    bus.write_text('format = 1\ndictionaries = ["gone.yaml"]\n', encoding="utf-8")
    with pytest.raises(DictionaryError) as info:
        load_bindings(bus)
    assert info.value.path == str(bus) and info.value.line == 2
    assert "gone.yaml does not exist" in info.value.message


def test_unknown_model_in_a_bus_file_names_the_bus_file_and_line(tmp_path: Path) -> None:
    bus = tmp_path / "site.toml"
    bus.write_text(
        'format = 1\n\n[[unit]]\naddress = 2\nmodel = "rvs-dn"\n\n'
        '[[unit]]\naddress = 5\nmodel = "no-such-pump"\n',
        encoding="utf-8",
    )
    with pytest.raises(DictionaryError) as info:
        load_bindings(bus)
    assert info.value.path == str(bus)
    assert info.value.line == 7
    assert "no-such-pump" in info.value.message
    assert str(info.value).startswith(f"{bus}:7: ")


def test_csv_reports_every_bad_row(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(
        "table,address,name,scale\n"
        "holding,x1,A,\n"  # line 2: address
        "holding,3,B,\n"
        "holding,4,C,fast\n"  # line 4: scale
        "holdng,5,D,\n",  # line 5: table (found by the builder)
        encoding="utf-8",
    )
    errors = check_dictionary(path)
    assert [e.line for e in errors] == [2, 4, 5], [str(e) for e in errors]


def test_ha_reports_every_bad_item(tmp_path: Path) -> None:
    path = tmp_path / "ha.yaml"
    path.write_text(
        "modbus:\n"
        "  - name: hub\n"
        "    sensors:\n"
        "      - name: A\n"
        "        address: -1\n"  # item at line 4
        "        slave: 1\n"
        "      - name: B\n"
        "        address: 3\n"
        "        slave: 1\n"
        "      - name: C\n"
        "        address: 4\n"
        "        slave: 999\n",  # item at line 10
        encoding="utf-8",
    )
    errors = check_dictionary(path)
    assert [e.line for e in errors] == [4, 10], [str(e) for e in errors]


def test_csv_header_problems_are_all_reported(tmp_path: Path) -> None:
    path = tmp_path / "head.csv"
    path.write_text("table,adress,nam\nholding,1,A\n", encoding="utf-8")
    messages = [e.message for e in check_dictionary(path)]
    assert any("'adress'" in m for m in messages) and any("'nam'" in m for m in messages)
