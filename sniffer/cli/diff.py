"""Provides `modscope diff`: what changed on a bus between two captures of it."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TextIO

from sniffer.analysis.diff import Side, diff_sides
from sniffer.cli.options import SubParsers, add_line_options, add_network_options, read_options
from sniffer.cli.replay import REPLAY_WINDOW
from sniffer.session.session import open_session
from sniffer.text import plain


def cmd_diff(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    # each capture counted a segment of rows at a time (`Side`), A before B: B's values
    # are held to the ranges A kept as they are met; no capture is kept whole
    sides: list[Side] = []
    for name in (args.a, args.b):
        side = Side(before=sides[0] if sides else None)
        session, capture = open_session(Path(name), read_options(args))
        session.ingest(capture.chunks(), window=REPLAY_WINDOW, segment=side, bounded=True)
        for w in capture.warnings:
            err.write(f"modscope: warning: {plain(w)}\n")
        sides.append(side)
    result = diff_sides(sides[0], sides[1], args.a, args.b)
    for line in result.text().splitlines():
        out.write(plain(line, 2000) + "\n")
    return 0 if result.same else 1


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "diff",
        help="compare two captures of the same bus",
        description=(
            "Compare two captures of one bus: first units that went silent or answer\n"
            "again and repeating requests that began failing (timeouts, exceptions) or\n"
            "recovered, with counts and shares; then units and repeating requests that\n"
            "appeared or vanished, poll periods and answer times that changed, and\n"
            "registers whose values in B left the range they kept in A.\n\n"
            "Times are compared only as far as each capture's stamps back them (as\n"
            "replay --stats shows them): a recording read every 16 ms bounds a fast\n"
            "answer (<48ms) and is no change against 2 ms; the last lines say which\n"
            "side's stamps left answer times uncompared. Each capture is read a segment\n"
            "at a time, keeping 8 bytes an answer for the medians (1M frames a side:\n"
            "about 110 MB).\n\n"
            "Exit status: 0 no difference, 1 the captures differ, 2 an error (a file\n"
            "missing or unreadable, named with the fix)."
        ),
        epilog="example:\n  modscope diff monday.pcapng friday.pcapng",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("a", metavar="A", help="the earlier capture")
    p.add_argument("b", metavar="B", help="the later capture")
    add_line_options(p)
    add_network_options(p)
    p.set_defaults(func=cmd_diff)
