"""Provides `modscope scan`: find a line's baud rate and format by listening (never
transmitting) at each common setting in turn."""

from __future__ import annotations

import argparse
from typing import TextIO

from sniffer.cli.options import SubParsers
from sniffer.errors import UsageError
from sniffer.scan import BAUDS, DWELL, FORMATS, MAX_DWELL, PortListener, Trial, live_command, scan
from sniffer.serial_source import PortError
from sniffer.text import plain

EPILOG = """\
examples:
  modscope scan /dev/ttyUSB0                    every common setting, about 15-30 s
  modscope scan /dev/ttyUSB0 -b 9600,19200      only these baud rates
  modscope scan /dev/ttyUSB0 --formats 8E1,8N1  only these formats

The port is opened with RTS and DTR off and only read: the scan changes nothing but the
local port's settings. Scan while the master polls: a silent line cannot be measured.
"""


def _bauds(text: str | None) -> tuple[int, ...]:
    if not text:
        return BAUDS
    try:
        found = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise UsageError(
            f"--baud {text!r}: give baud rates separated by commas, e.g. 9600,19200"
        ) from None
    if not found or any(b <= 0 for b in found):
        raise UsageError(f"--baud {text!r}: baud rates are positive numbers")
    return found


def _formats(text: str | None) -> tuple[str, ...]:
    if not text:
        return FORMATS
    from sniffer.scan import parse_format

    found = tuple(part.strip().upper() for part in text.split(",") if part.strip())
    for part in found:
        try:
            parse_format(part)
        except ValueError as exc:
            raise UsageError(f"--formats: {exc}") from None
    return found


def cmd_scan(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    if args.dwell <= 0 or args.max_dwell < args.dwell:
        raise UsageError("--dwell must be positive and --max-dwell at least --dwell")
    listener = PortListener(args.port)
    show = err.isatty()

    def progress(trial: Trial) -> None:
        if show:
            err.write(f"\r\x1b[Kscanning {args.port}: {trial.settings()} {trial.frames} frames")
            err.flush()

    try:
        result = scan(
            listener,
            _bauds(args.baud),
            _formats(args.formats),
            dwell=args.dwell,
            max_dwell=args.max_dwell,
            progress=progress,
        )
    except PortError as exc:
        raise UsageError(str(exc)) from None
    finally:
        if show:
            err.write("\r\x1b[K")
    for w in listener.warnings:
        err.write(f"modscope: warning: {plain(w)}\n")
    out.write(result.table() + "\n\n")
    if result.winner is None:
        out.write(f"no winner: {result.verdict}\n")
        return 1
    out.write(f"winner: {result.verdict}\n")
    for doubt in result.doubts:
        out.write(f"note: {doubt}\n")
    out.write(f"\n  {live_command(args.port, result.winner)}\n")
    return 0


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "scan",
        help="find a line's baud rate and format by listening (never transmits)",
        description=(
            "Listen passively at each common setting (1200-921600 baud; 8N1, 8E1, 8O1, 8N2; "
            "7E1 and 7O1 for ASCII), longer on a quiet line, and score each by frames "
            "whose CRC or LRC checks, answered requests, and the framing and parity errors "
            "the driver counted. Prints a ranked table, the winner and the `modscope live` "
            "command to use, or says the line was too quiet to decide."
        ),
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("port", metavar="PORT", help="device path (/dev/ttyUSB0) or pyserial URL")
    p.add_argument("-b", "--baud", metavar="LIST", help="baud rates to try, e.g. 9600,19200")
    p.add_argument("--formats", metavar="LIST", help="formats to try, e.g. 8E1,8N1,7E1")
    p.add_argument(
        "--dwell",
        type=float,
        default=DWELL,
        metavar="S",
        help=f"first listen per setting ({DWELL} s)",
    )
    p.add_argument(
        "--max-dwell",
        type=float,
        default=MAX_DWELL,
        metavar="S",
        help=f"longest listen on a quiet setting ({MAX_DWELL} s)",
    )
    p.set_defaults(func=cmd_scan)
