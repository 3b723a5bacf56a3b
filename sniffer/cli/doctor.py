"""Provides `modscope doctor`: a capture read to the end and turned into ranked findings
(`sniffer.analysis.doctor`), as text or JSON, with an exit status a script can act on."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TextIO

from sniffer.analysis.doctor import diagnose, report, response_bounds
from sniffer.cli.options import (
    SubParsers,
    add_device_options,
    add_line_options,
    add_network_options,
    bindings_for,
    line_warnings,
    read_options,
)
from sniffer.cli.verdicts import finish_read
from sniffer.errors import UsageError
from sniffer.session.session import open_session
from sniffer.text import plain


def cmd_doctor(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    path = Path(args.capture)
    if path.is_char_device():
        raise UsageError(
            f"{path}: doctor reads capture files; record the line first "
            f"(`modscope record {path} -o bus.pcapng --duration 60`) and give the recording"
        )
    options = read_options(args)
    bindings = bindings_for(args)
    session, capture = open_session(path, options, bindings=bindings, timeout=args.timeout)
    session.ingest(capture.chunks())
    session.warnings.extend(capture.warnings)
    for w in [*line_warnings(options, capture.info.recorded_line, str(path)), *session.warnings]:
        err.write(f"modscope: warning: {plain(w)}\n")
    if capture.empty:
        return finish_read(capture, session, err)  # (2: nothing could be read)
    bounds = response_bounds({u: b.dictionary.timing for u, b in bindings.items()})
    diagnosis = diagnose(session.store, session.line, session.pipeline.pairer.timeout, bounds)
    if args.format == "json":
        out.write(json.dumps([f.record() for f in diagnosis.findings], indent=2) + "\n")
    else:
        labels = {u: b.label for u, b in bindings.items()}
        what = f"{session.line.describe()}, mode {session.mode}"
        out.write(report(diagnosis, f"{plain(str(path))} ({plain(what)})", labels))
    return diagnosis.status


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "doctor",
        help="diagnose a bus from a capture: ranked findings with evidence and advice",
        description=(
            "Read a capture to the end and say what is wrong with the bus: silent and "
            "intermittent units, slow answers, two devices on one address, two masters, "
            "an overloaded line, errors that follow one station, polls that always earn "
            "an exception, wrong line settings, RTU timing violations (exact times only) "
            "and what writes changed. Ranked by what to fix first (docs/doctor.md)."
        ),
        epilog=(
            "exit status:\n"
            "  0  no finding is a warning or an error\n"
            "  1  some finding is a warning or an error\n"
            "  2  the capture cannot be read, or a usage error\n\n"
            "examples:\n"
            "  modscope doctor bus.pcapng\n"
            "  modscope doctor bus.pcapng --format json --bus site.toml\n"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("capture", metavar="CAPTURE", help="the capture file to diagnose")
    p.add_argument(
        "--format", choices=("text", "json"), default="text", help="text (default) or json"
    )
    add_line_options(p)
    add_network_options(p)
    add_device_options(p)
    p.set_defaults(func=cmd_doctor)
