"""The troubleshooter's toolkit as a user runs it: dict draft/check/show, diff, --filter,
-c, replay from standard input, sigrok with no line flags, and scan's errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from dissectors.checks import with_crc
from sniffer.cli import main
from sniffer.model import LineSettings
from sniffer.sources.pcapng_writer import PcapngWriter

ROOT = Path(__file__).resolve().parent.parent.parent
FIXTURES = ROOT / "tests" / "fixtures" / "dictionaries"
WIZ = ROOT / "tests" / "captures" / "sigrok" / "wizmodbus" / "wizmodbus.sr"
UNIT = 5


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def frames(values: list[int], exception_at: int | None = None) -> list[tuple[float, bytes]]:
    """Unit 5 polled 20 times for holding 10-11; an exception answer at one poll."""
    out: list[tuple[float, bytes]] = []
    for k, value in enumerate(values):
        t = k * 0.5
        out.append((t, with_crc(bytes([UNIT, 3, 0, 10, 0, 2]))))
        if k == exception_at:
            out.append((t + 0.02, with_crc(bytes([UNIT, 0x83, 2]))))
        else:
            body = bytes([UNIT, 3, 4]) + (1000 + k).to_bytes(2, "big") + value.to_bytes(2, "big")
            out.append((t + 0.02, with_crc(body)))
    return out


def write_capture(path: Path, rows: list[tuple[float, bytes]]) -> Path:
    """Raw serial reads in pcapng (link type 147), read at the default 19200 8E1."""
    with path.open("wb") as f:
        writer = PcapngWriter(f)
        port = writer.add_interface(147, name="test")
        for t, data in rows:
            writer.write_packet(port, 1_700_000_000 + t + 0.005, data)
    return path


@pytest.fixture
def capture(tmp_path: Path) -> Path:
    return write_capture(tmp_path / "a.pcapng", frames([7, 8, 9, 7] * 5, exception_at=6))


def test_draft_check_and_bind(
    capture: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    draft = tmp_path / "unit5.toml"
    code, _out, err = run(["dict", "draft", str(capture), "--unit", "5", "-o", str(draft)], capsys)
    assert code == 0 and f"wrote {draft}" in err
    code, out, _err = run(["dict", "check", str(draft)], capsys)
    assert code == 0 and "ok, TOML dictionary: draft-unit5 (2 entries)" in out
    code, out, _err = run(
        ["replay", str(capture), "--dict", str(draft), "--format", "text"], capsys
    )
    assert code == 0
    assert "Holding 10 (counter) = 1000" in out and "Holding 11 = 7" in out
    code, _out, err = run(["dict", "draft", str(capture), "--unit", "5", "-o", str(draft)], capsys)
    assert code == 2 and "exists" in err
    code, _out, err = run(["dict", "draft", str(capture), "--unit", "9"], capsys)
    assert code == 2 and "unit 9 never answered" in err and "5" in err


def test_dict_check_prints_every_problem(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("table,address,name\nholding,x,A\nholding,2,B\nholdng,3,C\n", encoding="utf-8")
    code, _out, err = run(["dict", "check", str(bad)], capsys)
    assert code == 1
    assert f"{bad}:2:" in err and f"{bad}:4:" in err and f"{bad}: 2 problems" in err


def test_ha_yaml_and_csv_work_everywhere_a_dictionary_goes(
    capture: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ha = str(FIXTURES / "home_assistant.yaml")
    code, out, _err = run(["dict", "show", "Boiler-room-unit3", "--dict", ha], capsys)
    assert code == 0 and "Flow temperature" in out
    code, out, _err = run(["dict", "show", ha], capsys)
    assert code == 0 and "Flow temperature" in out and "hub2" in out
    csv = str(FIXTURES / "registers.csv")
    code, out, err = run(
        ["replay", str(capture), "--dict", csv, "--unit", "5=registers", "--format", "text"], capsys
    )
    assert code == 0, err
    assert "Mode = Fault" not in out and "u5" in out


def listed(out: str) -> list[str]:
    """The rows of a text listing, without the line saying what its times are worth."""
    return [line for line in out.splitlines() if not line.startswith("# timing: ")]


def test_filter_count_and_stdin(capture: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _err = run(["replay", str(capture), "--filter", "kind:exception"], capsys)
    assert code == 0
    (line,) = listed(out)
    # counted from the capture's first frame, as the TUI does, not from the first match
    assert "exception 02" in line and line.split()[0].startswith("3.02")
    code, out, _err = run(["replay", "-r", str(capture), "-c", "3"], capsys)
    assert len(listed(out)) == 3
    code, _out, err = run(["replay", str(capture), "--filter", "fc:x"], capsys)
    assert code == 2 and "--filter: fc:x:" in err
    result = subprocess.run(
        [sys.executable, "-m", "sniffer.cli", "replay", "-", "--filter", "unit:5 fc:3", "-c", "2"],
        input=capture.read_bytes(),
        capture_output=True,
        cwd=ROOT,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert len(listed(result.stdout.decode())) == 2


def test_export_filter(capture: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_file = tmp_path / "x.csv"
    code, _out, err = run(
        ["export", str(capture), "-o", str(out_file), "--filter", "kind:request", "-c", "4"], capsys
    )
    assert code == 0 and "4 frames" in err
    assert len(out_file.read_text(encoding="utf-8").splitlines()) == 5  # header + 4


def test_diff(capture: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    other = write_capture(tmp_path / "b.pcapng", frames([7, 8, 9, 300] * 5))
    code, out, _err = run(["diff", str(capture), str(capture)], capsys)
    assert code == 0 and "no difference" in out
    code, out, _err = run(["diff", str(capture), str(other)], capsys)
    assert code == 1
    assert "unit 5: holding 11 left its range: 7..9 in A, 7..300 in B (5 of 20 readings" in out


def test_stats_show_the_poll_cycle(capture: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _err = run(["replay", str(capture), "--stats"], capsys)
    assert code == 0
    assert "poll cycle" in out and "read holding 10-11" in out and "500ms" in out


def test_sigrok_without_line_flags_says_what_it_chose(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(
        ["replay", str(WIZ), "--probe", "RX", "--probe", "TX", "--format", "text"], capsys
    )
    assert code == 0
    assert "no --baud given: chose 9600 8N1" in err
    assert out.count(" ok  ok ") == 88


def test_bytes_at_the_wrong_speed_suggest_scan(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # what a 9600-baud receiver made of 19200 8E1 traffic (tests/support/uart_double.py)
    from tests.support.uart_double import Wire, modbus_cycle

    line = LineSettings(19200, 8, "E", 1)
    got, _f, _p = Wire(line, *modbus_cycle(line)).receive(LineSettings(9600, 8, "E", 1), 0, 1)
    path = write_capture(tmp_path / "wrong.pcapng", [(0.5, bytes(v for _t, v in got))])
    code, _out, err = run(["replay", str(path), "--format", "text"], capsys)
    assert code == 2  # not one frame: nothing usable (sniffer.session.verdict)
    assert "not one Modbus frame" in err
    assert "wrong speed" in err and "modscope scan PORT" in err


def test_scan_names_a_missing_port(capsys: pytest.CaptureFixture[str]) -> None:
    code, _out, err = run(["scan", "/dev/ttyNOSUCH9", "-b", "9600"], capsys)
    assert code == 2 and "no such serial port" in err


def test_unknown_model_in_a_bus_file(
    capture: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bus = tmp_path / "bus.toml"
    bus.write_text('format = 1\n\n[[unit]]\naddress = 5\nmodel = "pump-x"\n', encoding="utf-8")
    code, _out, err = run(["replay", str(capture), "--bus", str(bus)], capsys)
    assert code == 2 and f"{bus}:3: no dictionary for model 'pump-x'" in err


@pytest.mark.peer
def test_bash_completion_completes_commands_options_and_choices(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, script, _err = run(["completion", "bash"], capsys)
    assert code == 0
    path = tmp_path / "modscope.bash"
    path.write_text(script, encoding="utf-8")

    def complete(*words: str) -> list[str]:
        quoted = " ".join(f'"{w}"' for w in ("modscope", *words))
        probe = (
            f"source {path}; COMP_WORDS=({quoted}); COMP_CWORD={len(words)}; _modscope; "
            'printf "%s\\n" "${COMPREPLY[@]}"'
        )
        done = subprocess.run(["bash", "-c", probe], capture_output=True, text=True, check=True)
        return done.stdout.split()

    assert complete("sc") == ["scan"]
    assert complete("replay", "--fil") == ["--filter"]
    assert complete("dict", "dr") == ["draft"]
    assert complete("dict", "draft", "x", "--fo") == ["--force"]
    assert complete("replay", "-P", "") == ["E", "N", "O"]
    code, zsh, _err = run(["completion", "zsh"], capsys)
    assert zsh.startswith("#compdef modscope") and "bashcompinit" in zsh


@pytest.mark.peer
def test_man_page_renders_without_warnings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, page, _err = run(["man"], capsys)
    assert code == 0
    for command in ("replay", "live", "scan", "diff", "dict draft", "export"):
        assert f".SS {command}\n" in page
    assert "\\fB\\-\\-filter\\fR \\fIQUERY\\fR" in page
    path = tmp_path / "modscope.1"
    path.write_text(page, encoding="utf-8")
    done = subprocess.run(
        ["groff", "-man", "-Tutf8", "-ww", "-z", str(path)], capture_output=True, text=True
    )
    assert done.returncode == 0 and done.stderr == ""


def test_the_command_line_filter_never_loads_the_tui_package() -> None:
    """--filter uses the matcher in sniffer.meaning.select; running a filtered replay must not
    import anything from sniffer.tui (which would tie the CLI to the TUI's files)."""
    code = (
        "import sys\n"
        "from sniffer.cli import main\n"
        "from sniffer.cli.filtering import Selection\n"
        "import sniffer.cli.replay, sniffer.cli.live, sniffer.cli.export\n"
        "print('\\n'.join(m for m in sys.modules if m.startswith('sniffer.tui')))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    assert out.stdout.split() == []


def test_the_tui_rows_module_shares_the_core_matcher() -> None:
    import sniffer.meaning.select
    import sniffer.tui.model

    used = vars(sniffer.tui.model)  # what the TUI's list model filters with
    assert used["FilterJob"] is sniffer.meaning.select.FilterJob
    assert used["Options"] is sniffer.meaning.select.Options


def test_filtered_replay_in_small_blocks_gives_the_same_rows(
    capture: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import sniffer.meaning.select

    args = ["replay", str(capture), "--format", "text", "--filter", "kind:exception,request unit:5"]
    code, whole, _ = run(args, capsys)
    monkeypatch.setattr(sniffer.meaning.select, "BLOCK", 3)  # columns scanned three rows at a time
    code2, small, _ = run(args, capsys)
    assert code == code2
    assert whole == small
    assert len(listed(whole)) == 21  # 20 requests and one exception answer


def _readme_runs() -> list[tuple[list[str], list[str]]]:
    """Each `$ modscope ...` line of the README's toolkit section and the lines after it."""
    import shlex

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## Unknown line, unknown device: the toolkit", 1)[1].split("\n## ", 1)[0]
    runs: list[tuple[list[str], list[str]]] = []
    for block in section.split("```")[1::2]:
        for line in block.strip("\n").splitlines():
            if line.startswith("$ modscope "):
                runs.append((shlex.split(line[len("$ modscope ") :]), []))
            elif runs:
                runs[-1][1].append(line)
    return runs


def test_the_readme_toolkit_outputs_are_what_the_demo_gives(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The README shows real output: the filter, dict draft and check runs on the demo
    give exactly those lines (scan runs through the UART double, diff needs a second
    simulated capture; tests/live/test_scan.py and test_diff cover them)."""
    import shutil

    from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE

    shutil.copy(DEMO_CAPTURE, tmp_path / "demo.pcapng")
    shutil.copy(DEMO_BUS, tmp_path / "demo-bus.toml")
    monkeypatch.chdir(tmp_path)
    checked = 0
    for args, want in _readme_runs():
        if args[0] in ("scan", "diff"):
            continue
        main(args)
        out, err = capsys.readouterr()
        assert (out + err).splitlines() == want, args
        checked += 1
    assert checked == 5
