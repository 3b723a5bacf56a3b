"""Provides the `modscope` argument parser, assembled from one module per command.

Each command module (`replay`, `live`, `scan`, `record`, `ports`, `export`, `diff`,
`dictcmd`, `tui`, `serve`, `manual`) has a `register(sub)` that adds its subparser and
sets `func`. `manual` makes the man page and completion scripts from this same parser:
it is handed `build_parser` rather than importing it, so the dependency runs one way.
"""

from __future__ import annotations

import argparse

# each command's module by its full name: `from sniffer.cli import ...` would reach for
# the package, whose __init__ imports this module
import sniffer.cli.dictcmd
import sniffer.cli.diff
import sniffer.cli.export
import sniffer.cli.live
import sniffer.cli.manual
import sniffer.cli.ports
import sniffer.cli.record
import sniffer.cli.replay
import sniffer.cli.scan
import sniffer.cli.serve
import sniffer.cli.tui
from sniffer import __version__, core

# in the order `modscope --help` lists them (`manual` last: see build_parser)
COMMANDS = (
    sniffer.cli.replay,
    sniffer.cli.live,
    sniffer.cli.scan,
    sniffer.cli.record,
    sniffer.cli.ports,
    sniffer.cli.export,
    sniffer.cli.diff,
    sniffer.cli.dictcmd,
    sniffer.cli.tui,
    sniffer.cli.serve,
)

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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="modscope",
        description="Passive Modbus RTU/ASCII bus analyser: live RS-485 lines and capture files.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--version", action="version", version=f"modscope {__version__} ({core.describe()})"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in COMMANDS:
        module.register(sub)
    sniffer.cli.manual.register(sub, build_parser)  # describes the parser: given the builder
    return parser
