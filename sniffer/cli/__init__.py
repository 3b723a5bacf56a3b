"""Provides the `modscope` command line: the parser assembled from one module per command.

Each command module (`replay`, `live`, `record`, `ports`, `export`, `dictcmd`, `tui`,
`serve`) has a `register(sub)` that adds its subparser and sets `func`; the options
several commands share are in `options`. Nothing outside this package imports it.

Exit status: 0 done, 1 done with findings (`dict check` found bad files), 2 a user
error (printed as one line: a missing file, a bad option, a port that refuses its
settings), 70 a bug in modscope (EX_SOFTWARE: the traceback is printed with a request
to report it), 130 interrupted.
"""

from __future__ import annotations

import argparse
import sys
import traceback
from collections.abc import Sequence
from typing import TextIO

from sniffer import __version__, core
from sniffer.cli import (
    dictcmd,
    diff,
    export,
    heap,
    live,
    manual,
    ports,
    record,
    replay,
    scan,
    serve,
    tui,
)
from sniffer.cli.options import Command
from sniffer.errors import USER_ERRORS
from sniffer.text import plain

EX_USAGE = 2  # what argparse uses for a bad command line; user errors share it
EX_SOFTWARE = 70  # sysexits.h: an internal software error (a bug in modscope)

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

REPORT = (
    "modscope: this is a bug in modscope {version}, not a problem with your input; "
    "please report it on the modscope issue tracker with the command line ({argv}) and "
    "the traceback above\n"
)


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
    for module in (replay, live, scan, record, ports, export, diff, dictcmd, tui, serve, manual):
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    if argv is None:
        heap.as_program()
    parser = build_parser()
    args = parser.parse_args(argv)
    out, err = sys.stdout, sys.stderr
    if args.command is None:
        # the bundled demo: in the TUI on a terminal, as a listing when piped
        args = parser.parse_args(["replay"])
    func: Command = args.func
    try:
        return func(args, out, err)
    except USER_ERRORS as exc:
        err.write(f"modscope: error: {plain(str(exc), 2000)}\n")
        return EX_USAGE
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0
    except Exception:
        return report_bug(err, sys.argv[1:] if argv is None else list(argv))


def report_bug(err: TextIO, argv: list[str]) -> int:
    """Print the traceback of the exception being handled and ask for a report."""
    import shlex

    traceback.print_exc(file=err)
    err.write(REPORT.format(version=__version__, argv=shlex.join(["modscope", *argv])))
    err.flush()
    return EX_SOFTWARE
