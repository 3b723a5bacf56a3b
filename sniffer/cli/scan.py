"""Provides `modscope scan`: find a line's baud rate and format by listening (never
transmitting) at each common setting in turn."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TextIO

import sniffer.live.scan as scanning
from sniffer.analysis.linescore import format_of, parse_format
from sniffer.cli.options import SubParsers
from sniffer.errors import UsageError
from sniffer.live.port import PortError
from sniffer.live.scan import (
    BAUDS,
    DWELL,
    FORMATS,
    MAX_DWELL,
    NoLineSettingsError,
    PortListener,
    ScanResult,
    Trial,
    live_command,
    no_line_settings,
    scan,
)
from sniffer.model import LineSettings
from sniffer.text import plain

EPILOG = """\
examples:
  modscope scan /dev/ttyUSB0                    every common setting, about 15-30 s
  modscope scan /dev/ttyUSB0 -b 9600,19200      only these baud rates
  modscope scan /dev/ttyUSB0 --formats 8E1,8N1  only these formats

The port is opened with RTS and DTR off and only read: the scan changes nothing but the
local port's settings. Scan while the master polls: a silent line cannot be measured.
A pseudo-terminal or a socket:// URL has no line settings to find: the scan says so and
exits 1. Settings the port refuses are skipped and listed. The winner comes with its
confidence (high, medium, low), the formats that read alike and what would tell them
apart. Exit status: 0 with a winner, 1 without one.
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
    found = tuple(part.strip().upper() for part in text.split(",") if part.strip())
    for part in found:
        try:
            parse_format(part)
        except ValueError as exc:
            raise UsageError(f"--formats: {exc}") from None
    return found


AUTO = "auto"  # --baud auto on live: scan first


def parse_baud(text: str) -> int | str:
    """`--baud N`, or `auto` where the command can scan for the line's settings."""
    if text.strip().lower() == AUTO:
        return AUTO
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a baud rate; give a number (19200) or auto to scan for it"
        ) from None


def accept_auto_baud(p: argparse.ArgumentParser) -> None:
    """Let the parser's -b/--baud take `auto` (added by add_line_options as a number)."""
    for action in p._actions:
        if action.dest == "baud":
            action.type = parse_baud
            action.metavar = "N|auto"
            action.help = (
                "baud rate (-b as in mbpoll), or auto: scan the first port for its baud rate "
                "and format first (as `modscope scan` does), then listen with the winner"
            )


def _progress(err: TextIO, port: str) -> Callable[[Trial], None]:
    show = err.isatty()

    def progress(trial: Trial) -> None:
        if show:
            err.write(f"\r\x1b[Kscanning {port}: {trial.settings()} {trial.frames} frames")
            err.flush()

    return progress


def _wanted_formats(args: argparse.Namespace) -> tuple[str, ...]:
    """The scan's formats that agree with the line flags given beside --baud auto."""
    out = []
    for text in FORMATS:
        bytesize, parity, stopbits = parse_format(text)
        if args.bytesize is not None and args.bytesize != bytesize:
            continue
        if args.parity is not None and args.parity != parity:
            continue
        if args.stopbits is not None and args.stopbits != stopbits:
            continue
        if args.mode == "ascii" and bytesize != 7 and args.bytesize is None:
            continue  # ASCII lines at 8 bits are rare; give --bytesize 8 to include them
        out.append(text)
    if not out:
        raise UsageError(
            "--baud auto: no common format fits the --bytesize/--parity/--stopbits given "
            f"(the scan tries {', '.join(FORMATS)}); drop the flag that rules them all out"
        )
    return tuple(out)


def _listen_anyway(args: argparse.Namespace, port: str, reason: str, err: TextIO) -> None:
    """`live --baud auto` on a port without line settings: listen at the flags given,
    without parity where none is given (some pseudo-terminals refuse even parity)."""
    default = LineSettings()
    args.baud = default.baud
    if args.parity is None:
        args.parity = "N"
    line = LineSettings(
        default.baud, args.bytesize or default.bytesize, args.parity, args.stopbits or 1
    )
    err.write(
        f"modscope: --baud auto: no line settings to find: {plain(reason)}; listening at "
        f"{line.baud} {format_of(line)}, which changes nothing here\n"
    )


def scan_for_live(args: argparse.Namespace, err: TextIO) -> ScanResult | None:
    """`live --baud auto`: scan the first port and put the winner's settings into `args`
    (baud, format, ASCII mode), saying on `err` what was chosen and how sure it is. No
    winner is a user error (exit 2) that says why and points at `modscope scan`. A port
    with no line settings (a pseudo-terminal, socket://) is listened to as it is. Nothing
    is done when no port is named (port_specs says so)."""
    names = [*args.ports, *args.extra_ports]
    if not names:
        args.baud = None
        return None
    port = names[0]
    reason = no_line_settings(port)
    if reason is not None:
        _listen_anyway(args, port, reason, err)
        return None
    formats = _wanted_formats(args)
    listener = PortListener(port)
    try:
        result = scan(
            listener,
            scanning.BAUDS,
            formats,
            dwell=scanning.DWELL,
            max_dwell=scanning.MAX_DWELL,
            progress=_progress(err, port),
        )
    except NoLineSettingsError as exc:
        raise UsageError(
            f"--baud auto on {port}: no line settings to find: {exc} (connect with "
            "socket://HOST:PORT if the server sends the line's bytes as they are)"
        ) from None
    except PortError as exc:
        raise UsageError(str(exc)) from None
    finally:
        if err.isatty():
            err.write("\r\x1b[K")
    for w in listener.warnings:
        err.write(f"modscope: warning: {plain(w)}\n")
    if result.refused:
        err.write(f"modscope: note: {plain(result.refused_text())}\n")
    seconds = sum(t.seconds for t in result.trials)
    if result.winner is None:
        hint = (
            f"start the master (or check A/B), then `modscope scan {port}` shows what each "
            "setting read"
            if result.quiet
            else f"`modscope scan {port}` shows what each setting read"
        )
        raise UsageError(f"--baud auto on {port}: {result.verdict} ({hint})")
    win = result.winner
    args.baud = win.line.baud
    args.bytesize = win.line.bytesize
    args.parity = win.line.parity
    args.stopbits = win.line.stopbits
    if win.mode == "ascii":
        args.mode = "ascii"
    err.write(
        f"modscope: --baud auto: {len(result.trials)} settings of {port} in {seconds:.1f} s; "
        f"chose {result.verdict}; confidence {result.confidence}; listening at "
        f"{win.line.baud} {format_of(win.line)}\n"
    )
    if result.confidence != "high":
        err.write(f"modscope: note: confidence {result.confidence}: {result.reason}\n")
    if len(names) > 1:
        err.write(f"modscope: note: the other ports are opened at the setting {port} gave\n")
    return result


def report(result: ScanResult, port: str) -> str:
    """What `modscope scan` prints after its table: the refused settings, the winner with
    its confidence and what would raise it, and the command to listen with."""
    lines: list[str] = []
    if result.refused:
        lines.append(result.refused_text())
    if result.winner is None:
        lines.append(f"no winner: {result.verdict}")
        return "\n".join(lines) + "\n"
    lines.append(f"winner: {result.verdict}")
    lines.append(f"confidence: {result.confidence}: {result.reason}")
    lines.extend(f"to raise it: {r}" for r in result.raise_it)
    lines.extend(f"note: {d}" for d in result.doubts)
    lines.append("")
    lines.append(f"  {live_command(port, result.winner)}")
    return "\n".join(lines) + "\n"


def cmd_scan(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    if args.dwell <= 0 or args.max_dwell < args.dwell:
        raise UsageError("--dwell must be positive and --max-dwell at least --dwell")
    bauds, formats = _bauds(args.baud), _formats(args.formats)
    reason = no_line_settings(args.port)
    if reason is not None:
        out.write(f"no line settings to find: {plain(reason)}\n")
        return 1
    listener = PortListener(args.port)
    show = err.isatty()

    def progress(trial: Trial) -> None:
        if show:
            err.write(f"\r\x1b[Kscanning {args.port}: {trial.settings()} {trial.frames} frames")
            err.flush()

    try:
        result = scan(
            listener,
            bauds,
            formats,
            dwell=args.dwell,
            max_dwell=args.max_dwell,
            progress=progress,
        )
    except NoLineSettingsError as exc:
        out.write(f"no line settings to find: {plain(str(exc))}\n")
        return 1
    except PortError as exc:
        raise UsageError(str(exc)) from None
    finally:
        if show:
            err.write("\r\x1b[K")
    for w in listener.warnings:
        err.write(f"modscope: warning: {plain(w)}\n")
    if result.trials:
        out.write(result.table() + "\n\n")
    out.write(report(result, args.port))
    return 0 if result.winner is not None else 1


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "scan",
        help="find a line's baud rate and format by listening (never transmits)",
        description=(
            "Listen passively at each common setting (1200-921600 baud; 8N1, 8E1, 8O1, 8N2; "
            "7E1 and 7O1 for ASCII), longer on a quiet line, and score each by the share "
            "of its bytes in frames whose CRC or LRC checks and by answered requests, then "
            "by the framing and parity errors the driver counted (where it is seen to "
            "count). Prints a ranked table, the winner with its confidence and the formats "
            "that read alike, and the `modscope live` command to use; or says the line was "
            "too quiet to decide, or that the port has no line settings to find."
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
