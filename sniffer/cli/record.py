"""Provides `modscope record`: every read of one or two ports to pcapng (link type 250),
undecoded, with an optional ring buffer."""

from __future__ import annotations

import argparse
import time
from typing import TYPE_CHECKING, TextIO

from sniffer.cli.lines import (
    add_port_options,
    add_recording_options,
    announce,
    check_reader,
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
from sniffer.cli.metrics import add_metrics_options, live_outputs, open_metrics
from sniffer.cli.options import SubParsers, add_device_options, bindings_for
from sniffer.errors import UsageError
from sniffer.framing.pipeline import LIVE_MERGE_SLACK
from sniffer.live.engine import WINDOW_ROWS, LiveCapture
from sniffer.outputs.mqtt.command import add_mqtt_options, live_publisher
from sniffer.session.session import Session

if TYPE_CHECKING:
    from sniffer.outputs.mqtt.publish import BusPublisher


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
    notify = notifier(err)
    session: Session | None = None
    publisher: BusPublisher | None = None
    metrics = None
    if args.mqtt or args.metrics:
        # publishing and metrics need the frames: the session frames what is recorded, as
        # live does
        try:
            bindings = bindings_for(args)
            session = Session(
                specs[0].line,
                bindings=bindings,
                timeout=args.timeout,
                source=", ".join(s.name for s in specs),
                merge_slack=LIVE_MERGE_SLACK,
            )
            metrics = open_metrics(args, err)
            publisher = live_publisher(
                args, session, bindings, specs, reader.clock.now, notify, err
            )
        except BaseException:
            reader.stop()
            recorder.close(reader.clock.now())
            if metrics is not None:
                metrics.close()
            raise
        if metrics is not None:
            metrics.watch(
                session.source,
                session,
                bindings,
                clock=reader.clock.now,
                lost=lambda: capture.lost_bytes,
            )
    capture = LiveCapture(
        reader,
        session,
        recorder=recorder,
        queue_size=queue,
        notify=notify,
        publisher=live_outputs(publisher, metrics),  # (the metrics taken after each pump)
        window=WINDOW_ROWS,  # --mqtt: rows published are let go
    )
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
                if session is not None:
                    capture.pump(wait)  # frames for the outputs; the recording has its own
                else:
                    stop.wait(wait)
                if show:
                    err.write("\r" + status(capture) + _published(publisher) + "\x1b[K")
                    err.flush()
    finally:
        capture.stop()
        if metrics is not None:
            metrics.close()
    if show:
        err.write("\r\x1b[K")
    err.write(f"modscope: {status(capture)}{_published(publisher)}\n")
    check_reader(capture)
    if recorder.stopped is not None:
        # said once already, as it happened: 1 for a full disk (the file ends with a
        # record saying so), 0 for a closed pipe (its reader took what it wanted)
        return recorder.status
    if capture.failure is not None:
        raise UsageError(capture.failure)
    return 0


def _published(publisher: BusPublisher | None) -> str:
    """`; 1,234 messages to the broker, 12 dropped` for the status line."""
    if publisher is None:
        return ""
    c = publisher.link.counts
    text = f"; {c.delivered:,} messages to the broker"
    if c.dropped:
        text += f", {c.dropped:,} dropped"
    if not publisher.link.connected.is_set():
        text += " (broker away, buffering)"
    return text


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "record",
        help="record a serial line to pcapng without decoding (never transmits)",
        description=(
            "Record every read of one or two ports, as the ports gave it, to pcapng (link "
            "type 250, line settings in the interface description) for `modscope replay`, "
            "with an optional ring buffer. Nothing is ever transmitted. --mqtt URL also "
            "publishes the bus to a broker (docs/mqtt.md); the recording never waits for it."
        ),
    )
    add_port_options(p)
    add_recording_options(p, required=True)
    add_device_options(p)
    add_mqtt_options(p)
    add_metrics_options(p)
    p.set_defaults(func=cmd_record)
