"""Dictionary drafting: a synthetic unit whose registers hold known kinds of values is
polled; the draft must guess each kind, pass `dict check`, and annotate when bound."""

from __future__ import annotations

import math
import struct
import tomllib
from pathlib import Path

import pytest

from dissectors.checks import with_crc
from dissectors.dictionary import check_dictionary, load_dictionaries
from sniffer.analysis.draft import Place, draft, guess_word, observe, roughness
from sniffer.framing.pipeline import frame_capture
from sniffer.meaning.annotate import load_bindings
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import Session

LINE = LineSettings(19200, 8, "E", 1)
UNIT = 5


def registers(k: int) -> list[int]:
    """What unit 5 holds at poll k, from holding register 100 on."""
    counter = 1000 + 3 * k  # 100: a counter
    mode = (0, 1, 2, 1)[k % 4]  # 101: an enum
    temperature = 20.0 + 5 * math.sin(k / 10)  # 102-103: f32, low word first (CDAB)
    raw = struct.unpack(">I", struct.pack(">f", temperature))[0]
    energy = 65_530 + 2 * k  # 104-105: u32, high word first, carries at k = 3
    status = (0, 0x0010, 0x0100, 0x0110)[k % 4]  # 106: bits 4 and 8
    return [
        counter,
        mode,
        raw & 0xFFFF,
        raw >> 16,
        energy >> 16,
        energy & 0xFFFF,
        status,
        0x1234,  # 107: a constant
        (-40 + k) & 0xFFFF,  # 108: s16 going from -40 through 0
    ]


def capture(polls: int = 60) -> list[Chunk]:
    chunks: list[Chunk] = []
    t = 0.0
    for k in range(polls):
        request = with_crc(bytes([UNIT, 3, 0, 100, 0, 9]))
        words = registers(k)
        answer = with_crc(bytes([UNIT, 3, 18]) + b"".join(w.to_bytes(2, "big") for w in words))
        chunks.append(Chunk(request, t + 0.005))
        chunks.append(Chunk(answer, t + 0.030))
        if k % 10 == 0:  # the master writes the setpoint at 200 now and then
            write = with_crc(bytes([UNIT, 6, 0, 200, 0, 50 + k]))
            chunks.append(Chunk(write, t + 0.060))
            chunks.append(Chunk(write, t + 0.075))
        t += 0.25
    return chunks


@pytest.fixture(scope="module")
def drafted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    store = frame_capture(capture(), LINE)
    text = draft(store, UNIT, "synthetic.pcapng")
    path = tmp_path_factory.mktemp("draft") / "draft.toml"
    path.write_text(text, encoding="utf-8")
    return path


def entries(path: Path) -> dict[int, dict[str, object]]:
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    return {int(e["pdu"]): e for e in data["entry"]}


def test_draft_guesses_each_kind(drafted: Path) -> None:
    found = entries(drafted)
    assert "(counter)" in str(found[100]["name"])
    assert found[101]["enum"] == {"0": "value 0", "1": "value 1", "2": "value 2"}
    assert (found[102]["type"], found[102]["word_order"]) == ("f32", "CDAB")
    assert 103 not in found
    assert (found[104]["type"], found[104]["word_order"]) == ("u32", "ABCD")
    assert found[106]["bits"] == {"4": "bit 4", "8": "bit 8"}
    assert "(constant)" in str(found[107]["name"])
    assert found[108]["type"] == "s16"
    assert found[200]["access"] == "rw"


def test_draft_carries_evidence_and_weak_comments(drafted: Path) -> None:
    text = drafted.read_text(encoding="utf-8")
    assert "#   holding 100-108 (9)" in text and "#   holding 200 (1)" in text
    found = entries(drafted)
    assert "wraps 1 times" in str(found[104]["notes"])
    assert "only grows: 1000 .. 1177 in 60 readings" in str(found[100]["notes"])
    assert "weak" not in str(found[100]["notes"])


def test_dict_check_accepts_the_draft(drafted: Path) -> None:
    assert check_dictionary(drafted) == []
    (d,) = load_dictionaries(drafted)
    assert d.model == f"draft-unit{UNIT}" and d.unit_hint == UNIT


def test_binding_the_draft_annotates_at_once(drafted: Path) -> None:
    bindings = load_bindings(None, [], [drafted])  # --dict draft.toml: binds unit 5
    assert bindings[UNIT].dictionary.model == f"draft-unit{UNIT}"
    session = Session(LINE, bindings=bindings)
    session.ingest(capture(4))
    texts = [
        r.text for i in range(len(session.store)) for r in session.describer.detail(i).registers
    ]
    assert "Holding 102 = 20.0" in texts  # poll 0: 20.0 + 5 sin(0)
    assert "Holding 101 (enum) = value 1" in texts
    assert "Holding 104 (counter) = 65536" in texts  # poll 3: the carry
    assert "Holding 106 (bits) = bit 4, bit 8" in texts


def test_weak_guesses_say_so() -> None:
    few = guess_word(Place("holding_registers", 7, reads=[(0.0, 5), (1.0, 6)]))
    assert few.weak and "only 2 readings" in few.weak[0]
    never = guess_word(Place("holding_registers", 8))
    assert never.kind == "unread" and never.weak


def test_roughness() -> None:
    assert roughness([1, 2, 3, 4]) == pytest.approx(1 / 3)
    assert roughness([5, 5, 5]) == 0.0
    assert roughness([0, 100, 0, 100]) == 1.0
    assert roughness([1, 2]) is None


def test_observe_counts_exceptions(tmp_path: Path) -> None:
    request = with_crc(bytes([UNIT, 3, 0x10, 0, 0, 2]))
    error = with_crc(bytes([UNIT, 0x83, 2]))
    store = frame_capture([Chunk(request, 0.01), Chunk(error, 0.03)], LINE)
    seen = observe(store, UNIT)
    assert seen.exceptions == {("holding_registers", 0x1000, 2): 1}
    assert "#   holding 4096 (2): 1" in draft(store, UNIT, "x")
