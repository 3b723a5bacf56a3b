"""Provides the `modscope` argument parser, assembled from one module per command.

Each command module (`replay`, `live`, `scan`, `record`, `ports`, `export`, `diff`,
`dictcmd`, `tui`, `serve`, `manual`) has a `register(sub)` that adds its subparser and
sets `func`. `manual` makes the man page and completion scripts from this same parser:
it is handed `build_parser` rather than importing it, so the dependency runs one way.

`Parser` is argparse's parser made to behave as tcpdump, tshark and jq users expect:
files may come after options (`replay A.pcap --format jsonl B.pcapng`), and a usage
error is one line naming the command, with a pointer to its `--help`. Adding a command
stays one import and one entry in `COMMANDS`; `sniffer.cli.combos` must classify its
options (a test fails until it does).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import NoReturn, cast

# the command modules by full name: the package's __init__ imports this module, and
# naming the package here (`from sniffer.cli import ...`) would read as a cycle
import sniffer.cli.dictcmd as dictcmd
import sniffer.cli.diff as diff
import sniffer.cli.doctor as doctor
import sniffer.cli.export as export
import sniffer.cli.live as live
import sniffer.cli.manual as manual
import sniffer.cli.ports as ports
import sniffer.cli.record as record
import sniffer.cli.replay as replay
import sniffer.cli.scan as scan
import sniffer.cli.serve as serve
import sniffer.cli.tui as tui
from sniffer import __version__, core
from sniffer.cli.combos import refusal
from sniffer.cli.options import SubParsers
from sniffer.text import plain

# in the order `modscope --help` lists them (then `manual`: see build_parser)
COMMANDS = (replay, live, scan, record, ports, export, diff, doctor, dictcmd, tui, serve)

EPILOG = """\
examples:
  modscope                                 open the TUI on the bundled demo capture
  modscope replay                          list the demo capture's frames
  modscope replay bus.pcapng --stats       per-unit statistics of a capture
  modscope replay scope.sr --probe RX --probe TX --baud 9600 --parity N
  modscope replay log.txt --format jsonl   one JSON object per frame
  modscope live /dev/ttyUSB0 --baud 19200  watch a line (never transmits)
  modscope dict show rvs-dn                what a device dictionary knows
  modscope scan /dev/ttyUSB0               find the line's baud rate and format
  modscope dict draft bus.pcapng --unit 7 -o unit7.toml   a dictionary to start from
  modscope diff monday.pcapng friday.pcapng               what changed on the bus
  modscope replay bus.pcapng --filter 'unit:3 kind:exception'

exit status: 0 done; 1 done with findings; 2 a user error (one line says what
to fix); 70 a bug in modscope (with a traceback to report); 130 interrupted
"""


class Parser(argparse.ArgumentParser):
    """An argparse parser whose commands take their files anywhere among their options
    and whose usage errors are one line.

    A command without subcommands of its own parses intermixed (argparse's
    `parse_known_intermixed_args`): the options first, then every word left over as the
    positionals, so `replay A --stats B` reads two files. argparse refuses that mode for
    a parser with subcommands (the top level, `dict`), which parse as usual. One trap
    stays, as in every getopt-style tool: an option with an optional value (`live
    --stats [S]`, `--ha-discovery [PREFIX]`, `--directions [ROLES]`) takes the word after
    it when that word could be its value; put files before such an option, or use
    `--stats=10`."""

    _mixing = False  # inside parse_known_intermixed_args, which calls back here

    def _leaf(self) -> bool:
        return not any(isinstance(a, argparse._SubParsersAction) for a in self._actions)

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        words = sys.argv[1:] if args is None else list(args)
        if self._mixing or not self._leaf() or "--" in words:
            # (after `--` every word is a file, even `-c`: argparse's own parse keeps that)
            return super().parse_known_args(words, namespace)
        self._mixing = True
        try:
            found, extras = self.parse_known_intermixed_args(words, namespace)
        finally:
            self._mixing = False
        if extras:  # said here, so the message names this command, not the top level
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        found.command_parser = self  # for the check of what goes with what (`combos`)
        return found, extras

    def error(self, message: str) -> NoReturn:
        """One line, as tshark, tcpdump, mbpoll and jq print: what is wrong and where to
        read the usage (argparse's default prints the whole usage block first)."""
        self.exit(2, f"{self.prog}: error: {plain(message, 500)} (see {self.prog} --help)\n")


def combination_error(args: argparse.Namespace, terminal: bool) -> str | None:
    """The one line refusing an option the command line would ignore (see
    `sniffer.cli.combos`), as a usage error of its command; `terminal`: stdout and stdin
    are terminals."""
    leaf = getattr(args, "command_parser", None)
    if not isinstance(leaf, argparse.ArgumentParser):
        return None
    command = leaf.prog.removeprefix(PROG).strip()
    why = refusal(command, leaf, args, terminal)
    if why is None:
        return None
    return f"{leaf.prog}: error: {plain(why, 500)} (see {leaf.prog} --help)\n"


PROG = "modscope"


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog=PROG,
        description="Passive Modbus RTU/ASCII bus analyser: live RS-485 lines and capture files.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--version", action="version", version=f"modscope {__version__} ({core.describe()})"
    )
    # (the commands' parsers are `Parser`s too: argparse makes them of the parser's class)
    sub = cast("SubParsers", parser.add_subparsers(dest="command", metavar="COMMAND"))
    for module in COMMANDS:
        module.register(sub)
    manual.register(sub, build_parser)  # describes the parser: given the builder
    return parser
