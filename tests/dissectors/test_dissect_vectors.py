"""The seed manuals' worked examples (tests/vectors/*.toml) dissect to what the manuals say.

Each example is dissected in its stated role (exceptions are responses), with its paired
request, and must give the stated unit, function and every PDU field in `fields`.
Vendor function codes are raw data here (their layout comes from device dictionaries),
so for those only unit and function are checked.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from dissectors.dissect import Role, dissect
from dissectors.functions import function_class
from tests.support.seedvectors import VECTORS, frame_body, load_examples


def same_value(got: Any, expected: Any) -> bool:
    if isinstance(expected, list):
        return isinstance(got, tuple) and list(got) == expected
    if isinstance(expected, str) and isinstance(got, bytes):
        return got.hex().upper() == expected.replace(" ", "").upper()
    return bool(got == expected)


# Fields a manual states that the printed bytes do not carry. modscope dissects the bytes
# as printed and reports what is wrong with them; it does not guess what was meant.
PRINTED_WRONG: dict[str, dict[str, str]] = {
    "rvs-dn-ex7-force-coils-req": {
        "values": "byte count 01 but two data bytes (00 07) follow: the bytes say all three "
        "coils OFF plus a trailing byte; the manual means 07 (all ON)",
    },
}

EXAMPLES = load_examples(VECTORS)
BY_ID = {example["id"]: example for example in EXAMPLES}


def test_vector_files_are_loaded() -> None:
    assert EXAMPLES, "no examples in tests/vectors/*.toml"
    assert len(BY_ID) == len(EXAMPLES), "example ids must be unique"


def check_example(example: dict[str, Any], by_id: dict[str, dict[str, Any]]) -> None:
    role = Role.REQUEST if example["role"] == "request" else Role.RESPONSE
    paired = example.get("pairs_with")
    request = frame_body(by_id[paired]) if paired else None
    result = dissect(frame_body(example), role, request=request)
    assert result.unit == example["unit"]
    assert result.function == example["function"]
    assert result.exception == (example["role"] == "exception")
    if function_class(example["function"]) == "user":
        return  # vendor layouts come from the device dictionaries
    wrong = PRINTED_WRONG.get(example["id"], {})
    if wrong:
        assert result.problems, "a misprinted frame must show its problems"
    for name, expected in example.get("fields", {}).items():
        if name in wrong:
            continue
        found = result.field(name)
        assert found is not None, f"{name} missing; fields: {[f.name for f in result.fields]}"
        assert same_value(found.value, expected), f"{name}: {found.value!r} != {expected!r}"


@pytest.mark.parametrize("example", EXAMPLES, ids=[str(e["id"]) for e in EXAMPLES])
def test_example(example: dict[str, Any]) -> None:
    check_example(example, BY_ID)


def test_loader_reads_both_modes(tmp_path: Path) -> None:
    """The loader and frame decoding, on a file of our own."""
    (tmp_path / "own.toml").write_text(
        "[[example]]\n"
        'id = "own-rtu"\nmode = "rtu"\nframe = "01 03 00 00 00 02 C4 0B"\n'
        'role = "request"\nunit = 1\nfunction = 3\nfields = { address = 0, quantity = 2 }\n'
        "[[example]]\n"
        'id = "own-ascii"\nmode = "ascii"\nframe = ":0103040001000AED\\r\\n"\n'
        'role = "response"\nunit = 1\nfunction = 3\npairs_with = "own-rtu"\n'
        "fields = { byte_count = 4, values = [1, 10] }\n",
        encoding="utf-8",
    )
    examples = load_examples(tmp_path)
    assert [frame_body(e) for e in examples] == [
        bytes.fromhex("010300000002"),
        bytes.fromhex("0103040001000A"),
    ]
    for example in examples:
        check_example(example, {e["id"]: e for e in examples})
    response = dissect(frame_body(examples[1]), Role.RESPONSE, request=frame_body(examples[0]))
    values = response.field("values")
    assert values is not None and same_value(values.value, [1, 10])
    assert response.data[0].address == 0
