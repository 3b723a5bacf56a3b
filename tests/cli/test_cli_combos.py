"""No silent options (issue 26): every option of every command is classified in
`sniffer.cli.combos`, an option the command line would ignore is refused in one line
naming both options, files may come after options, and usage errors are one line."""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from sniffer.cli import main
from sniffer.cli.combos import TABLES, options_of, refusal
from sniffer.cli.manual import _commands
from sniffer.cli.parser import build_parser
from sniffer.session.session import DEMO_CAPTURE
from tests.support.broker import Broker, running


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        code = main(argv)
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def leaves() -> dict[str, argparse.ArgumentParser]:
    return dict(_commands(build_parser()))


def test_every_command_has_a_table() -> None:
    assert set(leaves()) == set(TABLES)


@pytest.mark.parametrize("command", sorted(leaves()))
def test_every_option_is_classified_once(command: str) -> None:
    table = TABLES[command]
    options = set(options_of(leaves()[command]))
    domains = set().union(*(table.domain(g) for g in table.groups))
    assert not (table.common & domains), "an option is common and also tied to a facet"
    assert table.common | domains == options, (
        f"unclassified: {sorted(options - table.common - domains)}; "
        f"not options of {command}: {sorted((table.common | domains) - options)}"
    )
    for a, b, _ in table.exclusive:
        assert {a, b} <= options


REFUSED = [
    (["replay", "--mqtt", "mqtt://127.0.0.1:1/x", "--filter", "unit:3"], "--filter", "--mqtt"),
    (["replay", "--mqtt", "mqtt://127.0.0.1:1/x", "-c", "3"], "--count", "--mqtt"),
    (["replay", "--stats", "--format", "jsonl"], "--stats", "--format"),
    (["replay", "--stats", "--filter", "unit:3"], "--filter", "--stats"),
    (["replay", "--stats", "--jobs", "2"], "--jobs", "--stats"),
    (["replay", "--format", "text", "--mqtt-every", "5"], "--mqtt-every", "--mqtt"),
    (["replay", "--format", "text", "--ha-discovery"], "--ha-discovery", "--mqtt"),
    (["replay", "--format", "text", "--offset", "a=1"], "--offset", "several files"),
    (["export", "DEMO", "-o", "x.parquet", "--jobs", "2"], "--jobs", "Parquet"),
    (["export", "DEMO", "-o", "x.jsonl", "--raw-csv"], "--raw-csv", "JSONL"),
    (["export", "DEMO", "-o", "x.txt", "--what=registers", "--time=abs"], "--time", "--what"),
    (["export", "DEMO", "-o", "x.csv", "--time=abs"], "--time", "CSV"),
    (["replay", "--format", "jsonl", "--time", "abs"], "--time", "JSONL"),
    (["replay", "--format", "text", "--raw-csv"], "--raw-csv", "text listing"),
    (["record", "/dev/null", "-w", "x.pcapng", "--unit", "3=rvs-dn"], "--unit", "--mqtt"),
    (["record", "/dev/null", "-w", "x.pcapng", "--bus-name", "a"], "--bus-name", "--mqtt"),
    (["record", "/dev/null", "-w", "x.pcapng", "--timeout", "1"], "--timeout", "--metrics"),
    (["tui", "mqtt://127.0.0.1:1/x", "--baud", "9600"], "--baud", "mqtt://"),
    (["doctor", "/dev/ttyUSB9", "--carrier", "tcp"], "--carrier", "listening to a port"),
    (["doctor", "DEMO", "--duration", "1m"], "--duration", "capture file"),
    (["live", "mqtt://127.0.0.1:1/x", "--parity", "N", "--format", "text"], "--parity", "mqtt"),
]  # fmt: skip


@pytest.mark.parametrize(("argv", "option", "other"), REFUSED)
def test_an_option_that_cannot_apply_is_refused_in_one_line(
    argv: list[str], option: str, other: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    argv = [
        str(DEMO_CAPTURE) if a == "DEMO" else str(tmp_path / a) if a.startswith("x.") else a
        for a in argv
    ]
    code, out, err = run(argv, capsys)
    assert code == 2
    assert out == ""
    assert len(err.splitlines()) == 1, err
    line = err.strip()
    assert line.startswith(f"modscope {argv[0]}: error: ")
    assert option in line and other in line
    assert line.endswith(f"(see modscope {argv[0]} --help)")


def _namespace(argv: list[str]) -> tuple[argparse.ArgumentParser, argparse.Namespace]:
    args = build_parser().parse_args(argv)
    parser = args.command_parser
    assert isinstance(parser, argparse.ArgumentParser)
    return parser, args


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["replay", "--time", "abs"], "--time"),  # the TUI has its own time column
        (["replay", "--jobs", "2"], "--jobs"),
        (["live", "/dev/ttyUSB0", "--duration", "1h"], "--duration"),  # the TUI runs on
        (["live", "/dev/ttyUSB0", "--stats"], "--stats"),
    ],
)
def test_on_a_terminal_listing_options_are_refused_rather_than_ignored_by_the_tui(
    argv: list[str], option: str
) -> None:
    parser, args = _namespace(argv)
    why = refusal(argv[0], parser, args, terminal=True)
    assert why is not None and why.startswith(f"{option} does not apply to the TUI")
    assert refusal(argv[0], parser, args, terminal=False) is None  # piped: a listing


@pytest.mark.parametrize(
    "argv",
    [
        ["replay", "--format", "text", "--filter", "unit:3", "-c", "5", "--time", "abs"],
        ["replay", "--mqtt", "mqtt://h/x", "--format", "jsonl", "--filter", "unit:3"],
        ["replay", "--mqtt", "mqtt://h/x", "--stats", "--mqtt-every", "5", "--speed", "original"],
        ["replay", "A", "B", "--offset", "B=1.5", "--stats"],
        ["export", "A", "-o", "x.csv", "--raw-csv", "--jobs", "2"],
        ["export", "A", "-o", "x.txt", "--time", "abs", "--jobs", "2"],
        ["replay", "--format", "csv", "--raw-csv", "--jobs", "2"],
        ["export", "A", "-o", "x.pcapng", "--as", "rtu"],
        ["live", "/dev/ttyUSB0", "--pcap", "x.pcapng", "-c", "5", "--duration", "1m"],
        ["live", "/dev/ttyUSB0", "--mqtt", "mqtt://h/x", "--ha-discovery"],
        ["record", "/dev/ttyUSB0", "-w", "x.pcapng", "--mqtt", "mqtt://h/x", "--unit", "3=dcrl"],
        ["tui", "A", "--baud", "9600", "--speed", "original"],
        ["tui", "mqtt://h/x", "--mqtt-ca", "ca.pem"],
    ],
)
def test_options_that_apply_together_are_accepted(argv: list[str]) -> None:
    parser, args = _namespace(argv)
    assert refusal(argv[0], parser, args, terminal=False) is None
    assert refusal(argv[0], parser, args, terminal=True) is None


def test_files_may_come_after_options(capsys: pytest.CaptureFixture[str]) -> None:
    demo = str(DEMO_CAPTURE)
    first = run(["replay", demo, demo, "--format", "jsonl", "-c", "4"], capsys)
    mixed = run(["replay", demo, "--format", "jsonl", "-c", "4", demo], capsys)
    assert first[0] == mixed[0] == 0, mixed[2]
    assert mixed[1] == first[1] and len(mixed[1].splitlines()) == 4
    flags_first = run(["replay", "--format", "jsonl", "-c", "4", demo], capsys)
    assert flags_first[0] == 0 and len(flags_first[1].splitlines()) == 4
    # after `--` every word is a file, as getopt has it: `-c` here is a file name
    args = build_parser().parse_args(["replay", "--format", "text", "--", demo, "-c"])
    assert args.file == [demo, "-c"] and args.count is None


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["replay", "--format", "xml"], "invalid choice: 'xml'"),
        (["replay", "--no-such-option"], "unrecognized arguments: --no-such-option"),
        (["export", "a.pcapng"], "required: -o/--output"),
        (["dict", "show"], "required: model"),
        (["no-such-command"], "invalid choice"),
    ],
)
def test_a_usage_error_is_one_line_with_a_pointer_to_help(
    argv: list[str], says: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = run(argv, capsys)
    assert code == 2 and out == ""
    assert len(err.splitlines()) == 1, err
    assert says in err
    assert err.rstrip().endswith("--help)")


# -- --mqtt with a listing or the statistics: both happen (a real Mosquitto broker) --------


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    if shutil.which("mosquitto") is None and not Path("/usr/sbin/mosquitto").exists():
        pytest.skip("needs mosquitto (apt-get install mosquitto)")
    pytest.importorskip("paho.mqtt.client")
    with running(tmp_path) as b:
        yield b


def _retained(broker: Broker, topic: str) -> dict[str, str]:
    done = subprocess.run(
        ["mosquitto_sub", "-p", str(broker.port), "-v", "-W", "2", "--retained-only", "-t", topic],
        capture_output=True,
        timeout=30,
        check=False,
    )
    found = {}
    for line in done.stdout.decode().splitlines():
        name, _, payload = line.partition(" ")
        found[name] = payload
    return found


@pytest.mark.peer
def test_mqtt_with_a_jsonl_listing_publishes_and_lists(
    broker: Broker, capsys: pytest.CaptureFixture[str]
) -> None:
    url = f"mqtt://127.0.0.1:{broker.port}/combo"
    code, out, err = run(
        ["replay", "--mqtt", url, "--format", "jsonl", "--filter", "unit:3", "-c", "6"], capsys
    )
    assert code == 0, err
    alone, listed, _ = run(["replay", "--format", "jsonl", "--filter", "unit:3", "-c", "6"], capsys)
    assert alone == 0
    assert out == listed  # the same rows as without --mqtt
    rows = [json.loads(line) for line in out.splitlines()]
    assert len(rows) == 6 and {r["unit"] for r in rows} == {3}
    assert "values" in err and "published" in err
    retained = _retained(broker, "combo/#")
    assert any(t.startswith("combo/") and "/3/" in t for t in retained), sorted(retained)[:10]


@pytest.mark.peer
def test_mqtt_with_stats_publishes_and_prints_the_table(
    broker: Broker, capsys: pytest.CaptureFixture[str]
) -> None:
    url = f"mqtt://127.0.0.1:{broker.port}/combo"
    code, out, err = run(["replay", "--mqtt", url, "--stats"], capsys)
    assert code == 0, err
    _, alone, _ = run(["replay", "--stats"], capsys)
    assert out == alone
    assert "published" in err


def test_tui_opens_several_files_as_replay_does(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`tui A B` hands the TUI the same merged rows `replay A B` lists (the TUI itself is
    not started: it needs a terminal; what it is given is the point here)."""
    import sniffer.tui.app

    shown: list[int] = []

    def record(session: Any, capture: Any = None, live: Any = None, **kw: Any) -> int:
        shown.append(len(session.store))
        return 0

    monkeypatch.setattr(sniffer.tui.app, "run_tui", record)
    demo = str(DEMO_CAPTURE)
    code, _, err = run(["tui", demo, demo], capsys)
    assert code == 0, err
    listed = run(["replay", demo, demo, "--format", "jsonl"], capsys)
    assert listed[0] == 0
    assert shown == [len(listed[1].splitlines())] and shown[0] > 2000
    code, _, err = run(["tui", demo, demo, "--speed", "original"], capsys)
    assert code == 2 and "--speed does not apply to several files together" in err
