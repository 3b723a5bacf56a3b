"""Loading and checking dictionary files: every error names the file, the right line and a fix.

Each bad file below marks the line the error must name with `# HERE`.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.dictionary import (
    DictionaryError,
    builtin_models,
    check_dictionary,
    describe,
    load_dictionary,
    load_model,
)
from dissectors.dictionary.build import Builder
from dissectors.dictionary.reader import Source
from dissectors.dictionary.tomlpos import LineMap, scan_toml

FIXTURES = Path(__file__).parent.parent / "fixtures" / "dictionaries"
MAIN = Path(__file__).resolve().parent.parent.parent

HEAD = """\
format = 1

[device]
model = "t"

[spaces.hr]
table = "holding"
prefix = "4"
width = 4
first = 1
"""


def marked(text: str, mark: str = "# HERE") -> int:
    lines = [n for n, line in enumerate(text.splitlines(), start=1) if line.rstrip().endswith(mark)]
    assert len(lines) == 1, f"mark {mark!r} must be on exactly one line"
    return lines[0]


def write(tmp_path: Path, body: str, head: str = HEAD) -> tuple[Path, str]:
    text = head + textwrap.dedent(body)
    path = tmp_path / "device.toml"
    path.write_text(text, encoding="utf-8")
    return path, text


def fails(tmp_path: Path, body: str, head: str = HEAD) -> tuple[DictionaryError, int]:
    path, text = write(tmp_path, body, head)
    with pytest.raises(DictionaryError) as info:
        load_dictionary(path)
    error = info.value
    assert error.path == str(path)
    assert str(error) == f"{path}:{error.line}: {error.message}. Fix: {error.fix}"
    return error, marked(text)


# (id, body with "# HERE", words the message must hold, words the fix must hold)
CASES = [
    (
        "unknown key suggests the nearest",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        units = "V"   # HERE
        """,
        "unknown key 'units'",
        "write 'unit' instead of 'units'",
    ),
    (
        "unknown key without a near one lists the keys",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        colour = "red"   # HERE
        """,
        "unknown key 'colour'",
        "remove it",
    ),
    (
        "wrong value type",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        scale = "0.1"   # HERE
        """,
        "'scale' must be a number, not the string \"0.1\"",
        "scale = 0.1",
    ),
    (
        "integer expected",
        """
        [[entry]]
        pdu = "12"   # HERE
        table = "holding"
        name = "A"
        """,
        "'pdu' must be an integer",
        "no quotes",
    ),
    (
        "ref that no space parses",
        """
        [[entry]]
        ref = "30001"   # HERE
        name = "A"
        """,
        "no space reads the ref '30001'",
        "hr (40001)",
    ),
    (
        "ref two spaces parse equally well",
        """
        [spaces.other]
        table = "input"
        prefix = "4"
        width = 4
        first = 1

        [[entry]]
        name = "A"
        ref = "40001"   # HERE
        """,
        "read equally well by spaces 'hr' and 'other'",
        'add space = "hr"',
    ),
    (
        "ref outside 0-65535",
        """
        [spaces.big]
        table = "holding"
        prefix = "%R"
        pdu = 65000

        [[entry]]
        name = "A"
        ref = "%R9999"   # HERE
        """,
        "outside 0-65535",
        "first/pdu",
    ),
    (
        "bad enum key in an inline table",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        enum = { "0" = "Stop", "one" = "Run" }   # HERE
        """,
        "enum key 'one' is not a number",
        '"0x0A"',
    ),
    (
        "bad enum key in a sub-table",
        """
        [[entry]]
        ref = "40001"
        name = "A"

        [entry.enum]
        "0" = "Stop"
        "0x1G" = "Run"   # HERE
        """,
        "enum key '0x1G' is not a number",
        "hex",
    ),
    (
        "enum key outside the type",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        type = "u8"
        byte = "low"
        enum = { "256" = "Big" }   # HERE
        """,
        "enum key '256' is outside a u8 (0 to 255)",
        "from 0 to 255",
    ),
    (
        "two enum keys for one number",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        enum = { "10" = "Ten", "0x0A" = "Also ten" }   # HERE
        """,
        "enum keys '10' and '0x0A' are the same number",
        "keep one",
    ),
    (
        "min greater than max",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        min = 600   # HERE
        max = 120
        """,
        "min 600 is greater than max 120",
        "swap them",
    ),
    (
        "unknown table",
        """
        [[entry]]
        pdu = 3
        table = "holdings"   # HERE
        name = "A"
        """,
        "unknown table 'holdings'",
        "instead of 'holdings'",
    ),
    (
        "unknown type suggests ours",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        type = "uint16"   # HERE
        """,
        "unknown type 'uint16'",
        "write 'u16' instead of 'uint16'",
    ),
    (
        "unknown word order",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        type = "u32"
        word_order = "big_endian"   # HERE
        """,
        "unknown word_order 'big_endian'",
        "high_first (ABCD)",
    ),
    (
        "word order a 16-bit value cannot have",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        word_order = "low_first"   # HERE
        """,
        "u16 has a byte order but no word order",
        "high_first_swapped",
    ),
    (
        "str without length",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        type = "str"   # HERE
        """,
        "str without length",
        "add length = N",
    ),
    (
        "u8 without byte",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        type = "u8"   # HERE
        """,
        "u8 does not say which byte",
        'byte = "high"',
    ),
    (
        "bit out of range",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        bit = 16   # HERE
        """,
        "bit 16 is outside the register",
        "0 (least significant) to 15",
    ),
    (
        "bit of a ref out of range",
        """
        [spaces.R]
        table = "holding"
        prefix = "%R"
        first = 1
        bit_first = 1

        [[entry]]
        name = "A"
        ref = "%R151.17"   # HERE
        """,
        "bit 17 of ref '%R151.17' is outside the register",
        "numbers bits 1-16",
    ),
    (
        "bit field past bit 15",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        bit = 12
        width = 8   # HERE
        """,
        "a field of 8 bits from bit 12 does not fit",
        "width from 1 to 4",
    ),
    (
        "bit given twice",
        """
        [[entry]]
        ref = "40001.3"
        name = "A"
        bit = 3   # HERE
        """,
        "the bit is given twice",
        "remove bit",
    ),
    (
        "sign bit that is also a flag bit",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        type = "u32"
        sign_bit = 31
        flag_bits = { "31" = { set = "capacitive" } }   # HERE
        """,
        "bit 31 is both the sign_bit and a flag bit",
        "a bit of its own",
    ),
    (
        "sign bit outside the type",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        sign_bit = 16   # HERE
        """,
        "sign_bit 16 is outside a u16",
        "from 0 to 15",
    ),
    (
        "sign bit on a signed type",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        type = "s32"
        sign_bit = 31   # HERE
        """,
        "sign_bit needs an unsigned type, not s32",
        'type = "u16"',
    ),
    (
        "flag bit outside the value",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        flag_bits = { "20" = { set = "x" } }   # HERE
        """,
        "flag_bits key '20' is not a bit of the value (0-15)",
        "from 0 to 15",
    ),
    (
        "flag bit with an unknown key",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        flag_bits = { "14" = { on = "x" } }   # HERE
        """,
        "unknown key 'on'",
        "clear, set",
    ),
    (
        "bits on a signed type",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        type = "s16"
        bits = { "0" = "Run" }   # HERE
        """,
        "bits needs an unsigned type, not s16",
        'type = "u16"',
    ),
    (
        "bits together with enum",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        enum = { "0" = "x" }   # HERE
        bits = { "0" = "Run" }
        """,
        "'enum' does not go with bits",
        "split the entry",
    ),
    (
        "width without bit",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        width = 3   # HERE
        """,
        "width without bit",
        "add bit = N",
    ),
    (
        "scale on a string",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        type = "str"
        length = 2
        scale = 0.1   # HERE
        """,
        "'scale' does not apply to a str",
        "remove scale",
    ),
    (
        "default outside the range",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        min = 0
        max = 10
        default = 11   # HERE
        """,
        "default 11 is outside min 0 .. max 10",
        "check the manual",
    ),
    (
        "default not an enum name",
        """
        [[entry]]
        ref = "40001"
        name = "A"
        enum = { "0" = "Stop" }
        default = "Go"   # HERE
        """,
        "default 'Go' is not one of the enum names",
        '"Stop"',
    ),
    (
        "input written",
        """
        [[entry]]
        pdu = 0
        table = "input"
        name = "A"
        access = "rw"   # HERE
        """,
        "access 'rw' but input_registers cannot be written",
        'access = "r"',
    ),
    (
        "coil with a register key",
        """
        [[entry]]
        pdu = 0
        table = "coils"
        name = "A"
        scale = 2   # HERE
        """,
        "'scale' does not apply to coils (single bits)",
        "remove scale",
    ),
    (
        "missing name",
        """
        [[entry]]   # HERE
        ref = "40001"
        """,
        "entry #1: 'name' is missing",
        'name = "as the manual calls it"',
    ),
    (
        "no place",
        """
        [[entry]]   # HERE
        name = "A"
        """,
        "entry 'A' does not say where it is",
        'ref = "..."',
    ),
    (
        "two places",
        """
        [[entry]]
        name = "A"
        ref = "40001"
        pdu = 0   # HERE
        """,
        "gives both ref and pdu",
        "keep one",
    ),
    (
        "pdu without table",
        """
        [[entry]]
        name = "A"
        pdu = 0   # HERE
        """,
        "pdu = 0 without a table",
        'table = "holding"',
    ),
    (
        "address without a space",
        """
        [[entry]]
        name = "A"
        address = 5   # HERE
        """,
        "address = 5 but no space says how to count it",
        "default_space",
    ),
    (
        "unknown space",
        """
        [[entry]]
        name = "A"
        address = 5
        space = "HR"   # HERE
        """,
        "unknown space 'HR'",
        "write 'hr' instead of 'HR'",
    ),
    (
        "table that disagrees with the ref",
        """
        [[entry]]
        name = "A"
        ref = "40001"
        table = "input"   # HERE
        """,
        "table = 'input_registers' but its place is in holding_registers",
        "remove table",
    ),
    (
        "repeat without {n}",
        """
        [[entry]]
        ref = "40001"
        name = "Step"   # HERE
        repeat = 3
        """,
        "repeat = 3 but the name has no {n}",
        "Step {n} power",
    ),
    (
        "stride smaller than the entry",
        """
        [[entry]]
        ref = "40001"
        name = "Step {n}"
        type = "u32"
        repeat = 3
        stride = 1   # HERE
        """,
        "stride 1 is smaller than the entry's 2 elements",
        "at least 2",
    ),
    (
        "entry written as a table, not an array",
        """
        [entry]   # HERE
        ref = "40001"
        name = "A"
        """,
        "'entry' must be an array of tables",
        "[[entry]]",
    ),
    (
        "window parameter numbers repeat",
        """
        [[window]]
        name = "Setup"
        select = "40010"
        value = "40011"

        [[window.parameter]]
        number = 1
        name = "P1"

        [[window.parameter]]
        number = 1   # HERE
        name = "P1 again"
        """,
        "parameter 1 'P1 again'",
        "its own number",
    ),
    (
        "window parameter key error",
        """
        [[window]]
        name = "Setup"
        select = "40010"
        value = "40011"

        [[window.parameter]]
        number = 1
        name = "P1"
        unti = "A"   # HERE
        """,
        "unknown key 'unti'",
        "write 'unit' instead of 'unti'",
    ),
    (
        "standard function code",
        """
        [[function]]
        code = 3   # HERE
        name = "Read"
        """,
        "code 3 is a standard Modbus function",
        "65-72",
    ),
    (
        "bytes without length before the last field",
        """
        [[function]]
        code = 0x41
        name = "X"
        response = [
          { name = "Blob", type = "bytes" },   # HERE
          { name = "Tail", type = "u8" },
        ]
        """,
        "bytes without length before the last field",
        "add length = N",
    ),
    (
        "bad exception code",
        """
        [exceptions]
        "300" = "too big"   # HERE
        """,
        "key '300' is not an exception code 1-255",
        "decimal",
    ),
    (
        "negative timing",
        """
        [timing]
        response_ms = -5   # HERE
        """,
        "response_ms = -5 is negative",
        "0 or more",
    ),
]


@pytest.mark.parametrize(
    ("body", "message", "fix"),
    [pytest.param(body, message, fix, id=name) for name, body, message, fix in CASES],
)
def test_error_names_line_message_and_fix(
    tmp_path: Path, body: str, message: str, fix: str
) -> None:
    error, line = fails(tmp_path, body)
    assert error.line == line, str(error)
    assert message in error.message, str(error)
    assert fix in error.fix, str(error)


def test_overlap_names_both_entries_and_lines(tmp_path: Path) -> None:
    body = """
    [[entry]]   # FIRST
    ref = "40001"
    name = "Voltage"
    type = "u32"

    [[entry]]   # HERE
    ref = "40002"
    name = "Current"
    """
    error, line = fails(tmp_path, body)
    first = marked(HEAD + textwrap.dedent(body), "# FIRST")
    assert error.line == line
    assert error.message == (
        f"entry 'Current' (line {line}) overlaps entry 'Voltage' (line {first}) "
        "at holding_registers PDU address 1"
    )


def test_bit_fields_may_share_a_register_but_not_a_bit(tmp_path: Path) -> None:
    good = """
    [[entry]]
    ref = "40001.0"
    name = "A"
    [[entry]]
    ref = "40001"
    bit = 1
    width = 3
    name = "B"
    [[entry]]
    ref = "40001"
    type = "u8"
    byte = "high"
    name = "C"
    """
    path, _ = write(tmp_path, good)
    assert [e.name for e in load_dictionary(path).entries] == ["A", "B", "C"]
    bad = """
    [[entry]]
    ref = "40001"
    bit = 1
    width = 3
    name = "B"
    [[entry]]   # HERE
    ref = "40001.3"
    name = "A"
    """
    error, line = fails(tmp_path, bad)
    assert error.line == line and "overlaps entry 'B'" in error.message
    whole = """
    [[entry]]
    ref = "40001.0"
    name = "A"
    [[entry]]   # HERE
    ref = "40001"
    name = "Whole"
    """
    error, line = fails(tmp_path, whole)
    assert error.line == line and "'Whole'" in error.message


def test_repeat_copies_overlapping_another_entry(tmp_path: Path) -> None:
    body = """
    [[entry]]
    ref = "40005"
    name = "Lonely"
    [[entry]]   # HERE
    ref = "40001"
    name = "Step {n}"
    repeat = 5
    """
    error, line = fails(tmp_path, body)
    assert error.line == line
    assert "entry 'Step 5'" in error.message and "'Lonely'" in error.message


def test_toml_syntax_error_keeps_tomllib_line(tmp_path: Path) -> None:
    body = """
    [[entry]]
    ref = "40001"
    name = "A
    type = "u16"
    """
    path, text = write(tmp_path, body)
    with pytest.raises(DictionaryError) as info:
        load_dictionary(path)
    error = info.value
    assert error.line == text.splitlines().index('name = "A') + 1
    assert error.message.startswith("TOML syntax: ")
    assert "(at line" not in error.message
    assert "column" in error.fix


def test_duplicate_key_is_a_syntax_error(tmp_path: Path) -> None:
    body = """
    [[entry]]
    ref = "40001"
    name = "A"
    name = "B"   # HERE
    """
    error, line = fails(tmp_path, body)
    assert error.line == line


@pytest.mark.parametrize(
    ("head", "message"),
    [
        ('[device]\nmodel = "t"\n', "does not say its format"),
        ('format = 2   # HERE\n[device]\nmodel = "t"\n', "format = 2 is not a format"),
        ("format = 1\n", "no [device] table"),
        ('format = 1\n[device]\nmodel = "a b"   # HERE\n', "model 'a b' has characters"),
        ('format = 1\n[device]   # HERE\nname = "x"\n', "'model' is missing"),
        (
            'format = 1\n[device]\nmodel = "t"\ndefault_space = "hr"   # HERE\n',
            "not a declared space",
        ),
        ('format = 1\n[devices]   # HERE\nmodel = "t"\n', "unknown key 'devices'"),
        (
            'format = 1\n[device]\nmodel = "t"\n[spaces.x]   # HERE\nprefix = "4"\n',
            "'table' is missing",
        ),
        (
            'format = 1\n[device]\nmodel = "t"\n[spaces.x]\ntable = "holding"\n'
            "radix = 8   # HERE\n",
            "radix",
        ),
    ],
)
def test_file_level_errors(tmp_path: Path, head: str, message: str) -> None:
    path = tmp_path / "device.toml"
    path.write_text(head, encoding="utf-8")
    with pytest.raises(DictionaryError) as info:
        load_dictionary(path)
    error = info.value
    expected = marked(head) if "# HERE" in head else 1
    assert error.line == expected, str(error)
    assert message in error.message


def test_all_errors_are_collected_in_line_order(tmp_path: Path) -> None:
    body = """
    [[entry]]
    ref = "40001"
    name = "A"
    type = "uint16"   # HERE
    [[entry]]
    ref = "40002"
    name = "B"
    unitt = "V"
    [[entry]]
    ref = "99999"
    name = "C"
    """
    path, text = write(tmp_path, body)
    problems = check_dictionary(path)
    assert [p.message.split(":")[0] for p in problems] == ["entry 'A'", "entry 'B'", "entry 'C'"]
    assert problems[0].line == marked(text)
    assert problems[0].line is not None and problems[1].line is not None
    assert problems[0].line < problems[1].line
    with pytest.raises(DictionaryError) as info:
        load_dictionary(path)
    assert len(info.value.all) == 3


def test_unreadable_and_non_utf8_files(tmp_path: Path) -> None:
    with pytest.raises(DictionaryError, match="cannot read the file"):
        load_dictionary(tmp_path / "missing.toml")
    bad = tmp_path / "latin.toml"
    bad.write_bytes(b'format = 1\n[device]\nmodel = "caf\xe9"\n')
    with pytest.raises(DictionaryError) as info:
        load_dictionary(bad)
    assert info.value.line == 3 and "UTF-8" in info.value.message


def test_error_string_without_line() -> None:
    error = DictionaryError("x.toml", None, "broken", "mend it")
    assert str(error) == "x.toml: broken. Fix: mend it"
    assert (
        str(DictionaryError("x.toml", 4, "broken", "mend it")) == "x.toml:4: broken. Fix: mend it"
    )


# -- the line scanner ----------------------------------------------------------------------


def test_line_scanner_handles_strings_arrays_and_nesting() -> None:
    text = textwrap.dedent(
        '''\
        title = """
        [[entry]] inside a string
        """
        [a."b.c"]
        x = 1 # [[entry]]
        d.e = 'lit'
        [[entry]]
        arr = [
          1,
          { k = "v" },
        ]
        [entry.enum]
        "0" = "x"
        [[entry]]
        [[entry.sub]]
        y = 2
        [[entry.sub]]
        y = 3
        '''
    )
    lines = scan_toml(text)
    assert lines.exact(("title",)) == 1
    assert lines.exact(("a", "b.c")) == 4
    assert lines.exact(("a", "b.c", "x")) == 5
    assert lines.exact(("a", "b.c", "d", "e")) == 6
    assert lines.exact(("entry", 0)) == 7
    assert lines.exact(("entry", 0, "arr", 1)) == 10
    assert lines.exact(("entry", 0, "arr", 1, "k")) == 10
    assert lines.exact(("entry", 0, "enum", "0")) == 13
    assert lines.exact(("entry", 1)) == 14
    assert lines.exact(("entry", 1, "sub", 1, "y")) == 18
    assert lines.line(("entry", 1, "sub", 1, "missing")) == 17


# -- shipped models ------------------------------------------------------------------------


def test_unknown_model_lists_the_known_ones() -> None:
    with pytest.raises(DictionaryError) as info:
        load_model("no-such-device")
    error = info.value
    assert error.line is None
    assert "no dictionary for model 'no-such-device'" in error.message
    for model in builtin_models():
        assert model in error.fix
    assert "--dict FILE" in error.fix


def test_the_shipped_models_are_read_again_when_a_file_changes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """builtin_models reads each file once per version (a bus of many units looks its
    models up many times), and a file changed on disk is read again."""
    from dissectors.dictionary import loader

    monkeypatch.setattr(loader, "DEVICES_DIR", tmp_path)
    shipped = tmp_path / "pump.toml"
    shipped.write_text('[device]\nmodel = "pump-a"\n')
    assert builtin_models() == {"pump-a": shipped}
    assert builtin_models() == {"pump-a": shipped}
    shipped.write_text('[device]\nmodel = "pump-bb"\n')  # another size, another mtime
    assert builtin_models() == {"pump-bb": shipped}
    shipped.write_text("[device\n")  # unreadable: listed under its file name
    assert builtin_models() == {"pump": shipped}


def test_extra_dictionaries_come_first() -> None:
    d = load_model("every-type", [FIXTURES / "every_type.toml"])
    assert d.model == "every-type"
    with pytest.raises(DictionaryError) as info:
        load_model("nothing", [FIXTURES / "every_type.toml"])
    assert "every-type" in info.value.fix


def test_describe_lists_every_entry() -> None:
    d = load_dictionary(FIXTURES / "every_type.toml")
    text = describe(d)
    for entry in d.entries:
        assert entry.name in text
    line = next(row for row in text.splitlines() if "Under Voltage Trip" in row)
    for part in ("holding_registers", " 0 ", "40001", "u16", "V", "120..600 default 300", "rw"):
        assert part in line
    assert "%R151.3" in text and "f32 CDAB" in text and "0=Stop; 1=Run; 16=Fault" in text
    assert "function 0x41 (65) Get Slave Address (broadcast)" in text


def test_dictionary_package_stays_pure() -> None:
    code = (
        "import sys, dissectors.dictionary as d\n"
        "d.load_dictionary(sys.argv[1])\n"
        "names = ('textual', 'serial', 'construct', 'sniffer', 'yaml')\n"
        "bad = [m for m in names if m in sys.modules]\n"
        "print(','.join(bad))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code, str(FIXTURES / "every_type.toml")],
        cwd=MAIN,
        capture_output=True,
        text=True,
        check=True,
        env={"PYTHONPATH": str(MAIN)},
    )
    assert result.stdout.strip() == ""


# -- whatever a file holds, checking it gives a dictionary or a DictionaryError --------------

_WORDS = ["u16", "u32", "f32", "str", "bool", "u8", "s8", "high", "low", "40001", "40001.3"]
_WORDS += ["hr", "rw", "r", "CDAB", "holding", "coils", "{n}", ""]
_FLAG = st.dictionaries(st.sampled_from(["set", "clear", "on"]), st.text(max_size=3))
_NAMES = st.dictionaries(
    st.sampled_from(["0", "1", "0x10", "-1", "x", "31", "30"]),
    st.one_of(st.text(max_size=5), _FLAG),
)
_VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-70000, 70000),
    st.floats(allow_nan=True),
    st.sampled_from(_WORDS),
    st.lists(st.integers(0, 300), max_size=3),
    _NAMES,
)
_KEYS = ["ref", "address", "pdu", "table", "space", "name", "type", "byte", "bit", "width"]
_KEYS += ["length", "word_order", "scale", "offset", "precision", "sign_bit", "flag_bits"]
_KEYS += ["enum", "bits", "min", "max", "default", "access", "repeat", "stride", "n_first", "unit"]
_RANDOM_ENTRY = st.dictionaries(st.sampled_from(_KEYS), _VALUES, max_size=8)
_NEAR_VALID_ENTRY = st.builds(
    lambda place, extra: {"name": "Value {n}", "repeat": 2, **place, **extra},
    st.sampled_from([{"ref": "40001"}, {"pdu": 5, "table": "input"}, {"address": 9}]),
    st.dictionaries(st.sampled_from(_KEYS[6:]), _VALUES, max_size=3),
)
_ENTRY = st.one_of(_RANDOM_ENTRY, _NEAR_VALID_ENTRY, _NEAR_VALID_ENTRY)


@settings(max_examples=400, deadline=None)
@given(entries=st.lists(_ENTRY, max_size=4))
def test_builder_only_raises_dictionary_errors(entries: list[dict[str, object]]) -> None:
    data: dict[str, object] = {
        "format": 1,
        "device": {"model": "fuzz", "default_space": "hr"},
        "spaces": {"hr": {"table": "holding", "prefix": "4", "width": 4, "first": 1}},
        "entry": [{k: v for k, v in e.items() if v is not None} for e in entries],
    }
    try:
        d = Builder(Source("fuzz.toml", LineMap())).build(data)
    except DictionaryError as error:
        assert error.message and error.fix
        return
    for entry in d.entries:
        d.decode(entry.table, entry.address, [0xFFFF] * entry.size, write=True)


def test_names_must_be_one_printable_line(tmp_path: Path) -> None:
    body = """
    [[entry]]
    ref = "40001"
    name = "Evil\\u001b[2J"   # HERE
    """
    error, line = fails(tmp_path, body)
    assert error.line == line
    assert "control character" in error.message
    body = """
    [[entry]]
    ref = "40001"
    name = "A"
    enum = { "0" = "two\\nlines" }   # HERE
    """
    error, line = fails(tmp_path, body)
    assert error.line == line
    assert "on one line" in error.message
