"""Provides `modscope replay`: a capture file framed, paired and decoded, as a listing,
statistics or the TUI."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TextIO

from sniffer.cli.options import (
    SubParsers,
    add_device_options,
    add_line_options,
    add_output_options,
    bindings_for,
    read_options,
)
from sniffer.errors import UsageError
from sniffer.listing import Lister
from sniffer.session import Session
from sniffer.sources import Capture
from sniffer.text import plain


def cmd_replay(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from sniffer.session import DEMO_BUS, DEMO_CAPTURE, open_session

    path = Path(args.file) if args.file else DEMO_CAPTURE
    bindings = bindings_for(args, DEMO_BUS if not args.file else None)
    if not args.file and not DEMO_CAPTURE.exists():
        raise UsageError(f"the demo capture {DEMO_CAPTURE} is missing; give a capture FILE")
    options = read_options(args)
    use_tui = args.format is None and not args.stats and out.isatty() and sys.stdin.isatty()
    session, capture = open_session(path, options, bindings=bindings, timeout=args.timeout)
    if use_tui:
        from sniffer.tui.app import run_tui

        def reopen() -> tuple[Session, Capture]:
            return open_session(path, options, bindings=bindings, timeout=args.timeout)

        return run_tui(session, capture, reopen=reopen)
    show_progress = err.isatty()

    def progress(done: int, frames: int) -> None:
        if show_progress:
            err.write(f"\rindexing {plain(path.name)}: {done / 1e6:.1f} MB, {frames:,} rows")
            err.flush()

    session.ingest(capture.chunks(), progress)
    if show_progress:
        err.write("\r\x1b[K")
    session.warnings.extend(capture.warnings)
    for w in session.warnings:
        err.write(f"modscope: warning: {plain(w)}\n")
    if args.stats:
        labels = {u: plain(b.label) for u, b in bindings.items()}
        out.write(f"{plain(str(path))} ({session.line.describe()}, mode {session.mode})\n")
        out.write(session.stats.table(labels) + "\n")
        return 0
    lister = Lister(
        out,
        args.format or "text",
        session.describer,
        absolute=args.time == "abs",
        raw_csv=args.raw_csv,
    )
    lister.write(range(len(session.store)), flush=False)
    out.flush()
    return 0


def register(sub: SubParsers) -> None:
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
