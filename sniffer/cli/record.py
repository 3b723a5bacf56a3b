"""Provides `modscope record`: every read of one or two ports to pcapng (link type 250),
undecoded, with an optional ring buffer."""

from __future__ import annotations

import argparse
import time
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
    ring_options,
    status,
    stop_requests,
)
from sniffer.cli.options import SubParsers
from sniffer.errors import UsageError


def cmd_record(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    specs = port_specs(args)
    ring = ring_options(args)
    deadline = duration_option(args)
    queue = queue_option(args)
    reader = open_reader(specs, err)
    try:
        recorder = open_recorder(args, specs, ring)
    except BaseException:
        reader.stop()
        raise
    assert recorder is not None
    capture = LiveCapture(reader, None, recorder=recorder, queue_size=queue, notify=notifier(err))
    announce(err, "recording", specs, recorder)
    end = None if deadline is None else time.monotonic() + deadline
    show = err.isatty()
    try:
        with stop_requests() as stop:
            capture.start()
            while capture.running and not stop.is_set():
                wait = 0.2 if end is None else min(0.2, end - time.monotonic())
                if wait <= 0:
                    break
                stop.wait(wait)
                if show:
                    err.write("\r" + status(capture) + "\x1b[K")
                    err.flush()
    finally:
        capture.stop()
    if show:
        err.write("\r\x1b[K")
    err.write(f"modscope: {status(capture)}\n")
    if capture.failure is not None:
        raise UsageError(capture.failure)
    return 0


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "record",
        help="record a serial line to pcapng without decoding (never transmits)",
        description=(
            "Record every read of one or two ports, as the ports gave it, to pcapng (link "
            "type 250, line settings in the interface description) for `modscope replay`, "
            "with an optional ring buffer. Nothing is ever transmitted."
        ),
    )
    add_port_options(p)
    add_recording_options(p, required=True)
    p.set_defaults(func=cmd_record)
