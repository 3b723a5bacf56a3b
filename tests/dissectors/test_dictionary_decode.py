"""Decoding dictionary values from register words with answers worked out by hand."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.dictionary import DeviceDictionary, RegisterValue, load_dictionary

FIXTURES = Path(__file__).parent.parent / "fixtures" / "dictionaries"


@pytest.fixture(scope="module")
def every() -> DeviceDictionary:
    return load_dictionary(FIXTURES / "every_type.toml")


def one(
    d: DeviceDictionary, table: str, start: int, words: list[int], write: bool = False
) -> RegisterValue:
    found = d.decode(table, start, words, write=write)
    assert len(found) == 1, found
    return found[0]


def f32_words(value: float) -> tuple[int, int]:
    raw = struct.unpack(">I", struct.pack(">f", value))[0]
    return raw >> 16, raw & 0xFFFF


# -- each type --------------------------------------------------------------------------


def test_u16_with_unit(every: DeviceDictionary) -> None:
    v = one(every, "holding", 0, [300])
    assert v == RegisterValue(
        "holding_registers", 0, "Under Voltage Trip", 300, "V", "Under Voltage Trip = 300 V", (300,)
    )


@pytest.mark.parametrize(
    ("word", "value"), [(0x0000, 0), (0x7FFF, 32767), (0x8000, -32768), (0xFFFE, -2)]
)
def test_s16(every: DeviceDictionary, word: int, value: int) -> None:
    assert one(every, "holding", 1, [word]).value == value


def test_u8_high_and_s8_low_share_a_register(every: DeviceDictionary) -> None:
    high, low = every.decode("holding", 2, [0x12F6])
    assert (high.name, high.value) == ("High byte", 0x12)
    assert (low.name, low.value) == ("Low byte", -10)  # 0xF6 as s8
    assert high.raw == low.raw == (0x12F6,)


def test_u32_high_first(every: DeviceDictionary) -> None:
    assert one(every, "holding", 3, [0x1122, 0x3344]).value == 0x11223344


def test_s32_low_first(every: DeviceDictionary) -> None:
    # -2 is 0xFFFFFFFE: low word 0xFFFE first on the wire
    assert one(every, "holding", 5, [0xFFFE, 0xFFFF]).value == -2
    assert one(every, "holding", 5, [0x5678, 0x1234]).value == 0x12345678


# f32 400.0 is 0x43C80000; pi is 0x40490FDB (all four bytes differ)
@pytest.mark.parametrize(
    ("address", "words_400", "words_pi"),
    [
        (7, [0x43C8, 0x0000], [0x4049, 0x0FDB]),  # ABCD
        (9, [0x0000, 0x43C8], [0x0FDB, 0x4049]),  # CDAB
        (11, [0xC843, 0x0000], [0x4940, 0xDB0F]),  # BADC
        (13, [0x0000, 0xC843], [0xDB0F, 0x4940]),  # DCBA
    ],
)
def test_f32_word_orders(
    every: DeviceDictionary, address: int, words_400: list[int], words_pi: list[int]
) -> None:
    v = one(every, "holding", address, words_400)
    assert v.value == 400.0
    assert v.text.endswith("= 400.0 V" if address == 7 else "= 400.0")
    pi = one(every, "holding", address, words_pi)
    assert pi.value == 3.141593
    assert pi.text.endswith("3.141593" + (" V" if address == 7 else ""))


def test_f32_shortest_text(every: DeviceDictionary) -> None:
    v = one(every, "holding", 7, list(f32_words(0.1)))
    assert v.value == 0.1
    assert v.text == "F32 ABCD = 0.1 V"


def test_f32_nan_and_infinity(every: DeviceDictionary) -> None:
    nan = one(every, "holding", 7, [0x7FC0, 0x0000])
    assert isinstance(nan.value, float) and math.isnan(nan.value)
    assert nan.text == "F32 ABCD = NaN V"
    assert one(every, "holding", 7, [0xFF80, 0x0000]).text == "F32 ABCD = -inf V"


def test_u64_s64_f64(every: DeviceDictionary) -> None:
    assert one(every, "holding", 15, [0x0102, 0x0304, 0x0506, 0x0708]).value == 0x0102030405060708
    assert one(every, "holding", 19, [0xFFFF, 0xFFFF, 0xFFFF, 0xFFFE]).value == -2
    # f64 400.0 is 0x4079000000000000
    f64 = one(every, "holding", 23, [0x4079, 0, 0, 0])
    assert (f64.value, f64.text) == (400.0, "F64 = 400.0")


def test_str(every: DeviceDictionary) -> None:
    # "DCRL5" then NULs, two characters per register, high byte first
    v = one(every, "holding", 27, [0x4443, 0x524C, 0x3500, 0x0000])
    assert (v.value, v.text) == ("DCRL5", "Model name = DCRL5")


def test_str_escapes_control_characters(every: DeviceDictionary) -> None:
    v = one(every, "holding", 27, [0x4107, 0x0A1B, 0x5C80, 0x4242])
    assert v.value == "A\\x07\\x0a\\x1b\\\\\\x80BB"
    assert "\x07" not in v.text and "\n" not in v.text and "\x1b" not in v.text


def test_bits_of_one_register(every: DeviceDictionary) -> None:
    # bit 0 set, bits 1-3 = 5, bit 15 set
    run, mode, alarm = every.decode("holding", 31, [0x800B])
    assert (run.name, run.value, run.text) == ("Run", True, "Run = on")
    assert (mode.name, mode.value, mode.text) == ("Mode field", "Auto", "Mode field = Auto")
    assert (alarm.value, alarm.text) == ("Tripped", "Alarm = Tripped")
    cleared = every.decode("holding", 31, [0x0000])
    assert [v.text for v in cleared] == ["Run = off", "Mode field = Off", "Alarm = Normal"]


def test_bit_field_undocumented_value(every: DeviceDictionary) -> None:
    mode = every.decode("holding", 31, [0b0110])[1]  # field = 3
    assert mode.value == 3
    assert mode.text == "Mode field = 3 (undocumented)"
    assert mode.problems == ("value 3 is not one of the documented values",)


def test_enum(every: DeviceDictionary) -> None:
    assert one(every, "holding", 32, [1]).value == "Run"
    assert one(every, "holding", 32, [0x10]).text == "State = Fault"
    odd = one(every, "holding", 32, [7])
    assert (odd.value, odd.text) == (7, "State = 7 (undocumented)")
    assert odd.problems == ("value 7 is not one of the documented values",)


def test_bits(every: DeviceDictionary) -> None:
    v = one(every, "holding", 33, [0b1001])
    assert v.text == "Logic status = Motor running, Dual adjust on"
    assert v.value == 9
    assert one(every, "holding", 33, [0]).text == "Logic status = none"
    assert one(every, "holding", 33, [0x0021]).text == "Logic status = Motor running, bit 5"


@pytest.mark.parametrize(
    ("words", "value", "text"),
    [
        ([0xC000, 0x005F], -0.95, "Actual cos-phi = -0.95 capacitive"),  # sign + cap + 95
        ([0x0000, 0x005F], 0.95, "Actual cos-phi = 0.95 inductive"),
        ([0x8000, 0x005F], -0.95, "Actual cos-phi = -0.95 inductive"),
        ([0x4000, 0x0064], 1.0, "Actual cos-phi = 1.00 capacitive"),
        ([0x8000, 0x0000], 0.0, "Actual cos-phi = 0.00 inductive"),  # no negative zero
    ],
)
def test_sign_and_magnitude_with_flag(
    every: DeviceDictionary, words: list[int], value: float, text: str
) -> None:
    v = one(every, "holding", 34, words)
    assert (v.value, v.text) == (value, text)


def test_scale_and_offset(every: DeviceDictionary) -> None:
    volts = one(every, "holding", 36, [4000])
    assert (volts.value, volts.text) == (400.0, "Voltage = 400.0 V")
    temp = one(every, "holding", 37, [0xFFFE])  # -2 * 0.5 - 40
    assert (temp.value, temp.text) == (-41.0, "Temperature = -41.0 °C")


def test_precision(every: DeviceDictionary) -> None:
    v = one(every, "holding", 40, [12345])  # 12.345 kWh shown with 2 decimals
    assert (v.value, v.text) == (12.35, "Energy = 12.35 kWh")


def test_bool_register(every: DeviceDictionary) -> None:
    assert one(every, "holding", 38, [0x0100]).text == "Enabled = on"
    assert one(every, "holding", 38, [0]).value is False


def test_byte_swapped_u16(every: DeviceDictionary) -> None:
    assert one(every, "holding", 51, [0x3412]).value == 0x1234


def test_input_register_ref_in_hex_space(every: DeviceDictionary) -> None:
    v = one(every, "input", 13, [0x0001, 0x86A0])  # 100000 mA
    assert (v.table, v.address, v.text) == ("input_registers", 13, "Measured current = 100.000 A")


def test_ref_with_bit_in_percent_r_space(every: DeviceDictionary) -> None:
    v = one(every, "holding", 3150, [0b100])
    assert (v.name, v.value) == ("Flag bit", True)
    assert one(every, "holding", 3150, [0b011]).value is False


def test_repeat_stride_and_n(every: DeviceDictionary) -> None:
    values = every.decode("holding", 41, list(range(10)))
    assert [(v.address, v.name, v.value) for v in values] == [
        (41, "Step 1 power", 0),
        (43, "Step 2 power", 2),
        (45, "Step 3 power", 4),
        (47, "Step 4 power", 6),
        (49, "Step 5 power", 8),
    ]
    assert every.lookup("holding", 42) is None
    inputs = every.decode_bits("discrete_inputs", 0, [True, False, True])
    assert [(v.name, v.value) for v in inputs] == [
        ("Input 4", True),
        ("Input 5", False),
        ("Input 6", True),
    ]


def test_coils(every: DeviceDictionary) -> None:
    stop, start = every.decode_bits("coils", 0, [True, True])
    assert (stop.text, start.text) == ("Stop coil = on", "Start coil = Start")
    assert stop.raw == (1,)
    # FC 5 writes 0xFF00 for ON: decode() on a bit table treats nonzero as ON
    assert every.decode("coils", 1, [0xFF00], write=True)[0].value == "Start"


# -- ranges, writes, access ---------------------------------------------------------------


def test_range_problems_on_read_and_write(every: DeviceDictionary) -> None:
    read = one(every, "holding", 0, [700])
    assert read.problems == ("value 700 V above the documented maximum 600 V",)
    written = one(every, "holding", 0, [700], write=True)
    assert written.problems == ("written value 700 V above the documented maximum 600 V",)
    low = one(every, "holding", 0, [100], write=True)
    assert low.problems == ("written value 100 V below the documented minimum 120 V",)
    assert one(every, "holding", 0, [600], write=True).problems == ()


def test_access_problems(every: DeviceDictionary) -> None:
    assert one(every, "holding", 39, [1], write=True).problems == ()
    assert one(every, "holding", 39, [1]).problems == ("read from a write-only entry",)
    assert one(every, "input", 13, [0, 1], write=True).problems == ("written to a read-only entry",)
    assert one(every, "holding", 39, [9], write=True).problems == (
        "written value 9 is not one of the documented values",
    )


# -- ranges that cut entries ----------------------------------------------------------------


def test_partial_values(every: DeviceDictionary) -> None:
    # registers 4..7: the second half of U32 (3-4), all of S32 (5-6), first half of F32 (7-8)
    values = every.decode("holding", 4, [1, 2, 3, 4])
    assert [(v.name, v.partial) for v in values] == [
        ("U32", True),
        ("S32 low first", False),
        ("F32 ABCD", True),
    ]
    cut = values[0]
    assert cut.value is None
    assert cut.address == 3
    assert cut.raw == (1,)
    assert cut.text == "U32 = ? (only 1 of 2 registers in this frame)"
    assert values[2].raw == (4,)


def test_partial_string_shows_its_characters(every: DeviceDictionary) -> None:
    head = one(every, "holding", 27, [0x4443, 0x524C])
    assert head.partial and head.value == "DCRL…"
    tail = one(every, "holding", 29, [0x3500])
    assert tail.partial and tail.value == "…5…"


def test_every_entry_once_in_address_order(every: DeviceDictionary) -> None:
    values = every.decode("holding", 0, [0] * 60)
    names = [v.name for v in values]
    assert len(names) == len(set(names))
    assert [v.address for v in values] == sorted(v.address for v in values)
    expected = {e.name for e in every.entries if e.table == "holding_registers" and e.address < 60}
    assert set(names) == expected


def test_registers_without_entries_give_nothing(every: DeviceDictionary) -> None:
    assert every.decode("holding", 200, [1, 2, 3]) == []
    assert every.decode("holding", 0, []) == []


def test_lookup(every: DeviceDictionary) -> None:
    entry = every.lookup("holding_registers", 4)
    assert entry is not None and entry.name == "U32"
    assert [e.name for e in every.entries_at("holding", 31)] == ["Run", "Mode field", "Alarm"]
    assert every.lookup("coils", 5) is None


def test_bad_table_name_is_our_bug() -> None:
    d = load_dictionary(FIXTURES / "every_type.toml")
    with pytest.raises(ValueError, match="unknown Modbus table"):
        d.decode("holdings", 0, [1])
    with pytest.raises(ValueError, match="coils and discrete inputs"):
        d.decode_bits("holding", 0, [True])


def test_dictionary_is_immutable(every: DeviceDictionary) -> None:
    with pytest.raises(AttributeError):
        every.model = "other"  # type: ignore[misc]
    with pytest.raises(TypeError):
        every.exceptions[9] = "x"  # type: ignore[index]


# -- windows --------------------------------------------------------------------------------


def test_window_select_then_value(every: DeviceDictionary) -> None:
    window = every.windows[0]
    assert (window.select, window.value) == (3010, 3012)
    assert every.window_at(3010) is window
    selected = window.decode_select(1)
    assert (selected.value, selected.text) == (
        "P.01 CT primary",
        "Setup parameter = P.01 CT primary (1)",
    )
    read = window.decode(1, [250])
    assert (read.name, read.value, read.text) == ("P.01 CT primary", 250, "P.01 CT primary = 250 A")
    assert read.address == 3012
    too_big = window.decode(1, [20000], write=True)
    assert too_big.problems == ("written value 20000 A above the documented maximum 10000 A",)
    big = window.decode(6, [0x0001, 0x0000], table="input")
    assert (big.table, big.value) == ("input_registers", 65536)
    assert window.decode(30, [1]).value == "Auto"


def test_window_odd_cases(every: DeviceDictionary) -> None:
    window = every.windows[0]
    unknown = window.decode(99, [5])
    assert unknown.text == "Setup parameter 99 = 0x0005 (parameter not in the dictionary)"
    assert window.decode_select(99).text == "Setup parameter = 99 (not in the dictionary)"
    short = window.decode(6, [1])
    assert short.partial and short.value is None
    extra = window.decode(1, [250, 0])
    assert extra.value == 250
    assert extra.problems == ("2 registers for a 1-register parameter",)


# -- vendor functions, report server id, exceptions, timing ---------------------------------


def test_vendor_function_and_report_server_id(every: DeviceDictionary) -> None:
    function = every.functions[0x41]
    assert function.broadcast
    answer = function.decode_response(bytes([0x07]))
    assert [(f.name, f.value, f.start, f.end) for f in answer.fields] == [
        ("Slave address", 7, 0, 1)
    ]
    assert answer.problems == ()
    assert function.decode_response(b"").problems == (
        "'Slave address' needs 1 bytes, only 0 present",
    )
    assert every.report_server_id is not None
    report = every.report_server_id.decode(bytes([0x0A, 0xFF, 1, 2]))
    assert [f.text for f in report.fields] == [
        "Device type = DCRL3 (0x0A)",
        "Run indicator = on (0xFF)",
        "Rest = 01 02",
    ]
    odd = every.report_server_id.decode(bytes([0x0B, 0x00]))
    assert odd.problems == ("'Device type' value 11 is not one of the documented values",)
    assert dict(every.exceptions) == {3: "value outside the parameter's range", 6: "busy"}
    assert every.timing is not None
    assert every.timing.quiet_after_functions == (6, 16)


# -- never raise on bus data ----------------------------------------------------------------


@settings(max_examples=300, deadline=None)
@given(
    table=st.sampled_from(["holding", "input", "coils", "discrete_inputs"]),
    start=st.integers(0, 65535),
    words=st.lists(st.integers(-(2**20), 2**20), max_size=130),
    write=st.booleans(),
)
def test_decode_never_raises(table: str, start: int, words: list[int], write: bool) -> None:
    d = load_dictionary(FIXTURES / "every_type.toml")
    for value in d.decode(table, start, words, write=write):
        assert value.text.startswith(value.name)


@settings(max_examples=200, deadline=None)
@given(start=st.integers(0, 60), words=st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=60))
def test_decode_near_entries_never_raises(start: int, words: list[int]) -> None:
    d = load_dictionary(FIXTURES / "every_type.toml")
    for value in d.decode("holding", start, words):
        assert value.text
        assert "\n" not in value.text
    window = d.windows[0]
    for number in (1, 6, 30, 12345):
        assert window.decode(number, words).text
