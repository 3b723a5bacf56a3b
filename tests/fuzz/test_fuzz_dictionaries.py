"""Fuzz: every dictionary reader (TOML dictionaries, bus files, Home Assistant YAML, CSV
register lists) over damaged copies of the shipped and test files. Only DictionaryError
may escape, and it names the file."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from dissectors.dictionary import (
    DictionaryError,
    import_csv,
    import_home_assistant,
    load_dictionary,
)
from dissectors.dictionary.bus import load_bus
from tests.fuzz.harness import DEVICES, DICTIONARIES, budget, mutated, no_hang

pytestmark = [pytest.mark.fuzz, pytest.mark.slow]

# text that tends to break parsers: brackets, quotes, anchors, huge or odd numbers
TOKENS = [
    b"[", b"]", b"{", b"}", b"[[", b"]]", b'"', b"'", b"'''", b'"""', b"=", b".", b"\n",
    b"#", b"&a ", b"*a", b"<<: *a", b"- ", b": ", b"!include x", b"!!python/object:os.system",
    b"9" * 5000, b"-1", b"0x", b"1e999", b"nan", b"\x00", b"\xff", b"\\u0000", b"\t",
    b"ref = ", b"type = ", b"enum = {", b"bits = {", b";", b",", b"address: ", b"slave: 999",
]  # fmt: skip


@st.composite
def damaged_text(draw: st.DrawFn, seeds: list[bytes]) -> bytes:
    data = bytearray(draw(mutated(seeds)))
    for _ in range(draw(st.integers(0, 4))):
        at = draw(st.integers(0, len(data)))
        data[at:at] = draw(st.sampled_from(TOKENS))
    return bytes(data)


def _read(files: list[Path]) -> list[bytes]:
    return [p.read_bytes() for p in files]


# issue 30, item 8 in small: one long string named again and again by an alias
LONG_ALIASES = (
    b"modbus:\n- name: hub\n  type: tcp\n  host: h\n  port: 502\n  sensors:\n"
    + b"  - {name: &long "
    + b"x" * 4000
    + b", address: 0}\n"
    + b"".join(b"  - {name: *long, address: %d}\n" % k for k in range(1, 40))
)

READERS = {
    "toml": (load_dictionary, _read(sorted(DEVICES.glob("*.toml")))[:1]
             + _read([DICTIONARIES / "every_type.toml"])),
    "bus": (load_bus, _read([DICTIONARIES / "bus.toml"])),
    "yaml": (import_home_assistant,
             [*_read(sorted(DICTIONARIES.glob("home_assistant*.yaml"))), LONG_ALIASES]),
    "csv": (import_csv, _read(sorted(DICTIONARIES.glob("*.csv")))),
}  # fmt: skip
SUFFIX = {"toml": ".toml", "bus": ".toml", "yaml": ".yaml", "csv": ".csv"}
EXAMPLES = {"toml": 500, "bus": 300, "yaml": 500, "csv": 500}


@pytest.mark.parametrize("kind", sorted(READERS))
def test_damaged_dictionaries_raise_only_dictionary_errors(
    tmp_path_factory: pytest.TempPathFactory, kind: str
) -> None:
    reader, seeds = READERS[kind]
    folder = tmp_path_factory.mktemp(kind)
    counter = iter(range(1 << 30))

    @budget(EXAMPLES[kind])
    @given(damaged_text(seeds))
    def run(data: bytes) -> None:
        # a new name each time: load_dictionary caches by file identity
        path = folder / f"d{next(counter)}{SUFFIX[kind]}"
        path.write_bytes(data)
        with no_hang():
            try:
                reader(path)
            except DictionaryError as exc:
                assert exc.path == str(path)
                str(exc)
        path.unlink()

    run()
