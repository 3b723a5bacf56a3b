"""The `modscope` command as a user runs it: replay listings, statistics, errors, dict."""

from __future__ import annotations

import csv
import io
import json
import subprocess
import sys
from pathlib import Path

import pytest

from dissectors.checks import with_crc
from sniffer.cli import main
from sniffer.session.session import DEMO_CAPTURE

ROOT = Path(__file__).resolve().parent.parent.parent
WIZ = ROOT / "tests" / "captures" / "sigrok" / "wizmodbus" / "wizmodbus.sr"
JSONL_KEYS = {
    "index",
    "t",
    "t_end",
    "raw",
    "mode",
    "kind",
    "unit",
    "function",
    "check_ok",
    "problems",
}


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_replay_without_a_file_lists_the_demo(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["replay"], capsys)
    assert code == 0
    note, *lines = out.splitlines()
    assert note.startswith("# timing: ")  # what the times are worth, said first
    assert len(lines) > 1500
    assert "Read Holding Registers" in lines[0]
    assert any("Under Voltage Trip = 300 V" in line for line in lines)
    assert any("noise" in line for line in lines)
    assert any("timeout" in line for line in lines)


def test_jsonl_records_have_the_documented_fields(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["replay", "--format", "jsonl"], capsys)
    assert code == 0
    records = [json.loads(line) for line in out.splitlines()]
    assert all(set(r) >= JSONL_KEYS for r in records)
    kinds = {r["kind"] for r in records}
    assert {"request", "response", "exception", "noise"} <= kinds
    first = records[0]
    assert first["mode"] == "rtu" and first["kind"] == "request" and first["check_ok"] is True
    assert bytes.fromhex(first["raw"])[1] == first["function"] == 3
    assert first["t"] < first["t_end"]
    assert {"id", "role", "latency_ms", "status"} <= set(first["transaction"])
    assert first["fields"][0] == {
        "name": "address",
        "value": 3200,
        "text": "0x0C80",
        "span": [2, 4],
    }
    answer = records[1]
    assert answer["transaction"]["id"] == 0 and answer["transaction"]["status"] == "ok"
    assert answer["registers"][0]["name"] == "04.9A: Power Factor Read Point"
    assert answer["registers"][0]["unit"] == "%"
    bad = [r for r in records if not r["check_ok"] and r["kind"] != "noise"]
    assert len(bad) == 1 and "expected" in bad[0]["problems"][0]


def test_csv_listing(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["replay", "--format", "csv"], capsys)
    assert code == 0
    rows = list(csv.DictReader(io.StringIO(out)))
    assert rows[0]["name"] == "Read Holding Registers" and rows[0]["direction"] == "M>S"


def test_stats_table(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["replay", "--stats"], capsys)
    assert code == 0
    assert "Pump 1 starter" in out and "exceptions by code: 02 x5, 03 x1" in out
    unit4 = next(line for line in out.splitlines() if line.strip().startswith("4 "))
    assert unit4.split()[1:4] == ["12", "0", "0"]  # 12 requests, no answers, no exceptions


def test_sigrok_capture_with_probes(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["replay", str(WIZ), "--probe", "RX", "--probe", "TX", "--baud", "9600", "--parity", "N"]
    code, out, _ = run([*args, "--format", "jsonl"], capsys)
    records = [json.loads(line) for line in out.splitlines()]
    assert code == 0 and len(records) == 88
    assert all(r["check_ok"] for r in records)


def test_missing_file_is_an_error_naming_it(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    missing = tmp_path / "nope.pcapng"
    code, out, err = run(["replay", str(missing)], capsys)
    assert code == 2 and out == ""
    assert err.startswith("modscope: error: ") and str(missing) in err


def test_unknown_model_names_the_known_ones(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["replay", "--unit", "3=nosuch", "--format", "text"], capsys)
    assert code == 2 and "nosuch" in err and "rvs-dn" in err


def test_truncated_capture_warns_with_the_offset(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    demo = DEMO_CAPTURE.read_bytes()
    cut = tmp_path / "cut.pcapng"
    cut.write_bytes(demo[: len(demo) // 2 + 7])
    code, out, err = run(["replay", str(cut), "--format", "text"], capsys)
    assert code == 1 and len(out.splitlines()) > 500  # read, with a warning
    assert "warning" in err and "offset" in err


def test_raw_binary_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = tmp_path / "bus.bin"
    req = with_crc(bytes.fromhex("0103000a0002"))
    resp = with_crc(bytes.fromhex("01030400010002"))
    path.write_bytes(b"\x00" + req + resp)
    code, out, _ = run(["replay", str(path), "--mode", "rtu", "--format", "jsonl"], capsys)
    kinds = [json.loads(line)["kind"] for line in out.splitlines()]
    assert code == 0 and kinds == ["noise", "request", "response"]


def test_dict_list_show_check(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, out, _ = run(["dict", "list"], capsys)
    assert code == 0 and {"dcrl", "rvs-dn", "ved903b"} <= {
        line.split()[0] for line in out.splitlines()
    }
    code, out, _ = run(["dict", "show", "rvs-dn"], capsys)
    assert code == 0 and "Under Voltage Trip" in out
    broken = tmp_path / "broken.toml"
    broken.write_text(
        'format = 1\n[device]\nmodel = "x"\nname = "X"\n\n'
        '[[entry]]\npdu = 1\ntable = "holding"\nnmae = "oops"\n'
    )
    code, _, err = run(["dict", "check", str(broken)], capsys)
    assert code == 1 and f"{broken}:9" in err and "name" in err


def test_help_explains_the_commands() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "sniffer.cli", "--help"], capture_output=True, text=True, cwd=ROOT
    ).stdout
    for word in ("replay", "dict", "examples:"):
        assert word in out


# -- exit status as capture tools use it (issue 15) ------------------------------------------


@pytest.mark.parametrize(
    ("cut", "status"),
    [(None, 0), (50_000, 1), (120, 2)],  # whole; cut inside a block; cut before any packet
)
@pytest.mark.parametrize("command", ["replay", "export"])
def test_exit_status_says_whether_all_was_read(
    cut: int | None,
    status: int,
    command: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    capture = tmp_path / "bus.pcapng"
    demo = DEMO_CAPTURE.read_bytes()
    capture.write_bytes(demo if cut is None else demo[:cut])
    argv = ["replay", str(capture), "--stats"]
    if command == "export":
        argv = ["export", str(capture), "-o", str(tmp_path / "out.jsonl")]
    code, _, err = run(argv, capsys)
    assert code == status, err
    assert ("truncated pcapng block" in err) == (cut is not None)


def test_the_exit_status_is_in_the_help(capsys: pytest.CaptureFixture[str]) -> None:
    for command in ("replay", "export"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        out = capsys.readouterr().out
        assert "exit status:" in out and "read with warnings" in out


# -- line settings: the flags win over the file, with a warning --------------------------------


def test_flags_win_over_the_recorded_line_settings_with_a_warning(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, out, err = run(["replay", "--stats", "--baud", "9600", "--parity", "N"], capsys)
    # (the demo's reads carry their first byte's time, as modscope's recordings do: the
    # framer takes those as they are, so 9600 baud is not found too slow for them)
    assert code == 0
    assert "(9600 8N1" in out.splitlines()[0]  # the flags were used
    assert "recorded at 19200 8E1" in err and "--baud 9600, --parity N" in err
    code, out, err = run(["replay", "--stats", "--baud", "19200"], capsys)
    assert code == 0 and "warning" not in err  # a flag that agrees says nothing


# -- --unit ------------------------------------------------------------------------------------


def test_two_bindings_of_one_address_are_an_error_naming_both(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, out, err = run(
        ["replay", "--stats", "--unit", "3=rvs-dn", "--unit", "3=dcrl:Pump 1"], capsys
    )
    assert code == 2 and out == ""
    assert err == (
        "modscope: error: --unit '3=rvs-dn' and --unit '3=dcrl:Pump 1' both bind address 3; "
        "keep one\n"
    )


def test_a_label_with_a_space_binds_when_quoted(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["replay", "--stats", "--unit", "3=rvs-dn:Pump 1"], capsys)
    assert code == 0 and "Pump 1" in out


# -- the README agrees with the program ---------------------------------------------------------


def test_readme_example_listing_is_what_the_demo_gives(capsys: pytest.CaptureFixture[str]) -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split("### The listing", 1)[1].split("```", 2)[1]
    shown = [line for line in block.splitlines() if line.strip()]
    code, out, _ = run(["replay"], capsys)
    assert code == 0
    listed = out.splitlines()
    assert len(shown) >= 3
    for line in shown:
        assert line in listed, line


def test_readme_commands_with_spaces_are_quoted() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "--unit 3=rvs-dn:Pump 1" not in readme.replace("'3=rvs-dn:Pump 1'", "")
    assert "pip install 'modscope[serve]'" in readme
