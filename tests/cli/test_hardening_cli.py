"""The command line never passes a file's or the bus's control characters to a terminal
(issue 15, item 6), and `--raw-csv` is the one way to get unguarded CSV text (item 3)."""

from __future__ import annotations

import contextlib
import csv
import io
import json
from pathlib import Path

from dissectors.checks import with_crc
from sniffer.cli import main
from tests.support.hostile import HOSTILE_TOML

ESCAPES = 'notes = ["clear \\u001b[2J screen", "bell \\u0007 and CSI \\u009b31m"]\n'


def run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def no_controls(text: str) -> bool:
    return not any(
        (ord(c) < 0x20 and c != "\n") or 0x7F <= ord(c) < 0xA0 or c in "\u2028\u2029" for c in text
    )


def hostile_dict(tmp_path: Path) -> Path:
    text = HOSTILE_TOML.replace(
        'default_space = "hr"\n',
        'default_space = "hr"\nmanual = "see \\u001b]0;owned\\u0007"\n' + ESCAPES,
    )
    path = tmp_path / "hostile.toml"
    path.write_text(text, encoding="utf-8")
    return path


def capture(tmp_path: Path) -> Path:
    path = tmp_path / "bus.bin"
    request = with_crc(bytes.fromhex("010300000004"))
    answer = with_crc(bytes.fromhex("010308ffff0000") + b"\x1b[2J")
    path.write_bytes(request + answer)
    return path


def test_dict_show_escapes_notes_and_manual(tmp_path: Path) -> None:
    path = hostile_dict(tmp_path)
    code, out, _ = run(["dict", "show", "hostile", "--dict", str(path)])
    assert code == 0
    assert no_controls(out)
    assert "clear \\x1b[2J screen" in out
    assert "see \\x1b]0;owned\\x07" in out
    assert "CSI \\x9b31m" in out


def test_dict_check_escapes_file_names(tmp_path: Path) -> None:
    # the reader itself refuses control characters inside a dictionary's texts; a file
    # name (from an unpacked archive, say) can still carry them
    bad = tmp_path / "bad\x1b[2J.toml"
    bad.write_text("format = 1\n[device\n", "utf-8")
    good = tmp_path / "good\x07.toml"
    good.write_text('format = 1\n[device]\nmodel = "y"\nname = "y"\n', "utf-8")
    code, out, err = run(["dict", "check", str(bad), str(good)])
    assert code == 1
    assert no_controls(out + err)
    assert "bad\\x1b[2J.toml" in err
    assert "good\\x07.toml: ok" in out


def test_listings_escape_bus_and_dictionary_text(tmp_path: Path) -> None:
    args = ["replay", str(capture(tmp_path)), "--dict", str(hostile_dict(tmp_path))]
    args += ["--unit", "1=hostile:\x1b[31mred", "--mode", "rtu"]
    for fmt in ("text", "jsonl", "csv"):
        code, out, err = run([*args, "--format", fmt])
        assert code == 0, err
        assert no_controls(out.replace("\r\n", "\n")), fmt
        assert "\\x1b[2J" in out or "\\u001b[2J" in out, fmt
    code, out, _ = run([*args, "--stats"])
    assert code == 0
    assert no_controls(out)
    assert "\\x1b[31mred" in out


def test_export_csv_guards_formulas_unless_raw_csv(tmp_path: Path) -> None:
    cap, dictionary = capture(tmp_path), hostile_dict(tmp_path)
    guarded, raw = tmp_path / "g.csv", tmp_path / "r.csv"
    base = ["export", str(cap), "--what", "registers", "--dict", str(dictionary)]
    base += ["--unit", "1=hostile", "--mode", "rtu"]
    assert run([*base, "-o", str(guarded)])[0] == 0
    assert run([*base, "-o", str(raw), "--raw-csv"])[0] == 0
    names = [row["name"] for row in csv.DictReader(guarded.open(encoding="utf-8"))]
    raw_names = [row["name"] for row in csv.DictReader(raw.open(encoding="utf-8"))]
    assert "'=cmd|' /C calc'!A0" in names
    assert "=cmd|' /C calc'!A0" in raw_names


def test_replay_csv_takes_raw_csv_too(tmp_path: Path) -> None:
    code, out, _ = run(["replay", str(capture(tmp_path)), "--format", "csv", "--raw-csv"])
    assert code == 0
    assert next(csv.reader(io.StringIO(out)))[0] == "index"


def test_jsonl_stays_valid_json_with_escapes(tmp_path: Path) -> None:
    args = ["replay", str(capture(tmp_path)), "--dict", str(hostile_dict(tmp_path))]
    code, out, _ = run([*args, "--unit", "1=hostile", "--mode", "rtu", "--format", "jsonl"])
    assert code == 0
    rows = [json.loads(line) for line in out.splitlines()]
    texts = [r["text"] for row in rows for r in row.get("registers", ())]
    assert "Label = \\x1b[2J" in texts  # the bus string, escaped and still valid JSON
