"""The one table of meanings: every flag and status has one, and every view says the same."""

from __future__ import annotations

import json
from io import StringIO

from dissectors.checks import with_crc
from sniffer.framing.pipeline import frame_capture
from sniffer.meaning.describe import Describer
from sniffer.model import Chunk, LineSettings
from sniffer.outputs.listing import Lister
from sniffer.tui.render import FLAG_TAGS
from sniffer.vocab import (
    BAD_CHECK,
    FLAG_MEANINGS,
    FLAGS,
    PROBLEM_MASK,
    SEVERITIES,
    STATUS_NAMES,
    Flag,
    Status,
)


def test_every_flag_but_facts_has_one_meaning() -> None:
    facts = {Flag.NONE, Flag.ASCII, Flag.MBAP}
    assert {f for f in Flag if f not in facts} == set(FLAG_MEANINGS)
    assert len(FLAGS) == len(FLAG_MEANINGS)  # no flag listed twice
    kinds = [m.kind for _, m in FLAGS]
    assert len(set(kinds)) == len(kinds)
    assert all(m.severity in SEVERITIES and m.text for _, m in FLAGS)


def test_masks_follow_the_table() -> None:
    # a Modbus TCP frame has no CRC: its header is the check
    assert BAD_CHECK == Flag.CHECK_BAD | Flag.NON_HEX | Flag.ENVELOPE_BAD
    assert not PROBLEM_MASK & Flag.MBAP
    assert PROBLEM_MASK & Flag.TID_REUSED and PROBLEM_MASK & Flag.CUT_SHORT
    assert not PROBLEM_MASK & Flag.SILENCE_FRAMED  # a fact about framing, not a problem
    assert not PROBLEM_MASK & Flag.ASCII
    assert PROBLEM_MASK & Flag.RETRY and PROBLEM_MASK & Flag.CHECK_BAD


def test_status_names_cover_every_status() -> None:
    assert [s.label for s in Status] == list(STATUS_NAMES)


def test_tui_tags_come_from_the_table() -> None:
    assert dict(FLAG_TAGS) == {f: m.tag for f, m in FLAGS if m.tag}


def test_jsonl_keeps_problem_texts_and_adds_details() -> None:
    good = with_crc(bytes.fromhex("0103000a0002"))
    bad = good[:-1] + bytes([good[-1] ^ 0xFF])
    store = frame_capture([Chunk(good, 1.0), Chunk(bad, 2.0)], LineSettings(baud=9600))
    out = StringIO()
    lister = Lister(out, "jsonl", Describer(store))
    lister.write(range(len(store)))
    rows = [json.loads(line) for line in out.getvalue().splitlines()]
    broken = next(r for r in rows if not r["check_ok"])
    assert broken["problems"][0].startswith("CRC ")
    detail = broken["problem_details"][0]
    assert detail["kind"] == "check" and detail["severity"] == "error"
    assert detail["text"] == broken["problems"][0]
    body_len = len(bad) - 2
    assert detail["span"] == [body_len, body_len + 2]  # the CRC bytes after the body
    assert all("problem_details" not in r for r in rows if r["check_ok"] and not r["problems"])
