"""Provides the table of which options each way of running a command honours, and the
check that refuses, in one line naming both, an option the chosen way would ignore.

A command runs one way per *group*: replay shows the TUI, a listing, statistics or
publishes to a broker (the output group), of one capture or several (the input group).
Each way (a `Facet`) honours some options. An option of a group's domain (the options
any of its facets honours) applies only when a facet that honours it is active; the
options outside every domain apply whatever the command does (`Table.common`).
`tests/cli/test_cli_combos.py` holds the table to the parser: every option of every
command is in it exactly as `common` or in a domain, so a new option cannot slip
through unclassified.

The facets active for a command line are decided here from the parsed arguments and
whether the output is a terminal, the same way the commands decide (replay opens the
TUI on a terminal when nothing asks for a listing).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from sniffer.cli.doctor import _is_port as is_port  # (doctor's own rule for a port)
from sniffer.outputs.export import EXTENSIONS

LINE = ("--baud", "--bytesize", "--parity", "--stopbits", "--mode")
NETWORK = ("--carrier", "--port")
DEVICE = ("--bus", "--unit", "--dict")
PUBLISH = (
    "--mqtt",
    "--mqtt-ca",
    "--mqtt-password-file",
    "--bus-name",
    "--mqtt-every",
    "--ha-discovery",
)
METRICS = ("--metrics", "--metrics-hold")


@dataclass(frozen=True)
class Facet:
    """One way a command runs: `what` names it in a refusal ("publishing to a broker
    (--mqtt)"); `honours` are the options (long form) that take effect that way."""

    name: str
    what: str
    honours: frozenset[str]


def facet(name: str, what: str, *honours: str) -> Facet:
    return Facet(name, what, frozenset(honours))


@dataclass(frozen=True)
class Table:
    """A command's options: `common` apply always; each group's facets honour the rest;
    `exclusive` pairs cannot go together, whatever the facets (the reason says why);
    `active` names the facets a command line runs (terminal: stdout and stdin are both
    terminals)."""

    common: frozenset[str]
    groups: tuple[tuple[Facet, ...], ...] = ()
    exclusive: tuple[tuple[str, str, str], ...] = ()
    active: Callable[[argparse.Namespace, bool], set[str]] = field(
        default=lambda args, terminal: set()
    )

    def domain(self, group: tuple[Facet, ...]) -> frozenset[str]:
        return frozenset().union(*(f.honours for f in group))


def _is_broker(text: str | None) -> bool:
    return bool(text) and str(text).lower().startswith(("mqtt://", "mqtts://"))


def _replay_active(args: argparse.Namespace, terminal: bool) -> set[str]:
    files = [*(args.file or []), *([args.read] if args.read else [])]
    on = {"several" if len(files) > 1 else "one"}
    if args.mqtt:
        on.add("mqtt")
    if args.stats:
        on.add("stats")
    if args.format:
        on.add("listing")
    if not on - {"one", "several"}:
        # what replay does with no output asked for: the TUI on a terminal, else a listing
        # (a filter or a count asks for the listing too; so does standard input)
        listing = not terminal or args.filter or args.count is not None or "-" in files
        on.add("listing" if listing else "tui")
    return _listing_format(args, on)


# the listing's format: the time column is text's, the formula guard CSV's (JSONL has
# both times as numbers and no spreadsheet reads it)
LISTING_FORMATS = (
    facet("text", "a text listing", "--time"),
    facet("csv", "a CSV listing", "--raw-csv"),
    facet("jsonl", "a JSONL listing"),
)


def _listing_format(args: argparse.Namespace, on: set[str]) -> set[str]:
    return on | {args.format or "text"} if "listing" in on else on


REPLAY = Table(
    common=frozenset(
        ("--read", *LINE, "--timeout", *NETWORK, "--no-index", "--probe", "--invert", *DEVICE)
    ),
    groups=(
        (
            facet("one", "one capture"),
            facet("several", "several files replayed together", "--offset", "--gateway-timeout"),
        ),
        (
            facet("tui", "the TUI (replay on a terminal)"),
            facet(
                "listing",
                "a listing (--format)",
                "--format",
                "--time",
                "--raw-csv",
                "--jobs",
                "--filter",
                "--count",
                *METRICS,
            ),
            facet("stats", "the statistics (--stats)", "--stats", *METRICS),
            # (--metrics with --mqtt alone: the figures are taken when publishing ends)
            facet("mqtt", "publishing to a broker (--mqtt)", *PUBLISH, "--speed", *METRICS),
        ),
        LISTING_FORMATS,
    ),
    exclusive=(
        ("--stats", "--format", "both write standard output; run replay twice"),
        ("--mqtt", "--offset", "--mqtt publishes one capture; replay the files one at a time"),
    ),
    active=_replay_active,
)


def _export_active(args: argparse.Namespace, terminal: bool) -> set[str]:
    on = {args.what}
    fmt = args.format or EXTENSIONS.get(Path(args.output).suffix.lower())
    if fmt is not None:
        on.add(fmt)
    else:  # the command says it cannot tell the format; nothing to refuse before that
        on |= {"text", "csv", "jsonl", "pcapng", "parquet"}
    return on


EXPORT = Table(
    common=frozenset(("--output", "--what", "--format", "--filter", "--count", *LINE, "--timeout"))
    | frozenset((*NETWORK, "--no-index", "--probe", "--invert", *DEVICE)),
    groups=(
        (
            facet("frames", "--what frames", "--time"),
            facet("transactions", "--what transactions"),
            facet("registers", "--what registers"),
        ),
        (
            facet("text", "a text export", "--time", "--jobs"),
            facet("csv", "a CSV export", "--raw-csv", "--jobs"),
            facet("jsonl", "a JSONL export", "--jobs"),
            facet("pcapng", "a pcapng export", "--as", "--jobs"),
            facet("parquet", "a Parquet export (one process)"),
        ),
    ),
    active=_export_active,
)


def _live_active(args: argparse.Namespace, terminal: bool) -> set[str]:
    ports = [*(args.ports or []), *(args.extra_ports or [])]
    on = {"broker" if any(_is_broker(p) for p in ports) else "serial"}
    if args.mqtt:
        on.add("publish")
    if args.pcap:
        on.add("pcap")
    if args.format is not None or (args.pcap != "-" and (args.pcap or not terminal)):
        on.add("listing")
    if args.format is None and args.pcap is None and terminal:
        on.add("tui")
    return _listing_format(args, on)


LIVE = Table(
    common=frozenset(("--timeout", *DEVICE, "--write", "--rotate-size", "--rotate-time", "--keep"))
    | frozenset(("--queue", "--metrics")),
    groups=(
        (
            facet("serial", "serial ports", *LINE, "--port", "--directions"),
            facet(
                "broker", "a bus watched over MQTT (mqtt://)", "--mqtt-ca", "--mqtt-password-file"
            ),
        ),
        (
            facet("tui", "the TUI (live on a terminal)"),
            facet(
                "listing",
                "a listing (--format)",
                "--format",
                "--time",
                "--raw-csv",
                "--filter",
                "--count",
                "--duration",
                "--stats",
                "--backlog",
            ),
            facet(
                "pcap",
                "the pcapng stream (--pcap)",
                "--pcap",
                "--filter",
                "--count",
                "--duration",
                "--stats",
            ),
        ),
        (
            facet("publish", "publishing to a broker (--mqtt)", *PUBLISH),
            facet(
                "broker", "a bus watched over MQTT (mqtt://)", "--mqtt-ca", "--mqtt-password-file"
            ),
        ),
        LISTING_FORMATS,
    ),
    active=_live_active,
)


def _record_active(args: argparse.Namespace, terminal: bool) -> set[str]:
    on = {"frames"} if args.mqtt or args.metrics else {"bytes"}
    if args.mqtt:
        on.add("publish")
    return on


RECORD = Table(
    common=frozenset(("--port", *LINE, "--directions", "--write", "--rotate-size", "--queue"))
    | frozenset(("--rotate-time", "--keep", "--duration", "--metrics")),
    groups=(
        (
            facet("bytes", "a recording alone (record -w)"),
            facet("frames", "frames for --mqtt or --metrics", *DEVICE, "--timeout"),
        ),
        (facet("publish", "publishing to a broker (--mqtt)", *PUBLISH),),
    ),
    active=_record_active,
)


def _tui_active(args: argparse.Namespace, terminal: bool) -> set[str]:
    files = args.file or []
    if any(_is_broker(f) for f in files):
        return {"broker"}
    return {"several" if len(files) > 1 else "one"}


TUI = Table(
    common=frozenset(("--timeout", *DEVICE)),
    groups=(
        (
            facet("one", "one capture", *LINE, *NETWORK, "--speed"),
            facet("several", "several files together", *LINE, *NETWORK),
            facet(
                "broker", "a bus watched over MQTT (mqtt://)", "--mqtt-ca", "--mqtt-password-file"
            ),
        ),
    ),
    active=_tui_active,
)


def _doctor_active(args: argparse.Namespace, terminal: bool) -> set[str]:
    return {"port" if is_port(args.capture) else "file"}


DOCTOR = Table(
    common=frozenset(("--format", *LINE, "--timeout", *DEVICE)),
    groups=(
        (
            facet("file", "a capture file", *NETWORK),
            facet("port", "listening to a port", "--duration"),
        ),
    ),
    active=_doctor_active,
)

SERVE = Table(
    common=frozenset(
        (
            "--host",
            "--port",
            "--public-url",
            "--export-dir",
            "--max-sessions",
            *LINE,
            "--timeout",
            *DEVICE,
        )
    )
)

TABLES: dict[str, Table] = {
    "replay": REPLAY,
    "export": EXPORT,
    "live": LIVE,
    "record": RECORD,
    "tui": TUI,
    "serve": SERVE,
    "doctor": DOCTOR,
    # one way of running each: every option applies
    "scan": Table(common=frozenset(("--baud", "--formats", "--dwell", "--max-dwell"))),
    "ports": Table(common=frozenset(("--format",))),
    "diff": Table(common=frozenset((*LINE, "--timeout", *NETWORK))),
    "dict list": Table(common=frozenset()),
    "dict show": Table(common=frozenset(("--dict",))),
    "dict check": Table(common=frozenset()),
    "dict draft": Table(
        common=frozenset(
            ("--unit", "--output", "--model", "--force", "--quiet", *LINE, "--timeout")
        )
    ),
    "completion": Table(common=frozenset()),
    "man": Table(common=frozenset()),
}


def option_name(action: argparse.Action) -> str:
    """The name an option goes by in the table and in refusals: its first long form."""
    longs = [o for o in action.option_strings if o.startswith("--")]
    return longs[0] if longs else action.option_strings[0]


def options_of(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    """A command parser's options by name (not --help)."""
    return {
        option_name(a): a
        for a in parser._actions
        if a.option_strings and not isinstance(a, argparse._HelpAction)
    }


def given(parser: argparse.ArgumentParser, args: argparse.Namespace) -> list[str]:
    """The options a command line set to something other than their default."""
    out = []
    for name, action in options_of(parser).items():
        value = getattr(args, action.dest, None)
        if value != action.default and value not in (None, False, []):
            out.append(name)
    return out


def refusal(command: str, parser: argparse.ArgumentParser, args: argparse.Namespace,
            terminal: bool) -> str | None:  # fmt: skip
    """What is wrong with a command line's combination of options, in one line naming
    both sides; None when every option given takes effect."""
    table = TABLES.get(command)
    if table is None:
        return None
    said = given(parser, args)
    for a, b, why in table.exclusive:
        if a in said and b in said:
            return f"{a} and {b} do not go together: {why}"
    on = table.active(args, terminal)
    for name in said:
        for group in table.groups:
            if name not in table.domain(group):
                continue
            running = [f for f in group if f.name in on]
            if any(name in f.honours for f in running):
                continue
            takers = [f.what for f in group if name in f.honours and f.what]
            doing = " and ".join(f.what for f in running) or "this command line"
            return f"{name} does not apply to {doing}: {name} is for {' or '.join(takers)}"
    return None
