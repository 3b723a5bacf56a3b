"""Warnings in bounded memory (issue #30.8): a reader keeps the first 20 warnings of each
kind and counts the rest, said in one line at the end, for every reader the same way
(`sniffer.sources.base.Warnings`); a log of thousands of unreadable lines gives 21 lines,
not thousands."""

from __future__ import annotations

from pathlib import Path

import pytest

from sniffer.cli import main
from sniffer.model import SourceInfo
from sniffer.sources import ReadOptions, open_capture
from sniffer.sources.base import (
    WARNING_KINDS,
    WARNINGS_PER_KIND,
    Capture,
    Warnings,
    warning_kind,
)

CAPTURES = Path(__file__).resolve().parents[1] / "captures"
BAD = 5_000


def test_warnings_of_one_kind_past_the_first_20_are_counted() -> None:
    warnings = Warnings()
    for k in range(1, 1001):
        warnings.append(f"x.log line {k}: cannot read {'0Z' * (k % 7)!r} as hex bytes")
    warnings.append("x.log: no bytes found")
    assert len(warnings) == WARNINGS_PER_KIND + 1
    warnings.close()
    assert warnings[:WARNINGS_PER_KIND] == [
        f"x.log line {k}: cannot read {'0Z' * (k % 7)!r} as hex bytes" for k in range(1, 21)
    ]
    assert warnings[20:] == [
        "x.log: no bytes found",
        "and 980 more warning(s) like it, not shown (the first 20 of each kind are); the "
        "last: x.log line 1000: cannot read '0Z0Z0Z0Z0Z0Z' as hex bytes",
    ]
    # more of the kind after the count was said: the count is brought up to date in place
    warnings.append("x.log line 1001: cannot read '' as hex bytes")
    warnings.close()
    assert len(warnings) == 22
    assert warnings[21].startswith("and 981 more warning(s) like it")
    assert warnings[21].endswith("the last: x.log line 1001: cannot read '' as hex bytes")


def test_kinds_are_told_apart_by_their_words_not_their_numbers_or_excerpts() -> None:
    same = [
        "f line 7: offset 0x1f, expected 0x20; the packet ends there",
        "f line 9,999: offset 0xab, expected 0x2; the packet ends there",
    ]
    assert warning_kind(same[0]) == warning_kind(same[1])
    assert warning_kind("f line 1: cannot read 'a\\'b\"' as bytes") == warning_kind(
        'f line 2: cannot read "x\'" as bytes'
    )
    assert warning_kind("f line 1: the time goes back") != warning_kind("f line 1: no bytes")


def test_past_100_kinds_the_others_are_one_kind() -> None:
    letters = "abcdefghijklmnopqrstuvwxyz"
    warnings = Warnings(f"kind {letters[k % 26] * (k + 1)}" for k in range(500))
    assert len(warnings) == WARNING_KINDS + WARNINGS_PER_KIND
    warnings.close()
    assert warnings[-1].startswith(f"and {500 - WARNING_KINDS - WARNINGS_PER_KIND} more warning")


def test_a_plain_list_is_bounded_when_the_capture_is_read() -> None:
    """A reader that keeps its warnings in a plain list gets them bounded at the end."""
    info = SourceInfo(path="p.pcap", format="pcap")
    capture = Capture(info=info, _chunks=iter(()), warnings=[f"w {k}" for k in range(50)])
    list(capture.chunks())
    assert capture.warnings[:20] == [f"p.pcap: w {k}" for k in range(20)]
    assert len(capture.warnings) == 22  # and: no serial data
    assert capture.warnings[-1].startswith("p.pcap: and 30 more warning(s) like it")
    assert capture.warnings[-1].endswith("the last: p.pcap: w 49")


def _esphome(path: Path) -> Path:
    seed = (CAPTURES / "logs" / "esphome_hex_ms.log").read_bytes()
    bad = b"".join(b"[12:00:00.000][D][uart_debug:158]: >>> 01:0Z:%d\n" % k for k in range(BAD))
    path.write_bytes(seed + bad)
    return path


def _saleae(path: Path) -> Path:
    seed = (CAPTURES / "logs" / "saleae_logic2_table.csv").read_bytes()
    bad = b"".join(b'"Master","data",%d.5,0.001,0xZZ\n' % k for k in range(BAD))
    path.write_bytes(seed + bad)
    return path


def _text2pcap(path: Path) -> Path:
    packet = b"000000 01 03 00 00 00 02 c4 0b\n000020 01 02\n"  # an offset not expected
    path.write_bytes(packet * BAD)
    return path


def _socat(path: Path) -> Path:
    record = b"> 2024/05/01 12:00:00.000100  length=8 from=0 to=7\n 01 03\n--\n"  # too short
    path.write_bytes(record * BAD)
    return path


@pytest.mark.parametrize("make", [_esphome, _saleae, _text2pcap, _socat])
def test_every_reader_keeps_20_of_a_kind_and_counts_the_rest(tmp_path: Path, make: object) -> None:
    assert callable(make)
    path = make(tmp_path / "bad.txt")
    capture = open_capture(path, ReadOptions())
    list(capture.chunks())
    counted = [w for w in capture.warnings if "more warning(s) like it" in w]
    assert len(counted) == 1
    assert len(capture.warnings) <= 2 * WARNINGS_PER_KIND
    last = counted[0].split("the last: ", 1)[1]
    kind = warning_kind(last if last.startswith(str(path)) else f"{path}: {last}")
    kept = [w for w in capture.warnings if warning_kind(w) == kind]
    assert len(kept) == WARNINGS_PER_KIND
    more = int(counted[0].split(" more")[0].rsplit(" ", 1)[1].replace(",", ""))
    assert more + len(kept) >= BAD  # every bad line is a warning kept or counted
    assert counted[0].startswith(f"{path}: and ")


def test_replay_says_20_warnings_and_a_count(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _esphome(tmp_path / "bad.log")
    main(["replay", str(path), "--format", "jsonl", "--no-index"])
    err = capsys.readouterr().err
    warnings = [line for line in err.splitlines() if line.startswith("modscope: warning:")]
    # the seed's own unreadable line (line 11) is the first of the kind
    assert len(warnings) == WARNINGS_PER_KIND + 1
    assert f"{path} line 11: cannot read the bytes" in warnings[0]
    more = BAD + 1 - WARNINGS_PER_KIND
    assert warnings[-1].startswith(f"modscope: warning: {path}: and {more:,} more warning(s)")
    last = len(path.read_bytes().splitlines())
    assert warnings[-1].endswith(
        f"the last: {path} line {last}: cannot read the bytes of this uart_debug line "
        f"('01:0Z:{BAD - 1}'); the line is skipped (a cut line or another log format?)"
    )
