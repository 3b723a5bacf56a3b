"""Provides the `modscope` command line: replay, live, record, export, ports, dict, serve."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TextIO

from dissectors.dictionary import DictionaryError
from sniffer import __version__
from sniffer.annotate import Binding, load_bindings
from sniffer.listing import FORMATS, Lister
from sniffer.session import Session
from sniffer.sources import Capture, CaptureError, ReadOptions
from sniffer.text import plain

EPILOG = """\
examples:
  modscope                                 open the TUI on the bundled demo capture
  modscope replay                          list the demo capture's frames
  modscope replay bus.pcapng --stats       per-unit statistics of a capture
  modscope replay scope.sr --probe RX --probe TX --baud 9600 --parity N
  modscope replay log.txt --format jsonl   one JSON object per frame
  modscope live /dev/ttyUSB0 --baud 19200  watch a line (never transmits)
  modscope dict show rvs-dn                what a device dictionary knows
"""


class UsageError(Exception):
    """A problem with what the user asked for; printed without a traceback."""


def add_line_options(p: argparse.ArgumentParser) -> None:
    """The line settings every command takes (a file's own settings are the default)."""
    g = p.add_argument_group("line settings (default: what the capture recorded, else 19200 8E1)")
    g.add_argument("--baud", type=int, metavar="N", help="baud rate")
    g.add_argument("--bytesize", type=int, choices=(7, 8), help="data bits")
    g.add_argument("--parity", type=str.upper, choices=("N", "E", "O"), help="parity")
    g.add_argument("--stopbits", type=int, choices=(1, 2), help="stop bits")
    g.add_argument(
        "--mode", choices=("rtu", "ascii", "auto"), help="framing (default auto: from the traffic)"
    )
    g.add_argument(
        "--timeout",
        type=float,
        metavar="S",
        help="response timeout in seconds (default: 0.2 s plus a longest frame's time)",
    )


def add_device_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("device dictionaries")
    g.add_argument("--bus", metavar="FILE", help="bus file binding slave addresses to models")
    g.add_argument(
        "--unit",
        action="append",
        default=[],
        metavar="ADDR=MODEL[:LABEL]",
        help="bind one address, e.g. --unit 3=rvs-dn (repeatable; wins over --bus)",
    )
    g.add_argument(
        "--dict",
        action="append",
        default=[],
        metavar="FILE",
        help="a dictionary of your own (repeatable)",
    )


def add_output_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("output")
    g.add_argument(
        "--format",
        choices=FORMATS,
        help="plain listing instead of the TUI: text, jsonl or csv (default when piped: text)",
    )
    g.add_argument("--time", choices=("rel", "abs"), default="rel", help="time column style")


def read_options(args: argparse.Namespace) -> ReadOptions:
    return ReadOptions(
        baud=args.baud,
        bytesize=args.bytesize,
        parity=args.parity,
        stopbits=args.stopbits,
        mode=args.mode,
        probes=tuple(getattr(args, "probe", None) or ()),
        invert=bool(getattr(args, "invert", False)),
    )


def bindings_for(args: argparse.Namespace, default_bus: Path | None = None) -> dict[int, Binding]:
    bus = args.bus or (str(default_bus) if default_bus and default_bus.exists() else None)
    return load_bindings(bus, args.unit, args.dict)


# -- replay -------------------------------------------------------------------------------


def cmd_replay(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from sniffer.session import DEMO_BUS, DEMO_CAPTURE, open_session

    path = Path(args.file) if args.file else DEMO_CAPTURE
    bindings = bindings_for(args, DEMO_BUS if not args.file else None)
    if not args.file and not DEMO_CAPTURE.exists():
        raise UsageError(f"the demo capture {DEMO_CAPTURE} is missing; give a capture FILE")
    use_tui = args.format is None and not args.stats and out.isatty() and sys.stdin.isatty()
    session, capture = open_session(
        path, read_options(args), bindings=bindings, timeout=args.timeout
    )
    if use_tui:
        from sniffer.tui.app import run_tui

        def reopen() -> tuple[Session, Capture]:
            return open_session(path, read_options(args), bindings=bindings, timeout=args.timeout)

        return run_tui(session, capture, reopen=reopen)
    show_progress = err.isatty()

    def progress(done: int, frames: int) -> None:
        if show_progress:
            err.write(f"\rindexing {path.name}: {done / 1e6:.1f} MB, {frames:,} rows")
            err.flush()

    session.ingest(capture.chunks(), progress)
    if show_progress:
        err.write("\r\x1b[K")
    session.warnings.extend(capture.warnings)
    for w in session.warnings:
        err.write(f"modscope: warning: {plain(w)}\n")
    if args.stats:
        labels = {u: b.label for u, b in bindings.items()}
        out.write(f"{path} ({session.line.describe()}, mode {session.mode})\n")
        out.write(session.stats.table(labels) + "\n")
        return 0
    lister = Lister(out, args.format or "text", session.describer, absolute=args.time == "abs")
    lister.write(range(len(session.store)), flush=False)
    out.flush()
    return 0


# -- dict ---------------------------------------------------------------------------------


def cmd_dict(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from dissectors.dictionary import (
        builtin_models,
        describe,
        import_csv,
        import_home_assistant,
        load_dictionary,
        load_model,
    )

    if args.action == "list":
        for name, path in sorted(builtin_models().items()):
            d = load_dictionary(path)
            out.write(f"{name:<12} {d.name}  ({len(d.entries)} entries)\n")
        return 0
    if args.action == "check":
        bad = 0
        for file in args.files:
            try:
                if file.endswith((".yaml", ".yml")):
                    found = import_home_assistant(file)
                    out.write(f"{file}: ok, {len(found)} device(s) from Home Assistant YAML\n")
                elif file.endswith(".csv"):
                    d = import_csv(file)
                    out.write(f"{file}: ok, {len(d.entries)} entries from CSV\n")
                else:
                    d = load_dictionary(file)
                    out.write(f"{file}: ok, model {d.model}, {len(d.entries)} entries\n")
            except DictionaryError as exc:
                err.write(f"{exc}\n")
                bad += 1
        return 1 if bad else 0
    d = load_model(args.model, [Path(p) for p in args.dict])
    out.write(describe(d) + "\n")
    return 0


# -- the parser ---------------------------------------------------------------------------

Command = Callable[[argparse.Namespace, TextIO, TextIO], int]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="modscope",
        description="Passive Modbus RTU/ASCII bus analyser: live RS-485 lines and capture files.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"modscope {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser(
        "replay",
        help="frame, pair and decode a capture file (the bundled demo without FILE)",
        description=(
            "Read a capture (pcap/pcapng, sigrok .sr, socat -x or hexdump text, raw bytes; "
            "recognised from its content) and show every frame: in the TUI on a terminal, "
            "as a listing with --format or when piped."
        ),
    )
    p.add_argument("file", nargs="?", help="capture file (default: the bundled demo)")
    add_line_options(p)
    g = p.add_argument_group("logic analyser captures (.sr)")
    g.add_argument(
        "--probe",
        action="append",
        metavar="NAME|N",
        help="probe carrying UART data; give it twice for one probe per direction "
        "(requests first, then responses)",
    )
    g.add_argument("--invert", action="store_true", help="idle-low levels (RS-232 side)")
    add_device_options(p)
    add_output_options(p)
    p.add_argument("--stats", action="store_true", help="print the per-unit statistics table")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("dict", help="device dictionaries: list, show, check")
    dsub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    d = dsub.add_parser("list", help="the device models modscope ships")
    d.set_defaults(func=cmd_dict)
    d = dsub.add_parser("show", help="every entry a model's dictionary has")
    d.add_argument("model", help="model name (see `modscope dict list`)")
    d.add_argument("--dict", action="append", default=[], metavar="FILE", help="your own file")
    d.set_defaults(func=cmd_dict)
    d = dsub.add_parser("check", help="validate dictionary files (TOML, HA YAML, CSV)")
    d.add_argument("files", nargs="+", metavar="FILE")
    d.set_defaults(func=cmd_dict)

    for register in _extra_commands():
        register(sub)
    return parser


def _extra_commands() -> list[
    Callable[[argparse._SubParsersAction[argparse.ArgumentParser]], None]
]:
    """Commands that live in their own modules (live capture, export, the TUI). Imported
    here, not at the top: those modules build on this one's option helpers."""
    from sniffer import export, live
    from sniffer.tui import commands

    return [live.register, export.register, commands.register]


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    out, err = sys.stdout, sys.stderr
    if args.command is None:
        # the bundled demo: in the TUI on a terminal, as a listing when piped
        args = parser.parse_args(["replay"])
    func: Command = args.func
    try:
        return func(args, out, err)
    except (CaptureError, DictionaryError, UsageError, ValueError) as exc:
        err.write(f"modscope: error: {plain(str(exc), 2000)}\n")
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    sys.exit(main())
