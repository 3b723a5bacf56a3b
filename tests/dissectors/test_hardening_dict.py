"""Dictionary readers refuse hostile files fast, naming the file, the line and the limit
(issue 15, items 4, 5 and the 4,300-digit reference of item 8)."""

from __future__ import annotations

import contextlib
import io
import tracemalloc
from pathlib import Path

import pytest

from dissectors.dictionary import (
    DictionaryError,
    import_csv,
    import_home_assistant,
    load_dictionary,
)
from dissectors.dictionary.bus import load_bus
from dissectors.dictionary.limits import (
    MAX_DEPTH,
    MAX_DIGITS,
    MAX_EXPANDED,
    check_yaml,
    load_toml,
)
from sniffer.cli import main


def billion_laughs(levels: int = 7) -> str:
    """A Home Assistant file whose hub name is an alias of nested aliases: 431 bytes
    that expand to 9**7 strings (before the limits: 5.7 s and 460 MB, and accepted)."""
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]")
    lines += [
        "modbus:",
        f"- name: *a{levels - 1}",
        "  type: tcp",
        "  host: h",
        "  port: 502",
        "  sensors:",
        "  - {name: t, address: 1}",
    ]
    return "\n".join(lines) + "\n"


def long_aliases(length: int = 3_500_000, aliases: int = 100) -> str:
    """A Home Assistant file with one long sensor name and `aliases` more sensors named
    by an alias of it (issue 30, item 8: 3.5 MB that `dict check` passed and `dict show`
    took 42 s and 768 MB to print)."""
    lines = [
        "modbus:",
        "- name: hub",
        "  type: tcp",
        "  host: h",
        "  port: 502",
        "  sensors:",
        "  - name: &long " + "x" * length,
        "    address: 0",
    ]
    for k in range(aliases):
        lines += ["  - name: *long", f"    address: {k + 1}"]
    return "\n".join(lines) + "\n"


DICT_HEAD = 'format = 1\n[device]\nmodel = "x"\nname = "x"\n'


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_billion_laughs_yaml_is_refused_at_its_alias_line(tmp_path: Path) -> None:
    text = billion_laughs()
    assert len(text) < 445
    path = write(tmp_path, "laughs.yaml", text)
    with pytest.raises(DictionaryError) as caught:
        import_home_assistant(path)
    error = caught.value
    assert error.path == str(path)
    assert error.line == 6  # the first alias line that goes over the limit
    assert "200,000 values" in error.message


def test_yaml_alias_inside_its_own_value_is_a_loop(tmp_path: Path) -> None:
    path = write(tmp_path, "loop.yaml", "modbus: &m\n- name: hub\n  sensors: *m\n")
    with pytest.raises(DictionaryError) as caught:
        import_home_assistant(path)
    assert caught.value.line == 3
    assert "loop" in caught.value.message


def test_aliases_of_a_long_string_are_refused_by_their_characters(tmp_path: Path) -> None:
    path = write(tmp_path, "long.yaml", long_aliases())
    with pytest.raises(DictionaryError) as caught:
        import_home_assistant(path)
    error = caught.value
    assert error.path == str(path)
    # 3.5 million characters at line 7, as many again at each alias from line 9 on: the
    # fourth alias makes 17.5 million, over 16 Mi
    assert error.line == 9 + 2 * 3
    assert f"more than {MAX_EXPANDED:,} characters" in error.message
    assert "alias" in error.fix


def test_aliases_of_a_long_string_are_refused_in_bounded_memory(tmp_path: Path) -> None:
    # the check costs the file, not what it expands to: a generous bound of 4x the text
    path = write(tmp_path, "long.yaml", long_aliases())
    tracemalloc.start()
    try:
        with pytest.raises(DictionaryError):
            import_home_assistant(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 4 * 4 * 3_500_000  # characters of up to 4 bytes in a Python str


def test_the_character_limit_counts_what_anchors_hold() -> None:
    # nested collections: an alias of a list costs every string inside it
    half = "x" * (MAX_EXPANDED // 16)
    within = f"a: &a [{half}, {half}]\n" + "".join(f"{key}: *a\n" for key in "bcdefg")
    check_yaml("ok.yaml", within)  # 7 x 2 Mi characters (and 7 keys): 14 Mi of 16 Mi
    with pytest.raises(DictionaryError) as caught:
        check_yaml("big.yaml", within + "h: *a\n")  # 16 Mi and 8 characters of keys
    assert caught.value.line == 8


def test_small_aliases_stay_allowed() -> None:
    # HA users do reuse blocks with anchors: a few aliases are fine
    check_yaml("ok.yaml", "base: &b {slave: 1}\nmodbus:\n- sensors:\n  - *b\n  - *b\n")


@pytest.mark.parametrize(
    "text",
    [
        "modbus: " + "[" * 2000 + "]" * 2000 + "\n",
        "".join(" " * i + "- \n" for i in range(2000)),
        "".join(" " * i + f"k{i}:\n" for i in range(2000)) + " " * 2000 + "v: 1\n",
    ],
    ids=["flow", "block-sequences", "block-mappings"],
)
def test_deep_yaml_is_a_dictionary_error(tmp_path: Path, text: str) -> None:
    path = write(tmp_path, "deep.yaml", text)
    with pytest.raises(DictionaryError) as caught:
        import_home_assistant(path)
    assert caught.value.path == str(path)
    assert caught.value.line is not None
    assert f"more than {MAX_DEPTH} levels" in caught.value.message


@pytest.mark.parametrize(
    ("text", "line"),
    [
        ("x = " + "[" * 2000 + "]" * 2000 + "\n", 1),
        ("a = 1\nx = " + "{b = " * 2000 + "1" + "}" * 2000 + "\n", 2),
        ("a = 1\n\nx" + ".b" * 2000 + " = 1\n", 3),
        ("[x" + ".b" * 2000 + "]\nv = 1\n", 1),
    ],
    ids=["arrays", "inline-tables", "dotted-key", "dotted-header"],
)
def test_deep_toml_is_a_dictionary_error(tmp_path: Path, text: str, line: int) -> None:
    path = write(tmp_path, "deep.toml", DICT_HEAD + text)
    for read in (load_dictionary, load_bus):
        with pytest.raises(DictionaryError) as caught:
            read(path)
        assert caught.value.path == str(path)
        assert caught.value.line == line + DICT_HEAD.count("\n")
        assert f"more than {MAX_DEPTH} levels" in caught.value.message


def test_brackets_in_strings_and_comments_do_not_count() -> None:
    text = 'a = "' + "[" * 100 + '"\n# ' + "{" * 100 + "\nb = '''\n" + "[" * 100 + "'''\n"
    assert load_toml("ok.toml", text)["a"] == "[" * 100


def test_reference_of_4300_digits_names_file_and_line(tmp_path: Path) -> None:
    big = "4" + "0" * 4300
    text = DICT_HEAD + f'[[entry]]\nref = {big}\nname = "a"\ntype = "u16"\n'
    path = write(tmp_path, "big.toml", text)
    with pytest.raises(DictionaryError) as caught:
        load_dictionary(path)
    assert (caught.value.path, caught.value.line) == (str(path), 6)
    assert f"more than {MAX_DIGITS} digits" in caught.value.message


def test_yaml_number_of_4300_digits_names_file_and_line(tmp_path: Path) -> None:
    text = "modbus:\n- name: hub\n  sensors:\n  - {name: t, address: " + "9" * 4400 + "}\n"
    path = write(tmp_path, "big.yaml", text)
    with pytest.raises(DictionaryError) as caught:
        import_home_assistant(path)
    assert (caught.value.path, caught.value.line) == (str(path), 4)


@pytest.mark.parametrize("column", ["address", "max"])
def test_csv_hex_number_of_5000_digits_names_file_and_line(tmp_path: Path, column: str) -> None:
    # a hex integer converts whatever its length, but Python cannot print one this long
    # in decimal: the error message itself used to raise a bare ValueError
    row = {"address": "0", "max": "100"} | {column: "0x" + "9" * 5000}
    text = f"table,address,name,max\nholding,{row['address']},t,{row['max']}\n"
    path = write(tmp_path, "big.csv", text)
    with pytest.raises(DictionaryError) as caught:
        import_csv(path)
    assert (caught.value.path, caught.value.line) == (str(path), 2)


def test_csv_enum_key_of_5000_digits_names_file_and_line(tmp_path: Path) -> None:
    text = f'table,address,name,enum\nholding,10,Mode,"0=Stop; {"9" * 5000}=Fault"\n'
    path = write(tmp_path, "enum.csv", text)
    with pytest.raises(DictionaryError) as caught:
        import_csv(path)
    assert (caught.value.path, caught.value.line) == (str(path), 2)


def test_oversized_csv_is_refused_before_parsing(tmp_path: Path) -> None:
    path = write(tmp_path, "huge.csv", "table,address,name\n" + "# padding\n" * 500_000)
    with pytest.raises(DictionaryError) as caught:
        import_csv(path)
    assert "over the limit" in caught.value.message


def test_oversized_file_is_refused_before_parsing(tmp_path: Path) -> None:
    path = write(tmp_path, "huge.toml", DICT_HEAD + "# padding\n" * 500_000)
    with pytest.raises(DictionaryError) as caught:
        load_dictionary(path)
    assert "over the limit" in caught.value.message


@pytest.mark.parametrize("name", ["deep.toml", "deep.yaml", "laughs.yaml", "long.yaml"])
def test_dict_check_reports_each_bad_file_and_exits_1(tmp_path: Path, name: str) -> None:
    texts = {
        "deep.toml": DICT_HEAD + "x = " + "[" * 2000 + "]" * 2000 + "\n",
        "deep.yaml": "modbus: " + "[" * 2000 + "]" * 2000 + "\n",
        "laughs.yaml": billion_laughs(),
        "long.yaml": long_aliases(),
    }
    path = write(tmp_path, name, texts[name])
    out, err = io.StringIO(), io.StringIO()

    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["dict", "check", str(path)])
    assert code == 1
    assert err.getvalue().startswith(f"{path}:")


def test_replay_with_a_deep_dictionary_is_an_error_naming_it(tmp_path: Path) -> None:
    path = write(tmp_path, "deep.toml", DICT_HEAD + "x = " + "[" * 2000 + "]" * 2000 + "\n")
    capture = write(tmp_path, "c.bin", "")
    capture.write_bytes(bytes.fromhex("010300000001840a"))
    err = io.StringIO()

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(["replay", str(capture), "--format", "text", "--dict", str(path)])
    assert code == 2
    assert f"{path}:5:" in err.getvalue()
