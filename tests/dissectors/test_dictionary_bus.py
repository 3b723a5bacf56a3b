"""Bus files and --unit bindings."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from dissectors.dictionary import Bus, DictionaryError, UnitBinding, load_bus, parse_unit_binding

FIXTURES = Path(__file__).parent.parent / "fixtures" / "dictionaries"


def test_bus_file() -> None:
    bus = load_bus(FIXTURES / "bus.toml")
    assert isinstance(bus, Bus)
    assert dict(bus.line) == {"baud": 9600, "parity": "N", "stopbits": 2}
    assert sorted(bus.units) == [3, 7]
    assert bus.units[3] == UnitBinding(3, "rvs-dn", "Pump 1 starter")
    assert bus.units[3].line == 8
    assert bus.units[7].label == ""


def test_bus_without_line_settings(tmp_path: Path) -> None:
    path = tmp_path / "bus.toml"
    path.write_text('[[unit]]\naddress = 1\nmodel = "dcrl"\n', encoding="utf-8")
    bus = load_bus(path)
    assert dict(bus.line) == {}
    assert bus.units[1].model == "dcrl"


def test_parity_words_are_letters(tmp_path: Path) -> None:
    path = tmp_path / "bus.toml"
    path.write_text('[line]\nparity = "even"\nmode = "RTU"\nbytesize = 8\n', encoding="utf-8")
    assert dict(load_bus(path).line) == {"parity": "E", "mode": "rtu", "bytesize": 8}


BAD_BUSES = [
    ('[line]\nbaud = 9600\nparity = "X"   # HERE\n', "parity 'X'", '"N"'),
    ("[line]\nstopbits = 3   # HERE\n", "stopbits = 3", "1 or 2"),
    ('[line]\nbaud = "fast"   # HERE\n', "'baud' must be an integer", "baud = 12"),
    ("[line]\nspeed = 9600   # HERE\n", "unknown key 'speed'", "remove it"),
    ('[[unit]]\naddress = 0   # HERE\nmodel = "x"\n', "address = 0 is out of range", "1 to 247"),
    ('[[unit]]   # HERE\nmodel = "x"\n', "'address' is missing", "address = 3"),
    ("[[unit]]   # HERE\naddress = 2\n", "'model' is missing", 'model = "rvs-dn"'),
    ('[[unit]]\naddress = 2\nmodle = "x"   # HERE\n', "unknown key 'modle'", "write 'model'"),
    ('[[unit]]\naddress = 2\nmodel = "x y"   # HERE\n', "not a model name", "[device] model"),
    ("[[units]]   # HERE\naddress = 2\n", "unknown key 'units'", "write 'unit'"),
    ("format = 3   # HERE\n", "format = 3", "format = 1"),
    ("[line\nbaud = 1\n", "TOML syntax", "column"),
]


@pytest.mark.parametrize(("text", "message", "fix"), BAD_BUSES)
def test_bad_bus_files(tmp_path: Path, text: str, message: str, fix: str) -> None:
    path = tmp_path / "bus.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(DictionaryError) as info:
        load_bus(path)
    error = info.value
    lines = text.splitlines()
    expected = next((n for n, line in enumerate(lines, 1) if line.endswith("# HERE")), 1)
    assert error.line == expected, str(error)
    assert message in error.message, str(error)
    assert fix in error.fix, str(error)


def test_duplicate_unit_names_both_lines(tmp_path: Path) -> None:
    text = textwrap.dedent(
        """\
        [[unit]]
        address = 3
        model = "rvs-dn"

        [[unit]]
        address = 3
        model = "dcrl"
        """
    )
    path = tmp_path / "bus.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(DictionaryError) as info:
        load_bus(path)
    error = info.value
    assert error.line == 6
    assert error.message == "unit 3 (line 5) is already bound to 'rvs-dn' (line 1)"


@pytest.mark.parametrize(
    ("text", "binding"),
    [
        ("3=rvs-dn", UnitBinding(3, "rvs-dn", "")),
        ("3=rvs-dn:Pump 1", UnitBinding(3, "rvs-dn", "Pump 1")),
        (" 12 = dcrl : Cabinet A ", UnitBinding(12, "dcrl", "Cabinet A")),
        ("0x10=ved903b", UnitBinding(16, "ved903b", "")),
        ("247=x:a:b", UnitBinding(247, "x", "a:b")),
    ],
)
def test_parse_unit_binding(text: str, binding: UnitBinding) -> None:
    assert parse_unit_binding(text) == binding


@pytest.mark.parametrize(
    "text", ["", "3", "rvs-dn", "=rvs-dn", "3=", "x=rvs-dn", "0=rvs-dn", "248=rvs-dn", "3=rvs dn"]
)
def test_bad_unit_binding_says_the_form(text: str) -> None:
    with pytest.raises(ValueError, match="ADDRESS=MODEL or ADDRESS=MODEL:LABEL"):
        parse_unit_binding(text)
