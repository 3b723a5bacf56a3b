"""Provides the seed manuals' worked examples (tests/vectors/*.toml) to the tests."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

VECTORS = Path(__file__).parent.parent / "vectors"
MODELS = {"ved903b.toml": "ved903b", "dcrl.toml": "dcrl", "rvs-dn.toml": "rvs-dn"}


def load_examples(folder: Path = VECTORS) -> list[dict[str, Any]]:
    examples: list[dict[str, Any]] = []
    for path in sorted(folder.glob("*.toml")):
        with path.open("rb") as handle:
            document = tomllib.load(handle)
        for example in document.get("example", []):
            examples.append({**example, "_file": path.name})
    return examples


def wire_bytes(example: dict[str, Any]) -> bytes:
    """The example as it travels on the line: RTU bytes, or ASCII characters with CR LF."""
    frame = str(example["frame"])
    if example.get("mode") == "ascii":
        text = frame.strip()
        if not text.startswith(":"):
            text = ":" + text
        return text.replace(" ", "").encode("ascii") + b"\r\n"
    return bytes.fromhex(frame)


def frame_body(example: dict[str, Any]) -> bytes:
    """The unit byte and PDU of an example: RTU without its 2 CRC bytes, ASCII decoded
    from the hex between ':' and the LRC."""
    frame = str(example["frame"])
    if example.get("mode") == "ascii":
        text = frame.strip().removeprefix(":").replace(" ", "")
        return bytes.fromhex(text)[:-1]
    return bytes.fromhex(frame)[:-2]


def by_id(examples: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    return {str(e["id"]): e for e in examples}
