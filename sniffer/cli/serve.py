"""Provides `modscope serve`: the TUI in a web browser, one app per visitor, through the
optional textual-serve package (`pip install 'modscope[serve]'`)."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path
from typing import TextIO

from sniffer.cli.options import SubParsers, add_device_options, add_line_options
from sniffer.cli.tui import capture_path

SERVE_MISSING = (
    "modscope: error: `modscope serve` needs the optional textual-serve package; "
    "install it with: pip install 'modscope[serve]'\n"
)


def forwarded(args: argparse.Namespace) -> list[str]:
    """The `tui` command line that shows what `serve` was asked to show."""
    argv = ["tui"]
    if args.file:
        argv.append(str(Path(args.file).resolve()))
    for name in ("baud", "bytesize", "parity", "stopbits", "mode", "timeout"):
        value = getattr(args, name, None)
        if value is not None:
            argv += [f"--{name}", str(value)]
    if args.bus:
        argv += ["--bus", str(Path(args.bus).resolve())]
    for unit in args.unit:
        argv += ["--unit", unit]
    for d in args.dict:
        argv += ["--dict", str(Path(d).resolve())]
    return argv


def cmd_serve(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    capture_path(args)  # fail here, not in the browser, when there is nothing to show
    try:
        from textual_serve.server import Server
    except ImportError:
        err.write(SERVE_MISSING)
        return 2
    command = shlex.join([sys.executable, "-m", "sniffer.cli", *forwarded(args)])
    server = Server(command, host=args.host, port=args.port, title="modscope")
    server.serve()
    return 0


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "serve",
        help="serve the TUI in a web browser (needs modscope[serve])",
        description="Serve the TUI on a capture in a web browser, one app per visitor.",
    )
    p.add_argument("file", nargs="?", help="capture file (default: the bundled demo)")
    p.add_argument("--host", default="localhost", help="address to listen on (default localhost)")
    p.add_argument("--port", type=int, default=8000, help="port to listen on (default 8000)")
    add_line_options(p)
    add_device_options(p)
    p.set_defaults(func=cmd_serve)
