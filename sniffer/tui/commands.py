"""Provides the `tui` and `serve` commands (Textual is imported only when they run).

`modscope tui [FILE]` opens the TUI even when stdout is not a terminal (textual-serve
runs it that way); `modscope serve [FILE]` serves the same app in a web browser through
the optional `textual-serve` package (`pip install modscope[serve]`).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

if TYPE_CHECKING:
    SubParsers = argparse._SubParsersAction[argparse.ArgumentParser]
else:
    SubParsers = Any

SERVE_MISSING = (
    "modscope: error: `modscope serve` needs the optional textual-serve package; "
    "install it with: pip install 'modscope[serve]'\n"
)


def register(sub: SubParsers) -> None:
    from sniffer.cli import add_device_options, add_line_options

    p = sub.add_parser(
        "tui",
        help="open the TUI on a capture (the bundled demo without FILE)",
        description="Open the TUI on a capture, even when stdout is not a terminal.",
    )
    p.add_argument("file", nargs="?", help="capture file (default: the bundled demo)")
    add_line_options(p)
    add_device_options(p)
    p.add_argument(
        "--speed",
        choices=("fast", "original"),
        default="fast",
        help="index as fast as possible (default) or replay at the capture's own speed",
    )
    p.set_defaults(func=cmd_tui)

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


def _capture_path(args: argparse.Namespace) -> Path:
    from sniffer.session import DEMO_CAPTURE

    if args.file:
        path = Path(args.file)
        if not path.is_file():
            raise ValueError(f"{path}: no such file; give the path of a capture to show")
        return path
    if not DEMO_CAPTURE.exists():
        raise ValueError(f"the demo capture {DEMO_CAPTURE} is missing; give a capture FILE")
    return DEMO_CAPTURE


def cmd_tui(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from sniffer.cli import bindings_for, read_options
    from sniffer.session import DEMO_BUS, open_session

    path = _capture_path(args)
    bindings = bindings_for(args, DEMO_BUS if not args.file else None)
    options = read_options(args)
    session, capture = open_session(path, options, bindings=bindings, timeout=args.timeout)
    from sniffer.tui.app import run_tui

    return run_tui(session, capture, speed=1.0 if args.speed == "original" else None)


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
    _capture_path(args)  # fail here, not in the browser, when there is nothing to show
    try:
        from textual_serve.server import Server
    except ImportError:
        err.write(SERVE_MISSING)
        return 2
    command = shlex.join([sys.executable, "-m", "sniffer.cli", *forwarded(args)])
    server = Server(command, host=args.host, port=args.port, title="modscope")
    server.serve()
    return 0
