"""Provides `modscope doctor`: a capture read to the end and turned into ranked findings
(`sniffer.analysis.doctor`), as text or JSON, with an exit status a script can act on."""

from __future__ import annotations

import argparse
import json
import re
import time
from collections.abc import Mapping
from pathlib import Path
from typing import TextIO

from sniffer.analysis.doctor import diagnose, report, response_bounds
from sniffer.cli.lines import (
    announce,
    check_reader,
    duration_option,
    notifier,
    open_reader,
    status,
    stop_requests,
)
from sniffer.cli.options import (
    SubParsers,
    add_device_options,
    add_line_options,
    add_network_options,
    bindings_for,
    line_of,
    line_warnings,
    read_options,
)
from sniffer.cli.verdicts import finish_read
from sniffer.errors import UsageError
from sniffer.framing.pipeline import LIVE_MERGE_SLACK
from sniffer.live.engine import LiveCapture
from sniffer.live.port import PortSpec
from sniffer.meaning.annotate import Binding
from sniffer.session.session import Session, open_session
from sniffer.text import plain


def cmd_doctor(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    bindings = bindings_for(args)
    name = args.capture
    if _is_port(name):
        session = listen(args, name, bindings, err)
        title = f"{name} ({session.line.describe()}, mode {session.mode}, listened to)"
    else:
        if args.duration is not None:
            raise UsageError(f"--duration is for listening to a port; {name} is a file")
        path = Path(name)
        options = read_options(args)
        session, capture = open_session(path, options, bindings=bindings, timeout=args.timeout)
        session.ingest(capture.chunks())
        session.warnings.extend(capture.warnings)
        told = line_warnings(options, capture.info.recorded_line, str(path))
        for w in [*told, *session.warnings]:
            err.write(f"modscope: warning: {plain(w)}\n")
        if capture.empty:
            return finish_read(capture, session, err)  # (2: nothing could be read)
        title = f"{path} ({session.line.describe()}, mode {session.mode})"
    bounds = response_bounds({u: b.dictionary.timing for u, b in bindings.items()})
    diagnosis = diagnose(session.store, session.line, session.pipeline.pairer.timeout, bounds)
    if args.format == "json":
        out.write(json.dumps([f.record() for f in diagnosis.findings], indent=2) + "\n")
    else:
        labels = {u: b.label for u, b in bindings.items()}
        out.write(report(diagnosis, title, labels))
    return diagnosis.status


def _is_port(name: str) -> bool:
    """A serial port (a character device, a path under /dev, COM3, or a pyserial URL
    such as socket://host:4001) rather than a capture file."""
    if "://" in name or name.startswith("/dev/") or re.fullmatch(r"COM\d+", name):
        return True  # (a port that is missing is told as a port, not as a file)
    try:
        return Path(name).is_char_device()
    except OSError:
        return False


def listen(
    args: argparse.Namespace, name: str, bindings: Mapping[int, Binding], err: TextIO
) -> Session:
    """Listen to the port, never transmitting, for --duration (or until Ctrl-C), and
    return the session with every row heard."""
    line = line_of(read_options(args))
    duration = duration_option(args)
    specs = [PortSpec(name, line, channel=0)]
    reader = open_reader(specs, err)
    session = Session(
        line, bindings=bindings, timeout=args.timeout, source=name, merge_slack=LIVE_MERGE_SLACK
    )
    capture = LiveCapture(reader, session, notify=notifier(err))
    announce(err, "listening on", specs, None)
    end = None if duration is None else time.monotonic() + duration
    try:
        with stop_requests() as stop:
            capture.start()
            while capture.running and not stop.is_set():
                wait = 0.2 if end is None else min(0.2, end - time.monotonic())
                if wait <= 0:
                    break
                capture.pump(wait)
    finally:
        capture.stop()
    check_reader(capture)
    if capture.failure is not None:
        raise UsageError(capture.failure)
    err.write(f"modscope: {status(capture)}\n")
    return session


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
            "  modscope doctor /dev/ttyUSB0 --baud 19200 --duration 60s\n"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "capture",
        metavar="CAPTURE|PORT",
        help="the capture file to diagnose, or a serial port to listen to (never transmitting)",
    )
    p.add_argument(
        "--duration",
        metavar="TIME",
        help="with a PORT: listen this long (30s, 15m, 1h), then diagnose (default: until Ctrl-C)",
    )
    p.add_argument(
        "--format", choices=("text", "json"), default="text", help="text (default) or json"
    )
    add_line_options(p)
    add_network_options(p)
    add_device_options(p)
    p.set_defaults(func=cmd_doctor)
