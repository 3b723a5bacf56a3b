"""Provides the `modscope` argument parser, assembled from one module per command.

Each command module (`replay`, `live`, `scan`, `record`, `ports`, `export`, `diff`,
`dictcmd`, `tui`, `serve`, `manual`) has a `register(sub)` that adds its subparser and
sets `func`. `manual` makes the man page and completion scripts from this same parser:
it is handed `build_parser` rather than importing it, so the dependency runs one way.
"""

from __future__ import annotations

import argparse

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
    manual.register(sub, build_parser)  # describes the parser: given the builder
    return parser
