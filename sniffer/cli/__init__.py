"""Provides the `modscope` command line: `main` runs the command the parser
(`sniffer.cli.parser`, one module per command) picked and turns what goes wrong into an
exit status; the options several commands share are in `options`. Nothing outside this
package imports it.

Exit status: 0 done, 1 done with findings (`dict check` found bad files; a recording
stopped by a full disk, `sniffer.live.recorder`), 2 a user error (printed as one line:
a missing file, a bad option, a port that refuses its settings), 70 a bug in modscope
(EX_SOFTWARE: the traceback is printed with a request to report it), 130 interrupted.
"""

from __future__ import annotations

import shlex
import sys
import traceback
from collections.abc import Sequence
from typing import TextIO

from sniffer import __version__
from sniffer.cli import heap
from sniffer.cli.options import Command
from sniffer.cli.parser import build_parser, combination_error
from sniffer.errors import USER_ERRORS
from sniffer.outputs.mqtt.target import redact
from sniffer.text import plain

__all__ = ["EX_SOFTWARE", "EX_USAGE", "build_parser", "main", "report_bug"]

EX_USAGE = 2  # what argparse uses for a bad command line; user errors share it
EX_SOFTWARE = 70  # sysexits.h: an internal software error (a bug in modscope)

REPORT = (
    "modscope: this is a bug in modscope {version}, not a problem with your input; "
    "please report it on the modscope issue tracker with the command line ({argv}) and "
    "the traceback above\n"
)


def main(argv: Sequence[str] | None = None) -> int:
    if argv is None:
        heap.as_program()
    parser = build_parser()
    args = parser.parse_args(argv)
    out, err = sys.stdout, sys.stderr
    if args.command is None:
        # the bundled demo: in the TUI on a terminal, as a listing when piped
        args = parser.parse_args(["replay"])
    refused = combination_error(args, out.isatty() and sys.stdin.isatty())
    if refused is not None:  # an option the command line would ignore: said, not ignored
        err.write(refused)
        return EX_USAGE
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
    # a broker URL's password never reaches the report (sniffer.outputs.mqtt.target)
    err.write(redact(traceback.format_exc()))
    command = redact(shlex.join(["modscope", *argv]))
    err.write(REPORT.format(version=__version__, argv=command))
    err.flush()
    return EX_SOFTWARE
