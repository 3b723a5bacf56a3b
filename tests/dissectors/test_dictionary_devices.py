"""Every shipped dictionary in dissectors/devices loads and decodes synthetic data.

The folder is globbed at test time, so new device files are checked as they appear.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from pathlib import Path

import pytest

from dissectors.dictionary import (
    DeviceDictionary,
    Entry,
    builtin_models,
    check_dictionary,
    describe,
    load_dictionary,
    load_model,
)
from dissectors.dictionary.tomlpos import scan_toml

DEVICES = Path(__file__).resolve().parent.parent.parent / "dissectors" / "devices"
FILES = sorted(DEVICES.glob("*.toml"))


def zeros(n: int) -> list[int]:
    return [0x0000] * n


def ones(n: int) -> list[int]:
    return [0xFFFF] * n


def middle(n: int) -> list[int]:
    return [0x8000 | (0x1234 + k) for k in range(n)]


def small(n: int) -> list[int]:
    return [k + 1 for k in range(n)]


PATTERNS: dict[str, Callable[[int], list[int]]] = {
    "zeros": zeros,
    "ones": ones,
    "mid": middle,
    "small": small,
}


def test_the_devices_folder_has_dictionaries() -> None:
    assert FILES, f"no dictionaries in {DEVICES}"


def test_every_file_is_a_builtin_model() -> None:
    shipped = builtin_models()
    assert sorted(shipped.values()) == FILES
    for model, path in shipped.items():
        assert load_model(model).path == str(path)


def _check_value(d: DeviceDictionary, entry: Entry, words: list[int], write: bool) -> None:
    if entry.table in ("coils", "discrete_inputs"):
        values = d.decode_bits(
            entry.table, entry.address, [bool(w & 1) for w in words[:1]], write=write
        )
    else:
        values = d.decode(entry.table, entry.address, words[: entry.size], write=write)
    mine = [v for v in values if v.name == entry.name and v.address == entry.address]
    assert len(mine) >= 1, f"{entry.name} missing from {values}"
    for value in mine:
        assert entry.name in value.text
        assert not value.partial
        assert "\n" not in value.text


@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_dictionary_loads_and_every_entry_decodes(path: Path) -> None:
    problems = check_dictionary(path)
    assert problems == [], "\n".join(str(p) for p in problems)
    d = load_dictionary(path)
    assert d.entries, f"{path.name} has no entries"
    assert d.model and d.name
    for entry in d.entries:
        for make in PATTERNS.values():
            words = make(max(entry.size, 1))
            _check_value(d, entry, words, write=False)
            _check_value(d, entry, words, write=True)
    text = describe(d)
    for entry in d.entries:
        assert entry.name in text


@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_whole_tables_decode_in_one_read(path: Path) -> None:
    d = load_dictionary(path)
    for table in ("holding_registers", "input_registers"):
        entries = d.entries_in(table)
        if not entries:
            continue
        start = entries[0].address
        end = max(e.end for e in entries)
        for make in PATTERNS.values():
            # Read in 125-register chunks, as FC 3/4 would, some cutting entries in half.
            for chunk in range(start, end, 125):
                words = make(min(125, end - chunk))
                for value in d.decode(table, chunk, words):
                    assert value.text.startswith(value.name)
    for table in ("coils", "discrete_inputs"):
        entries = d.entries_in(table)
        if entries:
            start = entries[0].address
            count = entries[-1].address - start + 1
            values = d.decode_bits(table, start, [True] * count)
            assert len(values) == len(entries)


@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_windows_decode(path: Path) -> None:
    d = load_dictionary(path)
    for window in d.windows:
        for number, parameter in window.parameters.items():
            assert parameter.name in window.decode_select(number).text
            for make in PATTERNS.values():
                value = window.decode(number, make(parameter.spec.size))
                assert parameter.name in value.text
                assert not value.partial
        assert window.decode(65535, [1, 2]).text


@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_vendor_fields_decode(path: Path) -> None:
    d = load_dictionary(path)
    for function in d.functions.values():
        for data in (b"", bytes(8), bytes([0xFF]) * 8):
            function.decode_request(data)
            function.decode_response(data)
    if d.report_server_id is not None:
        for data in (b"", bytes(8), bytes([0xFF]) * 40):
            assert isinstance(d.report_server_id.decode(data).fields, tuple)


@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_line_scanner_finds_every_entry_and_key(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    data = tomllib.loads(text)
    found = scan_toml(text)
    for index, entry in enumerate(data.get("entry", [])):
        header = found.exact(("entry", index))
        assert header is not None
        assert lines[header - 1].strip().startswith("[[entry]]")
        for key in entry:
            line = found.exact(("entry", index, key))
            assert line is not None, (index, key)
            source = lines[line - 1]
            assert key in source or source.lstrip().startswith("[entry."), (index, key, source)


# -- fixes found by reading the seed dictionaries against their manuals --------------------


def _entry(d: DeviceDictionary, name: str) -> Entry:
    found = [e for e in d.entries if e.name == name]
    assert len(found) == 1, name
    return found[0]


def test_rvs_dn_insulation_setpoints_name_raw_1_off() -> None:
    d = load_model("rvs-dn")
    for name in ("Insulation Alarm", "Insulation Trip"):
        e = _entry(d, name)
        off = d.decode(e.table, e.address, [1])[0]
        assert off.text == f"{name} = off" and off.problems == ()
        low = d.decode(e.table, e.address, [2])[0]
        assert low.text == f"{name} = 0.2 MOhm" and low.problems == ()
        high = d.decode(e.table, e.address, [51], write=True)[0]
        assert high.problems == ("written value 5.1 MOhm above the documented maximum 5.0 MOhm",)
        assert e.spec.default == "off"


def test_rvs_dn_last_trip_number_0_is_not_undocumented() -> None:
    d = load_model("rvs-dn")
    e = _entry(d, "Last Trip Number")
    none = d.decode(e.table, e.address, [0])[0]
    assert none.problems == () and "undocumented" not in none.text
    assert d.decode(e.table, e.address, [5])[0].value == "Under Voltage"
    assert d.decode(e.table, e.address, [18])[0].problems != ()


def test_ved903b_fail_flags_list_the_active_ones() -> None:
    d = load_model("ved903b")
    e = _entry(d, "L26: Fail flags")
    assert e.ref == "%R20"
    # %R20.2 (L26/B) and %R20.14 (L26/M) set: bits 1 and 13
    shown = d.decode(e.table, e.address, [(1 << 1) | (1 << 13)])[0]
    assert shown.text == "L26: Fail flags = L26/B Load Overvoltage, L26/M Exciter Overtemperature"
    assert d.decode(e.table, e.address, [0])[0].text == "L26: Fail flags = none"
    second = _entry(d, "L26: Fail flags (second word)")
    assert d.decode(second.table, second.address, [0b1000])[0].value == 8
    assert "L26/C Under/Over Frequency" in d.decode(second.table, second.address, [8])[0].text


def test_special_values_need_no_enum(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(
        'format = 1\n[device]\nmodel = "s"\n\n[[entry]]\ntable = "holding"\npdu = 0\n'
        'name = "A"\nscale = 0.1\nenum = { "0" = "x" }\nspecial = { "1" = "off" }\n',
        encoding="utf-8",
    )
    (error,) = check_dictionary(path)
    assert error.line == 11 and "special" in error.message
