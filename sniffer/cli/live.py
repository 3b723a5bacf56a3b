"""Provides `modscope live`: watch serial lines as they run, in the TUI or as a listing
flushed per row, optionally recording (-w) and streaming to Wireshark (--pcap)."""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import sys
import time
from collections.abc import Callable
from typing import TextIO

from sniffer.capture import LiveCapture
from sniffer.cli.lines import (
    add_port_options,
    add_recording_options,
    announce,
    duration_option,
    notifier,
    open_reader,
    open_recorder,
    port_specs,
    queue_option,
    quiet_stdout,
    ring_options,
    stop_requests,
)
from sniffer.cli.options import SubParsers, add_device_options, add_output_options, bindings_for
from sniffer.errors import UsageError
from sniffer.export import PcapExporter
from sniffer.listing import Lister
from sniffer.pipeline import LIVE_MERGE_SLACK
from sniffer.session import Session
from sniffer.vocab import Status


def cmd_live(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    specs = port_specs(args)
    ring = ring_options(args)
    deadline = duration_option(args)
    queue = queue_option(args)
    if args.write == "-":
        raise UsageError("live writes its listing to standard output; record with -w FILE")
    if args.pcap == "-" and args.format is not None:
        raise UsageError("--pcap - takes standard output for itself; drop --format")
    if args.pcap and args.write and os.path.abspath(args.pcap) == os.path.abspath(args.write):
        raise UsageError("--pcap and -w name the same file; give each its own")
    bindings = bindings_for(args)
    session = Session(
        specs[0].line,
        bindings=bindings,
        timeout=args.timeout,
        source=", ".join(s.name for s in specs),
        merge_slack=LIVE_MERGE_SLACK,
    )
    use_tui = (
        args.format is None
        and args.pcap is None
        and out.isatty()
        and sys.stdin.isatty()
        and _tui_available()
    )
    reader = open_reader(specs, err)
    try:
        recorder = open_recorder(args, specs, ring)
    except BaseException:
        reader.stop()
        raise
    capture = LiveCapture(
        reader,
        session,
        recorder=recorder,
        queue_size=queue,
        notify=None if use_tui else notifier(err),
    )
    exporter: PcapExporter | None = None
    pcap_file = None
    try:
        if args.pcap:
            try:
                pcap_file = sys.stdout.buffer if args.pcap == "-" else open(args.pcap, "wb")  # noqa: SIM115
            except OSError as exc:
                raise UsageError(
                    f"{args.pcap}: cannot be written ({exc.strerror or exc}); choose a "
                    "folder you can write to"
                ) from None
            exporter = PcapExporter(pcap_file, session.describer, specs[0].line, name=specs[0].name)
        capture.start()
        if use_tui:
            # what the ports said while opening shows in the TUI, not behind it
            capture.messages.extend(f"warning: {w}" for w in reader.warnings)
            run_tui: Callable[..., int] = importlib.import_module("sniffer.tui.app").run_tui
            return run_tui(session, None, live=capture)
        announce(err, "listening on", specs, recorder)
        lister = None
        if args.pcap != "-":
            lister = Lister(
                out,
                args.format or "text",
                session.describer,
                absolute=args.time == "abs",
                raw_csv=args.raw_csv,
            )
        return stream(capture, lister, exporter, deadline)
    finally:
        capture.stop()
        if pcap_file is not None and pcap_file is not sys.stdout.buffer:
            pcap_file.close()


def _tui_available() -> bool:
    try:
        return importlib.util.find_spec("sniffer.tui.app") is not None
    except ModuleNotFoundError:
        return False


def stream(
    capture: LiveCapture,
    lister: Lister | None,
    exporter: PcapExporter | None,
    duration: float | None,
) -> int:
    """The listing loop: rows out as they are framed, each flushed, until stopped."""
    end = None if duration is None else time.monotonic() + duration
    assert capture.session is not None
    store = capture.session.store
    waiting: list[int] = []  # requests listed while they waited for their answer

    def emit(rows: range) -> None:
        nonlocal waiting
        if lister is not None:
            store.sync()
            status = store.status
            # a request listed as open that then got no answer is listed again
            again = [i for i in waiting if status[i] == Status.TIMEOUT]
            waiting = [i for i in waiting if status[i] == Status.OPEN]
            waiting += [i for i in rows if status[i] == Status.OPEN]
            lister.write(again)
            lister.write(rows)
        if exporter is not None:
            exporter.write(rows)

    try:
        with stop_requests() as stop:
            while capture.running and not stop.is_set():
                if end is not None and time.monotonic() >= end:
                    break
                emit(capture.pump())
            emit(capture.stop())
    except BrokenPipeError:
        quiet_stdout()
        capture.stop()
        return 0
    if capture.failure is not None:
        raise UsageError(capture.failure)
    return 0


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "live",
        help="watch a serial line as it runs (never transmits)",
        description=(
            "Listen to one or two serial ports without ever transmitting (RTS and DTR are "
            "not asserted, nothing is written) and show every frame as it comes: in the "
            "TUI on a terminal, else as a listing flushed per line (--format). --write "
            "records what the ports read; --pcap streams frames for Wireshark "
            "(modscope live /dev/ttyUSB0 --pcap - | wireshark -k -i -)."
        ),
    )
    add_port_options(p)
    add_device_options(p)
    add_output_options(p)
    p.add_argument(
        "--pcap",
        metavar="FILE",
        help="also write frames as Wireshark pcapng (link type 252, Modbus RTU); - for "
        "standard output, which then carries nothing else",
    )
    add_recording_options(p, required=False)
    p.set_defaults(func=cmd_live)
